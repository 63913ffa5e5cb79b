"""Cost and accuracy of the dynamic-backlash DF tables.

Part 1, the paper-model tables of Figs. 5-8 (M1 = M2 = 1 kg, h = 0.1 m, 9 eps x F in 10..50 N x w in
1..100 rad/s) built from an empty cache, with and without the probed starts (coexistence search), against
the bare kernel in the same run: the same simulations (same beta, same transient and window lengths)
through :class:`dfloop.impact.kernel.KernelRun` alone, without extraction or table logic.

Part 2, accuracy versus time knob by knob at eps = 0.5. Reference: direct simulation (transient 600
periods, 40 periods used) at random off-grid (F, w) points. For every setting: build time (no cache),
samples simulated, time per evaluated point, and the relative error of -1/N at the points the table marks
valid (median, 95th percentile, max), with the fraction of points whose actual error is within the
table's error estimate.

Run:  python benchmarks/bench_tables.py [--write]   (--write: benchmarks/results/bench_tables.md)
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from dfloop.impact import extract
from dfloop.impact.dynamic_backlash import DynamicBacklash, prepare_many
from dfloop.impact.sampling import ImpactSampler
from dfloop.impact.kernel import KernelRun
from dfloop.impact.model import ImpactParameters

M1, M2, H, EPS = 1.0, 1.0, 0.1, 0.5
REF = dict(transient_periods=600, periods=40)
EPS_ALL = tuple(round(0.1 * k, 1) for k in range(1, 10))
RNG = np.random.default_rng(12345)


class _TwoD:
    """Marks a table as two-dimensional while the physics stays the paper's (benchmarks the 2-D path)."""

    keeps_similarity = False

    def __repr__(self):
        return "_TwoD()"


def _paper_physics(self, force, omega, initial=None):
    return extract.impact_describing_function_batch(self.m1, self.m2, self.h, self.restitution, force, omega,
                                                    transient_periods=self.transient_periods, periods=self.periods,
                                                    initial=initial, on_event_limit="record")


def bare_kernel_seconds(tables) -> tuple[float, int]:
    """Time of the rest-start simulations of the tables' samples through the kernel alone (serial): the same
    beta and number of periods (transient + window), without period detection, DF or table logic. CPU time, as
    the build's (a shared machine's load inflates wall time, not this)."""
    t0 = time.process_time()
    n = 0
    for nl in tables:
        t = nl.table
        for u, tr, used in zip(t.x, t.extra["transient_periods"], t.extra["periods_used"]):
            run = KernelRun(ImpactParameters(M1 / M2, 1.0, 1.0, nl.restitution, math.exp(u), 1.0))
            run.advance((tr + used) * 2 * math.pi, 10 ** 9, keep=False)
            n += 1
    return time.process_time() - t0, n


def bare_probe_seconds(tables) -> tuple[float, int]:
    """Time of the window probes' simulations through the kernel alone (serial): from rest at each probe's beta
    for the periods it ran (until it settled on the interpolated orbit, or its whole adaptive run); CPU time."""
    t0 = time.process_time()
    n = 0
    for nl in tables:
        for us, periods in nl.sampler.probe_runs:
            for u, k in zip(us, periods):
                run = KernelRun(ImpactParameters(M1 / M2, 1.0, 1.0, nl.restitution, math.exp(u), 1.0))
                run.advance(max(k, 1.0) * 2 * math.pi, 10 ** 9, keep=False)
                n += 1
    return time.process_time() - t0, n


def paper_tables(**kw) -> dict:
    """Build the Figs. 5-8 tables from an empty cache (two worker threads, as examples/paper_figures.py)."""
    tables = [DynamicBacklash(M1, M2, H, e, cache=False, progress=False, **kw) for e in EPS_ALL]
    t0, c0 = time.perf_counter(), time.process_time()
    prepare_many(tables, (10.0, 50.0), (1.0, 100.0))
    build, cpu = time.perf_counter() - t0, time.process_time() - c0
    samples = sum(t.table.x.size for t in tables)
    sims = samples + sum(int(np.count_nonzero(np.isfinite(t.table.extra.get(f"start{k}.re", np.zeros(0)))))
                         for t in tables for k in range(t.starts))
    kernel, n_rest = bare_kernel_seconds(tables)
    periods = sum(float(np.sum(t.table.extra["transient_periods"] + t.table.extra["periods_used"])) for t in tables)
    probes = sum(t.table.n_probed for t in tables)
    probe_kernel, _ = bare_probe_seconds(tables)
    all_kernel = kernel / n_rest * sims + probe_kernel      # every simulation the build ran, through the kernel
    return {"build_s": build, "cpu_s": cpu, "samples": samples, "sims": sims, "probes": probes,
            "kernel_rest_s": kernel, "probe_kernel_s": probe_kernel, "all_kernel_s": all_kernel,
            "rest_periods": periods / samples, "ms_per_sim": 1e3 * cpu / sims, "kernel_ms": 1e3 * kernel / n_rest}


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


