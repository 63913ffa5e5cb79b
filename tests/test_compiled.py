"""The compiled pipeline (dfloop.solve.compiled) against the Python reference path (DFLOOP_COMPILED=0).

The compiled path runs the whole prediction in the compiled driver (solve/compiled/driver.py) where it applies and
finishes, and otherwise the Python driver with G, N, their slopes and the refinement in numba kernels. The truth
here is the Python path itself: on the textbook loops and on 160 random loops (plants of order
1-7 with dampings down to 1e-6, unstable poles, integrators, pure delays; every element kind with a compiled
form) both must find the same number of cycles, at the same amplitudes and frequencies to 1e-12 (relative; or
within the roots' own position uncertainty where rounding leaves more), with the same labels, on the same grid,
or fail with the same error.
"""
from __future__ import annotations

import math
import pickle
import warnings

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.describing.numeric import NumericDF
from dfloop.solve import as_plant
from dfloop.solve.compiled import CompiledResidual, driver_parts, residual_for, run_driver
from dfloop.solve.compiled import kernels as K
from dfloop.solve.delay import delayed
from dfloop.solve.grid import clog
from dfloop.solve.result import DeferredReport, GridReport
from dfloop.solve.roots import Residual

from fuzz_loops import random_element, random_plant

TEXTBOOK = [
    (ct.tf([1], [1, 3, 2, 0]), df.Relay()),
    (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.1)),
    (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, dead_zone=0.1)),
    (ct.tf([3], [1, 2, 3, 1]), df.Relay(M=1.5, dead_zone=0.2, hysteresis=0.1)),
    (ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)),
    (ct.tf([30], [1, 4, 1, -6]), df.Saturation(1.0)),
    (ct.tf([12], [1, 3, 3, 1]), df.DeadZone(0.5)),
    (ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)),
    (ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(h=0.2)),
    (ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0)),
    (ct.ss(ct.tf([4], [1, 2, 2, 1])), df.PreloadedSpring(0.5, k=0.2)),
    (delayed(ct.tf([2], [1, 1]), 0.5), df.CoulombViscousFriction(1.0, c=0.1)),
    (ct.tf([1], [1, 2, 2, 1]) * ct.tf(*ct.pade(5, 4)) * 4, df.Backlash(h=1.0)),
]
KINDS = ["saturation", "deadzone", "relay", "relay_hyst", "backlash", "cubic", "coulomb", "preload"]


@pytest.fixture(autouse=True)
def compiled_path(monkeypatch):
    """The compiled path wherever it applies (compiling its kernels first if this is a fresh install)."""
    monkeypatch.setenv("DFLOOP_COMPILED", "driver")


def _solve(G, N, monkeypatch, compiled: bool, **options):
    monkeypatch.setenv("DFLOOP_COMPILED", "driver" if compiled else "0")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return df.predict_limit_cycles(G, N, **options)
        except (ValueError, RuntimeError) as exc:
            return type(exc)


def _same(G, N, monkeypatch, **options) -> int:
    ref, got = _solve(G, N, monkeypatch, False, **options), _solve(G, N, monkeypatch, True, **options)
    if isinstance(ref, type):
        assert got is ref
        return 0
    assert len(got) == len(ref), (G, N, ref, got)
    assert got.grid_report.shape == ref.grid_report.shape  # the same grid, chosen from G and N
    assert got.grid_report.candidate_cells == ref.grid_report.candidate_cells
    assert got.window_source == ref.window_source
    assert np.allclose(got.amplitude_window + got.omega_window, ref.amplitude_window + ref.omega_window,
                       rtol=1e-12, atol=0)
    for c, r in zip(got, ref):
        # 1e-12, or the roots' own position uncertainty where rounding leaves more (roots.merge's rule for "the
        # same root": a root at the rounding floor of its residual, A ~ 1e7 on a saturation, moves by 3e-11)
        near = 1e-12 + _radius(G, N, r) + _radius(G, N, c)
        assert abs(np.log(c.amplitude / r.amplitude)) <= near and abs(np.log(c.frequency / r.frequency)) <= near
        assert c.stability == r.stability
        assert c.on_edge == r.on_edge and c.valid == r.valid
    return len(ref)


