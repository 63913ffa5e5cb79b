"""Error next to time for the biased-cycle and forced-response analyses (docs/bias_forced.md).

1. Dual-input DF of a saturation on 2000 (B, A) points: closed form, the quadrature path (the same map as a
   callable with its breakpoints) and scipy.integrate.quad per point (the baseline): max |error| against quad,
   time per point, ratio to the closed form's time in the same run.
2. Biased cycle of a relay with unequal levels (+1.5 / -0.6) around 4/(s+1)^3 with r0 = 0.4: prediction time, and
   the DF's error on period and bias against the exact orbit (matrix exponentials, switching times by fsolve).
3. Forced response of a cubic spring in 1/(s^2 + 0.2 s + 1), R = 0.3, 101 frequencies: time, largest error of the
   solutions against the cubic in A^2, and of the fold frequencies against the discriminant's zeros.

Run: python benchmarks/bench_bias_forced.py [--write]   (--write: benchmarks/results/bench_bias_forced.md)
"""
from __future__ import annotations

import math
import pathlib
import platform
import sys
import time

import control as ct
import numpy as np
from scipy.integrate import quad
from scipy.linalg import expm
from scipy.optimize import brentq, fsolve

from dfloop import CubicStiffness, Saturation
from dfloop.describing.dual_input import DualInputDF
from dfloop.solve.bias import predict_biased_cycles
from dfloop.solve.forced import forced_response


def best_time(fn, repeats=3):
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def dual_rows():
    rng = np.random.default_rng(1)
    B, A = rng.uniform(-2, 2, 2000), rng.uniform(0.1, 5, 2000)
    closed = DualInputDF(Saturation(1.0))
    numeric = DualInputDF(lambda x: np.clip(x, -1, 1), breakpoints=[-1.0, 1.0])

    def by_quad(n):
        out = []
        for b, a in zip(B[:n], A[:n]):
            pts = [t for L in (-1, 1) for s in [(L - b) / a] if abs(s) < 1 for t in (math.asin(s), math.pi - math.asin(s))]
            f = lambda t: min(max(b + a * math.sin(t), -1), 1)  # noqa: E731
            kw = dict(points=pts or None, limit=200, epsabs=1e-14, epsrel=1e-13)
            m = quad(f, -math.pi / 2, 1.5 * math.pi, **kw)[0] / (2 * math.pi)
            s = quad(lambda t: f(t) * math.sin(t), -math.pi / 2, 1.5 * math.pi, **kw)[0] / (math.pi * a)
            out.append((m, s))
        return np.array(out)

    n_quad = 200
    t_q, ref = best_time(lambda: by_quad(n_quad), 1)
    t_c, _ = best_time(lambda: (closed.mean(B, A), closed.N_A(B, A)))
    t_n, _ = best_time(lambda: (numeric.mean(B, A), numeric.N_A(B, A)))
    rows = []
    for name, dual, t, n in (("closed form", closed, t_c, B.size), ("quadrature (GL, located breaks)", numeric, t_n,
                                                                    B.size), ("scipy quad (baseline)", None, t_q, n_quad)):
        if dual is None:
            err = 0.0
        else:
            m, na = dual.mean(B[:n_quad], A[:n_quad]), dual.N_A(B[:n_quad], A[:n_quad]).real
            err = float(max(np.max(abs(m - ref[:, 0])), np.max(abs(na - ref[:, 1]))))
        rows.append((name, err, t / n * 1e6, (t / n) / (t_c / B.size)))
    return rows


