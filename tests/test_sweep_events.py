"""Births and deaths of limit cycles in a sweep, and the marginal test shared with predict_limit_cycles.

Every reference here is derived independently of dfloop's code:

- G(s) = K / (s (s + 1) (s + 2)): G(jw) = K / (-3 w^2 + j w (2 - w^2)), real (= -K/6) at the phase crossover
  w = sqrt(2). So the loop with a real gain n is marginal at K n = 6.
- Saturation (limit L, slope 1): N = 1 for A <= L, N = f(L/A) above, f(u) = (2/pi)(asin u + u sqrt(1 - u^2)).
  The cycle is born where the linear loop is marginal, K = 6, at the edge A = L, w = sqrt(2).
- Dead zone (delta, slope k): N -> k as A -> inf, so the cycle comes from infinity at K = 6 / k.
- Relay M with dead zone d: N = 4M/(pi A) sqrt(1 - (d/A)^2) has its maximum 2M/(pi d) at A = d sqrt(2), so the
  pair of cycles is born at a fold at K* = 6 / (2M/(pi d)) = 3 pi d / M, A = d sqrt(2), w = sqrt(2).
- Backlash (h, k = 1): the fold gain is the smallest K at which K G(jw) touches -1/N(X): for each X the
  frequency where arg G = arg(-1/N(X)) (brentq), K(X) = 1 / (|N(X)| |G0(jw)|), minimised over X (scipy's
  bounded scalar minimiser) -- a tangency computed without the continuation's machinery.
"""
import math

import control as ct
import numpy as np
from scipy.optimize import brentq, minimize_scalar

import dfloop as df
from dfloop.continuation import ContinuumAt, sweep
from dfloop.describing.base import DescribingFunction

G0 = ct.tf([1], [1, 3, 2, 0])


def _f(u):
    return (2 / math.pi) * (math.asin(u) + u * math.sqrt(1 - u * u))


def _sat_amplitude(K, L=1.0):
    """A > L with f(L/A) = 6/K (K > 6)."""
    return brentq(lambda A: _f(L / A) - 6 / K, L * (1 + 1e-15), 1e9 * L, xtol=1e-14, rtol=1e-15)


def test_saturation_birth_at_the_linear_critical_gain_and_no_continuum_failure():
    # K = 6 itself is a value: a continuum there (A in (0, 1]) is an event, not a failure
    res = sweep(lambda K: (K * G0, df.Saturation(1.0)), np.linspace(2, 20, 19), parameter="K", progress=False)
    births = [e for e in res.events if e.kind == "birth"]
    assert len(births) == 1
    b = births[0]
    assert abs(b.parameter - 6.0) < 1e-12 and abs(b.amplitude - 1.0) < 1e-9
    assert abs(b.frequency - math.sqrt(2)) < 1e-12 and b.cause == "linear range"
    cont = [e for e in res.events if e.kind == "continuum"]
    assert len(cont) == 1 and cont[0].parameter == 6.0
    assert isinstance(res.cycles[4], ContinuumAt) and len(res.cycles[4]) == 0
    # one stable branch, born at K = 6, nothing inside the linear range, amplitudes = closed form
    assert len(res.branches) == 1
    br = res.branches[0]
    assert br.kind == "stable" and br.parameter.min() >= 6.0 - 1e-12 and br.amplitude.min() >= 1.0
    assert br.start.startswith("born")
    K, A, w = br.at_values()
    for k, a, ww in zip(K, A, w):
        if k > 6.5:
            assert abs(a / _sat_amplitude(k) - 1) < 1e-9 and abs(ww - math.sqrt(2)) < 1e-9