def _radius(G, N, cycle) -> float:
    """4 |R| / s_min(J) at a cycle (log units): how far the true root may lie (as roots.merge bounds it)."""
    P, ra, rv = Residual(as_plant(G), N).slopes(np.log([cycle.amplitude]), np.log([cycle.frequency]))
    J = np.array([[ra[0].real, rv[0].real], [ra[0].imag, rv[0].imag]])
    return 4 * abs(1 + P[0]) / np.linalg.svd(J, compute_uv=False)[-1]


def test_every_compiled_kind_is_compiled_and_others_are_not():
    plant = as_plant(ct.tf([1], [1, 2, 1]))
    for N in (df.Saturation(1), df.DeadZone(1), df.Relay(), df.Relay(hysteresis=0.1, dead_zone=0.2),
              df.Backlash(1), df.CubicStiffness(1, 1), df.PreloadedSpring(1), df.CoulombViscousFriction(1)):
        assert isinstance(residual_for(plant, N), CompiledResidual)
    assert isinstance(residual_for(as_plant(delayed(ct.tf([1], [1, 1]), 0.2)), df.Relay()), CompiledResidual)
    numeric = NumericDF(lambda x: np.clip(x, -1, 1))
    assert type(residual_for(plant, numeric)) is Residual
    assert type(residual_for(as_plant(lambda w: 1 / (1j * w + 1)), df.Relay())) is Residual
    assert type(residual_for(plant, df.Quantizer(0.1))) is Residual

    class Softer(df.Saturation):  # a user's variant of a built-in element: its own N, not the compiled one
        def _evaluate(self, A, omega):
            return 0.5 * super()._evaluate(A, omega)

    assert type(residual_for(plant, Softer(1.0))) is Residual


def test_kernels_evaluate_what_the_python_residual_evaluates():
    rng = np.random.default_rng(4)
    a, v = rng.uniform(-4, 4, 300), rng.uniform(-3, 3, 300)
    for G, N in TEXTBOOK:
        plant = as_plant(G)
        ref, got = Residual(plant, N), residual_for(plant, N)
        x, y = ref._evaluate_slopes(a, v), got._evaluate_slopes(a, v)
        w = np.exp(v)[:, None]
        zeros, poles = plant.roots
        terms = (np.abs(1j * w / (1j * w - zeros)).sum(axis=1) + np.abs(1j * w / (1j * w - poles)).sum(axis=1)
                 + np.exp(v) * plant.delay)
        # P, G, N: rounding; dP/da: a central difference of step 1e-6 of N (rounding / 1e-6); dP/dv: the sum
        # of the pole and zero terms of d ln G / d ln w (rounding of each term)
        scale = [np.abs(x[0]), np.abs(x[0]) * 1e4 + np.abs(x[1]), np.abs(x[0]) * (1 + terms), np.abs(x[3]),
                 np.abs(x[4])]
        for p, q, s in zip(x, y, scale):
            assert np.all(np.abs(p - q) <= 1e-13 * s)
        assert np.max(np.abs(ref.terms(a, v) - got.terms(a, v)) / (1 + np.abs(ref.terms(a, v)))) < 1e-13


def test_complex_division_is_numpys():
    rng = np.random.default_rng(5)
    z = rng.normal(size=400) + 1j * rng.normal(size=400)
    d = rng.normal(size=400) * 10.0 ** rng.integers(-5, 5, 400) + 1j * rng.normal(size=400)
    got = np.array([K.cdiv(x, y) for x, y in zip(z, d)])
    assert np.array_equal(got, z / d)


def test_textbook_loops_agree(monkeypatch):
    assert sum(_same(G, N, monkeypatch) for G, N in TEXTBOOK) >= 15


def test_random_loops_agree(monkeypatch):
    rng = np.random.default_rng(19)
    found = 0
    for k in range(160):
        G, _, _, T = random_plant(rng)
        N = random_element(rng, KINDS[k % len(KINDS)])
        found += _same(delayed(G, T) if T else G, N, monkeypatch)
    assert found >= 60  # the comparison covers cycles, not only empty results



