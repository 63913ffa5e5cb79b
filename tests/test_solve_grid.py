"""The solver's grid rule and its guarantees (issue 7): every root found by construction, steep and
clustered roots, scale-free stability, continua reported, clear errors. Each test has an independent
truth: brentq on the phase condition, closed forms, or brute-force sampling."""
import math
import re

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq

import dfloop as df
from dfloop.describing.base import DescribingFunction
from dfloop.solve import ContinuumError, GridReport, grid
from dfloop.solve.plant import as_plant


def _delay_plant(T):
    return lambda w: np.exp(-1j * w * T) / (1j * w + 1)


def _delay_roots(T, lo, hi):
    """Relay around exp(-sT)/(s + 1): arg G = -(w T + atan w) = -(2m + 1) pi (brentq, independent)."""
    f = lambda w, m: w * T + np.arctan(w) - (2 * m + 1) * np.pi  # noqa: E731
    m_max = int((hi * T + np.pi / 2) / (2 * np.pi)) + 2
    return np.array([brentq(f, lo, hi, args=(m,), xtol=1e-14, rtol=1e-15) for m in range(m_max)
                     if f(lo, m) < 0 < f(hi, m)])


@pytest.mark.parametrize("T", [0.5, 1.0, 2.0])
@pytest.mark.parametrize("window", [(0.1, 400.0), (3.0, 60.0), (50.0, 300.0)])
def test_delay_loops_every_root_with_the_default_call(T, window):
    ref = _delay_roots(T, *window)
    cycles = df.predict_limit_cycles(_delay_plant(T), df.Relay(1.0), omega=window)
    w = np.array([c.frequency for c in cycles])
    assert w.size == ref.size
    np.testing.assert_allclose(w, ref, rtol=1e-10)
    # closed form of the amplitude: |G| = 4 M / (pi A)... i.e. A = 4 |G| / pi = 4 / (pi sqrt(1 + w^2))
    np.testing.assert_allclose([c.amplitude for c in cycles], 4 / (np.pi * np.sqrt(1 + ref ** 2)), rtol=1e-9)
    # the relay's -1/N runs left with A; G's phase falls with w: every crossing is stable (Loeb closed form)
    assert all(c.stability == "stable" for c in cycles)
    rep = cycles.grid_report
    assert isinstance(rep, GridReport) and rep.frequency_rule == "sampled" and rep.max_step_frequency <= 0.35
    assert rep.shape == cycles.grid_shape


@pytest.mark.parametrize("zeta", [1e-3, 1e-6, 1e-9, 1e-12])
@pytest.mark.parametrize("wn, M", [(1.0, 1.0), (1e4, 1e-3), (1e-3, 1e3)])
def test_resonance_of_any_damping_is_a_clean_stable_crossing(zeta, wn, M):
    # relay around wn^2 / (s (s^2 + 2 zeta wn s + wn^2)): G(j wn) = -1 / (2 zeta wn) exactly, so the cycle
    # is at w = wn, A = 4 M / (pi 2 zeta wn); Loeb: det = -N'(A) Im G'(wn) with Im G' = 1 / (2 zeta^2 wn^3) > 0
    G = ct.tf([wn ** 2], [1, 2 * zeta * wn, wn ** 2, 0])
    cycles = df.predict_limit_cycles(G, df.Relay(M), omega=(0.1 * wn, 10 * wn))
    assert len(cycles) == 1
    c = cycles[0]
    assert c.frequency == pytest.approx(wn, rel=1e-12)
    # residual bound: tol, or the rounding of ln w times |d ln G / d ln w| = 1 / zeta at the resonance
    # (ln w carries a relative error of one float spacing: 2e-15 at w = 1e4)
    assert c.relative_residual <= 1e-10 + 16 * np.spacing(abs(np.log(wn))) / zeta
    assert c.amplitude == pytest.approx(2 * M / (np.pi * zeta * wn), rel=1e-9 + c.relative_residual)
    assert c.stability == "stable" and abs(c.loeb_conditioning) > 0.5