def main(argv: list[str]) -> None:
    # load the compiled code (numba's on-disk cache) first: the timings are the table builds
    DynamicBacklash(M1, M2, H, EPS, cache=False, progress=False, starts=0).prepare((40.0, 50.0), (30.0, 31.0))
    paper = []
    for label, kw in (("default (2 probed starts, window probes every 0.002)", {}),
                      ("window_dx 100 (no window probes)", dict(window_dx=100.0)),
                      ("starts=0 (rest only; window probes)", dict(starts=0))):
        paper.append(dict(paper_tables(**kw), setting=label))
        print(paper[-1])
    window = ((10.0, 50.0), (5.0, 44.0))
    F, w = points(120, *window)
    t0 = time.perf_counter()
    ref, ref_regular = reference(F, w)
    t_ref = time.perf_counter() - t0
    base = dict(cache=False, progress=False, periods=20)
    rows = []
    settings = [("cubic, tol 1e-5, adaptive transient (default)", {}),
                ("cubic, tol 1e-4", dict(tol=1e-4)),
                ("linear, tol 1e-5", dict(method="linear")),
                ("probe_dx 10 (no regime probes)", dict(probe_dx=10.0)),
                ("window_dx 100 (no window probes)", dict(window_dx=100.0)),
                ("starts 0 (no coexistence search)", dict(starts=0)),
                ("fixed transient 100", dict(transient_periods=100)),
                ("detection window 10 periods (periods=10)", dict(periods=10))]
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
    original = ImpactSampler.extract
    ImpactSampler.extract = _paper_physics
    try:
        rows.append(measure("2-D (ln beta, ln w) table, small window",
                            lambda: DynamicBacklash(M1, M2, H, EPS, effects=(_TwoD(),), **base),
                            Fs, ws, refs, regs, small))
    finally:
        ImpactSampler.extract = original
    print(rows[-1])
    lines = ["# bench_tables: dynamic-backlash DF tables, cost and accuracy", "",
             "## Paper-model tables of Figs. 5-8 from an empty cache", "",
             f"9 eps x F in 10..50 N x w in 1..100 rad/s, M1 = M2 = 1 kg, h = 0.1 m, two worker threads "
             "(`prepare_many`), from an empty cache. 'CPU' is the process CPU time of the build (the machine is "
             "shared: wall time depends on the load, CPU time less); 'ms/sim' is CPU time / simulations; "
             "'periods/sample' is the mean transient + window of the rest-start runs; 'bare kernel' is the same "
             "rest-start simulations (same beta and number of periods) through KernelRun alone, serial, in the "
             "same run (CPU time). 'ms/sim' divides the whole build CPU time (window probes included) by the samples' simulations; "
             "the probes' cost is the difference between the first two rows. 'ratio' is ms/sim over the bare "
             "kernel's (the samples' simulations only); 'bare kernel, all runs' adds the window probes' own "
             "simulations (from rest at each probe's beta for the periods it ran) through the bare kernel, and "
             "'ratio, all runs' is the build's CPU time over that.", "",
             "| setting | build (s) | CPU (s) | samples | simulations | window probes | periods/sample | ms/sim | "
             "bare kernel ms/sim | ratio | bare kernel, all runs (s) | ratio, all runs |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in paper:
        lines.append(f"| {r['setting']} | {r['build_s']:.1f} | {r['cpu_s']:.1f} | {r['samples']} | {r['sims']} | "
                     f"{r['probes']} | "
                     f"{r['rest_periods']:.0f} | {r['ms_per_sim']:.2f} | {r['kernel_ms']:.2f} | "
                     f"{r['ms_per_sim'] / r['kernel_ms']:.1f} | {r['all_kernel_s']:.1f} | "
                     f"{r['cpu_s'] / r['all_kernel_s']:.1f} |")
    lines += ["", "## Accuracy versus time at eps = 0.5", "",
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
    if "--write" in argv:
        out = Path(__file__).parent / "results" / "bench_tables.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)


if __name__ == "__main__":
    main(sys.argv[1:])
