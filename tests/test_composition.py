"""Linear block + static element, and the paper's Fig. 2-3 mass + backlash system."""
import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.describing import negative_inverse

M1 = M2 = 1.0
H = 0.1
FORCES = np.array([10.0, 20.0, 30.0, 40.0, 50.0])


def test_limit_frequency_eq5_puts_the_displacement_at_half_the_clearance():
    mb = df.MassBacklash(M1, M2, H)
    wL = mb.limit_frequency(FORCES)
    np.testing.assert_allclose(wL, np.sqrt(2 * FORCES / (H * (M1 + M2))), rtol=1e-15)
    np.testing.assert_allclose(FORCES / ((M1 + M2) * wL**2), H / 2, rtol=1e-15)
    assert np.all(mb(FORCES, wL) == 0) and np.all(mb(FORCES, 2 * wL) == 0)
    assert np.all(mb(FORCES, wL * (1 - 1e-6)) != 0)


def test_fig3_values_against_numeric_df_of_python_control_backlash_composed_by_hand():
    """N(F, w) = G_m(jw) N_bl(|G_m| F), with N_bl from NumericDF driving python-control's operator."""
    mb = df.MassBacklash(M1, M2, H)
    nbl = df.NumericDF(ct.friction_backlash_nonlinearity(H), hysteretic=True)
    for F in FORCES:
        w = mb.limit_frequency(F) * np.array([0.05, 0.3, 0.7, 0.95, 0.999])
        g = -1.0 / ((M1 + M2) * w**2)
        by_hand = g * nbl(np.abs(g) * F)
        assert np.all(np.abs(mb(F, w) - by_hand) <= 1e-9 * np.abs(by_hand))


def test_fig3_negative_inverse_scales_with_force():
    """-1/N(F, w) depends on (F, w) only through X = F / (M w^2), times M w^2: at equal X the loci of
    two forces differ by the factor F2 / F1 (the paper's remark that the charts are proportional to F)."""
    mb = df.MassBacklash(M1, M2, H)
    X = np.array([0.051, 0.08, 0.3, 2.0])
    w10, w40 = np.sqrt(10 / ((M1 + M2) * X)), np.sqrt(40 / ((M1 + M2) * X))
    r10 = negative_inverse(mb, 10.0, w10)
    r40 = negative_inverse(mb, 40.0, w40)
    np.testing.assert_allclose(r40, 4 * r10, rtol=1e-13)


@pytest.mark.parametrize("F", [10.0, 50.0])
def test_low_frequency_slopes_40_and_80_db_per_decade(F):
    mb = df.MassBacklash(M1, M2, H)
    w = mb.limit_frequency(F) * np.logspace(-4, -2, 41)  # two decades well below w_L
    r = negative_inverse(mb, F, w)
    slope_re = np.polyfit(np.log10(w), 20 * np.log10(np.abs(r.real)), 1)[0]
    slope_im = np.polyfit(np.log10(w), 20 * np.log10(np.abs(r.imag)), 1)[0]
    assert abs(slope_re - 40) < 0.5 and abs(slope_im - 80) < 0.5
    assert np.all(r.real > 0) and np.all(r.imag > 0)  # -1/N in the first quadrant


def test_linear_then_static_accepts_tf_ss_and_callable_alike():
    G = ct.tf([2.0], [1.0, 3.0, 1.0])
    sat = df.Saturation(0.5)
    w = np.array([0.1, 1.0, 7.0])
    ref = G(1j * w) * sat(np.abs(G(1j * w)) * 1.3)
    for lin in (G, ct.ss(G), lambda s: 2.0 / (s * s + 3.0 * s + 1.0)):
        np.testing.assert_allclose(df.LinearThenStatic(lin, sat)(1.3, w), ref, rtol=1e-12)


def test_amplitude_domain_is_static_domain_over_gain():
    mb = df.MassBacklash(M1, M2, H)
    w = np.array([1.0, 5.0, 10.0])
    lo, hi = mb.amplitude_domain(w)
    np.testing.assert_allclose(lo, (H / 2) * (M1 + M2) * w**2, rtol=1e-15)
    assert np.all(np.isinf(hi))
    assert np.all(mb(lo, w) == 0) and np.all(mb(lo * (1 + 1e-9), w) != 0)


def test_broadcast_and_frequency_required():
    mb = df.MassBacklash(M1, M2, H)
    assert mb(FORCES[:, None], np.array([1.0, 2.0, 3.0])).shape == (5, 3)
    with pytest.raises(ValueError, match="omega"):
        mb(10.0)
    with pytest.raises(ValueError, match="omega"):
        mb.amplitude_domain()
