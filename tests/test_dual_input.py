"""Dual-input DF (dfloop.describing.dual_input) against an independent adaptive quadrature (scipy.integrate.quad with
the switching phases as breakpoints, derived here from each element's definition), and N_A(0, A) = N(A)."""
import numpy as np
import pytest
from scipy.integrate import quad

from dfloop import Backlash, CubicStiffness, DeadZone, PreloadedSpring, Relay, Saturation
from dfloop.describing.dual_input import DualInputDF
from dfloop.errors import DfloopError

# quad reports roundoff on the integrals that vanish (the cosine part of a static map, the mean of an odd one);
# every value is still compared to 1e-12 below
pytestmark = pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")

PAIRS = [(0.0, 0.7), (0.3, 0.7), (-0.45, 2.0), (1.2, 0.5), (0.9, 3.0), (-2.5, 1.0), (0.05, 10.0), (0.6, 1.6)]


def _phases(levels, B, A):
    out = []
    for L in levels:
        s = (L - B) / A
        if abs(s) < 1:
            out += [np.arcsin(s), np.pi - np.arcsin(s)]
    return out


def _moments(y, B, A, points):
    """(mean, N_A) of the output y(theta) by quad over [-pi/2, 3pi/2], split at ``points``."""
    kw = dict(points=sorted(points) or None, limit=400, epsabs=1e-14, epsrel=1e-13)
    lo, hi = -np.pi / 2, 1.5 * np.pi
    m = quad(y, lo, hi, **kw)[0] / (2 * np.pi)
    s = quad(lambda t: y(t) * np.sin(t), lo, hi, **kw)[0]
    c = quad(lambda t: y(t) * np.cos(t), lo, hi, **kw)[0]
    return m, (s + 1j * c) / (np.pi * A)


def _static_truth(f, levels):
    def truth(B, A):
        return _moments(lambda t: f(B + A * np.sin(t)), B, A, _phases(levels, B, A))
    return truth


def _close(dual, truth, pairs=PAIRS, tol=1e-12):
    for B, A in pairs:
        m, n = truth(B, A)
        scale = 1 + abs(n) + abs(m)
        assert abs(dual.mean(B, A) - m) <= tol * scale, (B, A)
        assert abs(dual.N_A(B, A) - n) <= tol * scale, (B, A)


@pytest.mark.parametrize("element, f, levels", [
    (Saturation(0.8, k=1.5), lambda x: 1.5 * min(max(x, -0.8), 0.8), [-0.8, 0.8]),
    (DeadZone(0.4, k=2.0), lambda x: 2.0 * (x - min(max(x, -0.4), 0.4)), [-0.4, 0.4]),
    (Relay(1.3), lambda x: 1.3 * np.sign(x), [0.0]),
    (Relay(0.7, dead_zone=0.5), lambda x: 0.7 * (x > 0.5) - 0.7 * (x < -0.5), [-0.5, 0.5]),
    (PreloadedSpring(0.4, k=2.0), lambda x: 2.0 * x + 0.4 * np.sign(x), [0.0]),
    (CubicStiffness(1.0, 0.3), lambda x: x + 0.3 * x ** 3, []),
])
def test_static_elements_match_quadrature(element, f, levels):
    dual = DualInputDF(element)
    _close(dual, _static_truth(f, levels))
    A = np.array([0.3, 0.9, 2.0, 7.0])
    np.testing.assert_allclose(dual.N_A(0.0, A), element(A), rtol=1e-12, atol=1e-14)
    # odd elements: no mean output without bias (to rounding of the output's size)
    assert np.all(np.abs(dual.mean(0.0, A)) <= 1e-14 * (1 + np.abs(element(A)) * A))