def test_saturation_birth_found_between_values_and_with_a_moving_edge():
    # values avoid K = 6: the birth is still located (by the edge constraint) to rounding
    res = sweep(lambda K: (K * G0, df.Saturation(1.0)), np.linspace(2.5, 20.5, 7), parameter="K", progress=False)
    (b,) = [e for e in res.events if e.kind == "birth"]
    assert abs(b.parameter - 6.0) < 1e-12 and abs(b.amplitude - 1.0) < 1e-9
    # sweep the saturation limit L at K = 9 (edge level moves with the parameter): the cycle's amplitude is
    # proportional to L (N depends on L/A only), and there is no birth inside the range
    res = sweep(lambda L: (9 * G0, df.Saturation(L)), np.linspace(0.5, 2.0, 4), parameter="L", progress=False)
    assert not [e for e in res.events if e.kind in ("birth", "death")]
    (br,) = res.branches
    L, A, _ = br.at_values()
    np.testing.assert_allclose(A / L, _sat_amplitude(9.0), rtol=1e-9)


def test_saturation_death_in_a_decreasing_sweep():
    res = sweep(lambda K: (K * G0, df.Saturation(2.0)), np.linspace(9, 3, 5), parameter="K", progress=False)
    (d,) = [e for e in res.events if e.kind == "death"]
    assert abs(d.parameter - 6.0) < 1e-12 and abs(d.amplitude - 2.0) < 2e-9


def test_dead_zone_cycle_born_from_infinity():
    k = 2.0  # N -> k: the loop with N's limit is marginal at K = 6 / k = 3
    res = sweep(lambda K: (K * G0, df.DeadZone(0.1, k=k)), np.linspace(2, 5, 4), parameter="K", progress=False)
    (b,) = [e for e in res.events if e.kind == "birth"]
    assert b.cause == "infinity" and math.isinf(b.amplitude)
    assert abs(b.parameter - 3.0) < 1e-12 and abs(b.frequency - math.sqrt(2)) < 1e-12
    (br,) = res.branches
    assert br.kind == "unstable"  # -1/N moves from -inf towards -1/k as A grows: the cycle is unstable
    K, A, _ = br.at_values()
    for kk, a in zip(K, A):  # k (1 - f(delta/A)) = 6/K
        ref = brentq(lambda x: k * (1 - _f(0.1 / x)) - 6 / kk, 0.1 * (1 + 1e-12), 1e8, xtol=1e-15, rtol=1e-15)
        assert abs(a / ref - 1) < 1e-8


def test_relay_with_dead_zone_born_at_a_fold_closed_form():
    M, d = 2.0, 0.3
    Kstar = 3 * math.pi * d / M
    res = sweep(lambda K: (K * G0, df.Relay(M, dead_zone=d)), np.linspace(0.8 * Kstar, 1.6 * Kstar, 5),
                parameter="K", progress=False)
    (f,) = res.folds()
    assert abs(f.parameter / Kstar - 1) < 1e-10
    assert abs(f.amplitude / (d * math.sqrt(2)) - 1) < 1e-5  # p is stationary at a fold: A to sqrt(rounding)
    assert abs(f.frequency - math.sqrt(2)) < 1e-9
    assert sorted(res.branches[i].kind for i in f.branches) == ["stable", "unstable"]


def _backlash_N(X, h):
    u = 1 - h / X
    return 0.5 * (1 + _f(u)) - 1j * (2 * h / (math.pi * X * X)) * (X - h / 2)


def _g0(w):
    s = 1j * w
    return 1 / (s ** 3 + 3 * s ** 2 + 2 * s)


class _Servo:
    """K / (jw (jw + 1) (jw + 2)) as a callable."""

    def __init__(self, K):
        self.K = K

    def __call__(self, w):
        return self.K * _g0(np.asarray(w))