def test_the_compiled_path_is_the_default_and_the_python_one_a_switch(monkeypatch):
    plant = as_plant(ct.tf([1], [1, 2, 1]))
    monkeypatch.delenv("DFLOOP_COMPILED")
    assert isinstance(residual_for(plant, df.Relay()), CompiledResidual)  # whatever numba's cache holds
    monkeypatch.setenv("DFLOOP_COMPILED", "0")
    assert type(residual_for(plant, df.Relay())) is Residual


def _status(G, N, grid=(64, 256), **windows) -> int:
    """The compiled driver's status on the loop (0: it answered; otherwise why it left it to the Python driver)."""
    parts = driver_parts(G, N)
    assert parts is not None
    w = [windows.get(k, np.nan) for k in ("w_lo", "w_hi", "A_lo", "A_hi")]
    return int(run_driver(*parts, *w, *grid, 1e-10, 1e-4)[0])


def test_the_driver_answers_the_common_case_and_agrees_with_the_python_path(monkeypatch):
    answered = [G_N for G_N in TEXTBOOK if _status(*G_N) == 0]
    assert len(answered) >= 11  # the driver, not the fallback, is what the comparisons above measure
    # given windows (the python-control problems) and another grid
    for G, N in answered[:6]:
        _same(G, N, monkeypatch, omega=(0.05, 30.0), amplitude=(0.2, 8.0), grid=(40, 120))


def test_fallback_cases_give_the_python_answer(monkeypatch):
    """Loops the driver leaves to the Python driver (here: N's limits leave no amplitude for a root, a token
    window; a plant that is a callable; an element without a compiled form) get exactly the Python answer."""
    token = [(ct.tf([2.50869721], [1.0, 2.63526412]), df.DeadZone(8.114730904806219, 0.30362030994322053)),
             (ct.tf([0.2947], [1, 1.547]), df.DeadZone(0.906166742393567, 0.11706236171721078))]
    for G, N in token:
        assert _status(G, N) == 9
        ref, got = _solve(G, N, monkeypatch, False), _solve(G, N, monkeypatch, True)
        assert got.amplitude_window == ref.amplitude_window and got.window_source == ref.window_source
        assert len(got) == len(ref) == 0
    assert driver_parts(lambda w: 1 / (1j * w + 1), df.Relay()) is None
    assert driver_parts(ct.tf([1], [1, 1]), NumericDF(lambda x: np.clip(x, -1, 1))) is None


# sampled servo loops K e^{-s tau} / (s (0.5 s + 1)) with a backlash of clearance h, on a coarse 8 x 32 grid, where
# the Python driver isolates: a cell of winding +1 or -1 whose refinement from the linear model's root fails, and a
# tangent seed that refines to a root (its box then isolated around it)
ISOLATED = [(5.9381, 1.9171, 0.03864, "failed"), (6.0036, 0.9781, 0.03173, "failed"),
            (6.6324, 1.0271, 0.00705, "seed"), (5.8881, 1.5638, 0.03646, "seed")]


@pytest.mark.parametrize("K, h, tau, branch", ISOLATED)
def test_the_driver_isolates_where_the_python_driver_does(K, h, tau, branch, monkeypatch):
    """Where a refinement fails or a seed refines to a root, the compiled driver isolates the box itself
    (quadrisection by windings): it answers, with the Python driver's cycles, labels and evaluation count."""
    from dfloop.solve import roots

    G, N = delayed(ct.tf([K], [0.5, 1, 0]), tau), df.Backlash(h=h)
    seen = []
    real = roots._isolate

    def spy(res, box, window, tol, hint=None):
        seen.append("seed" if hint is not None else "failed")
        return real(res, box, window, tol, hint)

    monkeypatch.setattr(roots, "_isolate", spy)
    ref = _solve(G, N, monkeypatch, False, grid=(8, 32))
    assert branch in seen  # the branch this loop exercises
    monkeypatch.setenv("DFLOOP_COMPILED", "driver")
    assert _status(G, N, grid=(8, 32)) == 0
    got = _solve(G, N, monkeypatch, True, grid=(8, 32))
    assert got.n_evaluations == ref.n_evaluations
    assert _same(G, N, monkeypatch, grid=(8, 32)) == len(ref) >= 1


