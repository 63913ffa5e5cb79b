"""The relay experiment: errors of the ultimate-point estimates next to the time each takes.

For each process (lag- to delay-dominant first order plus dead time, a third-order lag, a digital loop) the table
gives the true ultimate point (Ku, Tu), the DF's estimates and their errors with the DF's time (prediction only,
``relay_experiment(..., exact=False)``), and the experiment's estimates (exact relay cycle: closed form for FOPDT,
``exact_cycle`` otherwise) with their errors and the total time of ``relay_experiment``.

Run: python benchmarks/bench_autotune.py [--write]   (--write also writes benchmarks/results/bench_autotune.md)
"""
from __future__ import annotations

import pathlib
import sys
import time

import control as ct

import dfloop as df
from dfloop.autotune import relay_experiment

CASES = [  # (name, G, relay, delay)
    ("FOPDT T/L = 10 (lag dominant)", ct.tf([1.0], [10.0, 1.0]), df.Relay(1.0), 1.0),
    ("FOPDT T/L = 1", ct.tf([1.0], [1.0, 1.0]), df.Relay(1.0), 1.0),
    ("FOPDT T/L = 0.1 (delay dominant)", ct.tf([1.0], [0.1, 1.0]), df.Relay(1.0), 1.0),
    ("FOPDT T/L = 1, hysteresis 0.05", ct.tf([1.0], [1.0, 1.0]), df.Relay(1.0, hysteresis=0.05), 1.0),
    ("1/(s+1)^3", ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), df.Relay(1.0), 0.0),
    ("1/(s+1)^3, ZOH dt = 0.1", ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), 0.1), df.Relay(1.0), 0.0),
]


def main(argv: list[str]) -> str:
    lines = ["# Relay experiment: estimate errors vs time", "", "Command: `python benchmarks/bench_autotune.py --write`",
             "", "| process | Ku | Tu [s] | DF Ku err | DF Tu err | DF time [s] | exp. Ku err | exp. Tu err | "
             "total time [s] |", "|---|---|---|---|---|---|---|---|---|"]
    relay_experiment(*CASES[4][1:3], exact=False)    # warm-up
    for name, G, relay, delay in CASES:
        t0 = time.perf_counter()
        r_df = relay_experiment(G, relay, exact=False, delay=delay)
        t_df = time.perf_counter() - t0
        t0 = time.perf_counter()
        r = relay_experiment(G, relay, delay=delay)
        t_all = time.perf_counter() - t0
        e = r.errors
        lines.append(f"| {name} | {r.Ku:.4g} | {r.Tu:.4g} | {100 * e['Ku_df']:+.2f} % | {100 * e['Tu_df']:+.2f} % | "
                     f"{t_df:.3f} | {100 * e['Ku_experiment']:+.2f} % | {100 * e['Tu_experiment']:+.2f} % | {t_all:.3f} |")
        assert r_df.Ku_df == r.Ku_df
    text = "\n".join(lines) + "\n"
    print(text)
    if "--write" in argv:
        out = pathlib.Path(__file__).resolve().parent / "results" / "bench_autotune.md"
        out.write_text(text)
        print("wrote", out)
    return text


if __name__ == "__main__":
    main(sys.argv[1:])
