"""Start-up cost: ``import dfloop``, ``dfloop --help`` and the solver's first call, each in a fresh process.

Wall times of fresh interpreters (median of ``--repeats`` runs), as ratios against ``python -c pass`` measured
in the same run. For reference, the same run times the eager import of the heavy dependencies dfloop now
imports only where they are used (python-control, scipy.signal, matplotlib.pyplot).

The solver's first call (``predict_limit_cycles(G, Saturation(1))`` on a third-order plant, timed inside the
child after its imports) is measured twice: with an empty numba cache (``NUMBA_CACHE_DIR`` set to a new
directory: a fresh install) and again with that cache filled (every later process). The solver's grid kernels
are numpy, so the two agree; with ``--compare`` the same cold first call is timed on the other checkout (e.g.
one whose kernels were numba and compiled on that call).

Then every public entry point's first call (predict_limit_cycles, cycle_confidence, exact_cycle, verify_cycle,
sweep, the first DynamicBacklash value; predict_many, which compiles the solver's kernels for the batch) in a fresh
process with empty numba and table caches, with the line it
printed on the progress channel: each returns within 3 s or says at once that it compiles, and about how long.

Run: python benchmarks/bench_startup.py [--repeats N] [--compare OTHER_CHECKOUT] [--write]   (--write saves results/bench_startup.md)
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent

FIRST_CALL = """
import json, time
t0 = time.perf_counter()
import control as ct
from dfloop import Saturation, predict_limit_cycles  # imports the solver's modules
G = ct.tf([8], [1, 2, 2, 1])
N = Saturation(1.0)
t1 = time.perf_counter()
predict_limit_cycles(G, N)
t2 = time.perf_counter()
predict_limit_cycles(G, N)
t3 = time.perf_counter()
print(json.dumps({"imports": t1 - t0, "first": t2 - t1, "second": t3 - t2}))
"""


ENTRY = """
import json, sys, time
import control as ct
import dfloop as df
G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)
what = sys.argv[1]
t0 = time.perf_counter()
if what == "predict_limit_cycles":
    df.predict_limit_cycles(G, N)
elif what == "predict_many":
    from dfloop.batch import predict_many
    predict_many([(G, N)] * 2, progress=False)
elif what == "confidence":
    df.cycle_confidence(G, N, 1.0103, 1.5914)
elif what == "exact_cycle":
    df.exact_cycle(G, N, (1.0103, 1.5914))
elif what == "verify_cycle":
    df.verify_cycle(G, N, (1.0103, 1.5914))
elif what == "sweep":
    from dfloop.continuation import sweep
    sweep(lambda K: (ct.tf([K], [1, 1, 0]), df.Backlash(h=1.0)), [3.0, 4.0, 5.0], progress=False)
elif what == "DynamicBacklash":
    from dfloop.impact.dynamic_backlash import DynamicBacklash
    DynamicBacklash(1.0, 1.0, 0.1, 0.5, periods=20, starts=0)(50.0, 35.0)