def test_unequal_relay_closed_form_and_quadrature():
    M1, M2 = 2.0, 0.5
    dual = DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0])
    _close(dual, _static_truth(lambda x: M1 if x > 0 else -M2, [0.0]))
    # textbook form: beta = asin(B / A), m = (M1 (pi + 2 beta) - M2 (pi - 2 beta)) / (2 pi), N_A = 2 (M1 + M2) cos beta / (pi A)
    for B, A in [(0.2, 1.0), (-0.7, 0.9)]:
        beta = np.arcsin(B / A)
        assert dual.mean(B, A) == pytest.approx((M1 * (np.pi + 2 * beta) - M2 * (np.pi - 2 * beta)) / (2 * np.pi),
                                                rel=1e-13)
        assert dual.N_A(B, A) == pytest.approx(2 * (M1 + M2) * np.cos(beta) / (np.pi * A), rel=1e-13)
    # the same map through the quadrature path (a callable with its breakpoint)
    numeric = DualInputDF(lambda x: np.where(x > 0, M1, -M2), breakpoints=[0.0])
    assert numeric.method == "quadrature"
    _close(numeric, _static_truth(lambda x: M1 if x > 0 else -M2, [0.0]))


def test_asymmetric_callable_quadrature():
    """An asymmetric saturation with a smooth part: the quadrature path with its signed breakpoints."""
    def f(x):
        x = np.asarray(x, float)
        return np.where(x > 1.0, 1.0, np.where(x < -0.4, -0.4, x + 0.2 * np.sin(3 * x)))

    f_scalar = lambda x: float(f(x))  # noqa: E731
    dual = DualInputDF(f, breakpoints=[-0.4, 1.0])
    _close(dual, _static_truth(f_scalar, [-0.4, 1.0]))
    # the estimate (difference to half the nodes) bounds the error measured above
    assert np.all(dual.error_estimate(np.array([0.3, -0.2]), np.array([0.7, 2.0])) < 1e-10)


def _hysteresis_relay_truth(M, a):
    def truth(B, A):
        on, off = np.arcsin((a - B) / A), np.pi - np.arcsin((-a - B) / A)  # rising through +a, falling through -a
        y = lambda t: M if on < t < off else -M  # noqa: E731
        return _moments(y, B, A, [on, off])
    return truth


def test_hysteresis_relay_switching_phases():
    M, a = 1.5, 0.3
    dual = DualInputDF(Relay(M, hysteresis=a))
    assert dual.memory and dual.method == "switching phases"
    pairs = [(B, A) for B, A in PAIRS if A > abs(B) + a]
    assert len(pairs) >= 4
    _close(dual, _hysteresis_relay_truth(M, a), pairs)
    A = np.array([0.35, 1.0, 4.0])
    np.testing.assert_allclose(dual.N_A(0.0, A), Relay(M, hysteresis=a)(A), rtol=1e-12)


def test_three_level_relay_with_hysteresis_against_simulation():
    """Dead zone and hysteresis: N_A(0, A) = N(A) to rounding; biased cases against a 200 000-sample period of
    the element's own operator driven by B + A sin(theta) (accuracy ~ 1e-5 from the sampling)."""
    relay = Relay(1.0, hysteresis=0.2, dead_zone=0.5)
    dual = DualInputDF(relay)
    A = np.array([0.75, 1.0, 3.0])
    np.testing.assert_allclose(dual.N_A(0.0, A), relay(A), rtol=1e-12)
    theta = np.linspace(-np.pi / 2, 1.5 * np.pi, 200_000, endpoint=False)
    for B, A in [(0.3, 0.8), (-0.2, 1.5), (0.6, 0.3)]:
        op = relay.operator()
        x = B + A * np.sin(theta)
        for v in x:
            op(v)
        y = np.array([op(v) for v in x])
        m = y.mean()
        n = 2 * np.mean(y * np.exp(-1j * theta)) * 1j / A
        assert abs(dual.mean(B, A) - m) < 1e-4
        assert abs(dual.N_A(B, A) - n) < 1e-4


