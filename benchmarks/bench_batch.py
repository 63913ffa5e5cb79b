"""How a batch of loops scales from 1 to 2 workers on a local Dask cluster (dfloop.predict_many).

A Monte Carlo batch over plant uncertainty: K p / (s (s + 1)(s + p)) with K and p drawn at random, closed by
a dead-zone relay, a backlash or a saturation (every third loop each). The same batch runs in this process
(the baseline), then on a local Dask cluster of worker processes (``distributed.LocalCluster``) with 1 and
with 2 workers, through ``client.get_executor()``. Each cluster is warmed up first (the workers import dfloop
and load the compiled kernels once; that start-up is reported separately). One run of each, so on a shared
machine the ratios are noisy. Every parallel result is checked to be identical to the serial one.

Run: python benchmarks/bench_batch.py [--n 1000] [--write]
"""
from __future__ import annotations

import argparse
import os
import pathlib
import time

import control as ct
import numpy as np

import dfloop as df
from dfloop.batch import predict_many


def monte_carlo_loops(n: int, seed: int = 1) -> list:
    rng = np.random.default_rng(seed)
    elements = [df.Relay(M=1.0, dead_zone=0.1), df.Backlash(0.2), df.Saturation(1.0)]
    loops = []
    for i in range(n):
        K, p = rng.uniform(1.0, 5.0), rng.uniform(1.5, 3.0)
        loops.append((ct.tf([K * p], [1, 1 + p, p, 0]), elements[i % 3]))
    return loops


def identical(a, b) -> bool:
    return len(a) == len(b) and all(list(x) == list(y) for x, y in zip(a, b))


def main(n: int, write: bool) -> str:
    from distributed import Client, LocalCluster

    loops = monte_carlo_loops(n)
    predict_many(loops[:6], progress=False)  # JIT / import warm-up in this process
    t0, c0 = time.perf_counter(), time.process_time()
    serial = predict_many(loops, progress=False)
    t_serial, cpu_serial = time.perf_counter() - t0, time.process_time() - c0
    rows = [("in this process (baseline)", None, t_serial, True, cpu_serial / t_serial)]
    for workers in (1, 2):
        t0 = time.perf_counter()
        with LocalCluster(n_workers=workers, processes=True, threads_per_worker=1, dashboard_address=None) as cl, \
                Client(cl) as client:
            ex = client.get_executor()
            predict_many(loops[:4 * workers], executor=ex, chunksize=1, progress=False)  # workers import dfloop
            t_start = time.perf_counter() - t0
            cpu0 = sum(client.run(time.process_time).values())
            t0 = time.perf_counter()
            par = predict_many(loops, executor=ex, progress=False)
            t = time.perf_counter() - t0
            cpu = sum(client.run(time.process_time).values()) - cpu0
        rows.append((f"Dask LocalCluster, {workers} worker{'s' if workers > 1 else ''}", t_start, t,
                     identical(serial, par), cpu / (t * workers)))
    n_cycles = sum(len(r) for r in serial)
    t1 = rows[1][2]
    lines = ["# Batch of loops: 1 versus 2 Dask workers (dfloop.predict_many)", "",
             f"{n} loops (K p / (s (s+1)(s+p)), random K in [1, 5], p in [1.5, 3]; relay with dead zone, backlash, "
             f"saturation), {n_cycles} cycles in all; default chunk size (about 64 tasks, at least 128 loops or an eighth of the batch each). One run each; "
             f"machine: {os.cpu_count()} cores, shared. Command: `python benchmarks/bench_batch.py --n {n} --write`.",
             "CPU share: CPU time of the process(es) doing the work over (wall time x processes); below 1 the "
             "machine's other load took the rest, which caps the speed-up.",
             "", "| where | worker start-up (s) | batch time (s) | time / baseline | speed-up vs 1 worker | "
             "CPU share | identical to serial |", "|---|---|---|---|---|---|---|"]
    for name, start, t, same, share in rows:
        lines.append(f"| {name} | {'-' if start is None else f'{start:.1f}'} | {t:.2f} | {t / t_serial:.2f} | "
                     f"{'-' if start is None else f'{t1 / t:.2f}'} | {share:.2f} | {'yes' if same else 'NO'} |")
    table = "\n".join(lines) + "\n"
    if write:
        out = pathlib.Path(__file__).parent / "results" / "bench_batch.md"
        out.parent.mkdir(exist_ok=True)
        out.write_text(table)
    return table


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="loops in the batch (default 1000)")
    ap.add_argument("--write", action="store_true", help="write benchmarks/results/bench_batch.md")
    args = ap.parse_args()
    print(main(args.n, args.write))
