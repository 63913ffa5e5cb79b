"""Order of convergence and cost of the delay-equation solvers on elements with a delay: static elements
(dfloop.hybrid.dde) and a backlash, whose state is part of the history (dfloop.hybrid.dde_memory).

Loop 12/((s+1)(0.5s+1)) e^{-0.4s} with a saturation (kinks at +-1) and with a cubic stiffness x - 0.05 x^3
(smooth); backlash (clearance 0.5) around 3/(s(s+1)) e^{-0.2s} (a stable cycle) and 4/(s+1)^2 e^{-s} (an unstable
one). ``dde_orbit(..., nodes=n, max_nodes=2n)`` solves at n and 2n nodes per period and returns the 2n orbit; the
errors of A and w at 64, 128, 256 nodes are taken against 512 nodes, the observed order is log2 of the ratio of
successive errors. Also, for the default ``exact_cycle`` (resolution doubled from 128 until the change of A and w
is below 1e-8): the resolution it stops at, its error estimate (that last change), its true error against an orbit
4 times finer (``nodes`` 2x its resolution, ``max_nodes`` 4x), the two largest multipliers, and its time relative to
predict_limit_cycles on the same loop (BLAS single-threaded, as in the tests).

Run: python benchmarks/bench_dde_order.py [--write]   (--write writes benchmarks/results/bench_dde_order.md)
"""
from __future__ import annotations

import math
import os
import pathlib
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")      # small matrices: threads only add hand-off cost

import control as ct

import dfloop as df
from dfloop.hybrid import loop_model
from dfloop.hybrid.dde import dde_orbit
from dfloop.hybrid.dde_memory import memory_orbit
from dfloop.solve.delay import delayed

G = delayed(ct.tf([12.0], [1.0, 1.0]) * ct.tf([1.0], [0.5, 1.0]), 0.4)
SHORT = (32, 64, 128, 256)        # nodes: the orbits at 64, 128, 256 steps per period against 512
LONG = (128, 256, 512, 1024)      # the short delay needs >= 4.5 P / T = 103 steps: 256, 512, 1024 against 2048
ELEMENTS = [("saturation (kinks)", G, df.Saturation(1.0), -1, SHORT),
            ("cubic stiffness (smooth)", G, df.CubicStiffness(1.0, -0.05), -1, SHORT),
            ("backlash, 3/(s(s+1)) e^-0.2s", delayed(ct.tf([3.0], [1.0, 1.0, 0.0]), 0.2), df.Backlash(h=0.5), -1,
             LONG),
            ("backlash, 4/(s+1)^2 e^-s", delayed(ct.tf([4.0], [1.0, 2.0, 1.0]), 1.0), df.Backlash(h=0.5), 0, SHORT)]


def main() -> str:
    rows = ["| loop | steps per period | error A | error w | order A | order w |", "|---|---|---|---|---|---|"]
    cost = ["| loop | predict (ms) | exact_cycle / predict | nodes | error estimate A, w | error A, w (vs 4x nodes) | "
            "multipliers |", "|---|---|---|---|---|---|---|"]
    for name, G, N, which, nodes in ELEMENTS:
        df.predict_limit_cycles(G, N)                                   # warm-up
        t0 = time.perf_counter()
        c = df.predict_limit_cycles(G, N)[which]
        t_pred = time.perf_counter() - t0
        t0 = time.perf_counter()
        e = df.exact_cycle(G, N, c)
        t_exact = time.perf_counter() - t0
        loop = loop_model(G, N, c.amplitude, c.frequency)     # a DDELoop or MemoryDDELoop (the one dispatcher)
        solve = memory_orbit if "backlash" in name else dde_orbit
        o = {n: solve(loop, c.amplitude, c.frequency, nodes=n, max_nodes=2 * n) for n in nodes}
        ref = o[nodes[-1]]
        errs = {k: [abs(o[n][k] / ref[k] - 1) for n in nodes[:-1]] for k in ("amplitude", "frequency")}
        for i, n in enumerate(2 * n for n in nodes[:-1]):
            order = ["-", "-"] if i == 0 else [f"{math.log2(errs[k][i - 1] / errs[k][i]):.2f}"
                                               for k in ("amplitude", "frequency")]
            rows.append(f"| {name} | {n} | {errs['amplitude'][i]:.2e} | {errs['frequency'][i]:.2e} | {order[0]} | "
                        f"{order[1]} |")
        est = e.extra["error_estimate"]
        mu = ", ".join(f"{abs(m):.7g}" for m in sorted(e.multipliers[:2], key=lambda m: abs(abs(m) - 1)))
        fine = solve(loop, c.amplitude, c.frequency, nodes=2 * e.extra["nodes"], max_nodes=4 * e.extra["nodes"])
        true = (abs(e.amplitude / fine["amplitude"] - 1), abs(e.frequency / fine["frequency"] - 1))
        cost.append(f"| {name} | {1e3 * t_pred:.1f} | {t_exact / t_pred:.1f} | {e.extra['nodes']} | {est[0]:.1e}, "
                    f"{est[1]:.1e} | {true[0]:.1e}, {true[1]:.1e} | {mu} |")
    return "\n".join(["Errors against the finest orbit (512 steps (nodes) per period; 2048 for the backlash with "
                      "the short delay, which takes at least 4.5 P / T = 103):", "", *rows, "", *cost]) + "\n"


if __name__ == "__main__":
    text = main()
    print(text)
    if "--write" in sys.argv:
        out = pathlib.Path(__file__).parent / "results" / "bench_dde_order.md"
        out.write_text("# Delay equation solver: order of convergence\n\nCommand: `python benchmarks/bench_dde_order.py "
                       "--write`\n\n" + text)
