"""Impact kernel benchmark: exact JIT kernel vs a typical solve_ivp implementation, compile/cache times,
table build times, and accuracy-versus-time knobs of the DF extraction.

Run: python benchmarks/bench_impact_kernel.py [--write]   (--write: benchmarks/results/bench_impact_kernel.md)
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dfloop.impact.extract import impact_describing_function, impact_describing_function_batch
from dfloop.impact.kernel import simulate
from dfloop.impact.reference import simulate_solve_ivp

M1, M2, H, F = 1.0, 1.0, 0.1, 50.0
OUT = Path(__file__).parent / "results" / "bench_impact_kernel.md"


def compile_and_cache_times() -> list[str]:
    """Import, then first calls, in a fresh process with an empty numba cache and again with it filled: the kernel
    (``simulate``), then the adaptive DF driver that every table sample runs (``impact_describing_function``)."""
    code = ("import time; t = time.perf_counter(); from dfloop.impact.kernel import simulate; "
            "from dfloop.impact.extract import impact_describing_function as df; "
            "t1 = time.perf_counter(); simulate(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 1.0); t2 = time.perf_counter(); "
            "df(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, transient_periods=None); "
            "print(t1 - t, t2 - t1, time.perf_counter() - t2)")
    rows = ["| numba cache | import dfloop.impact (s) | first simulate call (s) | then first adaptive DF sample (s) |",
            "|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("empty (compile)", "filled (load)"):
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                 check=True).stdout.split()
            rows.append(f"| {label} | {float(out[0]):.2f} | {float(out[1]):.2f} | {float(out[2]):.2f} |")
    return rows


def solve_ivp_on_sticking_case() -> list[str]:
    """The sticking regime: the kernel resolves chatter + stuck phases; solve_ivp restarts without end."""
    eps, w, t_end = 0.5, 10.0, 2.0
    t0 = time.perf_counter()
    tr = simulate(M1, M2, H, eps, F, w, t_end)
    k_time = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        simulate_solve_ivp(M1, M2, H, eps, F, w, t_end, method="RK45", rtol=1e-8, atol=1e-11, max_impacts=3000)
        outcome = "finished"
    except RuntimeError as err:
        outcome = f"failed: {err}"
    s_time = time.perf_counter() - t0
    return ["| solver | result | wall time (s) |", "|---|---|---|",
            f"| exact JIT kernel | {tr.n_impacts} impacts, {tr.stuck_intervals.shape[0]} stuck phases to "
            f"t = {t_end} s | {k_time:.4f} |",
            f"| solve_ivp RK45 (typical) | {outcome} | {s_time:.2f} |"]


def kernel_vs_solve_ivp() -> list[str]:
    cases = [("periodic", 0.8, 35.0, 3.0), ("multi-impact (chatter-prone, no sticking)", 0.5, 17.5, 3.0)]
    settings = [("solve_ivp RK45 rtol=1e-8 atol=1e-11 (typical)", dict(method="RK45", rtol=1e-8, atol=1e-11)),
                ("solve_ivp DOP853 rtol=1e-12 (accurate)", dict(method="DOP853", rtol=1e-12))]
    rows = ["| case | solver | impacts | median cost per impact (us) | kernel speed-up | "
            "max abs impact-time diff (s) | max abs x1 diff / h |", "|---|---|---|---|---|---|---|"]
    for name, eps, w, t_end in cases:
        simulate(M1, M2, H, eps, F, w, t_end)  # warm (JIT load)
        per_impact = []
        for _ in range(30):
            t0 = time.perf_counter()
            tr = simulate(M1, M2, H, eps, F, w, t_end)
            per_impact.append((time.perf_counter() - t0) / tr.n_impacts)
        k_cost = statistics.median(per_impact)
        rows.append(f"| {name} (eps={eps}, w={w}) | exact JIT kernel | {tr.n_impacts} | {k_cost * 1e6:.2f} | 1 | - | - |")
        # long run: per-impact cost when the Python wrapper overhead is amortised
        long_t = []
        for _ in range(5):
            t0 = time.perf_counter()
            long = simulate(M1, M2, H, eps, F, w, 400 * t_end)
            long_t.append((time.perf_counter() - t0) / long.n_impacts)
        rows.append(f"| {name} (eps={eps}, w={w}) | exact JIT kernel, 400x longer run | {long.n_impacts} | "
                    f"{statistics.median(long_t) * 1e6:.2f} | - | - | - |")
        for label, opts in settings:
            costs = []
            for _ in range(3):
                t0 = time.perf_counter()
                ref = simulate_solve_ivp(M1, M2, H, eps, F, w, t_end, **opts)
                costs.append((time.perf_counter() - t0) / max(ref["t"].size, 1))
            cost = statistics.median(costs)
            n = min(ref["t"].size, tr.n_impacts)
            dt = np.max(np.abs(ref["t"][:n] - tr.impacts["t"][:n]))
            t = np.linspace(0, t_end, 2001)
            dx = np.max(np.abs(ref["sol"](t)[0] - tr.evaluate(t)["x1"])) / H
            rows.append(f"| {name} (eps={eps}, w={w}) | {label} | {ref['t'].size} | {cost * 1e6:.1f} | "
                        f"{cost / k_cost:.0f}x | {dt:.1e} | {dx:.1e} |")
    return rows


def _advanced(run, t_end):
    """``run`` (a forced motion) advanced to ``t_end`` (s); its trajectory."""
    run.advance(t_end, 10 ** 6)
    return run.trajectory()


def effects_engine_cost() -> list[str]:
    """The linear-mode engine (used when effects are given) against the JIT kernel, 40 forcing periods.

    Each run is warmed up once (JIT compile / cache load excluded), then timed as the median of 5 runs. The last
    table times one DF sample with effects (200 transient + 40 measured periods), the unit of a 2-D table.
    """
    from dfloop.impact.effects import CoulombFriction, LoadSpring, ViscousDamping
    from dfloop.impact.kernel import forced_motion
    from dfloop.impact.model import ImpactParameters

    eps, w = 0.8, 35.0
    t_end = 40 * 2 * np.pi / w
    runs = [("no effect", "JIT kernel", lambda: simulate(M1, M2, H, eps, F, w, t_end)),
            ("no effect", "linear-mode engine",
             lambda: _advanced(forced_motion(ImpactParameters(M1, M2, H, eps, F, w), closed_form=False), t_end)),
            ("ViscousDamping(5)", "linear-mode engine",
             lambda: simulate(M1, M2, H, eps, F, w, t_end, effects=(ViscousDamping(5.0),))),
            ("LoadSpring(40)", "linear-mode engine",
             lambda: simulate(M1, M2, H, eps, F, w, t_end, effects=(LoadSpring(40.0),))),
            ("CoulombFriction(20, m2)", "linear-mode engine",
             lambda: simulate(M1, M2, H, eps, F, w, t_end, effects=(CoulombFriction(20.0, "m2"),)))]
    rows = ["| effects | engine | impacts | time (s) | us per impact | x JIT kernel |", "|---|---|---|---|---|---|"]
    jit_per_impact = None
    for label, engine, run in runs:
        run()
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            tr = run()
            times.append(time.perf_counter() - t0)
        el = statistics.median(times)
        per_impact = el / tr.n_impacts
        jit_per_impact = jit_per_impact or per_impact
        rows.append(f"| {label} | {engine} | {tr.n_impacts} | {el:.4f} | {per_impact * 1e6:.1f} | "
                    f"{per_impact / jit_per_impact:.0f} |")
    rows += ["", "| effects (eps 0.7, w 20 rad/s) | one DF sample (s) |", "|---|---|"]
    for effects in [(ViscousDamping(0.8), LoadSpring(40.0)), (CoulombFriction(20.0, "m2"),)]:
        t0 = time.perf_counter()
        impact_describing_function(M1, M2, H, 0.7, F, 20.0, effects=effects)
        rows.append(f"| {', '.join(map(repr, effects))} | {time.perf_counter() - t0:.3f} |")
    return rows


def table_build_times() -> list[str]:
    """The paper's figure table: 200 frequencies 1..100 rad/s per eps (F = 50 N, h = 0.1 m)."""
    w = np.geomspace(1.0, 100.0, 200)
    rows = ["| eps | workers | points | transient + measured periods | impacts in measured windows | time (s) |",
            "|---|---|---|---|---|---|"]
    for eps in (0.1, 0.5, 0.9):
        for workers in (1, 2):
            t0 = time.perf_counter()
            res = impact_describing_function_batch(M1, M2, H, eps, F, w, workers=workers)
            el = time.perf_counter() - t0
            rows.append(f"| {eps} | {workers} | {w.size} | 200 + 40 | {int(res.n_impacts.sum())} | {el:.2f} |")
    return rows