def test_backlash_fold_against_an_independent_tangency():
    h = 0.2

    def gain(X):  # the gain at which K G0(jw) = -1/N(X) (phase match by brentq on the phase-crossing branch)
        target = np.angle(-1 / _backlash_N(X, h))
        w = brentq(lambda w: np.angle(_g0(w)) - target, 1e-3, math.sqrt(2) - 1e-12, xtol=1e-15, rtol=1e-15)
        return 1 / (abs(_backlash_N(X, h)) * abs(_g0(w)))

    opt = minimize_scalar(gain, bounds=(0.11, 0.5), method="bounded", options={"xatol": 1e-10})
    servo = (0.01, 100.0)  # the plant as a callable (cheaper to rebuild than a tf): the window is given
    res = sweep(lambda K: (_Servo(K), df.Backlash(h)), np.linspace(3.0, 5.5, 3), parameter="K", omega=servo,
                progress=False)
    (f,) = res.folds()
    assert abs(f.parameter / opt.fun - 1) < 1e-9
    assert abs(f.amplitude / opt.x - 1) < 1e-4
    # and the stable branch dies at infinity where N -> 1: K = 6
    res = sweep(lambda K: (_Servo(K), df.Backlash(h)), np.linspace(5.0, 7.0, 3), parameter="K", omega=servo,
                progress=False)
    (d,) = [e for e in res.events if e.kind == "death"]
    assert d.cause == "infinity" and abs(d.parameter - 6.0) < 1e-12


def test_sweep_marginal_label_is_the_solvers_and_right():
    """Near K = 6 the backlash's stable cycle has X >> h: dR/d(ln X) is tiny against dR/d(ln w). The sweep's
    old test (det / (sum |J|^2 / 2) < 1e-4) called those cycles marginal although the crossing angle is large;
    the shared test (the solver's) calls them stable. Truth: the sign of the Loeb determinant from closed-form
    derivatives of G0 and of the backlash DF."""
    h = 0.2
    vals = 6 - np.array([1e-3, 1e-4, 1e-5])
    res = sweep(lambda K: (K * G0, df.Backlash(h)), vals, parameter="K", amplitude=(0.05, 1e7), progress=False)
    (br,) = [b for b in res.branches if b.amplitude.max() > 100]
    K, X, w = br.at_values()
    labels = br.stability[br.value_index >= 0]
    assert K.size == 3
    for k, x, ww, lab, found in zip(K, X, w, labels, res.cycles):
        s = 1j * ww
        den = s ** 3 + 3 * s ** 2 + 2 * s
        dG_dw = 1j * -(3 * s ** 2 + 6 * s + 2) / den ** 2  # d/dw = j d/ds
        u = 1 - h / x
        dN = 0.5 * (4 / math.pi) * math.sqrt(1 - u * u) * h / x ** 2 \
            - 1j * (2 * h / math.pi) * (-1 / x ** 2 + h / x ** 3)
        ra = k * _g0(ww) * dN * x  # dR/d ln X
        rv = k * dG_dw * ww * _backlash_N(x, h)  # dR/d ln w
        det = ra.real * rv.imag - rv.real * ra.imag
        old = det / (0.5 * (abs(ra) ** 2 + abs(rv) ** 2))
        assert det > 0 and abs(old) < 1e-4  # stable, and the old sweep test would have said marginal
        assert lab == "stable"
        (same,) = [c for c in found if abs(c.amplitude / x - 1) < 1e-6]
        assert same.stability == lab  # the solver's label at the same value