def test_the_compiled_isolation_is_the_python_isolation_on_any_box():
    """driver._isolate against roots._isolate on boxes of random size and place around the cycles of loops with
    one to three cycles (boxes holding several roots, of winding 0, +-1 or +-2, cut by the window), with and
    without a hint, the Python one on the compiled residual: the same roots bit for bit, the same evaluation count, or the compiled one's status 2 exactly
    where the Python one meets an edge zero, a jump or an unresolved box."""
    from dfloop.solve.compiled.driver import _isolate
    from dfloop.solve.roots import Box, _isolate as py_isolate

    rng = np.random.default_rng(7)
    compared = several = fallbacks = 0
    for G, N in TEXTBOOK:
        N = df.as_element(N)
        cycles = df.predict_limit_cycles(G, N)
        if not len(cycles):
            continue
        gpart, npart = driver_parts(G, N)
        a_w, v_w = np.log(cycles.amplitude_window), np.log(cycles.omega_window)
        window = np.array([a_w[0], a_w[1], v_w[0], v_w[1]])
        ca, cv = np.log([c.amplitude for c in cycles]), np.log([c.frequency for c in cycles])
        for trial in range(13):
            k = rng.integers(ca.size)
            half_a, half_v = 10 ** rng.uniform(-3, 0, size=2)
            box = [max(ca[k] - half_a * rng.uniform(0.1, 1.9), window[0]), min(ca[k] + half_a, window[1]),
                   max(cv[k] - half_v * rng.uniform(0.1, 1.9), window[2]), min(cv[k] + half_v, window[3])]
            if trial == 12:  # every cycle in one box
                box = [max(ca.min() - 0.1, window[0]), min(ca.max() + 0.2, window[1]),
                       max(cv.min() - 0.15, window[2]), min(cv.max() + 0.1, window[3])]
            hint = (ca[k], cv[k]) if trial % 3 == 0 else None
            res = residual_for(as_plant(G), N)  # its kernels: G, N and the refinement are the driver's
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fa, fv, crossings = py_isolate(res, Box(*box), Box(*window), 1e-10, hint=hint)
            status, ga, gv, gvals, n_points = _isolate(
                gpart[0], gpart[1], gpart[2], gpart[3], float(gpart[4]), npart[0], npart[1], npart[2], npart[3],
                npart[4], *box, window, 1e-10, hint is not None, *(hint or (0.0, 0.0)))
            if status:
                assert status == 2 and (crossings or res.unresolved or res.n_points != n_points)
                fallbacks += 1
                continue
            assert not crossings and not res.unresolved
            assert n_points == res.n_points
            assert np.array_equal(ga, fa) and np.array_equal(gv, fv)  # the same kernels: the same bits
            assert np.allclose(gvals[0], -1, atol=1e-9)  # G N at the roots: 1 + G N = 0
            compared += 1
            several += len(set(np.round(fa, 6))) > 1
    assert compared >= 100 and several >= 3, (compared, several, fallbacks)


def test_driver_constants_are_the_python_drivers():
    from dfloop.solve import grid, predict, roots
    from dfloop.solve.compiled.driver import CONSTANTS as C

    assert (C["STEP"], C["GOLDEN"], C["MONOTONE_WIDTH"], C["MAX_ROUNDS"], C["MIN_WIDTH"], C["MAX_POINTS"]) == (
        grid.STEP, grid._GOLDEN, grid.MONOTONE_WIDTH, grid._MAX_ROUNDS, grid._MIN_WIDTH, grid._MAX_POINTS)
    assert (C["SPLIT_PHASE"], C["MAX_EDGE_DEPTH"], C["MAX_SEGMENTS"], C["JUMP_LENGTH"], C["JUMP_SIZE"],
            C["JUMP_KEEP"], C["TANGENT_THRESHOLD"], C["MAX_TANGENT_SEEDS"], C["MERGE_RADIUS"], C["JUMP_DOMINANCE"],
            C["DEGENERATE_SIN"], C["SEED_MARGIN"], C["SEED_SPLITS"], C["SEED_TESTS"]) == (
                roots._SPLIT_PHASE, roots._MAX_EDGE_DEPTH, roots._MAX_SEGMENTS, roots._JUMP_LENGTH, roots._JUMP_SIZE,
                roots._JUMP_KEEP, roots._TANGENT_THRESHOLD, roots._MAX_TANGENT_SEEDS, roots._MERGE_RADIUS,
                roots._JUMP_DOMINANCE, roots._DEGENERATE_SIN, roots._SEED_MARGIN, roots._SEED_SPLITS,
                roots._SEED_TESTS)
    assert (C["MAX_ISOLATE_DEPTH"], C["MAX_LIVE_BOXES"], C["EARLY_CONTINUUM_CHECK"]) == (
        roots._MAX_ISOLATE_DEPTH, roots._MAX_LIVE_BOXES, roots._EARLY_CONTINUUM_CHECK)
    from dfloop.solve import plant

    assert C["DECADES"] == plant._DECADES_BEYOND_FEATURES
    from dfloop.solve.compiled import driver

    assert np.array_equal(predict._REACH_GRID, driver._REACH)