def chatter_onset_vs_wc() -> list[str]:
    """Where long chatter runs start on the collision map (paper's Fig. 9) vs w_c of eq. (10), F = 50 N."""
    w = np.linspace(10.0, 45.0, 71)
    rows = ["| eps | w_c eq. (10) (rad/s) | highest w with n_A > 5 (rad/s) | n_A there | "
            "irregular points on the grid |", "|---|---|---|---|---|"]
    for eps in (0.2, 0.5, 0.8):
        res = impact_describing_function_batch(M1, M2, H, eps, F, w)
        long_runs = np.flatnonzero(res.max_run_A > 5)
        wc = ((2 * F / (M2 * H)) ** 2 * (1 - eps) ** 5) ** 0.25
        onset = f"{w[long_runs[-1]]:.1f} | {res.max_run_A[long_runs[-1]]}" if long_runs.size else "none | -"
        rows.append(f"| {eps} | {wc:.1f} | {onset} | {int((~res.regular).sum())} of {w.size} |")
    return rows


def accuracy_knobs() -> list[str]:
    cases = [(0.8, 35.0), (0.5, 10.0), (0.2, 30.0)]
    rows = ["| eps | w (rad/s) | transient periods | measured periods | period | rel. error of N | time (ms) |",
            "|---|---|---|---|---|---|---|"]
    for eps, w in cases:
        ref = impact_describing_function(M1, M2, H, eps, F, w, transient_periods=2000, periods=400)
        for tr_p, per in [(25, 10), (50, 10), (100, 20), (200, 40), (400, 80), (800, 160)]:
            times = []
            for _ in range(3):
                t0 = time.perf_counter()
                r = impact_describing_function(M1, M2, H, eps, F, w, transient_periods=tr_p, periods=per)
                times.append(time.perf_counter() - t0)
            err = abs(r.N - ref.N) / abs(ref.N)
            rows.append(f"| {eps} | {w} | {tr_p} | {per} | {r.period} | {err:.1e} | "
                        f"{statistics.median(times) * 1e3:.1f} |")
        rows.append(f"| {eps} | {w} | 2000 (reference) | 400 | {ref.period} | 0 | - |")
    return rows


