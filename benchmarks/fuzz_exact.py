"""Standing fuzz of exact_cycle against closed-loop runs: never a false "no orbit", never a stable orbit the loop
does not settle on.

Random loops (tests/fuzz_loops.py: plants of order 1-5 with integrators, light damping and delays; the static
elements with an exact time model: saturation, dead zone, relays, backlash, cubic stiffness, Coulomb friction,
preload, quantizer). For each of a loop's first three DF cycles labelled stable, verify_cycle runs the loop from
inside and outside the prediction (150 periods); where a run settles on a periodic motion (its per-period
amplitudes agree to 1e-3), exact_cycle's answer is classed:

- *agrees*: an orbit whose amplitude is within 2 % of a settled run;
- *unstable orbit, loop goes elsewhere*: an orbit with a multiplier outside the unit circle (the runs leave it);
- *no orbit, loop goes far*: "no orbit" while every run settles beyond max_deviation (0.5 in log A or log w);
- flagged, each listed: "no orbit" while a run settles within max_deviation of the prediction (a false "no
  orbit" if the run is right); a stable orbit the runs do not settle on; an exception.

    python benchmarks/fuzz_exact.py [--runs N] [--seed S] [--write]

Writes benchmarks/results/fuzz_exact.md only with --write.
"""
from __future__ import annotations

import argparse
import collections
import math
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

import dfloop as df  # noqa: E402
from dfloop.solve.delay import delayed  # noqa: E402
from fuzz_loops import random_element, random_plant  # noqa: E402

KINDS = ["saturation", "deadzone", "relay", "relay_hyst", "backlash", "cubic", "coulomb", "preload", "quantizer"]
MAX_DEVIATION = 0.5


def classify(G, N, c) -> tuple[str, str]:
    """(class, note) of exact_cycle's answer for the stable DF cycle c, against verify_cycle's runs."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            v = df.verify_cycle(G, N, c, periods=150)
        except ValueError as exc:
            return "runs refused", str(exc)[:120]
        runs = [s for s in (v.inside, v.outside) if s.oscillating and s.periodicity < 1e-3 and s.amplitude > 0]
        if not runs:
            return "no settled run", ""
        try:
            e = df.exact_cycle(G, N, c)
        except Exception as exc:  # noqa: BLE001 - a flagged outcome, listed with its type
            return "flagged: exception", f"{type(exc).__name__}: {str(exc)[:160]}"
    near = [s for s in runs if max(abs(math.log(s.amplitude / c.amplitude)),
                                   abs(math.log(s.frequency / c.frequency))) <= MAX_DEVIATION]
    settled = ", ".join(f"A={s.amplitude:.5g} w={s.frequency:.5g}" for s in runs)
    if e.success:
        if any(abs(e.amplitude - s.amplitude) <= 0.02 * s.amplitude for s in runs):
            return "agrees", ""
        if not e.stable:
            return "unstable orbit, loop goes elsewhere", ""
        return "flagged: stable orbit the runs leave", f"orbit A={e.amplitude:.5g} w={e.frequency:.5g}; runs {settled}"
    if near:
        return "flagged: no orbit, a run settles near", f"{e.message[:160]}; runs {settled}"
    return "no orbit, loop goes far", ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=120, help="random loops")
    ap.add_argument("--seed", type=int, default=14)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    counts = collections.Counter()
    notes = []
    t0 = time.perf_counter()
    for k in range(args.runs):
        G0, _, _, T = random_plant(rng, 5)
        N = random_element(rng, KINDS[k % len(KINDS)])
        G = delayed(G0, T) if T else G0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                cycles = df.predict_limit_cycles(G, N)
            except ValueError:
                counts["loops refused"] += 1
                continue
        counts["loops"] += 1
        for c in [c for c in cycles if c.stability == "stable"][:3]:
            cls, note = classify(G, N, c)
            counts[cls] += 1
            counts["stable DF cycles"] += 1
            if cls.startswith("flagged"):
                notes.append(f"loop {k} ({type(N).__name__}, delay {T:g}): {cls}: predicted A={c.amplitude:.4g} "
                             f"w={c.frequency:.4g}; {note}")
        print(f"loop {k:4d} {type(N).__name__:24s} {time.perf_counter() - t0:7.0f} s", flush=True)
    total = time.perf_counter() - t0
    classes = ["agrees", "unstable orbit, loop goes elsewhere", "no orbit, loop goes far",
               "flagged: no orbit, a run settles near", "flagged: stable orbit the runs leave", "flagged: exception",
               "no settled run", "runs refused"]
    lines = ["# Standing fuzz of exact_cycle against closed-loop runs", "",
             f"`python benchmarks/fuzz_exact.py --runs {args.runs} --seed {args.seed} --write` ({total:.0f} s on the "
             "shared 2-core machine)", "",
             f"{counts['loops']} loops, {counts['stable DF cycles']} stable DF cycles:", "",
             "| outcome | cycles |", "|---|---|"] + [f"| {c} | {counts[c]} |" for c in classes]
    if notes:
        lines += ["", "Flagged:", ""] + [f"- {n}" for n in notes]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "fuzz_exact.md")
        with open(path, "w") as fh:
            fh.write(text)


if __name__ == "__main__":
    main()
