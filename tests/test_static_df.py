"""Closed-form describing functions: identities, limits, the paper's form, and brute-force references."""
import control as ct
import numpy as np
import pytest
from scipy.integrate import quad

import dfloop as df


def quad_df_static(f, A, levels=()):
    """Independent reference: N = (2/(pi A)) int_{-pi/2}^{pi/2} f(A sin t) sin t dt by adaptive quadrature."""
    pts = sorted({float(s * np.arcsin(min(b / A, 1.0))) for b in levels for s in (-1, 1)})
    val, _ = quad(lambda t: float(f(A * np.sin(t))) * np.sin(t), -np.pi / 2, np.pi / 2,
                  points=pts or None, limit=400, epsabs=0.0, epsrel=1e-13)
    return 2.0 * val / (np.pi * A)


def sampled_df_operator(op, A, n=2**16):
    """Independent reference for hysteretic operators: warm-up period, then the DFT bin 1 of n samples."""
    theta = 2 * np.pi * np.arange(n) / n
    for t in theta:
        op(A * np.sin(t))
    y = np.array([op(A * np.sin(t)) for t in theta])
    return complex(2j * np.mean(y * np.exp(-1j * theta)) / A)


def f_design(u):
    return (2 / np.pi) * (np.arcsin(u) + u * np.sqrt(1 - u * u))


# ---------------------------------------------------------------------------------------------- backlash

@pytest.mark.parametrize("h,k", [(0.1, 1.0), (2.0, 3.5)])
def test_backlash_matches_design_eq4(h, k):
    X = h * np.array([0.51, 0.6, 0.75, 0.99, 1.01, 1.7, 4.0, 50.0])  # raw formula cancels nearer h/2
    ref = (k / 2) * (1 + f_design(1 - h / X)) - 1j * (2 * k * h / (np.pi * X**2)) * (X - h / 2)
    np.testing.assert_allclose(df.Backlash(h, k)(X), ref, rtol=1e-12, atol=0)


def test_backlash_matches_paper_form_with_principal_asin():
    """Paper eq. (4a)-(4b): Re N = (k/2)[1 - N_s(z)], z = (X/h)/(1 - X/h), N_s evaluated as f(1/z)."""
    h, k = 0.1, 1.0
    X = h * np.array([0.55, 0.8, 1.3, 2.0, 9.0])
    z = (X / h) / (1 - X / h)
    Ns = (2 / np.pi) * (np.arcsin(1 / z) + (1 / z) * np.cos(np.arcsin(1 / z)))
    ref = (k / 2) * (1 - Ns) - 1j * 2 * k * h * (X - h / 2) / (np.pi * X**2)
    np.testing.assert_allclose(df.Backlash(h, k)(X), ref, rtol=1e-12)


def test_backlash_imaginary_part_exact_near_the_dead_band_edge():
    """Im N = -(2 k h / (pi X^2))(X - h/2) with the rational part in exact arithmetic."""
    from fractions import Fraction as F
    h = 0.1
    for X in (h / 2 * (1 + 1e-12), h / 2 * (1 + 1e-9), h * (1 + 1e-9)):
        q = 2 * F(h) / F(X) ** 2 * (F(X) - F(h) / 2)
        assert abs(df.Backlash(h)(X).imag + float(q) / np.pi) <= 4e-16 * float(q) / np.pi


def test_backlash_checkpoints():
    h, k = 0.1, 2.0
    b = df.Backlash(h, k)
    assert b(h / 2) == 0
    assert abs(b(h) - (k / 2 - 1j * k / np.pi)) < 1e-15
    assert abs(b(1e9 * h) - k) < 1e-8 * k
    assert b(np.inf) == k
    lo, hi = b.amplitude_domain()
    assert lo == h / 2 and hi == np.inf
    assert b(lo * (1 + 1e-12)) != 0


def test_backlash_dead_band_is_exact_zero_and_nan_is_local():
    b = df.Backlash(0.1)
    X = np.array([0.0, 0.01, 0.05, np.nan, 0.2])
    n = b(X)
    assert np.all(n[:3] == 0) and not np.any(np.isnan(n[:3]))
    assert np.isnan(n[3]) and np.isfinite(n[4])


def test_backlash_broadcasts_and_rejects_negative_amplitude():
    b = df.Backlash(0.1)
    assert b(np.ones((3, 1)) * np.array([0.06, 0.2, 1.0])).shape == (3, 3)
    with pytest.raises(ValueError, match="X"):
        b([0.1, -0.1])


def test_play_operator_matches_python_control_friction_backlash():
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(scale=0.05, size=2000))
    mine, theirs = df.Backlash(0.3, k=1.0).operator(), ct.friction_backlash_nonlinearity(0.3)
    assert [mine(v) for v in x] == [float(theirs(v)) for v in x]
    scaled = df.Backlash(0.3, k=2.5).operator()
    fresh = ct.friction_backlash_nonlinearity(0.3)
    np.testing.assert_allclose([scaled(v) for v in x], [2.5 * fresh(v) for v in x], rtol=1e-15)