def main() -> None:
    lines = ["# Impact kernel benchmark", "",
             f"Machine: {os.cpu_count()} cores; python {sys.version.split()[0]}. "
             "Model: M1 = M2 = 1 kg, h = 0.1 m, F = 50 N.", "",
             "## JIT compile and cache load (subprocess, includes the import)", ""]
    lines += compile_and_cache_times()
    lines += ["", "## Exact kernel vs a typical solve_ivp implementation (terminal events, restart per impact)",
              "", "Same cases, same run; t_end = 3 s. Differences are against the kernel.", ""]
    lines += kernel_vs_solve_ivp()
    lines += ["", "## Sticking regime (eps = 0.5, w = 10 rad/s): chatter then stuck phases", ""]
    lines += solve_ivp_on_sticking_case()
    lines += ["", "## Effects engine (exact linear modes) vs the JIT kernel: eps 0.8, w 35 rad/s, 40 periods", "",
              "Warm (compile excluded), median of 5 runs.", ""]
    lines += effects_engine_cost()
    lines += ["", "## Building the paper's table (200 log-spaced w in 1..100 rad/s, beta 0.005..500)", ""]
    lines += table_build_times()
    lines += ["", "## Collision map: onset of long chatter runs vs w_c (71 w in 10..45 rad/s, F = 50 N)", ""]
    lines += chatter_onset_vs_wc()
    lines += ["", "## DF extraction: accuracy vs time", "",
              "Error of N relative to a run with 2000 transient and 400 measured periods.", ""]
    lines += accuracy_knobs()
    text = "\n".join(lines) + "\n"
    print(text)
    if "--write" in sys.argv[1:]:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        OUT.write_text(text)


if __name__ == "__main__":
    main()
