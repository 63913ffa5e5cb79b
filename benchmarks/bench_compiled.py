"""The compiled pipeline against python-control, the Python path and the floor, in one run.

For python-control's own small problems and dense 200 x 500 windows (the problems of
bench_solver_vs_control.py, same windows and grid sizes): python-control's describing_function_response, dfloop's
Python path (DFLOOP_COMPILED=0) and the compiled path; and the *floor*: evaluating G and N once on the initial
grid with numpy (G by python-control's frequency response, N by the element, one outer product), the least any
grid solver spends; and whether the compiled driver answered the call or left it to the Python driver (and
why). Then a batch of sampled servo loops (examples/monte_carlo_servo.py) through predict_many in this process
(chunks of loops through the compiled driver in parallel over the cores): microseconds per loop per core (and how
many of them the example's generator spends building the loops in python-control, timed alone), its floor (G and
N once on each loop's 64 x 256 grid), the peak traced memory of the streamed batch (tracemalloc, results kept as
one float per loop), the same batch from a coarse initial grid (8 x 32) with its answers compared loop by loop, and
the compiled driver alone on the loops' inputs converted beforehand (what a batch interface taking and returning
arrays, with no per-loop Python objects, would cost at best).

Run: python benchmarks/bench_compiled.py [--batch N] [--write]   (default N = 2000 loops; --write also writes
benchmarks/results/bench_compiled.md). Times are CPU times of this process (time.process_time), best of several
calls; the batch's wall time is given beside its CPU time.
"""
from __future__ import annotations

import inspect
import os
import pathlib
import sys
import time
import tracemalloc
import warnings

import control as ct
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))
sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "examples"))

import dfloop as df  # noqa: E402
from bench_solver_vs_control import PROBLEMS, floor  # noqa: E402
from dfloop.batch import predict_many  # noqa: E402
from dfloop.solve.compiled import driver_parts, run_batch  # noqa: E402
from monte_carlo_servo import sample, stable_amplitude  # noqa: E402

COMPILED_REPEATS = 50  # calls of tens of microseconds: the best of many is the one no other job interrupted
BATCH = int(sys.argv[sys.argv.index("--batch") + 1]) if "--batch" in sys.argv[1:] else 2000
COARSE = (8, 32)  # the batch's coarse initial grid (amplitudes, frequencies)


def best(fn, repeat: int):
    """(best CPU time of ``repeat`` calls, the last result): every call is single-threaded, and on a machine shared
    with other jobs its wall time includes theirs."""
    t_best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        t_best = min(t_best, time.process_time() - t0)
    return t_best, out


def pc_repeats(amps, omega) -> int:
    """Calls of python-control to take the best of: 10 on the small problems (a few ms each: one interrupted call
    would flatter the ratio), 2 on the dense windows (0.1 s each)."""
    return 2 if amps.size * omega.size > 10_000 else 10


def driver_status(G, N, amps, omega) -> str:
    """Whether the compiled driver answered the call itself, or why it left it to the Python driver."""
    from dfloop.solve.compiled import driver_parts, run_driver
    from dfloop.solve.compiled.driver import FALLBACK

    parts = driver_parts(G, df.as_element(N))
    if parts is None:
        return "n/a"
    status = int(run_driver(*parts, omega[0], omega[-1], amps[0], amps[-1], amps.size, omega.size, 1e-10, 1e-4)[0])
    return "answered" if status == 0 else f"fallback: {FALLBACK[status]}"


def solve(G, N, amps, omega):
    """One solver call on the problem's windows and grid (the path: ``DFLOOP_COMPILED``, set by :func:`path`
    outside the timed calls)."""
    return df.predict_limit_cycles(G, N, amplitude=(amps[0], amps[-1]), omega=(omega[0], omega[-1]),
                                   grid=(amps.size, omega.size))


def path(compiled: bool) -> None:
    os.environ["DFLOOP_COMPILED"] = "driver" if compiled else "0"


