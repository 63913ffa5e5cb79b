"""Accuracy versus time: the solver's grid rule (grid chosen from G and N) against fixed grids.

Problems with known answers: a relay around exp(-sT)/(s + 1) for T = 1 and T = 3 on 0.1..400 rad/s (each
cycle the root of w T + atan w = (2m + 1) pi, found here by brentq), and a lightly damped resonance
(zeta = 1e-4) with saturation (phase crossing found by brentq). Rows:

- "grid rule": the default call ``predict_limit_cycles(G, N, omega=...)``.
- "fixed n_A x n_w": the same winding-number root finder (``dfloop.solve.roots.find_roots``) on a fixed
  log-spaced grid over the same windows, without the grid rule: what the solver would find if it trusted
  a grid of that size. A fixed grid misses the roots where arg G turns by more than pi between samples.

For each row: cycles found, the worst relative frequency error over the expected cycles (inf when one is
missing), the time (median of repeats) and its ratio to the grid rule's time in the same run.

A second table: the relay around e^{-jw}/(jw + 1) on the wide window [0.1, 1e5] rad/s (15,916 cycles), the plant
given as a callable (sampled: midpoint, golden-section and slope samples, ``GridReport.uncertified``) and as a
first-class delay ``df.delayed(ct.tf([1], [1, 1]), 1.0)`` (the exact bound, the baseline): cycles found against
the closed form, uncertified intervals, time of the call (one run each: seconds) and where it goes (the grid
(resolve_plant), candidate cells, root finding), with the ratio to the delay plant in the same run.

Run: python benchmarks/bench_solver_grid.py [--write]   (--write updates benchmarks/results/bench_solver_grid.md)
"""
from __future__ import annotations

import math
import pathlib
import sys
import time
import warnings

import control as ct
import numpy as np
from scipy.optimize import brentq

import dfloop as df
from dfloop.solve.plant import as_plant
from dfloop.solve.roots import Residual, find_roots

FIXED = [(64, 256), (64, 1024), (64, 4096), (64, 16384)]


def delay_problem(T):
    def G(w):
        w = np.asarray(w, dtype=float)
        return np.exp(-1j * w * T) / (1j * w + 1)

    f = lambda w, m: w * T + np.arctan(w) - (2 * m + 1) * np.pi  # noqa: E731
    ref = np.array([brentq(f, 0.1, 400, args=(m,), xtol=1e-14) for m in range(int(400 * T / 6) + 3)
                    if f(0.1, m) < 0 < f(400, m)])
    return f"relay + delay T={T:g} ({ref.size} cycles)", G, df.Relay(1.0), (0.1, 400.0), ref


def resonance_problem():
    zeta, wn = 1e-4, 2.0
    G = ct.tf([wn ** 2], [1, 2 * zeta * wn, wn ** 2]) * ct.tf([1], [1, 0.05])
    phase = lambda w: np.angle(complex(G(1j * w))) % (2 * np.pi) - np.pi  # noqa: E731
    w0 = brentq(phase, wn * 0.999, wn * 1.001, xtol=1e-15)
    return "resonance zeta=1e-4 + saturation (1 cycle)", G, df.Saturation(1.0), (0.1, 20.0), np.array([w0])


def fixed_grid(G, N, omega, amplitude, shape):
    res = Residual(as_plant(G), N)
    a = np.linspace(math.log(amplitude[0]), math.log(amplitude[1]), shape[0])
    v = np.linspace(math.log(omega[0]), math.log(omega[1]), shape[1])
    ra, rv, _ = find_roots(res, a, v, res.grid(a, v), 1e-10)
    return np.exp(rv)


def timed(fn, repeats=3):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def error(w, ref):
    if w.size == 0:
        return math.inf
    return max(np.min(np.abs(w - r)) / r for r in ref)


