"""Tangent seeds are skipped only where no root can be (roots.seed_excluded): checked by brute force.

On grids chosen as the solver chooses them (G's exact rule, N's monotone sampled rule), every box that
``seed_excluded`` declares empty is sampled densely: the relative residual |1 + G N| / (1 + |G N|) must stay above
0.00125 (what the proof promises) everywhere; boxes around the solver's roots must never be excluded; and on the
backlash servo most boxes are excluded (the test is not vacuous).
"""
from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.solve import as_plant
from dfloop.solve.delay import delayed
from dfloop.solve.grid import clog, resolve_plant, resolve_sampled
from dfloop.solve.roots import Residual, seed_excluded

LOOPS = [(ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0), (0.55, 20.0), (0.05, 20.0)),
         (delayed(ct.tf([8.0], [0.5, 1.0, 0.0]), 0.02), df.Backlash(h=1e-3), (5.1e-4, 0.05), (0.1, 100.0)),
         (ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0), (0.2, 20.0), (0.05, 20.0))]


def _grid(G, N, A_win, w_win, na=24, nw=48):
    plant = as_plant(G)
    res = Residual(plant, N)
    v, g, eps_v, _, _ = resolve_plant(plant, np.linspace(math.log(w_win[0]), math.log(w_win[1]), nw))
    a, n, eps_a, _, _ = resolve_sampled(lambda A: res._n(A, None), np.linspace(math.log(A_win[0]),
                                                                                math.log(A_win[1]), na),
                                        "N", monotone=True)
    return res, a, v, n, g, eps_a, eps_v


@pytest.mark.parametrize("k", range(len(LOOPS)))
def test_excluded_boxes_hold_no_root_by_brute_force(k):
    G, N, A_win, w_win = LOOPS[k]
    res, a, v, n, g, eps_a, eps_v = _grid(G, N, A_win, w_win)
    ln_n, ln_g = clog(n), clog(g)
    excluded = checked = 0
    rng = np.random.default_rng(k)
    for _ in range(60):
        i, j = int(rng.integers(2, a.size - 2)), int(rng.integers(2, v.size - 2))
        if not seed_excluded(res, a, v, ln_n, eps_a, ln_g, eps_v, i - 2, i + 2, j - 2, j + 2):
            continue
        excluded += 1
        aa, vv = np.meshgrid(np.linspace(a[i - 2], a[i + 2], 41), np.linspace(v[j - 2], v[j + 2], 41))
        P = res.terms(aa.ravel(), vv.ravel())
        rel = np.abs(1 + P) / (1 + np.abs(P))
        assert rel.min() >= 0.00125, (k, i, j, rel.min())
        checked += 1
    assert checked == excluded and excluded >= 10  # the proof applies to most boxes of these grids


@pytest.mark.parametrize("k", range(2))
def test_boxes_around_roots_are_never_excluded(k):
    G, N, A_win, w_win = LOOPS[k]
    cycles = df.predict_limit_cycles(G, N, amplitude=A_win, omega=w_win)
    assert len(cycles) >= 1
    res, a, v, n, g, eps_a, eps_v = _grid(G, N, A_win, w_win)
    ln_n, ln_g = clog(n), clog(g)
    for c in cycles:
        i = int(np.clip(np.searchsorted(a, math.log(c.amplitude)), 2, a.size - 3))
        j = int(np.clip(np.searchsorted(v, math.log(c.frequency)), 2, v.size - 3))
        for di in (-1, 0):
            for dj in (-1, 0):
                assert not seed_excluded(res, a, v, ln_n, eps_a, ln_g, eps_v, i + di - 2, i + di + 2, j + dj - 2,
                                         j + dj + 2)


@pytest.mark.parametrize("k", range(len(LOOPS)))
def test_compiled_exclusion_of_the_python_driver_drops_only_empty_boxes(k):
    # the Python driver on a compiled loop decides its seeds in the compiled driver's kernel (driver.kept_seeds):
    # every seed it drops must have a +-2-node box that holds nothing the refinement could accept (brute force),
    # the seeds next to the solver's roots must be kept, and most seeds of these grids are dropped
    from dfloop.solve.compiled import driver
    from dfloop.solve.compiled.residual import compiled_loop

    G, N, A_win, w_win = LOOPS[k]
    res, a, v, n, g, eps_a, eps_v = _grid(G, N, A_win, w_win)
    loop = compiled_loop(res.plant, N)
    assert loop is not None
    rng = np.random.default_rng(10 + k)
    si, sj = rng.integers(0, a.size, 80), rng.integers(0, v.size, 80)
    cycles = df.predict_limit_cycles(G, N, amplitude=A_win, omega=w_win)
    near = [(int(np.searchsorted(a, math.log(c.amplitude))), int(np.searchsorted(v, math.log(c.frequency))))
            for c in cycles]
    si, sj = np.concatenate([si, [i for i, _ in near]]), np.concatenate([sj, [j for _, j in near]])
    keep = driver.kept_seeds(loop, a, v, n, g, eps_a, eps_v, si, sj)
    for s in np.flatnonzero(~keep):
        i, j = si[s], sj[s]
        i0, i1, j0, j1 = max(i - 2, 0), min(i + 2, a.size - 1), max(j - 2, 0), min(j + 2, v.size - 1)
        aa, vv = np.meshgrid(np.linspace(a[i0], a[i1], 41), np.linspace(v[j0], v[j1], 41))
        P = res.terms(aa.ravel(), vv.ravel())
        rel = np.abs(1 + P) / (1 + np.abs(P))
        assert rel.min() >= 0.00125, (k, i, j, rel.min())
    assert keep[80:].all() and (~keep[:80]).sum() >= 20