def main() -> str:
    warnings.simplefilter("ignore")
    rows = ["| problem | grid | python-control [ms] | Python path [ms] | compiled [ms] | floor [ms] | "
            "compiled vs python-control | compiled / floor | same answers | driver |", "|---|---|---|---|---|---|---|---|---|---|"]
    for name, G, F, N, amps, omega in PROBLEMS:
        t_pc, _ = best(lambda: ct.describing_function_response(G, F, amps, omega), pc_repeats(amps, omega))
        path(False)
        t_py, r_py = best(lambda: solve(G, N, amps, omega), 3)
        path(True)
        solve(G, N, amps, omega)
        t_c, r_c = best(lambda: solve(G, N, amps, omega), COMPILED_REPEATS)
        t_f = floor(G, N, amps, omega)
        same = len(r_py) == len(r_c) and all(abs(a.amplitude / b.amplitude - 1) <= 1e-12 and
                                             abs(a.frequency / b.frequency - 1) <= 1e-12 and a.stability == b.stability
                                             for a, b in zip(r_py, r_c))
        rows.append(f"| {name} | {amps.size} x {omega.size} | {t_pc * 1e3:.2f} | {t_py * 1e3:.2f} | {t_c * 1e3:.3f} | "
                    f"{t_f * 1e3:.3f} | {t_pc / t_c:.0f}x | {t_c / t_f:.1f}x | {'yes' if same else 'NO'} | "
                    f"{driver_status(G, N, amps, omega)} |")
    os.environ["DFLOOP_COMPILED"] = "driver"
    list(predict_many(sample(20, 0), keep=stable_amplitude, progress=False))  # compiled and warm
    t0, c0 = time.perf_counter(), time.process_time()
    amps = predict_many(sample(BATCH, 1), keep=stable_amplitude, progress=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    c0 = time.process_time()
    for _ in sample(BATCH, 1):  # the loops alone: python-control's tf arithmetic in the example's generator
        pass
    gen = time.process_time() - c0
    # the initial grid is a knob of cost only where both axes are refined by bounds (a rational G's exact rule, a
    # built-in element's monotone sampling): the same loops from a coarse initial grid, and their kept amplitudes
    t0, c0 = time.perf_counter(), time.process_time()
    amps_coarse = predict_many(sample(BATCH, 1), keep=stable_amplitude, progress=False, grid=COARSE)
    wall_c, cpu_c = time.perf_counter() - t0, time.process_time() - c0
    a, c = np.asarray(amps), np.asarray(amps_coarse)
    hit = np.isfinite(a)
    n_same = int(np.sum((hit == np.isfinite(c)) & (~hit | np.isclose(a, c, rtol=1e-9, atol=0))))
    n_mem = min(BATCH, 500)  # memory of the stream, traced on its first loops (tracemalloc slows Python 2-3x)
    tracemalloc.start()
    predict_many(sample(n_mem, 1), keep=stable_amplitude, progress=False)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    import resource
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    # floor of one batch loop: G and N once on its 64 x 256 initial grid
    G, N = next(sample(1, 1))
    plant = df.solve.as_plant(G)
    w, A = np.logspace(-2, 2.3, 256), np.linspace(0.3, 5.0, 64)

    def once():
        return N(A)[:, None] * plant(w)[None, :]
    t_floor = best(once, 50)[0]
    p = float(np.mean(np.isfinite(amps)))
    # what an arrays-in, arrays-out batch interface would cost at best: the compiled driver alone on the loops'
    # inputs converted before the timing (no per-loop Python objects), in the batch's chunks of 256 loops
    n_k = min(BATCH, 20000)
    inputs = [driver_parts(G, df.as_element(N)) for G, N in sample(n_k, 1)]
    windows = [(np.nan,) * 4] * n_k
    mtol = inspect.signature(df.predict_limit_cycles).parameters["marginal_tol"].default
    kernel = {}
    for grid in ((64, 256), COARSE):
        c0 = time.process_time()
        answered = 0
        for s in range(0, n_k, 256):
            answered += int(np.sum(run_batch(inputs[s:s + 256], windows[s:s + 256], *grid, 1e-10, mtol)[0] == 0))
        kernel[grid] = ((time.process_time() - c0) / n_k, answered)
    rows += ["", f"Batch: {BATCH} sampled servo loops (examples/monte_carlo_servo.py: K e^(-s tau)/(s(0.5s+1)) with "
             f"backlash) through predict_many(keep=...) in this process (the compiled driver on chunks of 256 loops, "
             f"in parallel over the cores): {cpu / BATCH * 1e6:.0f} us "
             f"CPU per loop per core ({wall / BATCH * 1e6:.0f} us wall), of which {gen / BATCH * 1e6:.0f} us generate "
             f"the loops (the example's K * G0 in python-control) and {(cpu - gen) / BATCH * 1e6:.0f} us are "
             f"dfloop's; floor (G and N once on a 64 x 256 grid) "
             f"{t_floor * 1e6:.0f} us, ratio {cpu / BATCH / t_floor:.0f}x; peak traced memory "
             f"{peak / 2**20:.1f} MiB for "
             f"{n_mem} loops (streamed in chunks of 256: independent of the number of loops but for one float kept "
             f"per loop); peak resident memory of the whole benchmark process {rss:.0f} MiB; "
             f"P(stable cycle) = {p:.3f}.",
             "", f"The batch from a coarse initial grid, grid={COARSE} (the default is (64, 256); both axes are "
             f"refined to the same step bound from there): {cpu_c / BATCH * 1e6:.0f} us CPU per loop per core "
             f"({wall_c / BATCH * 1e6:.0f} us wall), {(cpu_c - gen) / BATCH * 1e6:.0f} us dfloop's; the kept "
             f"amplitude equal (within 1e-9, or absent in both) on {n_same} of {BATCH} loops.",
             "", f"The compiled driver alone (the floor of an arrays-in, arrays-out batch interface: the first {n_k} "
             f"loops' inputs converted before the timing, run_batch on chunks of 256, no result objects): "
             f"{kernel[(64, 256)][0] * 1e6:.0f} us CPU per loop at the default grid, "
             f"{kernel[COARSE][0] * 1e6:.0f} us from grid={COARSE}; the driver answered "
             f"{kernel[(64, 256)][1]} and {kernel[COARSE][1]} of {n_k} loops."]
    return "\n".join(rows)


if __name__ == "__main__":
    table = main()
    print(table)
    if "--write" in sys.argv[1:]:
        out = pathlib.Path(__file__).parent / "results" / "bench_compiled.md"
        out.write_text("# Compiled pipeline vs python-control, the Python path and the floor\n\nCommand: "
                       f"`python benchmarks/bench_compiled.py --batch {BATCH} --write` (CPU times, best of 10 "
                       f"runs for python-control (2 on the dense windows), 3 for the Python path, "
                       f"{COMPILED_REPEATS} compiled, 20 for the floor; one process, on a machine shared with other "
                       "jobs).\n\n" + table + "\n")