@pytest.mark.parametrize("w1", [1.0, 1.0123456789])
@pytest.mark.parametrize("d", [1e-9, 1e-7])
def test_roots_1e9_apart_are_two_roots_with_opposite_stability(w1, d):
    # G = -(1/w) (1 + j (w - w1)(w - w2) / (d w1^2)): real (= -1/w) exactly at w1 and w2 = w1 (1 + d),
    # crossing the relay's locus (the negative real axis) at a clean angle each time
    w2 = w1 * (1 + d)
    G = lambda w: -(1 / w) * (1 + 1j * (w - w1) * (w - w2) / (d * w1 * w1))  # noqa: E731
    cycles = df.predict_limit_cycles(G, df.Relay(1.0), omega=(0.5, 2.0))
    assert len(cycles) == 2
    np.testing.assert_allclose([c.frequency for c in cycles], [w1, w2], rtol=1e-12)
    np.testing.assert_allclose([c.amplitude for c in cycles], [4 / (np.pi * w1), 4 / (np.pi * w2)], rtol=1e-12)
    assert {c.stability for c in cycles} == {"stable", "unstable"}


def test_exact_variation_bound_holds_against_dense_sampling():
    rng = np.random.default_rng(7)
    for _ in range(5):
        poles = np.concatenate([-rng.uniform(0.01, 3, 2) + 1j * rng.uniform(0.2, 3, 2), -rng.uniform(0.1, 3, 2)])
        zeros = np.array([rng.uniform(-2, 2) + 1j * rng.uniform(0.1, 3)])
        num = np.real(np.poly(np.concatenate([zeros, zeros.conj()])))
        den = np.real(np.poly(np.concatenate([poles[:2], poles[:2].conj(), poles[2:]])))
        plant = as_plant(ct.tf(num, den))
        edges = np.sort(rng.uniform(0.05, 5, 12))
        for w0, w1 in zip(edges[:-1], edges[1:]):
            w = np.linspace(w0, w1, 20001)
            g = plant(w)
            lg = np.log(np.abs(g)) + 1j * np.unwrap(np.angle(g))
            assert np.max(np.abs(lg - lg[0])) <= plant.log_variation(w0, w1) * (1 + 1e-9)


def _random_roots(rng, n):
    """n roots: lightly damped and unstable pairs, real roots, integrators, roots on the imaginary axis."""
    out = []
    while len(out) < n:
        kind = rng.integers(5)
        wn = 10 ** rng.uniform(-2, 2)
        if kind == 0 and len(out) + 2 <= n:  # a pair, damping 1e-7..1, either half-plane
            z = 10 ** rng.uniform(-7, 0) * rng.choice([1, -1])
            out += [wn * (-z + 1j * math.sqrt(1 - z * z)), wn * (-z - 1j * math.sqrt(1 - z * z))]
        elif kind == 1 and len(out) + 2 <= n:  # on the imaginary axis
            out += [1j * wn, -1j * wn]
        elif kind == 2:
            out.append(0.0)
        else:
            out.append(wn * rng.choice([1, -1]))
    return np.array(out[:n], complex)


def _random_intervals(rng, n):
    """A random plant (:func:`_random_roots`: 0-3 zeros, 4-6 poles) and n random intervals [w0, w1] of it plus one
    just below each root's frequency: wide, narrow down to 1e-12 (relative), straddling roots' frequencies."""
    zeros, poles = _random_roots(rng, rng.integers(0, 4)), _random_roots(rng, rng.integers(4, 7))
    plant = as_plant(ct.tf(np.real(np.poly(zeros)) if zeros.size else [1.0], np.real(np.poly(poles))))
    z, p = plant.roots
    special = np.abs(np.concatenate([z, p]).imag)
    w0 = np.concatenate([10 ** rng.uniform(-3, 3, n), special[special > 0] * (1 - 10 ** rng.uniform(-9, -1))])
    return plant, w0, w0 * np.exp(10 ** rng.uniform(-12, 0.3, w0.size))