def test_driver_roots_are_numpys():
    """The driver's poles and zeros are the Plant's (np.roots), bit for bit, also where it skips numpy's call."""
    from dfloop.solve.compiled.parts import _roots

    rng = np.random.default_rng(7)
    for _ in range(500):
        n = int(rng.integers(1, 5))
        p = np.concatenate([rng.normal(size=n) * 10.0 ** rng.integers(-5, 5, n), np.zeros(rng.integers(0, 3))])
        p[0] = p[0] or 1.0
        assert np.array_equal(np.roots(p), _roots(p))


def test_a_fresh_install_does_not_make_a_single_call_wait_for_the_driver(monkeypatch, capsys):
    """Default mode on an installation whose driver is not compiled (numba's cache empty: simulated): the call runs
    the Python driver on the compiled residual, with the driver's answer (1e-12), says once how to compile the
    driver, and compiles nothing of it; once the driver is ready, calls use it."""
    import dfloop.progress as progress
    import dfloop.solve.compiled.residual as residual
    import dfloop.solve.predict as predict

    G, N = ct.tf([4], [1, 2, 1, 0]), df.Backlash(h=0.5)
    monkeypatch.setenv("DFLOOP_COMPILED", "driver")
    ref = df.predict_limit_cycles(G, N)
    monkeypatch.setenv("DFLOOP_COMPILED", "1")
    monkeypatch.setenv("DFLOOP_PROGRESS", "1")
    monkeypatch.setattr(residual, "_DRIVER_READY", [])
    monkeypatch.setattr(residual, "_DRIVER_HINTED", [])
    monkeypatch.setattr(progress, "compile_pending", lambda *d: True)

    def no_driver(*args):
        raise AssertionError("the driver ran on a fresh install")

    monkeypatch.setattr(predict, "run_driver", no_driver)
    got = [df.predict_limit_cycles(G, N) for _ in range(2)]
    hint = capsys.readouterr().err
    assert hint.count("the compiled solver driver is not compiled") == 1        # said once, not per call
    for r in got:
        assert [c.stability for c in r] == [c.stability for c in ref] and len(ref) >= 1
        assert [x for c in r for x in (c.amplitude, c.frequency)] == pytest.approx(
            [x for c in ref for x in (c.amplitude, c.frequency)], rel=1e-12)
    assert not residual.driver_wanted()
    monkeypatch.setattr(progress, "compile_pending", lambda *d: False)     # compiled (dfloop warmup, a batch)
    assert residual.driver_wanted() and residual._DRIVER_READY


