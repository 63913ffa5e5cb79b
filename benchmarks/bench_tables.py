"""Accuracy versus time of the dynamic-backlash DF table, knob by knob.

Model: M1 = M2 = 1 kg, h = 0.1 m, eps = 0.5. Reference: direct simulation (transient 300 periods,
40 periods used) at random off-grid (F, w) points. For every setting: build time (no cache), samples
simulated, time per evaluated point, and the relative error of -1/N at the points the table marks
valid (median, 95th percentile, max), with the fraction of points whose actual error is within the
table's error estimate (interpolation only: the reference uses longer runs than the table).

Run:  python benchmarks/bench_tables.py     (writes benchmarks/results/bench_tables.md)
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from dfloop.impact import extract
from dfloop.impact.dynamic_backlash import DynamicBacklash

M1, M2, H, EPS = 1.0, 1.0, 0.1, 0.5
REF = dict(transient_periods=300, periods=40)
RNG = np.random.default_rng(12345)


class _TwoD:
    """Marks a table as two-dimensional while the physics stays the paper's (benchmarks the 2-D path)."""

    keeps_similarity = False

    def __repr__(self):
        return "_TwoD()"


def _paper_physics(self, force, omega):
    return extract.impact_describing_function_batch(self.m1, self.m2, self.h, self.restitution, force, omega,
                                                    transient_periods=self.transient_periods, periods=self.periods)


def points(n, F_window, w_window):
    """Random (F, w) with impacts (beta > 1/4)."""
    F, w = [], []
    while len(F) < n:
        f = RNG.uniform(*F_window)
        om = math.exp(RNG.uniform(math.log(w_window[0]), math.log(w_window[1])))
        if f / (M2 * H * om * om) > 0.26:
            F.append(f)
            w.append(om)
    return np.array(F), np.array(w)


def reference(F, w):
    r = extract.impact_describing_function_batch(M1, M2, H, EPS, F, w, **REF)
    return -1.0 / r.N, r.period > 0


def measure(label, make, F, w, ref, ref_regular, window):
    nl = make()
    t0 = time.perf_counter()
    nl.prepare(*window)
    build = time.perf_counter() - t0
    n = nl(F, w)
    valid = nl.validity(F, w) & ref_regular
    est = nl.error_estimate(F, w)
    q = np.repeat(F, 50), np.repeat(w, 50)
    t0 = time.perf_counter()
    nl(*q)
    per_eval = (time.perf_counter() - t0) / q[0].size
    z = -1.0 / n[valid]
    rel = np.abs(z - ref[valid]) / np.abs(ref[valid])
    covered = np.abs(n[valid] - (-1.0 / ref[valid])) <= est[valid]
    return {"setting": label, "build_s": build, "samples": nl.n_simulations, "eval_us": per_eval * 1e6,
            "valid": f"{np.count_nonzero(valid)}/{F.size}", "median": np.median(rel),
            "p95": np.percentile(rel, 95), "max": rel.max(), "covered": np.mean(covered)}


def main() -> None:
    window = ((10.0, 50.0), (5.0, 44.0))
    F, w = points(120, *window)
    t0 = time.perf_counter()
    ref, ref_regular = reference(F, w)
    t_ref = time.perf_counter() - t0
    base = dict(cache=False, transient_periods=100, periods=20)
    rows = []
    settings = [("cubic, tol 1e-5 (default)", {}),
                ("cubic, tol 1e-3", dict(tol=1e-3)),
                ("cubic, tol 1e-4", dict(tol=1e-4)),
                ("cubic, tol 1e-6", dict(tol=1e-6)),
                ("linear, tol 1e-5", dict(method="linear")),
                ("pchip, tol 1e-5", dict(method="pchip")),
                ("base_dx 0.05", dict(base_dx=0.05)),
                ("edge_dx 1e-3", dict(edge_dx=1e-3)),
                ("transient 50, periods 20", dict(transient_periods=50)),
                ("transient 200, periods 20", dict(transient_periods=200)),
                ("transient 100, periods 10", dict(periods=10)),
                ("transient 100, periods 40", dict(periods=40))]
    for label, kw in settings:
        args = dict(base, **kw)
        rows.append(measure(f"1-D {label}", lambda: DynamicBacklash(M1, M2, H, EPS, **args), F, w, ref,
                            ref_regular, window))
        print(rows[-1])
    # 1-D similarity table versus the 2-D table on a smaller window (the 2-D build is the expensive one)
    small = ((30.0, 50.0), (28.0, 40.0))
    inside = (F >= 30) & (w >= 28) & (w <= 40)
    Fs, ws, refs, regs = F[inside], w[inside], ref[inside], ref_regular[inside]
    rows.append(measure("1-D similarity table, small window", lambda: DynamicBacklash(M1, M2, H, EPS, **base),
                        Fs, ws, refs, regs, small))
    print(rows[-1])
    original = DynamicBacklash._extract
    DynamicBacklash._extract = _paper_physics
    try:
        rows.append(measure("2-D (ln beta, ln w) table, small window",
                            lambda: DynamicBacklash(M1, M2, H, EPS, effects=(_TwoD(),), **base),
                            Fs, ws, refs, regs, small))
    finally:
        DynamicBacklash._extract = original
    print(rows[-1])
    lines = ["# bench_tables: dynamic-backlash DF table, accuracy versus time", "",
             f"M1 = M2 = {M1} kg, h = {H} m, eps = {EPS}; {F.size} random points with F in {window[0]} N, "
             f"w in {window[1]} rad/s (beta > 0.26); reference: direct simulation, transient "
             f"{REF['transient_periods']} + {REF['periods']} periods ({t_ref:.2f} s for all points, "
             f"{1e3 * t_ref / F.size:.2f} ms per point). Errors are relative errors of -1/N at points valid in "
             "both the table and the reference; 'covered' = fraction where |N - N_ref| <= error_estimate. "
             "The small-window rows use the points with F >= 30 N, 28 <= w <= 40 rad/s.", "",
             "| setting | build (s) | samples | eval (us/pt) | valid | median err | p95 err | max err | covered |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['setting']} | {r['build_s']:.2f} | {r['samples']} | {r['eval_us']:.2f} | {r['valid']} | "
                     f"{r['median']:.1e} | {r['p95']:.1e} | {r['max']:.1e} | {r['covered']:.2f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    out = Path(__file__).parent / "results" / "bench_tables.md"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)


if __name__ == "__main__":
    main()