def _variation_reference(plant, w0, w1, delay=0.0):
    """Plant.log_variation recomputed so that it stays accurate on tiny intervals: each factor's change of ln|jw - r|
    as 0.5 log1p of the exact relative change of |jw - r|^2 (h (p0 + p1) / d0^2, or p^2 / x^2 down to the
    minimum), its turn as atan2(x h, x^2 + p0 p1), h = w1 - w0 (differences of logarithms lose ~1e-16 absolute);
    a pure delay's turn delay * h joins the negative turns."""
    z, p = plant.roots
    r = np.concatenate([z, p])
    sign = np.concatenate([np.ones(z.size), -np.ones(p.size)])
    x, y = -r.real, r.imag
    w0, w1 = w0[:, None], w1[:, None]
    h, p0, p1 = w1 - w0, w0 - y, w1 - y
    with np.errstate(divide="ignore", invalid="ignore"):
        inside = (p0 < 0) & (p1 > 0)
        change = 0.5 * np.log1p(h * (p0 + p1) / (x * x + p0 * p0))  # ln d1 - ln d0, where monotone
        up = np.where(inside, 0.5 * np.log1p(p1 * p1 / (x * x)), np.maximum(change, 0))
        down = np.where(inside, 0.5 * np.log1p(p0 * p0 / (x * x)), np.maximum(-change, 0))
    turn = sign * np.arctan2(x * h, x * x + p0 * p1)
    rise = np.where(sign > 0, up, down).sum(-1)
    fall = np.where(sign > 0, down, up).sum(-1)
    arg = np.maximum(np.where(turn > 0, turn, 0).sum(-1), -np.where(turn < 0, turn, 0).sum(-1) + delay * h[:, 0])
    return np.hypot(arg, np.maximum(rise, fall))


def test_interval_bound_is_above_the_exact_variation_and_within_a_few_percent():
    # grid._interval_bound (rational arithmetic: sinh of the magnitude changes, tangents of the turns) against the
    # exact variation's bound (log_variation's, accurate also on tiny intervals) on random intervals: never below
    # it, and above it by at most tan t / t - 1 of a step t (sinh t / t - 1 is smaller), so within 4.3 % on the grid's
    # intervals (|d ln G| <= STEP), plus the turns' rounding margin. Intervals straddle roots' frequencies, end next
    # to them, or are 1e-12 wide.
    rng = np.random.default_rng(11)
    n_checked = 0
    for _ in range(150):
        plant, w0, w1 = _random_intervals(rng, 60)
        z, p = plant.roots
        p0, d0 = grid.node_terms(plant, w0)
        p1, d1 = grid.node_terms(plant, w1)
        eps = grid._interval_bound(plant, w0, w1, p0, p1, d0, d1, grid.allpass_pairs(z, p))
        exact = _variation_reference(plant, w0, w1)
        finite = np.isfinite(exact)
        assert np.array_equal(np.isfinite(eps), finite)
        assert np.all(eps[finite] >= exact[finite] * (1 - 1e-14))
        np.testing.assert_allclose(plant.log_variation(w0, w1)[finite], exact[finite], rtol=1e-9, atol=1e-14)
        small = finite & (exact <= grid.STEP)  # each factor's term at most tan t / t of its change t <= STEP, plus
        margin = grid.ANGLE_ROUNDING * (z.size + p.size)  # the absolute rounding margin of the turns
        assert np.all(eps[small] <= exact[small] * (math.tan(grid.STEP) / grid.STEP) * (1 + 1e-13) + margin)
        n_checked += small.sum()
    assert n_checked > 5000


