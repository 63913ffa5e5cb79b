"""NumericDF against every closed form: static functions, hysteretic operators, edges and huge amplitudes."""
import control as ct
import numpy as np
import pytest
from scipy.special import i1

import dfloop as df

EPS = np.finfo(float).eps


def rel_err(a, b):
    return np.abs(np.asarray(a) - np.asarray(b)) / np.abs(np.asarray(b))


@pytest.mark.parametrize("make_op", [lambda h: df.Backlash(h).operator(),
                                     lambda h: ct.friction_backlash_nonlinearity(h)])
def test_backlash_operator_at_edges_and_huge_amplitudes(make_op):
    h = 0.1
    X = np.array([h / 2 * (1 + 1e-9), h / 2 * (1 + 1e-6), 0.06, h, 0.3, 1.0, h / 2 * 1e6])
    num = df.NumericDF(make_op(h), hysteretic=True)(X)
    assert np.all(rel_err(num, df.Backlash(h)(X)) < 1e-9)


def test_backlash_element_is_taken_as_its_operator_and_slope_scales():
    X = np.array([0.07, 0.1, 2.0])
    np.testing.assert_allclose(df.NumericDF(df.Backlash(0.1, k=2.5))(X), df.Backlash(0.1, k=2.5)(X), rtol=1e-9)


STATIC = [
    (df.Saturation(0.7, 3.0), 0.7),
    (df.DeadZone(0.7, 3.0), 0.7),
    (df.CubicStiffness(2.0, 0.4), 1.0),
    (df.Quantizer(0.25), 0.125),
    (df.PreloadedSpring(1.5, 2.0), 1.0),
    (df.CoulombViscousFriction(0.8, 0.3), 1.0),
]
FACTORS = np.array([1 + 1e-6, 1.001, 1.5, 2.0, 3.3, 10.0, 1e3, 1e6])


@pytest.mark.parametrize("el,edge", STATIC)
def test_static_with_breakpoints_matches_closed_form(el, edge):
    A = edge * (FACTORS[:-1] if isinstance(el, df.Quantizer) else FACTORS)  # 4e6 levels: too slow
    num = df.NumericDF(el.output, breakpoints=el.breakpoints)(A)
    assert np.all(rel_err(num, el(A)) < 1e-9)


@pytest.mark.parametrize("el,edge", [s for s in STATIC if not isinstance(s[0], df.Quantizer)])
def test_static_switching_points_located_without_breakpoints(el, edge):
    A = edge * FACTORS
    assert np.all(rel_err(df.NumericDF(el.output)(A), el(A)) < 1e-9)


def test_static_element_is_taken_as_its_output_with_its_breakpoints():
    q = df.Quantizer(0.25)
    nd = df.NumericDF(q)
    assert not nd.hysteretic and not nd.locate
    A = np.array([0.3, 7.0, 60.0])  # 480 levels at the top: only breakpoints resolve them
    assert np.all(rel_err(nd(A), q(A)) < 1e-9)
    via_operator = df.NumericDF(df.Saturation(1.0), hysteretic=True)
    assert via_operator.hysteretic and rel_err(via_operator(2.0), df.Saturation(1.0)(2.0)) < 1e-9


def test_quantizer_located_without_breakpoints_while_levels_are_a_few_cells_apart():
    q = df.Quantizer(0.25)
    A = np.array([0.2, 0.4, 0.9, 1.3])
    assert np.all(rel_err(df.NumericDF(q.output)(A), q(A)) < 1e-9)


def test_dead_zone_right_at_the_edge_is_limited_by_conditioning_only():
    """At A = delta (1 + e) the output is O(e A) while the input carries rounding eps A: the DF's relative
    condition number is about 1/e, so agreement is bounded by a few eps / e (2e-7 for e = 1e-9)."""
    dz = df.DeadZone(1.0)
    for e in (1e-9, 1e-8):
        A = 1 + e
        assert rel_err(df.NumericDF(dz.output, breakpoints=[1.0])(A), dz(A)) < 4 * EPS / e


@pytest.mark.parametrize("a,d", [(0.0, 0.0), (0.3, 0.0), (0.0, 0.5), (0.2, 0.5), (0.5, 0.2)])
def test_relay_operators_match_closed_form(a, d):
    rel = df.Relay(1.5, hysteresis=a, dead_zone=d)
    on = a + d
    A = np.array([max(on, 0.1) * (1 + 1e-6), 0.8, 1.1, 3.0, 1e3])
    assert np.all(rel_err(df.NumericDF(rel)(A), rel(A)) < 1e-9)


def test_relay_with_hysteresis_at_and_just_above_the_switching_level():
    rel = df.Relay(1.0, hysteresis=0.5)
    assert abs(df.NumericDF(rel)(0.5)) < 1e-15 and rel(0.5) == 0  # strict crossing: no switching
    A = 0.5 * (1 + 1e-12)
    assert rel_err(df.NumericDF(rel)(A), rel(A)) < 1e-9


def test_smooth_asymmetric_function_against_bessel():
    """exp(A sin t) has fundamental 2 I1(A) sin t: N = 2 I1(A) / A (the even part adds nothing)."""
    A = np.array([0.1, 1.0, 5.0, 20.0])
    assert np.all(rel_err(df.NumericDF(np.exp)(A), 2 * i1(A) / A) < 1e-12)


def test_vectorised_shape_nan_and_zero_amplitude():
    nd = df.NumericDF(df.Saturation(1.0).output)
    out = nd(np.array([[0.5, np.nan], [2.0, 3.0]]))
    assert out.shape == (2, 2) and np.isnan(out[0, 1]) and np.all(np.isfinite(out[[0, 1, 1], [0, 0, 1]]))
    with pytest.raises(ValueError, match="A"):
        nd(0.0)


def test_non_rate_independent_operator_is_rejected():
    class Drifting:
        def __init__(self):
            self.calls = 0

        def __call__(self, x):
            self.calls += 1
            return x + 1e-3 * self.calls

    with pytest.raises(ValueError, match="periodic"):
        df.NumericDF(Drifting(), hysteretic=True)(1.0)


def test_error_estimate_bounds_the_error_and_sampled_baseline():
    sat = df.Saturation(1.0)
    coarse = df.NumericDF(sat.output, nodes=3, rtol=1e-6)
    A = np.array([1.5, 4.0])
    est = coarse.error_estimate(A)
    assert np.all(np.abs(coarse(A) - sat(A)) <= est) and np.all(est < 1e-5)
    sampled = df.NumericDF(df.Saturation(1.0).output, method="sampled", samples=4096)
    err = rel_err(sampled(2.0), df.Saturation(1.0)(2.0))
    assert 1e-12 < err < 1e-4  # sampling a kink converges only algebraically


def test_operator_is_not_mutated():
    op = df.Backlash(0.1).operator()
    df.NumericDF(op, hysteretic=True)(0.3)
    assert op.center == 0.0