def biased_row():
    M1, M2, K, r0 = 1.5, 0.6, 4.0, 0.4
    G = ct.tf([K], [1, 3, 3, 1])
    relay = DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0])
    t, cycles = best_time(lambda: predict_biased_cycles(G, relay, r0=r0, amplitude=(0.01, 50)))
    (c,) = cycles
    sys_ = ct.ss(G)
    Am, Bm, Cm = np.asarray(sys_.A), np.asarray(sys_.B), np.asarray(sys_.C)
    n = Am.shape[0]

    def flow(tt, u):
        big = np.zeros((n + 1, n + 1))
        big[:n, :n], big[:n, n:] = Am, Bm * u
        E = expm(big * tt)
        return E[:n, :n], E[:n, n]

    def eqs(tt):
        P1, q1 = flow(tt[0], M1)
        P2, q2 = flow(tt[1], -M2)
        x0 = np.linalg.solve(np.eye(n) - P2 @ P1, P2 @ q1 + q2)
        return [(Cm @ x0)[0] - r0, (Cm @ (P1 @ x0 + q1))[0] - r0]

    frac = (math.pi + 2 * math.asin(c.bias / c.amplitude)) / (2 * math.pi)
    t1, t2 = fsolve(eqs, [frac * c.period, (1 - frac) * c.period], xtol=1e-12)
    T = t1 + t2
    e_mean = r0 - K * (M1 * t1 - M2 * t2) / T
    return t, (c.period - T) / T, c.bias - e_mean


def forced_row():
    z, k1, k3, R = 0.1, 1.0, 0.5, 0.3
    G = ct.tf([1.0], [1.0, 2 * z, 1.0])
    w = np.linspace(0.5, 3.0, 101)
    t, res = best_time(lambda: forced_response(G, CubicStiffness(k1, k3), R, w, amplitude=(1e-3, 20)))

    def cubic(ww):
        c, q, d2 = 1 - ww * ww + k1, 0.75 * k3, 4 * z * z * ww * ww
        return np.array([q * q, 2 * c * q, c * c + d2, -R * R * ((1 - ww * ww) ** 2 + d2)])

    def disc(ww):
        a, b, c, d = cubic(ww)
        return 18 * a * b * c * d - 4 * b ** 3 * d + b * b * c * c - 4 * a * c ** 3 - 27 * a * a * d * d

    err = 0.0
    for ww, sols in zip(res.omega, res.solutions):
        x = np.roots(cubic(ww))
        truth = np.sort(np.sqrt(x[(abs(x.imag) < 1e-9 * abs(x)) & (x.real > 0)].real))
        err = max(err, float(np.max(abs(np.array([p.amplitude for p in sols]) / truth - 1))))
    fold_err = 0.0
    for j in res.jumps:
        k = np.searchsorted(w, j.omega)
        fold_err = max(fold_err, abs(j.omega / brentq(disc, w[k - 1], w[k], xtol=1e-15, rtol=1e-15) - 1))
    return t, err, fold_err, len(res.jumps)


def main():
    lines = [f"# bench_bias_forced ({platform.processor() or platform.machine()}, python {platform.python_version()})",
             "", "## Dual-input DF of a saturation (2000 points; errors against scipy quad on 200)", "",
             "| method | max abs error | time per point [us] | time / closed form |", "|---|---|---|---|"]
    for name, err, us, ratio in dual_rows():
        lines.append(f"| {name} | {err:.1e} | {us:.2f} | {ratio:.1f} |")
    t, dT, dB = biased_row()
    lines += ["", "## Biased cycle: relay +1.5/-0.6, 4/(s+1)^3, r0 = 0.4", "",
              "| prediction time [s] | period error vs exact | bias error vs exact mean |", "|---|---|---|",
              f"| {t:.3f} | {dT:+.2%} | {dB:+.2e} |"]
    t, err, fold_err, nj = forced_row()
    lines += ["", "## Forced response: cubic spring, 1/(s^2+0.2s+1), R = 0.3, 101 frequencies", "",
              "| time [s] | max rel. error of solutions vs cubic in A^2 | jumps | max rel. error of folds vs discriminant |",
              "|---|---|---|---|", f"| {t:.3f} | {err:.1e} | {nj} | {fold_err:.1e} |"]
    table = "\n".join(lines)
    print(table)
    if "--write" in sys.argv[1:]:
        out = pathlib.Path(__file__).parent / "results" / "bench_bias_forced.md"
        out.write_text(table + "\n")


if __name__ == "__main__":
    main()