def test_the_drivers_one_interval_bound_is_above_the_exact_variation_and_within_a_few_percent():
    # driver._variation_bound (the rational bound of one interval, used where the default amplitude window skips
    # blocks of refined frequencies) against the exact variation's bound, a pure delay included: never below it,
    # within tan t / t of it on intervals where it is at most STEP (plus the turns' rounding margin)
    from dfloop.solve.compiled.driver import _variation_bound

    rng = np.random.default_rng(23)
    n_checked = 0
    for _ in range(100):
        plant, w0, w1 = _random_intervals(rng, 40)
        z, p = (np.ascontiguousarray(r, complex) for r in plant.roots)
        delay = rng.choice([0.0, 10 ** rng.uniform(-3, 1)])
        eps = np.array([_variation_bound(z, p, delay, a, b) for a, b in zip(w0, w1)])
        exact = _variation_reference(plant, w0, w1, delay)
        finite = np.isfinite(exact)
        assert np.array_equal(np.isfinite(eps), finite)
        assert np.all(eps[finite] >= exact[finite] * (1 - 1e-12))
        small = finite & (exact <= grid.STEP)
        margin = grid.ANGLE_ROUNDING * (z.size + p.size)
        assert np.all(eps[small] <= exact[small] * (math.tan(grid.STEP) / grid.STEP) * (1 + 1e-12) + margin)
        n_checked += small.sum()
    assert n_checked > 2000


def test_compiled_grid_is_the_python_grid_bit_for_bit_from_the_same_nodes():
    # the compiled driver's G grid computes grid._interval_bound's IEEE expressions (and numpy's summation order):
    # from the same initial nodes, the same nodes, and the same bounds wherever the nodes' e^v agree (libm's exp
    # and numpy's may differ in the last place, which moves a bound next to a lightly damped pole)
    from dfloop.solve.compiled import driver

    rng = np.random.default_rng(5)
    for _ in range(40):
        zeros, poles = _random_roots(rng, rng.integers(0, 4)), _random_roots(rng, rng.integers(1, 7))
        poles = poles[np.abs(poles.real) > 0]  # no root on the axis inside the window: finite bounds
        if poles.size == 0:
            continue
        zeros = zeros[:poles.size]
        plant = as_plant(ct.tf(np.real(np.poly(zeros)) if zeros.size else [1.0], np.real(np.poly(poles))))
        v = np.linspace(np.log(1e-2), np.log(1e2), int(rng.integers(4, 200)))
        nodes, _, eps = grid.resolve_plant(plant, v)[:3]
        z, p = (np.ascontiguousarray(r, complex) for r in plant.roots)
        c_nodes, c_w, c_eps, status = driver._resolve_plant(z, p, 0.0, v)
        assert status == 0 and np.array_equal(nodes, c_nodes)
        same_w = np.exp(nodes) == c_w
        same = same_w[:-1] & same_w[1:]
        assert same.mean() > 0.5 and np.array_equal(eps[same], c_eps[same])


def test_no_root_outside_the_candidate_cells_brute_force():
    # a plant with four crossings, resolved by the exact rule; brute force on a 20x finer grid finds no
    # sign change of Im(G) on the negative real axis that the solver did not report
    G = ct.tf([5], [1, 1, 0]) * ct.tf([1, 0.1, 4], [1, 0.02, 1]) * ct.tf([1, 0.05, 16], [1, 0.02, 9])
    cycles = df.predict_limit_cycles(G, df.Relay(1.0), omega=(0.05, 20))
    w = np.logspace(np.log10(0.05), np.log10(20), 400_000)
    g = as_plant(G)(w)
    flip = np.flatnonzero((np.sign(g.imag[1:]) != np.sign(g.imag[:-1])) & (g.real[1:] < 0))
    ref = [brentq(lambda x: as_plant(G)(np.array([x]))[0].imag, w[i], w[i + 1], xtol=1e-15) for i in flip]
    assert len(cycles) == len(ref) == 4
    np.testing.assert_allclose([c.frequency for c in cycles], ref, rtol=1e-10)
    assert cycles.grid_report.frequency_rule == "exact" and cycles.grid_report.candidate_cells >= len(ref)


