"""Pairs of cycles born and dying between two given values of a sweep: found by the valley scan, or flagged.

A pair that exists only for p in (p1, p2), with no given value inside, meets no value where the solver could
report it. The references are closed forms for a relay with dead zone d (output M) around
K(p) / (s (s + 1) (s + a(p))): N has its maximum N* = 2 M / (pi d) at A = d sqrt 2, the phase crossover is
w = sqrt(a), where G = -K / (a (1 + a)), so cycles exist iff K(p) N* >= a (1 + a) (equality: a fold, a
double root at A = d sqrt 2), and between the folds their amplitudes solve N(A) = a (1 + a) / K(p):
with x = 1 / A^2, x - d^2 x^2 = (pi a (1 + a) / (4 M K))^2.

- K(p) = K0 p e^{-p}, a = 2: folds where p e^{-p} = c = 6 pi d / (2 M K0), p = -W(-c) on the two real
  branches of Lambert's W;
- random loops: K(p) = Kc(p) (1 + eps - s (p - pc)^2) with Kc(p) = a(p) (1 + a(p)) / N* and a(p) linear in
  p: folds at pc -+ sqrt(eps / s) (none when eps < 0); and a brute-force check on a fine grid of p with
  :func:`dfloop.predict_limit_cycles` on its own (relays with hysteresis too, where N is complex): the number
  of cycles at each grid point equals the number of sweep branches that span it.
"""
import math

import control as ct
import numpy as np
import pytest
from scipy.special import lambertw

import dfloop as df
from dfloop import predict_limit_cycles
from dfloop.continuation import UnresolvedInterval, _Family, sweep

S3 = ct.tf([1], [1, 0])


def _amplitudes(K, a, M, d):
    """The two cycle amplitudes (small, large) of the dead-zone relay at gain K."""
    c = math.pi * a * (1 + a) / (4 * M * K)
    disc = math.sqrt(1 - 4 * d * d * c * c)
    x = [(1 + disc) / (2 * d * d), (1 - disc) / (2 * d * d)]
    return [1 / math.sqrt(xi) for xi in x]


def _plant(K, a):
    return K * ct.tf([1], [1, 1 + a, a, 0])  # K / (s (s + 1) (s + a))


def _check_pair(res, p1, p2, a_of, K_of, M, d, tol=1e-6):
    """The sweep has exactly the pair (p1, p2): one fold at each end (born, then dying), two branches between
    whose every point is a closed-form cycle."""
    assert not res.notes and not res.unresolved
    folds = res.folds()
    assert len(folds) == 2 and len(res.events) == 2, res
    born, dies = sorted(folds, key=lambda e: e.parameter)
    assert abs(born.parameter - p1) <= tol and abs(dies.parameter - p2) <= tol, (born, dies, p1, p2)
    assert "are born together" in born.detail and "die together" in dies.detail
    assert "valley scan" in born.detail
    for e in (born, dies):
        assert abs(e.amplitude / (d * math.sqrt(2)) - 1) <= 1e-5
        assert abs(e.frequency - math.sqrt(a_of(e.parameter))) <= 1e-6
    assert len(res.branches) == 2 and {b.kind for b in res.branches} == {"stable", "unstable"}
    for b in res.branches:
        assert b.start == "fold" and b.end == "fold"
        col = 1 if b.kind == "stable" else 0  # the larger cycle is the stable one
        for p, A, w in zip(b.parameter[1:-1], b.amplitude[1:-1], b.frequency[1:-1]):
            assert abs(w - math.sqrt(a_of(p))) <= 1e-8
            assert abs(A / _amplitudes(K_of(p), a_of(p), M, d)[col] - 1) <= 1e-6


def test_isola_between_two_values_lambert_w_closed_form():
    M, d, delta = 1.0, 0.1, 1e-4
    K0 = 6 * math.pi * d / (2 * M) * math.e / (1 - delta)  # max of K0 p e^{-p} N* / 6 is 1 / (1 - delta)
    c = 6 * math.pi * d / (2 * M * K0)
    p1, p2 = -lambertw(-c, 0).real, -lambertw(-c, -1).real  # 0.98592, 1.01421: 0.028 wide
    assert 0.98 < p1 < p2 < 1.02

    def loop_at(p):
        return _plant(K0 * p * math.exp(-p), 2.0), df.Relay(M=M, dead_zone=d)

    res = sweep(loop_at, [0.2, 1.2, 2.2], parameter="p", progress=False)  # no value within 0.18 of the pair
    assert all(len(c) == 0 for c in res.cycles)  # the solver sees nothing at the values
    _check_pair(res, p1, p2, lambda p: 2.0, lambda p: K0 * p * math.exp(-p), M, d)
    row = res.to_dict()
    assert row["unresolved"] == [] and [e["kind"] for e in row["events"]] == ["fold", "fold"]
    assert "are born together" in repr(res)


def _random_loop(rng):
    M, d = rng.uniform(0.5, 2.0), rng.uniform(0.05, 0.2)
    a0, a1 = rng.uniform(0.5, 3.0), rng.uniform(-0.4, 0.4)
    width = 10 ** rng.uniform(-2.5, -1.2)  # half-width of the pair's interval
    pc = rng.uniform(0.15, 0.85)
    s = rng.uniform(0.5, 4.0)
    eps = s * width ** 2 * (1 if rng.uniform() < 0.75 else -1)
    n_star = 2 * M / (math.pi * d)

    def a_of(p):
        return a0 * (1 + a1 * p)

    def K_of(p):
        return a_of(p) * (1 + a_of(p)) / n_star * (1 + eps - s * (p - pc) ** 2)

    return M, d, a_of, K_of, pc, width, eps