def test_three_level_relay_against_quadrature_of_its_operator():
    """The output at phase t from the element's own operator (rate independent: the turning points of two warm-up
    periods, then the input at t), integrated by quad between the crossings of the four switching levels."""
    relay = Relay(1.0, hysteresis=0.2, dead_zone=0.5)
    dual = DualInputDF(relay)
    levels = [0.7, 0.3, -0.7, -0.3]

    def truth(B, A):
        def y(t):
            op = relay.operator()
            turns = [B - A, B + A] * 2 + [B - A] + ([B + A] if t > np.pi / 2 else [])
            for v in turns:
                op(v)
            return op(B + A * np.sin(t))
        return _moments(y, B, A, _phases(levels, B, A) + [np.pi / 2])

    pairs = [(0.3, 0.8), (-0.2, 1.5), (0.6, 0.3), (0.0, 2.0), (-1.1, 0.9), (0.45, 0.4)]
    _close(dual, truth, pairs)


def test_backlash_shift_invariance_against_branches():
    h, k = 0.6, 2.0
    dual = DualInputDF(Backlash(h, k))

    def truth(B, A):
        lo, hi = B - A + h / 2, B + A - h / 2  # driven side at the turning points
        def y(t):
            e = B + A * np.sin(t)
            return k * (max(e - h / 2, lo) if t < np.pi / 2 else min(e + h / 2, hi))
        t_r = np.arcsin(np.clip((lo + h / 2 - B) / A, -1, 1))
        t_f = np.pi - np.arcsin(np.clip((hi - h / 2 - B) / A, -1, 1))
        return _moments(y, B, A, [t_r, np.pi / 2, t_f])

    _close(dual, truth, [(B, A) for B, A in PAIRS if A > h / 2])


def test_bad_input():
    dual = DualInputDF(Saturation(1.0))
    with pytest.raises(DfloopError, match="A"):
        dual.mean(0.0, -1.0)
    with pytest.raises(DfloopError, match="B"):
        dual.N_A(np.nan, 1.0)
    with pytest.raises(DfloopError, match="levels"):
        DualInputDF.piecewise_affine([1.0, 0.0], [0, 1, 2], [0, 0, 0])
    with pytest.raises(DfloopError, match="nodes"):
        DualInputDF(Saturation(1.0), nodes=10_000)
    assert "closed form" in repr(dual)


def test_quantizer_needs_its_breakpoints():
    from dfloop import Quantizer

    with pytest.raises(DfloopError, match="breakpoints"):
        DualInputDF(Quantizer(0.5))
    q = Quantizer(0.5)
    dual = DualInputDF(q, breakpoints=q.breakpoints(4.0))
    levels = np.concatenate([-q.breakpoints(4.0), q.breakpoints(4.0)])
    _close(dual, _static_truth(lambda x: float(q.output(x)), levels), [(0.3, 1.1), (-0.2, 2.7), (0.0, 1.9)])


def test_ideal_relay_exposes_its_static_map():
    dual = DualInputDF(Relay(2.0, dead_zone=0.3))
    np.testing.assert_array_equal(dual.function(np.array([-1.0, -0.2, 0.2, 1.0])), [-2.0, 0.0, 0.0, 2.0])
    np.testing.assert_array_equal(dual.breakpoints, [-0.3, 0.3])
    assert DualInputDF(Relay(1.0, hysteresis=0.1)).function is None


def test_bias_gain():
    dual = DualInputDF(Relay(1.0))
    # N_B(0, A) of the ideal relay: 2 M / (pi A); elsewhere m / B
    assert dual.N_B(0.0, 2.0) == pytest.approx(1 / np.pi, rel=1e-8)
    assert dual.N_B(0.5, 2.0) == pytest.approx(dual.mean(0.5, 2.0) / 0.5, rel=1e-15)
    asym = DualInputDF.piecewise_affine([0.0], [-1.0, 2.0], [0.0, 0.0])
    assert asym.N_B(0.0, 1.0) == np.inf