t1 = time.perf_counter()
print(json.dumps({"first": t1 - t0}))
"""
ENTRIES = ["predict_limit_cycles", "predict_many", "confidence", "exact_cycle", "verify_cycle", "sweep", "DynamicBacklash"]


def cold_entry(what: str, root: pathlib.Path = ROOT) -> tuple[float, str]:
    """Seconds of the first call of one public entry point in a fresh process with empty numba and table caches
    (a fresh install), and the first line it printed on the progress channel (stderr; '' when silent)."""
    with tempfile.TemporaryDirectory(prefix="dfloop-fresh-") as tmp:
        env = _env(root, NUMBA_CACHE_DIR=tmp + "/numba", DFLOOP_CACHE_DIR=tmp + "/tables")
        done = subprocess.run([sys.executable, "-c", ENTRY, what], env=env, cwd=root, check=True,
                              capture_output=True, text=True)
    said = next((line for line in done.stderr.splitlines() if "compil" in line), "")
    return json.loads(done.stdout.strip().splitlines()[-1])["first"], said


def _env(root: pathlib.Path = ROOT, **extra) -> dict:
    env = dict(os.environ, PYTHONPATH=str(root) + os.pathsep + os.environ.get("PYTHONPATH", ""), MPLBACKEND="Agg")
    env.update(extra)
    return env


def wall(args: list[str], repeats: int, root: pathlib.Path = ROOT) -> float:
    """Median wall time (s) of ``python <args>`` in fresh processes, with ``root`` first on the path."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, *args], env=_env(root), cwd=root, check=True, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def first_call(cache: str, root: pathlib.Path = ROOT) -> dict:
    """Times (s) of the imports and the first two solver calls in a fresh process, numba cache in ``cache``."""
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=_env(root, NUMBA_CACHE_DIR=cache), cwd=root,
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(repeats: int, compare: pathlib.Path | None = None) -> str:
    base = wall(["-c", "pass"], repeats)
    rows = [("python -c pass (baseline)", base),
            ("import dfloop", wall(["-c", "import dfloop"], repeats)),
            ("dfloop --help (python -m dfloop.cli --help)", wall(["-m", "dfloop.cli", "--help"], repeats)),
            ("from dfloop import predict_limit_cycles, Saturation",
             wall(["-c", "from dfloop import predict_limit_cycles, Saturation"], repeats)),
            ("reference: import control, scipy.signal, matplotlib.pyplot",
             wall(["-c", "import control, scipy.signal, matplotlib.pyplot"], repeats))]
    if compare is not None:
        rows += [(f"import dfloop ({compare})", wall(["-c", "import dfloop"], repeats, compare)),
                 (f"dfloop --help ({compare})", wall(["-m", "dfloop.cli", "--help"], repeats, compare))]
    lines = ["# Start-up: fresh-process wall times", "",
             f"Median of {repeats} fresh processes each; ratio against `python -c pass` in the same run.", "",
             "| command | wall time (s) | / python -c pass |", "|---|---|---|"]
    lines += [f"| {name} | {t:.3f} | {t / base:.1f} |" for name, t in rows]
    with tempfile.TemporaryDirectory(prefix="dfloop-numba-") as cache:
        cold = first_call(cache)
        warm = [first_call(cache) for _ in range(repeats)]
    warm_first = statistics.median(w["first"] for w in warm)
    warm_second = statistics.median(w["second"] for w in warm)
    lines += ["", "First solver call, `predict_limit_cycles(tf([8], [1, 2, 2, 1]), Saturation(1))`, timed inside "
              "a fresh process after its imports:", "",
              "| numba cache | first call (s) | second call in the same process (s) | first / second |",
              "|---|---|---|---|",
              f"| empty (fresh install) | {cold['first']:.3f} | {cold['second']:.4f} | "
              f"{cold['first'] / cold['second']:.0f} |",
              f"| filled (median of {repeats}) | {warm_first:.3f} | "
              f"{warm_second:.4f} | {warm_first / warm_second:.0f} |"]
    lines += ["", "First call of each public entry point in a fresh process with empty numba and table caches (a "
              "fresh install; loop 5/(s(s+1)) with Backlash(1), cycle A = 1.0103, w = 1.5914; the sweep over K = 3, 4, "
              "5; DynamicBacklash(1, 1, 0.1, 0.5, periods=20, starts=0) at F = 50 N, w = 35 rad/s), and what it said "
              "on the progress channel (stderr) before paying a compile:", "",
              "| entry point | first call (s) | announcement |", "|---|---|---|"]
    for what in ENTRIES:
        t, said = cold_entry(what)
        lines.append(f"| {what} | {t:.1f} | {said or ('none needed (< 3 s)' if t < 3 else 'NONE')} |")
    if compare is not None:
        with tempfile.TemporaryDirectory(prefix="dfloop-numba-") as cache:
            other = first_call(cache, compare)
        lines.append(f"| empty, {compare} | {other['first']:.3f} | {other['second']:.4f} | "
                     f"{other['first'] / other['second']:.0f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="fresh processes per measurement (default 5)")
    parser.add_argument("--compare", type=pathlib.Path, help="another checkout (e.g. the main branch) to time too")
    parser.add_argument("--write", action="store_true", help="write benchmarks/results/bench_startup.md")
    args = parser.parse_args()
    table = main(args.repeats, args.compare)
    print(table)
    if args.write:
        out = pathlib.Path(__file__).parent / "results" / "bench_startup.md"
        out.parent.mkdir(exist_ok=True)
        out.write_text(table)
