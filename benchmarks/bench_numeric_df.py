"""Accuracy versus time of NumericDF against the closed forms, for its knobs.

Rows: Gauss-Legendre nodes per piece with switching instants located (default), with breakpoints
supplied (static elements), without location (adaptive halving only), and plain uniform sampling of one
period with 2^k samples (the DFT baseline). Columns: max relative error over the amplitudes, time per
amplitude, and its ratio to the closed form's time per amplitude measured in the same run.

Run: python benchmarks/bench_numeric_df.py [--write]   (--write: benchmarks/results/bench_numeric_df.md)
"""
from __future__ import annotations

import pathlib
import sys
import platform
import time

import numpy as np

import dfloop as df


def best_time(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def cases():
    h = 0.1
    yield ("Backlash h=0.1 (operator)", df.Backlash(h), df.Backlash(h).operator(), True, None,
           np.array([h / 2 * (1 + 1e-9), h / 2 * 1.001, 0.06, h, 0.3, 5.0, h / 2 * 1e6]))
    rel = df.Relay(1.0, hysteresis=0.2, dead_zone=0.5)
    yield ("Relay M=1 a=0.2 d=0.5 (operator)", rel, rel.operator(), True, None,
           np.array([0.7 * 1.001, 0.8, 1.5, 4.0, 1e3]))
    sat = df.Saturation(1.0)
    yield ("Saturation 1 (static f)", sat, sat.output, False, sat.breakpoints,
           np.array([1.001, 1.5, 3.0, 10.0, 1e3, 1e6]))
    dz = df.DeadZone(1.0)
    yield ("DeadZone 1 (static f)", dz, dz.output, False, dz.breakpoints,
           np.array([1 + 1e-6, 1.001, 1.5, 3.0, 10.0, 1e3, 1e6]))


def configs(static: bool):
    for nodes in (4, 8, 16, 32):
        yield f"pieces, located, {nodes} nodes", dict(nodes=nodes)
    if static:
        yield "pieces, breakpoints given, 16 nodes", dict(nodes=16, breakpoints=True)
    yield "pieces, not located (adaptive only), 16 nodes", dict(nodes=16, locate=False)
    for k in (8, 10, 12, 14, 16):
        yield f"sampled DFT, 2^{k} samples", dict(method="sampled", samples=2**k)


def main() -> str:
    lines = [
        "# NumericDF accuracy versus time against the closed forms",
        "",
        f"Machine: {platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}. "
        "Time per amplitude = best wall time of the call over all amplitudes / number of amplitudes; "
        "ratio = that / closed-form time per amplitude (closed form over the same amplitudes, same run).",
        "",
    ]
    for title, exact, element, hysteretic, bps, A in cases():
        ref = exact(A)
        t_closed = best_time(lambda: exact(A), 200) / A.size
        lines += [f"## {title}", "",
                  f"Amplitudes: {', '.join(f'{a:.9g}' for a in A)}. Closed form: {t_closed * 1e6:.2f} us per amplitude.",
                  "", "| configuration | max rel. error | time per amplitude (ms) | ratio to closed form |",
                  "|---|---:|---:|---:|"]
        for name, kw in configs(not hysteretic):
            kw = dict(kw)
            if kw.pop("breakpoints", False):
                kw["breakpoints"] = bps
            nd = df.NumericDF(element, hysteretic=hysteretic, **kw)
            try:
                out = nd(A)
                err = float(np.max(np.abs(out - ref) / np.abs(ref)))
                t = best_time(lambda: nd(A), 1 if hysteretic else 3) / A.size
                lines.append(f"| {name} | {err:.1e} | {t * 1e3:.3f} | {t / t_closed:.0f} |")
            except RuntimeError as exc:  # a bound was hit: report it instead of a number
                lines.append(f"| {name} | bound hit: {exc} | - | - |")
        lines.append("")
    sat = df.Saturation(1.0)
    many = np.geomspace(1.001, 1e3, 2000)
    nd = df.NumericDF(sat.output, breakpoints=sat.breakpoints)
    t_many = best_time(lambda: nd(many), 3) / many.size
    err = float(np.max(np.abs(nd(many) - sat(many)) / np.abs(sat(many))))
    t_closed = best_time(lambda: sat(many), 50) / many.size
    lines += ["## Vectorisation over amplitudes (static f, breakpoints given, 16 nodes)", "",
              f"2000 amplitudes in one call: {t_many * 1e3:.4f} ms per amplitude, max rel. error {err:.1e}, "
              f"ratio to closed form {t_many / t_closed:.0f}.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    table = main()
    print(table)
    if "--write" in sys.argv[1:]:
        out = pathlib.Path(__file__).parent / "results" / "bench_numeric_df.md"
        out.parent.mkdir(exist_ok=True)
        out.write_text(table + "\n")
