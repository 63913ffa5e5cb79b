"""What a continuation sweep costs against the independent solves it replaces, and how exact its fold is.

Loop: K / (s (s+1)(s+2)) closed by a backlash of clearance 0.2 (two cycles for K above a fold gain, a stable
and an unstable one, which merge at the fold). Baseline: ``predict_limit_cycles`` at every value (what one
would do by hand, leaving the matching and the fold to the eye). ``sweep`` runs the same solves (its
completeness check) plus the continuation. The fold gain is compared with an independent computation: along
the Nyquist curve, arg(-1/N(X)) = arg G0(jw) gives X(w) and the cycle gain K(w) = 1/(|G0| |N(X)|); the fold
is the minimum of K(w) (brentq on dK/dw = 0). Times are CPU times of this process (one run each; the
work is single-threaded, and CPU time is less disturbed than wall time on a shared machine).

Run: python benchmarks/bench_sweep.py [--write] [--figure]
(--write: benchmarks/results/bench_sweep.md; --figure: docs/figures/sweep_backlash_gain.png)
"""
from __future__ import annotations

import argparse
import pathlib
import time

import control as ct
import numpy as np
from scipy.optimize import brentq

import dfloop as df
from dfloop.continuation import sweep

G0 = ct.tf([1], [1, 3, 2, 0])
BL = df.Backlash(0.2)


def loop_at(K):
    return K * G0, BL


def reference_fold() -> float:
    g0 = lambda w: 1 / ((1j * w) * (1j * w + 1) * (1j * w + 2))  # noqa: E731

    def k_of_w(w):
        x = brentq(lambda x: float(np.angle(-1 / BL(x))) - np.angle(g0(w)), 0.1 * (1 + 1e-13), 1e9, xtol=1e-15,
                   rtol=1e-15, maxiter=500)
        return 1 / (abs(g0(w)) * abs(complex(BL(x))))

    w = brentq(lambda w: (k_of_w(w * (1 + 1e-5)) - k_of_w(w * (1 - 1e-5))) / (2e-5 * w), 0.4, 0.9, xtol=1e-13)
    return k_of_w(w)


def main(write: bool, figure: bool) -> str:
    k_ref = reference_fold()
    sweep(loop_at, [3.0, 4.0], progress=False)  # warm-up (JIT)
    rows = ["| values | independent solves (CPU s) | sweep (CPU s) | sweep / solves | branches | fold K | fold rel. error |",
            "|---|---|---|---|---|---|---|"]
    res = None
    for n in (10, 50):
        values = np.linspace(2.5, 5.5, n)
        t0 = time.process_time()
        for K in values:
            df.predict_limit_cycles(*loop_at(K))
        t_solve = time.process_time() - t0
        t0 = time.process_time()
        res = sweep(loop_at, values, parameter="K", progress=False)
        t_sweep = time.process_time() - t0
        (fold,) = res.folds()
        rows.append(f"| {n} | {t_solve:.2f} | {t_sweep:.2f} | {t_sweep / t_solve:.2f} | {len(res.branches)} | "
                    f"{fold.parameter:.12g} | {abs(fold.parameter / k_ref - 1):.1e} |")
    table = ("# Sweep: continuation versus independent solves (backlash, gain K)\n\n"
             f"Reference fold gain (brentq on dK/dw = 0 along the Nyquist curve): K = {k_ref:.12g}. "
             "Command: `python benchmarks/bench_sweep.py --write`.\n\n" + "\n".join(rows) + "\n")
    if write:
        out = pathlib.Path(__file__).parent / "results" / "bench_sweep.md"
        out.parent.mkdir(exist_ok=True)
        out.write_text(table)
    if figure:
        import matplotlib

        matplotlib.use("Agg")
        ax_a, _ = res.plot().axes[:, 0]
        ax_a.set_title("K/(s(s+1)(s+2)) with backlash h = 0.2: cycles against the gain")
        out = pathlib.Path(__file__).parents[1] / "docs" / "figures" / "sweep_backlash_gain.png"
        ax_a.figure.savefig(out, dpi=110)
    return table


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write benchmarks/results/bench_sweep.md")
    ap.add_argument("--figure", action="store_true", help="write docs/figures/sweep_backlash_gain.png")
    args = ap.parse_args()
    print(main(args.write, args.figure))