@pytest.mark.parametrize("G, N", [TEXTBOOK[0], TEXTBOOK[4], TEXTBOOK[7], TEXTBOOK[12]])
def test_driver_windings_are_the_python_windings_on_every_cell(G, N):
    """The compiled windings (which pass over a cell whose four edge steps all turn R by less than pi/2) give
    every cell of a coarse grid the winding the Python driver's grid_windings gives it, cycles' cells included.
    (The cells they pass over as provably empty are checked in tests/test_seed_exclusion.py.)"""
    from dfloop.solve.compiled.driver import _windings
    from dfloop.solve.roots import grid_windings

    N = df.as_element(N)
    gpart, npart = driver_parts(G, N)
    res = Residual(as_plant(G), N)
    a, v = np.linspace(np.log(0.05), np.log(5.0), 30), np.linspace(np.log(0.1), np.log(10.0), 40)
    n, g = N(np.exp(a)).astype(complex), as_plant(G)(np.exp(v))
    ii, jj = (x.ravel() for x in np.meshgrid(np.arange(a.size - 1), np.arange(v.size - 1), indexing="ij"))
    flat = ii * v.size + jj
    ln_n, ln_g = clog(n), clog(g)
    eps_a = np.full(a.size - 1, np.inf)  # no bound on N's pieces: every cell goes through the windings themselves
    cells, windings, status, _ = _windings(gpart[0], gpart[1], gpart[2], gpart[3], float(gpart[4]), npart[0], npart[1], npart[2],
                                 a, v, n, g, flat, ln_n, eps_a, ln_g.real, np.full(v.size, np.nan), np.full(v.size - 1, 1.0))
    ri, rj, wind, suspects = grid_windings(res, a, v, np.outer(n, g), cells=(ii, jj))
    assert status == 0 and not suspects
    assert cells.tolist() == (ri * v.size + rj).tolist() and windings.tolist() == wind.tolist()
    assert np.all(np.abs(wind) == 1) and cells.size >= 1  # a cycle's cell is among them


def test_the_python_driver_passes_over_the_cells_the_compiled_one_does(monkeypatch):
    """The Python driver passes over the windings of the cells the compiled driver's _cells_apart proves free of
    zeros (roots.cell_apart, or the compiled kernel on a compiled loop): on the textbook loops both paths spend the
    same evaluations on their windings, seeds and refinements (a count that moves with every cell bisected)."""
    for G, N in TEXTBOOK:
        counts = []
        for mode in ("0", "driver"):
            monkeypatch.setenv("DFLOOP_COMPILED", mode)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                counts.append(df.predict_limit_cycles(G, N).n_evaluations)
        assert counts[0] == counts[1], (G, N, counts)


def test_the_limit_reach_index_found_by_bisection_is_the_scans():
    """driver._reach_index bisects the amplitude grid for the first point where the element's bound c / A (tail)
    or c A^2 + d (head) passes the threshold; it must read the index (and threshold) a scan of every point reads,
    for bounds and thresholds across the grid's whole range, at its ends and beyond, and with no crossing at all."""
    from dfloop.solve.compiled.driver import _REACH, _reach_index

    def scan(c, d, half, to_inf):
        if to_inf:
            for i, A in enumerate(_REACH):
                if c / A < half:
                    return i, c / A
            return -1, np.inf
        for i, A in enumerate(_REACH):
            if not (c * (A * A) + d < half):
                return (-1, np.inf) if i == 0 else (i - 1, c * (_REACH[i - 1] ** 2) + d)
        return -1, c * (_REACH[-1] ** 2) + d

    rng = np.random.default_rng(4)
    cases = [(c, d, h) for c, d, h in zip(10.0 ** rng.uniform(-300, 300, 150), 10.0 ** rng.uniform(-320, 5, 150),
                                            10.0 ** rng.uniform(-300, 300, 150))]
    cases += [(1.0, 0.0, 1e-320), (1.0, 0.0, np.inf), (0.0, 0.0, 1.0), (1e300, 1e300, 1e-300), (1.0, 0.0, np.nan),
              (_REACH[17], 0.0, 1.0), (1.0, 0.0, 1.0 / _REACH[4000])]
    hits = 0
    with np.errstate(over="ignore", invalid="ignore"):
        for c, d, half in cases:
            for to_inf in (True, False):
                got, want = _reach_index(c, d, half, to_inf), scan(c, d, half, to_inf)
                assert got[0] == want[0] and (got[1] == want[1] or (np.isnan(got[1]) and np.isnan(want[1]))), \
                    (c, d, half, to_inf, got, want)
                hits += got[0] > 0
    assert hits >= 100