def wide_window() -> str:
    """The callable plant on [0.1, 1e5] rad/s against the same plant with a first-class delay."""
    import functools

    import dfloop.solve.predict as predict

    f = lambda w, m: w + np.arctan(w) - (2 * m + 1) * np.pi  # noqa: E731
    expected = sum(1 for m in range(20000) if f(0.1, m) < 0 < f(1e5, m))
    plants = [("callable e^{-jw}/(jw + 1)", lambda w: np.exp(-1j * np.asarray(w, float)) / (1j * np.asarray(w, float) + 1)),
              ("df.delayed(tf(1, [1, 1]), 1)", df.delayed(ct.tf([1], [1, 1]), 1.0))]
    stages = ("resolve_plant", "candidate_cells", "find_roots")
    rows = ["| plant | cycles found / expected | uncertified intervals | time (s) | grid (s) | candidate cells (s) "
            "| roots (s) | time / delay plant |", "|---|---|---|---|---|---|---|---|"]
    out = []
    for name, G in plants:
        spent = dict.fromkeys(stages, 0.0)
        originals = {s: getattr(predict, s) for s in stages}

        def timed_stage(fn, stage):
            @functools.wraps(fn)
            def run(*a, **k):
                t0 = time.perf_counter()
                try:
                    return fn(*a, **k)
                finally:
                    spent[stage] += time.perf_counter() - t0
            return run

        for s in stages:
            setattr(predict, s, timed_stage(originals[s], s))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t0 = time.perf_counter()
                cycles = df.predict_limit_cycles(G, df.Relay(1.0), omega=(0.1, 1e5))
                total = time.perf_counter() - t0
        finally:
            for s in stages:
                setattr(predict, s, originals[s])
        out.append((name, len(cycles), len(cycles.grid_report.uncertified), total, spent))
    base = out[-1][3]
    for name, n, unc, total, spent in out:
        rows.append(f"| {name} | {n} / {expected} | {unc} | {total:.1f} | {spent['resolve_plant']:.1f} | "
                    f"{spent['candidate_cells']:.1f} | {spent['find_roots']:.1f} | {total / base:.2f} |")
    return "\n".join(rows)


def main() -> str:
    rows = ["| problem | method | final grid (A x w) | cycles found / expected | max freq. error (rel.) | time (ms) "
            "| time / grid rule |", "|---|---|---|---|---|---|---|"]
    for name, G, N, omega, ref in (delay_problem(1.0), delay_problem(3.0), resonance_problem()):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            df.predict_limit_cycles(G, N, omega=omega)  # warm-up (JIT, caches)
            t_rule, cycles = timed(lambda: df.predict_limit_cycles(G, N, omega=omega))
            w = np.array([c.frequency for c in cycles])
            shape = cycles.grid_report.shape
            rows.append(f"| {name} | grid rule (default call) | {shape[0]} x {shape[1]} | {len(cycles)} / {ref.size} | "
                        f"{error(w, ref):.1e} | {1e3 * t_rule:.1f} | 1.00 |")
            for grid in FIXED:
                t, w = timed(lambda: fixed_grid(G, N, omega, cycles.amplitude_window, grid))
                rows.append(f"| {name} | fixed {grid[0]} x {grid[1]} | {grid[0]} x {grid[1]} | {w.size} / {ref.size} | "
                            f"{error(w, ref):.1e} | {1e3 * t:.1f} | {t / t_rule:.2f} |")
    return "\n".join(rows)


if __name__ == "__main__":
    table = main() + "\n\nWide window, relay around the delay plant on [0.1, 1e5] rad/s (one run each):\n\n" + wide_window()
    print(table)
    if "--write" in sys.argv[1:]:
        out = pathlib.Path(__file__).parent / "results" / "bench_solver_grid.md"
        out.parent.mkdir(exist_ok=True)
        out.write_text("# Solver: the grid rule against fixed grids (completeness, accuracy, time)\n\n"
                       "Command: `python benchmarks/bench_solver_grid.py --write` (median of 3 runs; ratios "
                       "against the grid rule in the same run).\n\n" + table + "\n")
