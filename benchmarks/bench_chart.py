"""What a two-parameter design chart costs against one sweep along one axis, and how exact its boundaries are.

Two loops: (a) a saturation (limit 1) around K e^{-sT}/(s(s+1)), chart over (K, T): the boundary is the birth
curve from the linear loop, K_c(T) = w sqrt(1 + w^2) with atan(w) + w T = pi/2 (closed form); (b) a backlash
(clearance h) around K/(s(s+1)(s+2)), chart over (K, h): the boundary is the fold, at a gain independent of h.
The chart runs at resolution 100 (boundary steps of 2/100 of the chart, a 100 x 100 filled picture) with 13 x 13
region samples; the baseline is one sweep along K with 100 values at the nominal value of the other parameter.
A brute-force 100 x 100 grid of ``predict_limit_cycles`` calls is estimated from the mean time of the sweep's
solves. Times are CPU times of this process, same run (the work is single-threaded; CPU time is less disturbed
than wall time on a shared machine).

Run: python benchmarks/bench_chart.py [--write]   (--write: benchmarks/results/bench_chart.md; the chart's figure
in docs/ is drawn by examples/design_chart.py --figure)
"""
from __future__ import annotations

import argparse
import math
import pathlib
import time
from functools import partial

import control as ct
import numpy as np
from scipy.optimize import brentq

import dfloop as df
from dfloop.chart import ChartAxis, design_chart
from dfloop.continuation import sweep
from dfloop.solve.delay import delayed

G1 = ct.tf([1], [1, 1, 0])
G3 = ct.tf([1], [1, 3, 2, 0])
OMEGA = (0.05, 20.0)


def delayed_saturation(K, T):
    return delayed(K * G1, T), df.Saturation(1.0)


def backlash_servo(K, h):
    return K * G3, df.Backlash(h)


def _row(fn, K, fixed):
    return fn(K, fixed)


def critical_gain(T):
    w = brentq(lambda w: math.atan(w) + w * T - math.pi / 2, 1e-9, 1e3, xtol=1e-15, rtol=1e-15)
    return w * math.sqrt(1 + w * w)


CASES = [
    ("saturation, K e^{-sT}/(s(s+1)): (K, T)", delayed_saturation, ChartAxis(0.5, 5.0, "gain K"),
     ChartAxis(0.1, 1.0, "delay T", "s"), (1.0, 0.5), dict(omega=OMEGA)),
    ("backlash, K/(s(s+1)(s+2)): (K, h)", backlash_servo, ChartAxis(2.5, 5.5, "gain K"),
     ChartAxis(0.1, 0.5, "clearance h", "m"), (3.0, 0.3), {}),
]


def accuracy(name, res) -> str:
    if name.startswith("saturation"):
        err = max(abs(K / critical_gain(T) - 1) for b in res.boundaries for K, T in zip(b.x, b.y))
        return f"max rel. error vs K_c(T): {err:.1e}"
    xs = np.concatenate([b.x for b in res.boundaries if b.kind == "fold"])
    return f"fold gain spread over h: {np.ptp(xs) / xs.mean():.1e} (rel.)"


def main(write: bool) -> str:
    sweep(partial(_row, backlash_servo, fixed=0.2), [3.0, 4.0], progress=False)  # warm-up
    rows = ["| loop | one sweep, 100 values (CPU s) | chart 100 x 100 (CPU s) | chart / sweep | brute-force 100 x 100 "
            "grid (estimated CPU s) | boundaries | solves in the chart | accuracy |",
            "|---|---|---|---|---|---|---|---|"]
    for name, fn, xa, ya, nominal, opts in CASES:
        t0 = time.process_time()
        s = sweep(partial(_row, fn, fixed=nominal[1]), np.linspace(xa.start, xa.stop, 100), progress=False, **opts)
        t_sweep = time.process_time() - t0
        t0 = time.process_time()
        for K in np.linspace(xa.start, xa.stop, 20):
            df.predict_limit_cycles(*fn(K, nominal[1]), **opts)
        t_solve = (time.process_time() - t0) / 20
        t0 = time.process_time()
        res = design_chart(fn, xa, ya, nominal=nominal, samples=13, resolution=100, progress=False, **opts)
        t_chart = time.process_time() - t0
        rows.append(f"| {name} | {t_sweep:.2f} | {t_chart:.2f} | {t_chart / t_sweep:.2f} | {1e4 * t_solve:.0f} | "
                    f"{len(res.boundaries)} ({', '.join(b.kind for b in res.boundaries)}) | {res.n_solves} | "
                    f"{accuracy(name, res)} |")
        assert s.branches is not None
    table = ("# Design charts: cost against one sweep, accuracy of the traced boundaries\n\n"
             "Command: `python benchmarks/bench_chart.py --write` (CPU times, one run, same process).\n\n"
             + "\n".join(rows) + "\n")
    if write:
        out = pathlib.Path(__file__).parent / "results" / "bench_chart.md"
        out.parent.mkdir(exist_ok=True)
        out.write_text(table)
    return table


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write benchmarks/results/bench_chart.md")
    args = ap.parse_args()
    print(main(args.write))