def test_the_driver_finds_the_jumps_the_python_driver_finds():
    """driver._near_jump reads a dominant step of P = N G in a patch from N's and G's own steps (every column's
    steps along A are |G_j| times N's, every row's along w |N_i| times G's); roots._near_jump does the same on an
    OuterProduct. Both must find what roots.dominant_steps finds on the patch of the full outer product, on random
    samples with planted jumps, flat stretches and zeros (and find jumps often, and not always)."""
    from dfloop.solve.compiled.driver import _near_jump
    from dfloop.solve.roots import OuterProduct, _near_jump as python_near_jump, dominant_steps

    rng = np.random.default_rng(8)
    found = 0
    for trial in range(400):
        na, nv = int(rng.integers(3, 14)), int(rng.integers(3, 14))
        n = np.exp(np.cumsum(rng.normal(0, 0.05, na)) + 1j * np.cumsum(rng.normal(0, 0.05, na)))
        g = np.exp(np.cumsum(rng.normal(0, 0.05, nv)) + 1j * np.cumsum(rng.normal(0, 0.05, nv)))
        g *= 10 ** rng.uniform(-3, 3)
        if trial % 3 == 0:  # a jump of N
            n[int(rng.integers(1, na)):] *= rng.uniform(1.5, 3.0)
        if trial % 5 == 0:  # a jump of G
            g[int(rng.integers(1, nv)):] *= np.exp(1j * rng.uniform(0.5, 2.0))
        if trial % 7 == 0:  # G zero on a stretch
            g[:int(rng.integers(1, nv))] = 0
        i, j = int(rng.integers(0, na)), int(rng.integers(0, nv))
        r0, r1, c0, c1 = max(i - 4, 0), min(i + 5, na), max(j - 4, 0), min(j + 5, nv)
        patch = np.outer(n, g)[r0:r1, c0:c1]
        want = bool(dominant_steps(patch).any() or dominant_steps(patch.T).any())
        assert _near_jump(n, g, r0, r1, c0, c1) == want, trial
        assert python_near_jump(OuterProduct(n, g), np.array([i]), np.array([j]), 3)[0] == want, trial
        found += want
    assert 50 <= found <= 350


def test_the_grids_phase_wrap_and_hypotenuse_are_the_same_bits_in_both_drivers():
    """grid.wrap_phase and grid.hypot (the grids' rules, written as exact IEEE operations so the compiled driver's
    _wrapped and _hypot give the same bits) agree bit for bit with their compiled forms (the wrap of a difference
    of two angles, |d| <= 2 pi), stay within a few ulp of
    np.angle(np.exp(1j d)) and np.hypot, and keep their NaN and infinity semantics, over the whole range."""
    from dfloop.solve.compiled.driver import _hypot, _wrapped
    from dfloop.solve.grid import hypot, wrap_phase

    rng = np.random.default_rng(12)
    d = np.concatenate([rng.uniform(-2 * np.pi, 2 * np.pi, 20000), rng.uniform(-50, 50, 2000),
                        [np.pi, -np.pi, 2 * np.pi, -2 * np.pi, 0.0, np.nan, np.inf, -np.inf, 1e300]])
    got, compiled = wrap_phase(d), np.array([_wrapped(x) for x in d])
    near = ~(np.abs(d) > 2 * np.pi)  # a difference of two angles: exact there (beyond, both round sin, cos, atan2)
    assert np.array_equal(got[near], compiled[near], equal_nan=True)
    assert np.allclose(got[~near], compiled[~near], rtol=0, atol=1e-13, equal_nan=True)
    with np.errstate(invalid="ignore"):
        ref = np.angle(np.exp(1j * d))
    assert np.array_equal(np.isnan(got), np.isnan(ref))
    turn = np.abs(got - ref)
    turn = np.minimum(turn, np.abs(turn - 2 * np.pi))  # pi and -pi are the same phase
    assert np.nanmax(turn) <= 1e-14
    x = np.concatenate([rng.standard_normal(20000) * 10.0 ** rng.uniform(-200, 200, 20000),
                        [np.inf, -np.inf, np.nan, 0.0, 1e-300, 1e300, np.nan]])
    y = np.concatenate([rng.standard_normal(20000) * 10.0 ** rng.uniform(-3, 3, 20000),
                        [np.nan, 1.0, np.inf, 0.0, 1e-300, 1e300, 2.0]])
    got = hypot(x, y)
    assert np.array_equal(got, [_hypot(a, b) for a, b in zip(x, y)], equal_nan=True)
    ref = np.hypot(x, y)
    assert np.array_equal(np.isnan(got), np.isnan(ref)) and np.array_equal(np.isinf(got), np.isinf(ref))
    fin = np.isfinite(ref) & (ref > 0)
    assert np.max(np.abs(got[fin] - ref[fin]) / ref[fin]) <= 4.5e-16