def _continuum_ranges(excinfo):
    err = excinfo.value
    assert isinstance(err, ValueError) and re.search(r"continuum of solutions.*A in \[.*omega in \[", str(err))
    return err.amplitude_range, err.omega_range


def test_continuum_nyquist_through_minus_one_under_saturation():
    # 8 / (s + 1)^3 at w = sqrt(3) is exactly -1; saturation N = 1 for A <= 1: every A <= 1 is a solution
    G = ct.tf([8], [1, 3, 3, 1])
    with pytest.raises(ContinuumError) as exc:
        df.predict_limit_cycles(G, df.Saturation(1.0), amplitude=(0.1, 10))
    (a0, a1), (w0, w1) = _continuum_ranges(exc)
    assert w0 == pytest.approx(np.sqrt(3), rel=1e-6) and w1 == pytest.approx(np.sqrt(3), rel=1e-6)
    assert a0 == pytest.approx(0.1, rel=1e-6) and a1 == pytest.approx(1.0, rel=1e-6)


@pytest.mark.parametrize("N, amplitude", [(df.Saturation(1.0), (0.1, 10)), (df.DeadZone(0.5), (0.6, 10)),
                                          (df.Saturation(1.0), None)])
def test_continuum_double_integrator(N, amplitude):
    # G = 1/s^2 = -1/w^2 lies on the negative real axis: 1 + G N = 0 on the curve w = sqrt(N(A))
    with pytest.raises(ContinuumError) as exc:
        df.predict_limit_cycles(ct.tf([1], [1, 0, 0]), N, amplitude=amplitude, omega=(0.01, 10))
    (a0, a1), (w0, w1) = _continuum_ranges(exc)
    assert a1 > 1.5 * a0  # a curve, not a point
    # N is monotonic in A: the curve's ends are (a0, w at a0) and (a1, w at a1), w = sqrt(N)
    ends = sorted([np.sqrt(N(a0).real), np.sqrt(N(a1).real)])
    assert (w0, w1) == pytest.approx(tuple(ends), rel=1e-5)


def test_tangent_root_stays_marginal_under_rescaling():
    for k in (1e-6, 1.0, 1e6):
        G = lambda w, k=k: k * (-2 + 1j * (w - 1) ** 2)  # noqa: E731
        cycles = df.predict_limit_cycles(G, df.Relay(M=1.0 / k), omega=(0.5, 2))
        assert len(cycles) == 1 and cycles[0].stability == "marginal"
        assert cycles[0].amplitude == pytest.approx(8 / np.pi, rel=1e-6)


@pytest.mark.parametrize("G, kw, match", [
    (ct.tf([1, 2, 3, 4], [1, 1]), {}, "G must be proper"),
    (ct.tf([0], [1, 1]), {}, "G is zero"),
    (lambda w: 0 * w, {"omega": (1, 2)}, "G is zero at every frequency"),
    (lambda w: np.ones(3), {"omega": (1, 2)}, "same shape as omega"),
    (lambda w: np.where(w > 1.5, np.inf, 1 / (1j * w)), {"omega": (1, 2)}, "not finite"),
    (ct.tf([8], [1, 2, 2, 1]), {"grid": (20000, 20000)}, r"would need 29\.8 GiB"),
    (ct.tf([8], [1, 2, 2, 1]), {"tol": np.nan}, "tol must not be NaN"),
    (ct.tf([8], [1, 2, 2, 1]), {"marginal_tol": np.nan}, "marginal_tol must not be NaN"),
])
def test_clear_errors(G, kw, match):
    with pytest.raises(ValueError, match=match):
        df.predict_limit_cycles(G, df.Saturation(1.0), **kw)


