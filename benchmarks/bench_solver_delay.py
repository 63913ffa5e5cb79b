"""Time of the default call on the delay loops of issue 7: a relay around exp(-sT)/(s + 1), w in [0.1, 400].

Every cycle is the root of w T + atan w = (2m + 1) pi (brentq); the table gives the cycles found against
that reference, the time of the default call (median of 5) and the grid the rule chose.

Run: python benchmarks/bench_solver_delay.py [--write]   (--write updates benchmarks/results/bench_solver_delay.md)
"""
from __future__ import annotations

import pathlib
import sys
import time

import numpy as np
from scipy.optimize import brentq

import dfloop as df


def main() -> str:
    rows = ["| T [s] | cycles found / expected | max freq. error (rel.) | default call [ms] | grid (A x w) |",
            "|---|---|---|---|---|"]
    for T in (0.5, 1.0, 2.0, 3.0):
        G = lambda w, T=T: np.exp(-1j * np.asarray(w) * T) / (1j * np.asarray(w) + 1)  # noqa: E731
        f = lambda w, m, T=T: w * T + np.arctan(w) - (2 * m + 1) * np.pi  # noqa: E731
        ref = np.array([brentq(f, 0.1, 400, args=(m,), xtol=1e-14) for m in range(int(400 * T / 6) + 3)
                        if f(0.1, m) < 0 < f(400, m)])
        df.predict_limit_cycles(G, df.Relay(1.0), omega=(0.1, 400))  # warm-up
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            cycles = df.predict_limit_cycles(G, df.Relay(1.0), omega=(0.1, 400))
            times.append(time.perf_counter() - t0)
        w = np.array([c.frequency for c in cycles])
        err = max(np.min(np.abs(w - r)) / r for r in ref) if w.size else np.inf
        shape = cycles.grid_report.shape
        rows.append(f"| {T:g} | {len(cycles)} / {ref.size} | {err:.1e} | {1e3 * np.median(times):.1f} | "
                    f"{shape[0]} x {shape[1]} |")
    return "\n".join(rows)


if __name__ == "__main__":
    table = main()
    print(table)
    if "--write" in sys.argv[1:]:
        out = pathlib.Path(__file__).parent / "results" / "bench_solver_delay.md"
        out.parent.mkdir(exist_ok=True)
        out.write_text("# Solver: default call on the delay loops\n\nCommand: `python benchmarks/bench_solver_delay.py "
                       "--write` (median of 5 runs).\n\n" + table + "\n")