def _curve(plant, v: np.ndarray) -> np.ndarray:
    """j pi - ln G(e^v) on a dense grid v, on one continuous branch of arg."""
    ln_g = np.log(np.abs(plant(np.exp(v)))) + 1j * np.unwrap(np.angle(plant(np.exp(v))))
    return -ln_g.real + 1j * (np.pi - ln_g.imag)


def _random_pieces(seed: int, shortest: float, longest: float):
    """(plant, v0, v1, chord deviation h, dense v, the curve there) on 300 random pieces of G: random plants (order
    1-7, dampings down to 1e-6, integrators, zeros, delays), 5 intervals each of length shortest..longest (ln w)
    anywhere near the roots."""
    from fuzz_loops import random_plant
    from dfloop.solve.grid import chord_deviation

    rng = np.random.default_rng(seed)
    for _ in range(60):
        G, _, _, T = random_plant(rng)
        plant = as_plant(delayed(G, T) if T else G)
        zeros, poles = plant.roots
        for _ in range(5):
            v0 = math.log(10 ** rng.uniform(-1.5, 1.5))
            v1 = v0 + 10 ** rng.uniform(math.log10(shortest), math.log10(longest))
            v = np.linspace(v0, v1, 2001)
            yield rng, plant, v0, v1, chord_deviation(zeros, poles, float(plant.delay), v0, v1), v, _curve(plant, v)


def test_chord_deviation_bounds_the_curve_by_dense_sampling():
    """j pi - ln G(e^v) stays within grid.chord_deviation of its chord on every interval of _random_pieces;
    the bound is tight to within a modest factor where the curvature is steady (not vacuous)."""
    tight = 0
    for _, plant, v0, v1, h, v, t in _random_pieces(31, 1e-3, 0.5):
        chord = t[0] + (t[-1] - t[0]) * (v - v0) / (v1 - v0)
        dev = np.max(np.abs(t - chord))
        assert dev <= h + 1e-13 * (1 + np.max(np.abs(t))), (plant, v0, v1, dev, h)  # + this sampling's rounding
        tight += dev >= h / 20
    assert tight >= 30


def test_chord_gap_is_a_lower_bound_on_the_distance_to_the_curve():
    """grid.chord_gap never exceeds the distance (arg modulo 2 pi) from a rectangle spanned by two points to the
    densely sampled curve j pi - ln G over the interval, on _random_pieces and rectangles placed near the curve;
    and it separates pairs the two discs of radius e cannot (the reason it exists)."""
    from dfloop.solve.grid import chord_gap
    from dfloop.solve.roots import _gap

    sharper = 0
    for rng, plant, v0, v1, h, v, t in _random_pieces(32, 10 ** -2.5, 0.3):
        e = float(plant.log_variation(math.exp(v0), math.exp(v1)))
        # a flat rectangle beside the curve's middle, rotated by 2 pi k in arg
        mid = t[1000] + complex(rng.uniform(-0.2, 0.2), rng.choice([-1, 1]) * rng.uniform(0.0, 0.3))
        mid += 2j * np.pi * int(rng.integers(-2, 3))
        half = complex(rng.uniform(0, 0.3), rng.uniform(0, 0.05))
        l0, l1 = mid - half, mid + half
        x0, x1 = min(l0.real, l1.real), max(l0.real, l1.real)
        y0, y1 = min(l0.imag, l1.imag), max(l0.imag, l1.imag)
        dx = np.maximum(np.maximum(x0 - t.real, t.real - x1), 0.0)
        dy = np.maximum(np.abs(np.angle(np.exp(1j * (t.imag - 0.5 * (y0 + y1))))) - 0.5 * (y1 - y0), 0.0)
        true = np.min(np.hypot(dx, dy))
        gap = chord_gap(l0, l1, complex(t[0]), complex(t[-1]), e, h)
        assert gap <= true + 1e-12, (plant, v0, v1, gap, true)
        lens = max(_gap(l0, l1, complex(t[0]), e), _gap(l0, l1, complex(t[-1]), e))
        sharper += gap >= 0.005 > lens
    assert sharper >= 20


