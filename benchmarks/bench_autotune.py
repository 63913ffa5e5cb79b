"""The relay experiment: errors of the ultimate-point estimates next to the time each takes.

For each process (lag- to delay-dominant first order plus dead time, a third-order lag, a digital loop) the table
gives the true ultimate point (Ku, Tu), the DF's estimates and their errors with the DF's time (prediction only,
``relay_experiment(..., exact=False)``), and the experiment's estimates (exact relay cycle: closed form for FOPDT,
``exact_cycle`` otherwise) with their errors and the total time of ``relay_experiment``. A second table takes
synthetic recordings (the exact orbit of a known FOPDT/SOPDT plus measurement noise) and gives the error of the
ultimate point read by the DF from the record, and of the one of the fitted model (with its 95 % interval's half
width), next to the time of each.

Run: python benchmarks/bench_autotune.py [--write]   (--write also writes benchmarks/results/bench_autotune.md)
"""
from __future__ import annotations

import pathlib
import sys
import time

import control as ct

import dfloop as df
from dfloop.autotune import ProcessModel, relay_experiment
from dfloop.autotune.fit import fit_relay_record
from dfloop.autotune.synthetic import synthetic_record

CASES = [  # (name, G, relay, delay)
    ("FOPDT T/L = 10 (lag dominant)", ct.tf([1.0], [10.0, 1.0]), df.Relay(1.0), 1.0),
    ("FOPDT T/L = 1", ct.tf([1.0], [1.0, 1.0]), df.Relay(1.0), 1.0),
    ("FOPDT T/L = 0.1 (delay dominant)", ct.tf([1.0], [0.1, 1.0]), df.Relay(1.0), 1.0),
    ("FOPDT T/L = 1, hysteresis 0.05", ct.tf([1.0], [1.0, 1.0]), df.Relay(1.0, hysteresis=0.05), 1.0),
    ("1/(s+1)^3", ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), df.Relay(1.0), 0.0),
    ("1/(s+1)^3, ZOH dt = 0.1", ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), 0.1), df.Relay(1.0), 0.0),
    ("SOPDT 2 e^-s/((4s+1)(s+1)), hysteresis 0.05, bias 0.2", ProcessModel(2.0, (4.0, 1.0), 1.0),
     df.Relay(1.0, hysteresis=0.05), 0.0),
]
RECORDS = [  # (name, true model, model fitted, noise sd)
    ("FOPDT T/L = 3, noise 0.01", ProcessModel(2.0, (3.0,), 1.0), "FOPDT", 0.01),
    ("FOPDT T/L = 3, noise 0.05", ProcessModel(2.0, (3.0,), 1.0), "FOPDT", 0.05),
    ("FOPDT T/L = 0.3, noise 0.02", ProcessModel(1.0, (0.3,), 1.0), "FOPDT", 0.02),
    ("SOPDT (4, 1, 1), noise 0.02", ProcessModel(2.0, (4.0, 1.0), 1.0), "SOPDT", 0.02),
    ("SOPDT (4, 1, 1) fitted as FOPDT, noise 0.02", ProcessModel(2.0, (4.0, 1.0), 1.0), "FOPDT", 0.02),
]


def main(argv: list[str]) -> str:
    lines = ["# Relay experiment: estimate errors vs time", "", "Command: `python benchmarks/bench_autotune.py --write`",
             "", "| process | Ku | Tu [s] | DF Ku err | DF Tu err | DF time [s] | exp. Ku err | exp. Tu err | "
             "total time [s] |", "|---|---|---|---|---|---|---|---|---|"]
    relay_experiment(*CASES[4][1:3], exact=False)    # warm-up
    for name, G, relay, delay in CASES:
        t0 = time.perf_counter()
        bias = 0.2 if isinstance(G, ProcessModel) else 0.0
        r_df = relay_experiment(G, relay, exact=False, delay=delay, bias=bias)
        t_df = time.perf_counter() - t0
        t0 = time.perf_counter()
        r = relay_experiment(G, relay, delay=delay, bias=bias)
        t_all = time.perf_counter() - t0
        e = r.errors
        lines.append(f"| {name} | {r.Ku:.4g} | {r.Tu:.4g} | {100 * e['Ku_df']:+.2f} % | {100 * e['Tu_df']:+.2f} % | "
                     f"{t_df:.3f} | {100 * e['Ku_experiment']:+.2f} % | {100 * e['Tu_experiment']:+.2f} % | {t_all:.3f} |")
        assert r_df.Ku_df == r.Ku_df
    lines += ["", "Recorded experiments (synthetic: exact orbit + white noise on y, relay 1.2/-0.8, hysteresis 0.05, "
              "10 periods, 200 samples per period, seed 0):", "",
              "| record | DF Ku err | DF Tu err | reading time [s] | fit | fit Ku err (95 % half width) | "
              "fit Tu err (95 % half width) | fit time [s] |", "|---|---|---|---|---|---|---|---|"]
    for name, model, kind, noise in RECORDS:
        rec = synthetic_record(model, high=1.2, low=-0.8, hysteresis=0.05, cycles=10, noise=noise, seed=0)
        Ku, Tu = model.ultimate_point()
        t0 = time.perf_counter()
        feats = rec.features()
        t_read = time.perf_counter() - t0
        t0 = time.perf_counter()
        fit = fit_relay_record(rec, kind)
        t_fit = time.perf_counter() - t0
        hw = {k: 50 * (fit.intervals[k][1] - fit.intervals[k][0]) / v for k, v in (("Ku", fit.Ku), ("Tu", fit.Tu))}
        lines.append(f"| {name} | {100 * (feats.Ku / Ku - 1):+.2f} % | {100 * (feats.Tu / Tu - 1):+.2f} % | "
                     f"{t_read:.3f} | {kind} | {100 * (fit.Ku / Ku - 1):+.2f} % ({hw['Ku']:.2f} %) | "
                     f"{100 * (fit.Tu / Tu - 1):+.2f} % ({hw['Tu']:.2f} %) | {t_fit:.2f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if "--write" in argv:
        out = pathlib.Path(__file__).resolve().parent / "results" / "bench_autotune.md"
        out.write_text(text)
        print("wrote", out)
    return text


if __name__ == "__main__":
    main(sys.argv[1:])
