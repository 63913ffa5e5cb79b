"""Convergence of the delay equation with impacts (dfloop.hybrid.delay_impact) against an event-located run.

The PD loop of models/dynamic_backlash_pd.toml (masses 1 kg, clearance 0.1 m, restitution 0.5) behind a pure
delay T = 4 ms (2 % of the period). ``impact_orbit(..., nodes=n)`` solves at N, 3N/2 and 2N steps per period
(N = max(n, 3 P / T)) and returns the 2N orbit with its error estimate; the truth is the event-located solve_ivp
run of the delay equation of tests/test_delay_impact.py (DOP853, rtol 1e-12, restarted at every impact, every T
and every delayed impact), started on the finest orbit and run 12 periods. Reported per resolution: A and w, their
true errors, the estimate, the trivial multiplier's distance to 1 (the multipliers' error) and the largest
non-trivial |multiplier|, and the time.

Run: python benchmarks/bench_delay_impact.py [--write]   (--write writes benchmarks/results/bench_delay_impact.md)
"""
from __future__ import annotations

import math
import os
import pathlib
import sys
import time

import control as ct
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

from test_delay_impact import F0, PD, W0, _Fixed, reference  # noqa: E402

from dfloop.hybrid import loop_model  # noqa: E402
from dfloop.hybrid.delay_impact import impact_orbit  # noqa: E402
from dfloop.solve.delay import delayed  # noqa: E402

T = 0.004
NODES = (151, 256, 512)


def main() -> str:
    loop = loop_model(delayed(PD, T), _Fixed(), F0, W0)
    impact_orbit(loop, F0, W0, nodes=NODES[0])            # compile and warm up
    runs = []
    for n in NODES:
        t0 = time.perf_counter()
        o = impact_orbit(loop, F0, W0, nodes=n)
        runs.append((n, o, time.perf_counter() - t0))
    o = runs[-1][1]
    P, zm, H, Nn = o["period"], o["extra"]["zm0"], o["extra"]["history0"], o["extra"]["nodes"]
    tn = P / Nn * np.arange(-H.size, 1)
    vals = np.append(H, zm[0])
    hits, x = reference(ct.ss(PD), T, zm, lambda t: np.interp(t, tn, vals), 12 * P, loop.step_loop.v_stick)
    late = hits[hits > 7 * P]
    P_ref = float(np.mean(np.diff(late)))
    t = late[-2] + P_ref * np.arange(512) / 512
    A_ref = abs(2 * np.mean(x(t) * np.exp(-2j * math.pi * np.arange(512) / 512)))
    w_ref = 2 * math.pi / P_ref
    rows = [f"Reference: A = {A_ref:.7f} N, w = {w_ref:.7f} rad/s (impact spacing settled to "
            f"{np.ptp(np.diff(late)) / P_ref:.1e} of the period).", "",
            "| steps per period | A | w | error A | error w | estimate A, w | trivial multiplier - 1 | "
            "largest other | time (s) |", "|---|---|---|---|---|---|---|---|---|"]
    for n, r, dt in runs:
        mu = r["multipliers"]
        k = int(np.argmin(np.abs(mu - 1)))
        other = float(np.max(np.abs(np.delete(mu, k))))
        eA, ew = r["extra"]["error_estimate"]
        rows.append(f"| {r['extra']['nodes']} | {r['amplitude']:.7f} | {r['frequency']:.7f} | "
                    f"{r['amplitude'] / A_ref - 1:.1e} | {r['frequency'] / w_ref - 1:.1e} | {eA:.1e}, {ew:.1e} | "
                    f"{abs(mu[k] - 1):.1e} | {other:.4f} | {dt:.1f} |")
    return "\n".join(rows) + "\n"


if __name__ == "__main__":
    text = main()
    print(text)
    if "--write" in sys.argv:
        out = pathlib.Path(__file__).parent / "results" / "bench_delay_impact.md"
        out.write_text("# Delay equation with impacts: convergence against an event-located run\n\nCommand: "
                       "`python benchmarks/bench_delay_impact.py --write`\n\n" + text)