def test_a_plant_is_converted_once_whatever_its_coefficients_dtype():
    """The driver's plant part is remembered by the coefficients as given (integer ones too, as tf([1], [1, 3, 2, 0])
    stores them), and two plants whose coefficients differ only in dtype or byte order are not confused."""
    from dfloop.solve.compiled.parts import plant_part

    ints = ct.tf([1], [1, 3, 2, 0])
    assert ints.num_array[0, 0].dtype.kind == "i"
    first = plant_part(ints)
    assert plant_part(ct.tf([1], [1, 3, 2, 0])) is first  # a new object, the same contents: no conversion
    floats = plant_part(ct.tf([1.0], [1.0, 3.0, 2.0, 0.0]))
    assert floats is not first and all(np.array_equal(x, y) for x, y in zip(floats[:4], first[:4]))
    swapped = ct.tf(np.array([1.0], ">f8"), np.array([1.0, 3.0, 2.0, 0.0], ">f8"))
    got = plant_part(swapped)
    assert got is None or all(np.array_equal(x, y) for x, y in zip(got[:4], first[:4]))


def test_a_compiled_result_reads_and_pickles_its_grid_report_as_the_python_path_builds_it(monkeypatch):
    """The compiled driver's result builds its GridReport on first reading (result.DeferredReport): read after a
    pickle round trip or directly, it is the report the Python driver builds for the loop (rules, shape, counts;
    the largest steps to 1e-12), and a pickled result keeps its cycles."""

    for G, N in TEXTBOOK[:3] + TEXTBOOK[7:9]:
        got, ref = _solve(G, N, monkeypatch, True), _solve(G, N, monkeypatch, False)
        assert isinstance(got._grid_report, DeferredReport)  # not built yet
        back = pickle.loads(pickle.dumps(got))
        assert [(c.amplitude, c.frequency, c.stability) for c in back] == \
            [(c.amplitude, c.frequency, c.stability) for c in got]
        for report in (back.grid_report, got.grid_report):
            assert isinstance(report, GridReport) and report == got.grid_report
            assert (report.shape, report.frequency_rule, report.amplitude_rule, report.n_jumps,
                    report.candidate_cells) == (ref.grid_report.shape, ref.grid_report.frequency_rule,
                                                ref.grid_report.amplitude_rule, ref.grid_report.n_jumps,
                                                ref.grid_report.candidate_cells)
            assert math.isclose(report.max_step_frequency, ref.grid_report.max_step_frequency, rel_tol=1e-12)
            assert math.isclose(report.max_step_amplitude, ref.grid_report.max_step_amplitude, rel_tol=1e-12)


def test_the_drivers_sorts_are_numpys_on_runs_ties_and_signed_zeros():
    """driver._order is np.argsort(kind="stable"), driver._sorted takes the values in that order (so it is
    np.sort with ties, signed zeros included, in their stable order) and driver._unique gives np.unique's values:
    on shuffled data, concatenated ascending and descending runs (the grids' case), repeated values and mixed
    -0.0 / 0.0, empty and one-element arrays."""
    from dfloop.solve.compiled.driver import _order, _sorted, _unique

    rng = np.random.default_rng(23)
    for t in range(400):
        m = int(rng.integers(0, 300))
        kind = t % 4
        if kind == 0:
            x = rng.normal(size=m)
        elif kind == 1:
            x = np.concatenate([np.sort(rng.normal(size=int(rng.integers(0, 60)))) * rng.choice([1, -1])
                                for _ in range(int(rng.integers(1, 6)))])
        elif kind == 2:
            x = rng.integers(-4, 4, m).astype(float)
            x[rng.random(m) < 0.3] = -0.0
        else:
            x = np.repeat(rng.normal(size=max(m // 3, 1)), 3)[:m]
        x = np.ascontiguousarray(x, float)
        stable = np.argsort(x, kind="stable")
        assert np.array_equal(_order(x), stable)
        s = _sorted(x)
        assert np.array_equal(s, x[stable]) and np.array_equal(np.signbit(s), np.signbit(x[stable]))
        assert np.array_equal(_unique(x), np.unique(x))
