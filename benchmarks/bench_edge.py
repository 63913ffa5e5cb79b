"""Cost of edge tracking (dfloop.hybrid.edge) inside exact_cycle's globalisation, against the globalisation alone.

For each loop whose prediction exact_cycle cannot shoot (Newton and the homotopy fail) and whose motions around it
split between two fates, the same run times ``exact_cycle`` twice: as shipped (the globalisation followed by edge
tracking on the boundary between the fates) and with the edge tracking switched off (the globalisation as it
was before it: motions from 3 starts, shootings from them). The ratio is (with edge) / (without); the edge
tracking's own cost is also given in predicted periods flowed (``extra["edge"]["flow_periods"]``; the
globalisation alone flows 3 x 200). Each time is the best of ``--repeat`` runs (default 2), after a warm-up.

Loops: the backlash servo 5/(s(s+1)), h = 1 (inner prediction); 1.5/(s(s+1)^2), h = 0.2; the order-12 loop
4/(s(s+1)) Pade_8(1 s) / ((0.1s+1)(0.05s+1)), h = 0.5; 3/(s(s+1)^2) with a dead zone 0.5 from a made-up
prediction 0.85 times the DF's, max_deviation 0.1 (edge tracking finds the unstable orbit there).

Run: python benchmarks/bench_edge.py [--repeat N] [--write]   (--write writes benchmarks/results/bench_edge.md)
"""
from __future__ import annotations

import os
import pathlib
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")      # small matrices: threads only add hand-off cost

import control as ct

import dfloop as df
from dfloop.hybrid import globalise


def _loops():
    pade = ct.tf(*ct.pade(1.0, 8))
    order12 = ct.tf([4.0], [1, 1, 0]) * pade * ct.tf([1], [0.1, 1]) * ct.tf([1], [0.05, 1])
    dz = ct.tf([3.0], [1.0, 2.0, 1.0, 0.0])
    c_dz = df.predict_limit_cycles(dz, df.DeadZone(0.5))[0]
    return [("backlash servo 5/(s(s+1)), h=1", ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0), None, {}),
            ("1.5/(s(s+1)^2), backlash h=0.2", ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(h=0.2), None, {}),
            ("order 12 (Pade 8), backlash h=0.5", order12, df.Backlash(h=0.5), None, {}),
            ("3/(s(s+1)^2), dead zone 0.5, made-up prediction", dz, df.DeadZone(0.5),
             (0.85 * c_dz.amplitude, c_dz.frequency), {"max_deviation": 0.1})]


def _best(fn, repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(repeat: int) -> str:
    rows = ["| loop | outcome | exact_cycle with edge tracking (s) | without (s) | ratio | edge: periods flowed, "
            "trials | boundary motion |", "|---|---|---|---|---|---|---|"]
    original = globalise._edge
    for name, G, N, pred, kw in _loops():
        cycle = pred or df.predict_limit_cycles(G, N)[0]
        df.exact_cycle(G, N, cycle, **kw)                            # warm-up (compiled code, caches)
        t_with, e = _best(lambda: df.exact_cycle(G, N, cycle, **kw), repeat)
        globalise._edge = lambda *a, **k: None
        try:
            t_without, e0 = _best(lambda: df.exact_cycle(G, N, cycle, **kw), repeat)
        finally:
            globalise._edge = original
        edge = e.extra.get("edge", {})
        rows.append(f"| {name} | {e.extra.get('outcome', 'orbit') if not e.success else 'orbit (confirmed)'} "
                    f"(was {e0.extra.get('outcome')}) | {t_with:.3g} | {t_without:.3g} | {t_with / t_without:.2f} | "
                    f"{edge.get('flow_periods', 0):.0f}, {edge.get('trials', 0)} | {edge.get('outcome', '-')} |")
    return "\n".join(rows) + "\n"


if __name__ == "__main__":
    repeat = int(sys.argv[sys.argv.index("--repeat") + 1]) if "--repeat" in sys.argv else 2
    text = main(repeat)
    print(text)
    if "--write" in sys.argv:
        out = pathlib.Path(__file__).parent / "results" / "bench_edge.md"
        out.write_text("# Edge tracking: cost inside exact_cycle's globalisation\n\nCommand: `python "
                       f"benchmarks/bench_edge.py --repeat {repeat} --write`\n\n" + text)
