"""Standing fuzz of predict_limit_cycles against the independent 1-D reference (tests/df_reference.py).

Random loops (tests/fuzz_loops.py: plants of order 1-7, damping down to 1e-6, unstable poles, integrators,
delays; every element kind including Quantizer, LinearThenStatic, MassBacklash and NumericDF static and
hysteretic; default and explicit windows). Counts runs, misses (reference roots the solver did not return),
extras (returned roots the reference does not have, and whose residual from python-control's G and the element
is not at rounding level), verified extras (returned roots the reference's scans missed, with that residual below
1e-9 relative), residual-bound violations, errors, runs over the time limit, and the peak memory of the process.

    python benchmarks/fuzz_solver.py [--runs N] [--seed S] [--time-limit SECONDS] [--kinds KIND ...] [--write]

``--kinds`` restricts the runs to those element kinds (taken in turn), e.g. the resonance kinds
``linear_then_static_resonance mass_backlash_resonance``. Writes benchmarks/results/fuzz_solver.md (with
``--kinds``: fuzz_solver_<kinds>.md) only with --write.
"""
from __future__ import annotations

import argparse
import collections
import os
import resource
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

import fuzz_loops  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--time-limit", type=float, default=30.0, help="solver seconds above which a run is over time")
    ap.add_argument("--kinds", nargs="+", choices=fuzz_loops.KINDS, help="only these element kinds, in turn")
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    counts = collections.Counter()
    per_kind = collections.defaultdict(collections.Counter)
    notes = []
    t0 = time.perf_counter()
    for seed in range(args.seed, args.seed + args.runs):
        out = fuzz_loops.run_case(seed, kind=args.kinds[seed % len(args.kinds)] if args.kinds else None)
        k = out["kind"]
        counts["runs"] += 1
        per_kind[k]["runs"] += 1
        err = out["error"]
        if err in ("continuum", "outside domain", "reference out of reach"):
            counts[err] += 1
        elif err is not None:
            counts["errors"] += 1
            notes.append(f"seed {seed} ({k}): {err[:160]}")
        for name in ("misses", "extras", "extras_verified", "bad_residual"):
            n = len(out[name])
            counts[name] += n
            per_kind[k][name] += n
            if n:
                notes.append(f"seed {seed} ({k}, T={out['T']}, windows {'default' if out['omega'] is None else 'given'}): "
                             f"{name} {out[name][:3]}")
        counts["roots"] += out.get("n_reference") or 0
        if out["time"] > args.time_limit:
            counts["over_time"] += 1
        print(f"seed {seed:5d} {k:20s} {out['time']:6.2f} s  misses {len(out['misses'])} extras {len(out['extras'])}"
              f"{'  ' + err[:60] if err else ''}", flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    total = time.perf_counter() - t0
    lines = ["# Standing fuzz of the solver against the independent 1-D reference", "",
             f"`python benchmarks/fuzz_solver.py --runs {args.runs} --seed {args.seed}"
             f"{' --kinds ' + ' '.join(args.kinds) if args.kinds else ''} --write` "
             f"({total:.0f} s on the shared 2-core machine)", "",
             "| runs | reference roots | misses | extras | verified extras | residual-bound violations | errors "
             f"| over time (> {args.time_limit:g} s) | continuum | reference out of reach | peak memory |",
             "|---|---|---|---|---|---|---|---|---|---|---|",
             f"| {counts['runs']} | {counts['roots']} | {counts['misses']} | {counts['extras']} "
             f"| {counts['extras_verified']} | {counts['bad_residual']} "
             f"| {counts['errors']} | {counts['over_time']} | {counts['continuum']} | {counts['reference out of reach']} "
             f"| {peak:.0f} MiB |", "", "| element | runs | misses | extras |", "|---|---|---|---|"]
    lines += [f"| {k} | {c['runs']} | {c['misses']} | {c['extras']} |" for k, c in sorted(per_kind.items())]
    if notes:
        lines += ["", "Notes:", ""] + [f"- {n}" for n in notes]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        name = "fuzz_solver" + ("_" + "_".join(args.kinds) if args.kinds else "") + ".md"
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", name)
        with open(path, "w") as fh:
            fh.write(text)


if __name__ == "__main__":
    main()