@pytest.mark.parametrize("k", range(len(LOOPS)))
def test_cells_the_compiled_windings_pass_over_as_empty_are_empty_by_brute_force(k):
    """The windings skip a cell that driver._cells_apart (compiled driver) or roots.cell_apart (Python driver)
    proves free of anything the refinement could accept (so of roots: its winding is 0): sampled densely, such a
    cell's relative residual stays above 0.00125; the two decide alike (from the same bounds; their logarithms may
    differ in the last place); and the test applies to many cells of these grids (not vacuous)."""
    from dfloop.solve.compiled.driver import _cells_apart
    from dfloop.solve.roots import cell_apart

    G, N, A_win, w_win = LOOPS[k]
    res, a, v, n, g, eps_a, eps_v = _grid(G, N, A_win, w_win)
    zeros, poles = (np.ascontiguousarray(r, complex) for r in res.plant.roots)
    ln_n, ln_g = clog(n), clog(g)
    arg_g = np.full(v.size, np.nan)

    def compiled_apart(ci, cj):
        return _cells_apart(zeros, poles, float(res.plant.delay), a, v, ln_n, eps_a, g, ln_g.real, arg_g, eps_v,
                            np.asarray(ci, np.int64), np.asarray(cj, np.int64))

    ci, cj = (x.ravel() for x in np.meshgrid(np.arange(a.size - 1), np.arange(v.size - 1), indexing="ij"))
    mask = compiled_apart(ci, cj)
    apart = differ = 0
    for i, j, compiled in zip(ci.tolist(), cj.tolist(), mask.tolist()):
        python = cell_apart(res, a, v, ln_n, eps_a, ln_g, eps_v, i, j)
        differ += compiled != python
        if not (compiled or python):
            continue
        apart += 1
        if (i * 7 + j) % 5:  # a fifth of them sampled densely (the suite's time)
            continue
        aa, vv = np.meshgrid(np.linspace(a[i], a[i + 1], 21), np.linspace(v[j], v[j + 1], 21))
        P = res.terms(aa.ravel(), vv.ravel())
        assert (np.abs(1 + P) / (1 + np.abs(P))).min() >= 0.00125, (k, i, j)
    assert apart >= 0.5 * (a.size - 1) * (v.size - 1) and differ <= 0.001 * apart
    for c in df.predict_limit_cycles(G, N, amplitude=A_win, omega=w_win):  # a cycle's own cell is never passed over
        i, j = np.searchsorted(a, math.log(c.amplitude)) - 1, np.searchsorted(v, math.log(c.frequency)) - 1
        assert not compiled_apart([i], [j])[0]
        assert not cell_apart(res, a, v, ln_n, eps_a, ln_g, eps_v, i, j)


def test_a_pair_with_close_ends_is_one_no_test_separates():
    """seed_excluded (and the compiled _no_root_in) end a box's search at once at a pair whose N end lies within the
    margin of a G end (_close_ends): that must be a pair neither test can ever separate, so the answer is the one
    the search would reach at its budget. On _random_pieces with N pieces placed near the curve's ends: whenever the
    ends are close, both the discs and the thickened chord fail; the compiled kernel decides alike; and both
    outcomes occur (not vacuous)."""
    from dfloop.solve.compiled.driver import _close_ends as compiled_close_ends
    from dfloop.solve.grid import chord_gap
    from dfloop.solve.roots import _SEED_MARGIN, _close_ends, _gap

    close = far = 0
    for rng, plant, v0, v1, h, v, t in _random_pieces(41, 10 ** -2.5, 0.3):
        e = float(plant.log_variation(math.exp(v0), math.exp(v1)))
        t0, t1 = complex(t[0]), complex(t[-1])
        end = t0 if rng.random() < 0.5 else t1
        l0 = end + 0.006 * complex(*rng.standard_normal(2)) + 2j * np.pi * int(rng.integers(-1, 2))
        l1 = l0 + complex(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3))
        if rng.random() < 0.5:
            l0, l1 = l1, l0
        got = _close_ends(l0, l1, t0, t1)
        assert compiled_close_ends(l0, l1, t0, t1) == got
        if got:
            close += 1
            assert max(_gap(l0, l1, t0, e), _gap(l0, l1, t1, e)) < _SEED_MARGIN
            assert chord_gap(l0, l1, t0, t1, e, h) < _SEED_MARGIN
        else:
            far += 1
    assert close >= 30 and far >= 30