class _Loop:
    def __init__(self, M, d, a_of, K_of, hysteresis=0.0):
        self.M, self.d, self.a_of, self.K_of, self.h = M, d, a_of, K_of, hysteresis

    def __call__(self, p):
        return _plant(self.K_of(p), self.a_of(p)), df.Relay(M=self.M, dead_zone=self.d, hysteresis=self.h)


def test_random_pairs_between_values_match_closed_forms():
    rng = np.random.default_rng(16)
    for _ in range(4):
        M, d, a_of, K_of, pc, width, eps = _random_loop(rng)
        values = [0.0, 0.5, 1.0] if abs(pc - 0.5) > width + 0.02 else [0.0, 0.3, 1.0]
        res = sweep(_Loop(M, d, a_of, K_of), values, parameter="p", progress=False,
                    omega=(0.05, 20.0), amplitude=(0.01, 100.0))
        if eps < 0:
            assert not res.branches and not res.events and not res.unresolved
        else:
            _check_pair(res, pc - width, pc + width, a_of, K_of, M, d)


def _span_count(res, p):
    return sum(1 for b in res.branches if min(b.parameter) < p < max(b.parameter))


def test_brute_force_grid_finds_nothing_the_sweep_misses():
    """Relays with and without hysteresis (complex N: the folds are no longer at the phase crossover): at 41
    points of p the solver's own count equals the number of sweep branches spanning the point."""
    rng = np.random.default_rng(7)
    grid = np.linspace(0.0, 1.0, 41)[1:-1] + 0.003
    for k in range(3):
        M, d, a_of, K_of, pc, width, _ = _random_loop(rng)
        width = rng.uniform(0.06, 0.12)  # wide enough for the grid to see, narrow enough to miss the values
        eps = 3.0 * width ** 2
        n_star = 2 * M / (math.pi * d)

        def K2(p, a_of=a_of, n_star=n_star, eps=eps, pc=pc):
            return a_of(p) * (1 + a_of(p)) / n_star * (1 + eps - 3.0 * (p - pc) ** 2)

        pc_far = min(max(pc, 0.2), 0.8)
        values = [0.0, 1.0] if k < 2 else [0.0, 0.5 + (0.25 if pc_far < 0.5 else -0.25), 1.0]
        loop = _Loop(M, d, a_of, K2, hysteresis=0.1 * d * k)
        opts = dict(omega=(0.05, 20.0), amplitude=(0.01, 100.0))
        res = sweep(loop, values, parameter="p", progress=False, **opts)
        assert not res.notes and not res.unresolved
        events = [e.parameter for e in res.events]
        seen = 0
        for p in grid:
            if any(abs(p - e) < 1e-6 for e in events):
                continue
            G, N = loop(p)
            n = len(predict_limit_cycles(G, N, **opts))
            assert n == _span_count(res, p), (k, p, n, res)
            seen += n
        assert seen > 0  # the pair is there, between the given values


def test_search_bound_reports_the_interval():
    """With the search's probes bounded to 1 the pair cannot be reached: the interval is flagged, not dropped."""
    import dfloop.continuation as cont

    M, d, delta = 1.0, 0.1, 1e-4
    K0 = 6 * math.pi * d / (2 * M) * math.e / (1 - delta)

    def loop_at(p):
        return _plant(K0 * p * math.exp(-p), 2.0), df.Relay(M=M, dead_zone=d)

    saved = cont._GOLDEN
    cont._GOLDEN = 1
    try:
        with pytest.warns(UserWarning, match="may exist"):
            res = sweep(loop_at, [0.2, 1.2, 2.2], parameter="p", progress=False, probes=2)
    finally:
        cont._GOLDEN = saved
    assert not res.branches
    (u,) = res.unresolved
    assert isinstance(u, UnresolvedInterval) and u.low < 0.9859 and u.high > 1.0142
    assert "bound of 1 probes" in u.why and res.notes and "may exist" in res.notes[0]
    assert res.to_dict()["unresolved"][0]["low"] == u.low


def test_bad_probes():
    with pytest.raises(ValueError, match="probes"):
        sweep(lambda p: (_plant(1.0, 2.0), df.Relay(M=1.0, dead_zone=0.1)), [0.0, 1.0], probes=0)


def test_edge_level_flags_a_vanished_edge_instead_of_raising():
    """A relay whose hysteresis shrinks to zero at the end of the range: at q = 1 its amplitude-domain edge no
    longer exists. The corrector on that edge returns None with the reason (before: RuntimeError)."""
    def loop_at(p):
        return _plant(2.0, 2.0), df.Relay(M=1.0, hysteresis=0.2 * (1 - p))

    values = np.array([0.0, 1.0])
    fam = _Family(loop_at, values, np.array([0.0, 1.0]), (math.log(0.01), math.log(10.0), math.log(0.1),
                                                          math.log(10.0)))
    (edge,) = [e for e in fam.edges(0.0) if e[0] == "amplitude domain"]
    X = np.array([math.log(0.2), 0.0, 1.0])
    assert fam._edge_level(edge, X) is None and "disappeared" in fam.last_failure
    assert fam._edge_row(edge, X) is None
    assert fam.correct(X, np.array([0.0, 0.0, 1.0]), 1.0, edge=(edge, 1)) is None
    assert "disappeared" in fam.last_failure
    assert abs(fam._edge_level(edge, np.array([0.0, 0.0, 0.5])) - math.log(0.1)) < 1e-15
