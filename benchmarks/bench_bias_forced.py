"""Error next to time for the biased-cycle and forced-response analyses (docs/bias_forced.md).

1. Dual-input DF of a saturation on 2000 (B, A) points: closed form, the quadrature path (the same map as a
   callable with its breakpoints) and scipy.integrate.quad per point (the baseline): max |error| against quad,
   time per point, ratio to the closed form's time in the same run.
2. Biased cycle of a relay with unequal levels (+1.5 / -0.6) around 4/(s+1)^3 with r0 = 0.4: prediction time, and
   the DF's error on period and bias against the exact orbit (matrix exponentials, switching times by fsolve).
3. Forced response of a cubic spring in 1/(s^2 + 0.2 s + 1), R = 0.3, 101 frequencies: time, largest error of the
   solutions against the cubic in A^2, and of the fold frequencies against the discriminant's zeros.
4. Exact biased orbits (exact_cycle with the constant input): a relay with a dead zone and r0 = 0.15 around
   22/((s+1)(s+2)(s+3)), both biased cycles (stable and unstable): time, and period / mean against Tsypkin's exact
   relay solution (partial fractions, tests/test_biased_exact.py); the DF's own errors beside them.
5. Three-level relay with hysteresis (hysteresis 0.1, dead zone 0.3) around 4/(s+1)^3, r0 = 0.3: biased prediction
   time; its dual-input DF per point in closed form against the generic path (switching phases of the element's
   time model, the baseline, same run) and the largest difference between them.
6. Exact forced response of the cubic spring (R = 0.3, every 4th of 101 frequencies, 32 orbits): time, the
   largest |DF - exact| amplitude difference, and the largest deviation of det(monodromy) from exp(-2 zeta T)
   (Liouville: the spring adds no damping).

Run: python benchmarks/bench_bias_forced.py [--write] [--figures]   (--write: benchmarks/results/bench_bias_forced.md;
--figures: docs/figures/forced_response.png and docs/figures/jump_region.png)
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


def exact_biased_rows():
    import importlib.util

    from dfloop import Relay
    from dfloop.biased import biased_cycles

    spec = importlib.util.spec_from_file_location("tb", pathlib.Path(__file__).parents[1] / "tests" /
                                                  "test_biased_exact.py")
    tb = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tb)
    G, r0, d = ct.tf([22.0], [1, 6, 11, 6]), 0.15, 0.2
    t, cycles = best_time(lambda: biased_cycles(G, Relay(1.0, dead_zone=d), r0=r0, amplitude=(0.201, 20)), 1)
    levels = [(d, True), (d, False), (-d, False), (-d, True)]
    rows = []
    for c in sorted(cycles, key=lambda c: c.amplitude):
        ex = c.exact
        tau, e_mean, T = tb._tsypkin(G, [1.0, 0.0, -1.0, 0.0], [x for x, _ in levels], r0, tb._guess(c, levels))
        rows.append(("stable" if ex.stable else "unstable", ex.period / T - 1, ex.mean - e_mean,
                     (c.amplitude - ex.amplitude) / ex.amplitude, c.bias - ex.mean))
    return t, rows


def three_level_rows():
    from dfloop import Relay
    from dfloop.describing.base import DescribingFunction

    relay = Relay(1.0, hysteresis=0.1, dead_zone=0.3)

    class Generic(DescribingFunction):   # the same relay known only by its time model
        def _evaluate(self, A, omega):
            return relay(A)

        def time_model(self, amplitude):
            return relay.time_model(amplitude)

    G = ct.tf([4.0], [1, 3, 3, 1])
    t_pred, _ = best_time(lambda: predict_biased_cycles(G, relay, r0=0.3, amplitude=(0.41, 20)), 1)
    rng = np.random.default_rng(2)
    B, A = rng.uniform(-1.5, 1.5, 400), rng.uniform(0.05, 2.5, 400)
    closed, generic = DualInputDF(relay), DualInputDF(Generic())
    t_c, out_c = best_time(lambda: (closed.mean(B, A), closed.N_A(B, A)))
    t_g, out_g = best_time(lambda: (generic.mean(B, A), generic.N_A(B, A)), 1)
    diff = max(float(np.max(np.abs(out_c[0] - out_g[0]))), float(np.max(np.abs(out_c[1] - out_g[1]))))
    return t_pred, t_c / B.size * 1e6, t_g / B.size * 1e6, diff


def exact_forced_row(figures=False):
    from dfloop.hybrid.forced import exact_forced_response

    z = 0.1
    G, N = ct.tf([1.0], [1.0, 2 * z, 1.0]), CubicStiffness(1.0, 0.5)
    res = forced_response(G, N, 0.3, np.linspace(0.5, 3.5, 101), amplitude=(1e-3, 20))
    t, ex = best_time(lambda: exact_forced_response(G, N, res, every=4), 1)
    liouville = max(abs(abs(np.prod(p.multipliers)) / math.exp(-2 * z * 2 * math.pi / p.omega) - 1) for p in ex.flat())
    if figures:
        import matplotlib

        matplotlib.use("Agg")
        from dfloop.solve.forced import jump_region

        out = pathlib.Path(__file__).parents[1] / "docs" / "figures"
        ex.plot().figure.savefig(out / "forced_response.png", dpi=110, bbox_inches="tight")
        region = jump_region(G, N, np.linspace(0.22, 0.3, 17), np.linspace(0.5, 3.5, 301),
                             amplitude=(1e-3, 20))
        region.plot().figure.savefig(out / "jump_region.png", dpi=110, bbox_inches="tight")
    return t, len(ex.flat()), ex.largest_difference, liouville, len(ex.disagreements())


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
    t, rows = exact_biased_rows()
    lines += ["", "## Exact biased orbits: relay, dead zone 0.2, r0 = 0.15, 22/((s+1)(s+2)(s+3))", "",
              f"biased_cycles with both exact orbits: {t:.3f} s", "",
              "| orbit | period vs Tsypkin (rel.) | mean vs Tsypkin | DF amplitude error | DF bias error |",
              "|---|---|---|---|---|"]
    lines += [f"| {k} | {dT:+.1e} | {dm:+.1e} | {dA:+.2%} | {dB:+.2e} |" for k, dT, dm, dA, dB in rows]
    t_pred, us_c, us_g, diff = three_level_rows()
    lines += ["", "## Three-level relay (hysteresis 0.1, dead zone 0.3), 4/(s+1)^3, r0 = 0.3", "",
              "| biased prediction [s] | dual DF closed form [us/point] | generic time-model path (baseline) "
              "[us/point] | baseline / closed form | max difference |", "|---|---|---|---|---|",
              f"| {t_pred:.3f} | {us_c:.2f} | {us_g:.1f} | {us_g / us_c:.0f} | {diff:.1e} |"]
    t, n, diff, liouville, disagree = exact_forced_row("--figures" in sys.argv[1:])
    lines += ["", "## Exact forced response: cubic spring, R = 0.3, every 4th of 101 frequencies", "",
              "| time [s] | orbits | largest DF amplitude error | max det(monodromy) vs exp(-2 zeta T) | "
              "DF/exact disagreements (kind or stability) |", "|---|---|---|---|---|",
              f"| {t:.3f} | {n} | {diff:.2%} | {liouville:.1e} | {disagree} |"]
    table = "\n".join(lines)
    print(table)
    if "--write" in sys.argv[1:]:
        out = pathlib.Path(__file__).parent / "results" / "bench_bias_forced.md"
        out.write_text(table + "\n")


if __name__ == "__main__":
    main()