def test_backlash_closed_form_against_sampled_operator():
    h = 0.1
    for X in (0.06, 0.1, 0.37):
        ref = sampled_df_operator(df.Backlash(h).operator(), X)
        assert abs(df.Backlash(h)(X) - ref) < 2e-4 * abs(ref)


# ------------------------------------------------------------------------------------ saturation, dead zone

def test_saturation_plus_dead_zone_is_the_linear_gain():
    """sat(x) + dz(x) = k x, and the DF is linear in the element: N_sat + N_dz = k for every A."""
    A = np.geomspace(1e-3, 1e6, 200)
    total = df.Saturation(0.7, 3.0)(A) + df.DeadZone(0.7, 3.0)(A)
    np.testing.assert_allclose(total, 3.0, rtol=1e-14)


@pytest.mark.parametrize("el,levels", [
    (df.Saturation(0.7, 3.0), [0.7]),
    (df.DeadZone(0.7, 3.0), [0.7]),
    (df.CubicStiffness(2.0, -0.4), []),
    (df.Quantizer(0.25), [0.125, 0.375, 0.625, 0.875, 1.125, 1.375, 1.625, 1.875]),
    (df.PreloadedSpring(1.5, 2.0), [0.0]),
    (df.CoulombViscousFriction(0.8, 0.3), [0.0]),
])
def test_static_closed_forms_against_adaptive_quadrature(el, levels):
    for A in (0.2, 0.69, 0.71, 1.0, 1.9):
        ref = quad_df_static(el.output, A, levels)
        assert abs(el(A) - ref) <= 1e-11 * max(abs(ref), 1e-300) + 1e-15


def test_dead_zone_and_quantizer_zero_inside_band():
    assert np.all(df.DeadZone(1.0)([0.0, 0.5, 1.0]) == 0)
    assert np.all(df.Quantizer(1.0)([0.0, 0.3, 0.5]) == 0)
    assert df.Saturation(1.0)(0.0) == 1.0


def test_quantizer_tends_to_unit_gain():
    n = df.Quantizer(1.0)(np.array([10.0, 100.0, 1000.0]))
    assert np.all(np.abs(n - 1) < np.array([1e-2, 1e-3, 1e-4]))


def test_quantizer_level_bound_raises():
    with pytest.raises(ValueError, match="levels"):
        df.Quantizer(1e-9)(1.0)


# ---------------------------------------------------------------------------------------------------- relay

def test_relay_special_cases():
    A = np.array([1.0, 1.3, 2.0, 10.0])
    M, a, d = 2.0, 0.6, 0.8
    np.testing.assert_allclose(df.Relay(M)(A), 4 * M / (np.pi * A), rtol=1e-15)
    np.testing.assert_allclose(df.Relay(M, hysteresis=a)(A),
                               4 * M / (np.pi * A) * np.exp(-1j * np.arcsin(a / A)), rtol=1e-14)
    np.testing.assert_allclose(df.Relay(M, dead_zone=d)(A),
                               4 * M * np.sqrt(1 - (d / A) ** 2) / (np.pi * A), rtol=1e-14)


def test_relay_zero_below_switching_and_infinite_at_zero_for_ideal():
    assert np.all(df.Relay(1.0, 0.2, 0.5)([0.0, 0.3, 0.69]) == 0)
    assert np.all(df.Relay(1.0, hysteresis=0.5)([0.0, 0.49, 0.5]) == 0)
    assert df.Relay(1.0)(0.0) == np.inf


@pytest.mark.parametrize("a,d", [(0.3, 0.0), (0.0, 0.5), (0.2, 0.5), (0.5, 0.2)])
def test_relay_closed_form_against_sampled_operator(a, d):
    rel = df.Relay(1.5, hysteresis=a, dead_zone=d)
    for A in (0.8, 1.1, 3.0):
        ref = sampled_df_operator(rel.operator(), A)
        assert abs(rel(A) - ref) < 2e-4 * abs(ref)


def test_relay_operator_switching_sequence():
    op = df.Relay(1.0, hysteresis=0.25, dead_zone=0.5).operator()  # on at 0.75, off at 0.25
    xs = [0.0, 0.74, 0.75, 0.76, 0.5, 0.26, 0.25, 0.24, -0.75, -0.76, -0.26, -0.24, 0.8]
    assert [op(x) for x in xs] == [0, 0, 0, 1, 1, 1, 1, 0, 0, -1, -1, 0, 1]
    hyst = df.Relay(2.0, hysteresis=0.5).operator()  # up above +0.5, down below -0.5, starts at rest
    xs = [0.0, 0.4, 0.5, 0.51, 0.0, -0.5, -0.51, 0.3, 0.5, 0.51]
    assert [hyst(x) for x in xs] == [0, 0, 0, 2, 2, 2, -2, -2, -2, 2]
    ideal = df.Relay(3.0).operator()
    assert [ideal(x) for x in [0.0, 1e-300, -2.0, 0.0]] == [0, 3, -3, -3]  # x = 0 holds the output


# ---------------------------------------------------------------------------------------------- the rest