class _DelayedRelay(DescribingFunction):
    """A frequency-dependent N: a relay followed by a delay T, N(A, w) = 4 / (pi A) exp(-j w T)."""

    frequency_dependent = True

    def __init__(self, T):
        self.T = T

    def _evaluate(self, A, omega):
        return df.Relay(1.0)(A) * np.exp(-1j * omega * self.T)


@pytest.mark.parametrize("T", [0.5, 2.0])
def test_delay_inside_a_frequency_dependent_N_every_root(T):
    # the delay moved from G into N: the same roots (brentq), found although G = 1/(s + 1) is smooth
    ref = _delay_roots(T, 0.1, 400.0)
    cycles = df.predict_limit_cycles(lambda w: 1 / (1j * w + 1), _DelayedRelay(T), omega=(0.1, 400.0))
    assert len(cycles) == ref.size
    np.testing.assert_allclose([c.frequency for c in cycles], ref, rtol=1e-10)
    assert all(c.stability == "stable" for c in cycles)


@pytest.mark.parametrize("order", [1, 3, 6, 10])
def test_grid_bound_with_allpass_pairs_holds_against_dense_sampling(order):
    # a Pade delay's zeros mirror its poles: resolve_plant counts each pair's magnitude by the joint bound of
    # grid.allpass_pairs (the pair's modulus is ~1). The bound of every final interval must still hold the change
    # of ln G sampled densely, on the Pade chain alone and with a pair mirrored only to 1e-10 (a pair the rule
    # accepts with a slack) or to 1e-6 (a pair it must refuse: counted root by root)
    rng = np.random.default_rng(order)
    num, den = ct.pade(rng.uniform(0.2, 3.0), order)
    base = ct.tf([2.0], [1.0, 1.2, 1.0]) * ct.tf(num, den)
    pr = -rng.uniform(0.3, 2.0) + 1j * rng.uniform(0.5, 4.0)
    for mismatch, counted in ((0.0, True), (1e-10, True), (1e-6, False)):
        z = -np.conj(pr) + mismatch * abs(pr.real) * np.exp(1j * rng.uniform(0, 2 * np.pi))
        pair = ct.tf(np.real(np.poly([z, np.conj(z)])), np.real(np.poly([pr, np.conj(pr)])))
        plant = as_plant(base * pair)
        zeros, poles = plant.roots
        paired, slack = grid.allpass_pairs(zeros, poles)
        # the Pade chain's pairs (all its roots), and the extra pair only within the mismatch the rule allows
        assert paired.sum() == 2 * order + (4 if counted else 0)
        assert 0 <= slack < 1e-6
        v = np.linspace(np.log(0.05), np.log(50.0), 40)
        nodes, _, eps = grid.resolve_plant(plant, v)[:3]
        assert eps.max() <= grid.STEP
        for i in rng.choice(eps.size, 25, replace=False):
            w = np.exp(np.linspace(nodes[i], nodes[i + 1], 2001))
            g = plant(w)
            lg = np.log(np.abs(g)) + 1j * np.unwrap(np.angle(g))
            assert np.max(np.abs(lg - lg[0])) <= eps[i]


def test_allpass_pairs_pairs_only_mirrors():
    # no mirror: nothing paired; a zero at a pole's mirror with the other pole's imaginary part: not paired
    zeros = np.array([1.0 + 2.0j, 1.0 - 2.0j, -3.0 + 0.0j])
    poles = np.array([-1.0 + 1.0j, -1.0 - 1.0j, -0.5 + 0.0j])
    paired, slack = grid.allpass_pairs(zeros, poles)
    assert not paired.any() and slack == 0.0
    # exact mirrors pair one to one (a repeated pole is taken once per zero)
    paired, slack = grid.allpass_pairs(np.array([2.0 + 0j, 2.0 + 0j]), np.array([-2.0 + 0j, -2.0 + 0j, -2.0 + 0j]))
    assert paired.tolist() == [True, True, True, True, False] and 0 < slack < 1e-14
