"""Accuracy versus time for the solver's one knob, the initial (amplitude x frequency) grid.

Two hard problems with known answers: a relay around exp(-s)/(s + 1) (48 cycles in 0.1..300 rad/s, each the
root of w T + atan w = (2m + 1) pi, found here by brentq), and a lightly damped resonance (zeta = 1e-4) with
saturation, whose cycle amplitude follows from the closed-form saturation DF. For each grid size the table gives
the number of cycles found, the worst frequency error against the reference, and the time (median of repeats),
with the time as a ratio to the default grid.

Run: python benchmarks/bench_solver_grid.py
"""
from __future__ import annotations

import pathlib
import time
import warnings

import control as ct
import numpy as np
from scipy.optimize import brentq

import dfloop as df

GRIDS = [(8, 32), (16, 64), (32, 128), (64, 256), (128, 512)]
DEFAULT = (64, 256)


def delay_problem():
    T = 1.0

    def G(w):
        w = np.asarray(w, dtype=float)
        return np.exp(-1j * w * T) / (1j * w + 1)

    f = lambda w, m: w * T + np.arctan(w) - (2 * m + 1) * np.pi  # noqa: E731
    ref = np.array([brentq(f, 0.1, 300, args=(m,), xtol=1e-14) for m in range(80) if f(0.1, m) < 0 < f(300, m)])
    return "relay + delay (48 cycles)", G, df.Relay(1.0), dict(omega=(0.1, 300.0)), ref


def resonance_problem():
    zeta, wn, k = 1e-4, 2.0, 1.0
    G = ct.tf([k * wn**2], [1, 2 * zeta * wn, wn**2]) * ct.tf([1], [1, 0.05])
    # phase -180 deg where the lag of the resonance plus the first-order pole reach pi: solve numerically
    phase = lambda w: np.angle(complex(G(1j * w))) % (2 * np.pi) - np.pi  # noqa: E731
    w0 = brentq(phase, wn * 0.999, wn * 1.001, xtol=1e-15)
    return "resonance zeta=1e-4 + saturation", G, df.Saturation(1.0), dict(omega=(0.1, 20.0)), np.array([w0])


def timed(fn, repeats=3):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def main() -> str:
    rows = ["| problem | grid (A x w) | cycles found / expected | max freq. error (rel.) | time (ms) | time / default grid |",
            "|---|---|---|---|---|---|"]
    for name, G, N, kw, ref in (delay_problem(), resonance_problem()):
        df.predict_limit_cycles(G, N, **kw)  # warm-up (JIT, caches)
        t_default, _ = timed(lambda: df.predict_limit_cycles(G, N, grid=DEFAULT, **kw))
        for grid in GRIDS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t, cycles = timed(lambda: df.predict_limit_cycles(G, N, grid=grid, **kw))
            w = np.array([c.frequency for c in cycles])
            err = max((np.min(np.abs(w - r)) / r for r in ref), default=np.inf) if w.size else np.inf
            rows.append(f"| {name} | {grid[0]} x {grid[1]} | {len(cycles)} / {ref.size} | {err:.1e} | "
                        f"{1e3 * t:.1f} | {t / t_default:.2f} |")
    table = "# Solver: initial grid versus completeness, accuracy and time\n\n" + "\n".join(rows) + "\n"
    out = pathlib.Path(__file__).parent / "results" / "bench_solver_grid.md"
    out.parent.mkdir(exist_ok=True)
    out.write_text(table)
    return table


if __name__ == "__main__":
    print(main())