def test_preloaded_spring_and_coulomb_are_gain_plus_relay():
    A = np.geomspace(0.01, 100, 50)
    np.testing.assert_allclose(df.PreloadedSpring(1.5, 2.0)(A), 2.0 + df.Relay(1.5)(A), rtol=1e-15)
    np.testing.assert_allclose(df.CoulombViscousFriction(0.8, 0.3)(A), 0.3 + df.Relay(0.8)(A), rtol=1e-15)


def test_cubic_stiffness_formula_and_softening_domain():
    c = df.CubicStiffness(2.0, -0.6)
    A = np.array([0.0, 0.5, 1.0])
    np.testing.assert_allclose(c(A), 2.0 - 0.45 * A**2, rtol=1e-15)
    lo, hi = c.amplitude_domain()
    assert lo == 0 and abs(c(hi)) < 1e-14


def test_static_operators_follow_output():
    for el in (df.Saturation(0.5), df.DeadZone(0.5), df.Quantizer(0.3), df.CubicStiffness(1.0, 2.0)):
        op = el.operator()
        xs = np.linspace(-2, 2, 41)
        assert [op(x) for x in xs] == [float(v) for v in el.output(xs)]


def test_every_element_exported_and_reprs():
    for name in ("Backlash", "Saturation", "DeadZone", "Relay", "CubicStiffness", "Quantizer",
                 "PreloadedSpring", "CoulombViscousFriction"):
        assert hasattr(df, name)
    assert repr(df.Backlash(0.1)) == "Backlash(h=0.1, k=1.0)"


# ------------------------------------------------------------------ limits at A = 0 and A = inf
# (element, N(0), N(inf), amplitude scale): the documented limits; the check is that N at amplitudes
# 1e-9 and 1e9 times the element's scale approaches them (an independent evaluation of the closed forms
# away from the end points), and that the end points themselves return exactly the limit, never NaN.
_LIMITS = [
    (df.Backlash(0.2, 3.0), 0.0, 3.0, 0.2),
    (df.Saturation(1.5, 2.0), 2.0, 0.0, 1.5),
    (df.DeadZone(0.5, 2.0), 0.0, 2.0, 0.5),
    (df.Relay(2.0), np.inf, 0.0, 1.0),
    (df.Relay(2.0, hysteresis=0.1), 0.0, 0.0, 0.1),
    (df.Relay(2.0, dead_zone=0.3), 0.0, 0.0, 0.3),
    (df.CubicStiffness(2.0, 0.5), 2.0, np.inf, 1.0),
    (df.CubicStiffness(2.0, -0.5), 2.0, -np.inf, 1.0),
    (df.Quantizer(0.25), 0.0, 1.0, 0.25),
    (df.PreloadedSpring(1.0, 3.0), np.inf, 3.0, 1.0),
    (df.CoulombViscousFriction(1.0, 0.5), np.inf, 0.5, 1.0),
]


@pytest.mark.parametrize("el,n0,ninf,scale", _LIMITS, ids=[repr(c[0]) for c in _LIMITS])
def test_limits_at_zero_and_infinite_amplitude(el, n0, ninf, scale):
    with np.errstate(all="raise", under="ignore"):  # no overflow or invalid-operation warnings either
        at = el(np.array([0.0, np.inf]))
    assert at[0] == n0 and at[1] == ninf
    if isinstance(el, df.Quantizer):
        big = el(1e5 * scale)  # its level bound (1e7 levels) caps the amplitude
        assert abs(big - 1.0) < 1e-8
    else:
        big = el(1e9 * scale)
        assert (abs(big - ninf) <= 1e-6 * max(1.0, abs(ninf))) if np.isfinite(ninf) else abs(big) > 1e15
    small = el(1e-9 * scale)
    assert (abs(small - n0) <= 1e-6 * max(1.0, abs(n0))) if np.isfinite(n0) else abs(small) > 1e8


@pytest.mark.parametrize("el", [c[0] for c in _LIMITS], ids=[repr(c[0]) for c in _LIMITS])
def test_extreme_finite_amplitudes_give_no_nan_and_no_warning(el):
    a = np.array([5e-324, 1e-300, 1e-150, 1e150, 1e300, 1.7e308])
    if isinstance(el, df.Quantizer):
        a = np.array([5e-324, 1e-300, 1e-150])
    with np.errstate(all="raise", under="ignore"):
        n = el(a)
    assert not np.any(np.isnan(n))


def test_composition_limits_keep_exact_zero_parts_of_G():
    ideal = df.LinearThenStatic(lambda s: 1.0 / (s * s), df.Relay(1.0))  # G(jw) = -1/w^2: real
    n = ideal(0.0, 2.0)
    assert n.real == -np.inf and n.imag == 0.0  # numpy's -0.25 * (inf + 0j) would give NaN in the imaginary part
    mb = df.MassBacklash(1.0, 3.0, 0.1, k=2.0)
    np.testing.assert_array_equal(mb([0.0, np.inf], 2.0), [0.0, -2.0 / (4.0 * 4.0)])
    with pytest.raises(ValueError, match="omega"):
        mb(1.0, np.inf)