def test_relay_with_hysteresis_born_at_the_edge_of_its_domain():
    """Relay M with hysteresis a: -1/N = -(pi A / 4M) e^{j asin(a/A)} is the horizontal half-line
    Im = -pi a / (4M), Re <= 0, starting at A = a (where N's domain begins, N(a+) != 0). G = K/(s+1)^2 meets it
    on its w > 1 part iff Im G(j1) = -K/2 < -pi a/(4M): the cycle is born at K = pi a / (2M), A = a, w = 1.
    The DF has a square-root edge there (asin near 1), so the birth is located to about sqrt(rounding)."""
    M, a = 1.0, 0.2
    Kb = math.pi * a / (2 * M)
    G = ct.tf([1], [1, 2, 1])
    res = sweep(lambda K: (K * G, df.Relay(M, hysteresis=a)), np.linspace(0.5 * Kb, 3 * Kb, 6), parameter="K",
                progress=False)
    (b,) = [e for e in res.events if e.kind == "birth"]
    assert b.cause == "amplitude domain"
    assert abs(b.parameter / Kb - 1) < 2e-7 and abs(b.amplitude / a - 1) < 1e-12 and abs(b.frequency - 1) < 2e-7
    (br,) = res.branches
    K, A, w = br.at_values()
    for k, x, ww in zip(K, A, w):  # on the half-line: Im G(jw) = -pi a/(4M) and A = 4M |G(jw)| / pi
        g = k / (1j * ww + 1) ** 2
        assert abs(g.imag / (-math.pi * a / (4 * M)) - 1) < 1e-9 and abs(x / (4 * M * abs(g) / math.pi) - 1) < 1e-9


def test_cubic_spring_cycle_dies_at_zero_amplitude():
    """N = k1 + 3 k3 A^2 / 4 -> k1 as A -> 0: the cycle (A^2 = (6/K - k1) 4 / (3 k3), for K < 6/k1) shrinks to
    zero amplitude where the loop with N(0) = k1 is marginal, K = 6 / k1."""
    k1, k3 = 1.5, 2.0
    res = sweep(lambda K: (K * G0, df.CubicStiffness(k1, k3)), np.linspace(2, 5, 4), parameter="K", progress=False)
    (d,) = [e for e in res.events if e.kind == "death"]
    assert d.cause == "zero amplitude" and d.amplitude == 0.0
    assert abs(d.parameter - 6 / k1) < 1e-12 and abs(d.frequency - math.sqrt(2)) < 1e-12
    (br,) = res.branches
    K, A, _ = br.at_values()
    np.testing.assert_allclose(A, np.sqrt((6 / K - k1) * 4 / (3 * k3)), rtol=1e-9)


class _StepRelay(DescribingFunction):
    """An ideal relay whose level halves at A = 2 (N jumps there; no declared breakpoints)."""

    def _evaluate(self, A, omega):
        with np.errstate(divide="ignore"):
            return np.where(A < 2.0, 4.0, 2.0) / (np.pi * A) + 0j


class _Cubed:
    """K / (jw + 1)^3 (picklable callable plant)."""

    def __init__(self, K):
        self.K = K

    def __call__(self, w):
        return self.K / (1j * np.asarray(w) + 1) ** 3


def test_branch_ends_where_n_jumps():
    """G = K/(s+1)^3 crosses the negative real axis at w = sqrt 3 at -K/8; -1/N = -pi A/4 for A < 2 and
    -pi A/2 from A = 2 on. So A = K/(2 pi) below the jump (dies at K = 4 pi) and A = K/(4 pi) above it
    (born at K = 8 pi): in between no cycle (-K/8 lies in the gap of -1/N). The jump is not declared by the
    element: the sweep finds it by probing N where continuation stops."""
    import pytest

    with pytest.warns(UserWarning, match="jump crossing"):  # the solver at K = 18, in the gap
        res = sweep(lambda K: (_Cubed(K), _StepRelay()), np.linspace(6, 30, 5), omega=(0.1, 10), parameter="K",
                    progress=False)
    d, b = sorted([e for e in res.events if e.kind in ("birth", "death")], key=lambda e: e.parameter)
    assert d.kind == "death" and d.cause == "jump" and abs(d.parameter / (4 * math.pi) - 1) < 1e-12
    assert b.kind == "birth" and b.cause == "jump" and abs(b.parameter / (8 * math.pi) - 1) < 1e-12
    assert abs(d.amplitude - 2) < 1e-12 and abs(b.frequency - math.sqrt(3)) < 1e-12
    assert [br.kind for br in res.branches] == ["stable", "stable"] and not res.notes
