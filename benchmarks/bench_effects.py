"""Effects engine benchmark: cost per impact of the exact linear-mode engine against the JIT kernel.

The same motions (M1 = M2 = 1 kg, h = 0.1 m, F = 50 N, 200 forcing periods from rest) are simulated by the
closed-form JIT kernel of the paper's model and by the compiled linear-mode engine with no effect, zero damping,
damping, a spring and Coulomb friction. Each run is warmed once (JIT load excluded), then timed as the median of
7 runs including the engine's setup (mode matrices and exponentials); ratios are per impact, in this run, and
per event (impacts plus separations and, with friction, stops and stick-slip transitions; the kernel's events
counted as its impacts).
The last table times whole DF samples of the scene ``models/dynamic_backlash_pd.toml`` with the damping its
comment suggests, ViscousDamping(c=5).

Run: python benchmarks/bench_effects.py [--write]   (--write: benchmarks/results/bench_effects.md)
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

from dfloop.impact.effects import CoulombFriction, LoadSpring, ViscousDamping
from dfloop.impact.kernel import forced_motion
from dfloop.impact.extract import impact_describing_function
from dfloop.impact.kernel import simulate
from dfloop.impact.model import ImpactParameters

M1, M2, H, F = 1.0, 1.0, 0.1, 50.0
PERIODS = 200
OUT = Path(__file__).parent / "results" / "bench_effects.md"
MOTIONS = [(0.8, 35.0, "period 1, two impacts per period"), (0.5, 20.0, "multi-impact"),
           (0.5, 10.0, "chatter and sticking")]
EFFECTS = [("none (engine)", ()), ("ViscousDamping(0)", (ViscousDamping(0.0),)),
           ("ViscousDamping(2)", (ViscousDamping(2.0),)), ("LoadSpring(40)", (LoadSpring(40.0),)),
           ("CoulombFriction(5, m2)", (CoulombFriction(5.0, "m2"),))]



def _engine(p, t_end, effects):
    """The forced motion from rest on the linear-mode engine (the paper's model too when effects is empty)."""
    run = forced_motion(p, effects, 1e-9, closed_form=False)
    run.advance(t_end, 10 ** 7)
    return run.trajectory()

def _median_time(run, repeats: int = 7):
    out = run()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = run()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def cost_per_impact() -> list[str]:
    rows = ["| motion (eps, w rad/s) | engine, effects | impacts | events | time (ms) | us per impact | x kernel "
            "| us per event | x kernel per event |", "|---|---|---|---|---|---|---|---|---|"]
    for eps, w, name in MOTIONS:
        t_end = PERIODS * 2 * math.pi / w
        p = ImpactParameters(M1, M2, H, eps, F, w)
        el, tr = _median_time(lambda: simulate(M1, M2, H, eps, F, w, t_end))
        kernel = el / tr.n_impacts
        rows.append(f"| {name} ({eps}, {w}) | JIT kernel | {tr.n_impacts} | {tr.n_impacts} | {el * 1e3:.2f} | "
                    f"{kernel * 1e6:.2f} | 1 | {kernel * 1e6:.2f} | 1 |")
        for label, effects in EFFECTS:
            el, tr = _median_time(lambda: _engine(p, t_end, effects))
            per = el / max(tr.n_impacts, 1)
            per_event = el / max(tr.n_events, 1)
            rows.append(f"| {name} ({eps}, {w}) | linear-mode, {label} | {tr.n_impacts} | {tr.n_events} | "
                        f"{el * 1e3:.2f} | {per * 1e6:.2f} | {per / kernel:.1f} | {per_event * 1e6:.2f} | "
                        f"{per_event / kernel:.1f} |")
    return rows


def scene_damping_samples() -> list[str]:
    """DF samples (100 transient + 20 measured periods) of the scene's element with ViscousDamping(5)."""
    rows = ["| F (N) | w (rad/s) | impacts | time per sample (ms) |", "|---|---|---|---|"]
    for force, w in [(42.07, 5.0), (20.0, 20.0), (60.0, 12.3), (30.0, 40.0)]:
        el, r = _median_time(lambda: impact_describing_function(1.0, 1.0, 0.1, 0.5, force, w,
                                                               effects=(ViscousDamping(5.0),)), repeats=3)
        rows.append(f"| {force} | {w} | {r.n_impacts} | {el * 1e3:.1f} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write benchmarks/results/bench_effects.md")
    args = parser.parse_args()
    lines = ["# Effects engine benchmark", "",
             f"Machine: {os.cpu_count()} cores; python {sys.version.split()[0]}. M1 = M2 = 1 kg, h = 0.1 m, "
             f"F = 50 N, {PERIODS} forcing periods from rest; median of 7 warm runs, setup included.", "",
             "## Cost per impact, linear-mode engine vs the JIT kernel on the same motions", ""]
    lines += cost_per_impact()
    lines += ["", "## Scene `dynamic_backlash_pd` element with ViscousDamping(c=5): one DF sample", ""]
    lines += scene_damping_samples()
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        OUT.write_text(text)


if __name__ == "__main__":
    main()
