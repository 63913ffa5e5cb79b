"""Predicted versus exact limit cycles: how well the cheap confidence brackets the DF's true error, and cost.

For each loop (relays, saturation, dead zone, backlash, cubic stiffness, an open-loop-unstable plant) the table
gives the DF prediction, the exact cycle (:func:`dfloop.exact_cycle`), the true relative errors of the
prediction, the confidence's estimated errors (:func:`dfloop.solve.confidence.cycle_confidence`) with the ratio
true / estimate, whether the bracket (2x the estimate) holds, and the distortion at the element's input. A
second table gives the cost of the confidence and of exact_cycle as ratios to the cost of
predict_limit_cycles for the same loop (one run each, after a warm-up run of all three that compiles the JIT
functions). A third compares exact_cycle on the smooth (DOP853) path, compiled (dfloop.hybrid.smooth_compiled), with
the same exact_cycle on scipy's solve_ivp (DFLOOP_COMPILED=0, the path of a user's Python f) and with a plain scipy
shooting of the same loop (solve_ivp DOP853 + scipy.optimize.root on (s0, T) with the phase condition x(0) = 0,
finite-difference Jacobian) at the same accuracy, best of 5 runs each.

Run: python benchmarks/bench_exact.py [--repeat N] [--cpu] [--write] | --high-order | --compile
(--write also writes benchmarks/results/bench_exact.md;
--repeat N: the cost table takes the best of N runs of each call, steadier on a shared machine; default 1;
--high-order: only the table of high-order loops (function high_order, printed, not written);
--compile: only the compile time of the smooth-loop integrator on a fresh numba cache (CPU seconds of a new process
that compiles it, less one that loads it; printed, not written: the estimate COMPILE_SECONDS announces);
--cpu: times are this process's CPU time (time.process_time) instead of wall time: on a machine shared with other
jobs the wall time of a single-threaded call includes the time others run, its CPU time does not)
"""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import tempfile
import time

import control as ct
import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

import dfloop as df
from dfloop.solve.confidence import BRACKET, cycle_confidence
from dfloop.exact import exact_cycle

LOOPS = [
    ("relay, 1/(s(s+1)(s+2))", ct.tf([1], [1, 3, 2, 0]), df.Relay()),
    ("relay + hysteresis 0.1, 2/(s(s+1)(s+2))", ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.1)),
    ("relay + dead zone 0.1, 2/(s(s+1)(s+2))", ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, dead_zone=0.1)),
    ("relay, dz 0.2 + hyst 0.1, 3/(s^3+2s^2+3s+1)", ct.tf([3], [1, 2, 3, 1]),
     df.Relay(M=1.5, dead_zone=0.2, hysteresis=0.1)),
    ("saturation, 8/(s^3+2s^2+2s+1)", ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)),
    ("saturation, 30/((s-1)(s+2)(s+3))", ct.tf([30], [1, 4, 1, -6]), df.Saturation(1.0)),
    ("dead zone 0.5, 12/(s+1)^3 (unstable)", ct.tf([12], [1, 3, 3, 1]), df.DeadZone(0.5)),
    ("backlash servo h=1, 5/(s(s+1))", ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)),
    ("backlash h=0.2, 1.5/(s(s+1)^2)", ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(h=0.2)),
    ("cubic 10x - x^3, 1/(s+1)^3", ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0)),
]


REPEAT = int(sys.argv[sys.argv.index("--repeat") + 1]) if "--repeat" in sys.argv[1:] else 1
CLOCK = time.process_time if "--cpu" in sys.argv[1:] else time.perf_counter


def timed(fn, repeat: int = 1):
    """(best time of ``repeat`` calls, the last result); wall time, or CPU time with --cpu."""
    best = float("inf")
    for _ in range(repeat):
        t0 = CLOCK()
        out = fn()
        best = min(best, CLOCK() - t0)
    return best, out


def scipy_shooting(G, N, amplitude: float, frequency: float, rtol: float = 1e-12):
    """Plain single shooting of the loop s' = A s + B f(-C s): unknowns (s0, T), equations phi_T(s0) = s0 and
    x(0) = -C s0 = 0 (phase), solved by scipy.optimize.root (hybr, finite-difference Jacobian); the start is the
    harmonic-balance state at x's upward zero crossing. Returns (amplitude of x's fundamental, frequency)."""
    sys_ = ct.ss(G)
    A, B, C = np.asarray(sys_.A, float), np.asarray(sys_.B, float)[:, 0], np.asarray(sys_.C, float)[0]
    n = A.shape[0]
    f = N.output

    def rhs(t, s):
        return A @ s + B * float(f(np.array(-C @ s)))

    def flow(s0, T, dense=False):
        return solve_ivp(rhs, (0.0, T), s0, method="DOP853", rtol=rtol, atol=rtol * np.max(np.abs(s0)),
                         dense_output=dense)

    def F(u):
        s0, T = u[:n], u[n]
        return np.append(flow(s0, T).y[:, -1] - s0, -C @ s0)

    s0 = (np.linalg.solve(1j * frequency * np.eye(n) - A, B) * complex(N(amplitude)) * amplitude).imag
    sol = root(F, np.append(s0, 2 * np.pi / frequency), method="hybr")
    if not sol.success:
        raise RuntimeError(f"scipy shooting failed: {sol.message}")
    s0, T = sol.x[:n], sol.x[n]
    t = np.arange(1024) * (T / 1024)
    x = -C @ flow(s0, T, dense=True).sol(t)
    return abs(2j * np.mean(x * np.exp(-2j * np.pi * t / T))), 2 * np.pi / T


def _python_path(fn):
    """fn() with DFLOOP_COMPILED=0: the smooth loop on scipy's solve_ivp (and the prediction's Python path)."""
    old = os.environ.get("DFLOOP_COMPILED")
    os.environ["DFLOOP_COMPILED"] = "0"
    try:
        return fn()
    finally:
        if old is None:
            del os.environ["DFLOOP_COMPILED"]
        else:
            os.environ["DFLOOP_COMPILED"] = old


def smooth_versus_scipy() -> str:
    """exact_cycle (compiled DOP853) against exact_cycle on scipy's solve_ivp and against the plain scipy shooting
    on the cubic loop, best of 5 each."""
    name, G, N = LOOPS[-1]
    c = df.predict_limit_cycles(G, N)[0]
    exact_cycle(G, N, c)
    _python_path(lambda: exact_cycle(G, N, c))
    scipy_shooting(G, N, c.amplitude, c.frequency)

    t_pred, _ = timed(lambda: df.predict_limit_cycles(G, N), 5)
    t_ex, e = timed(lambda: exact_cycle(G, N, c), 5)
    t_py, e_py = _python_path(lambda: timed(lambda: exact_cycle(G, N, c), 5))
    t_sp, (A_sp, w_sp) = timed(lambda: scipy_shooting(G, N, c.amplitude, c.frequency), 5)
    mu = np.max(np.abs(e.multipliers - e_py.multipliers))
    return ("| loop | predict (ms) | exact_cycle / predict | on solve_ivp / predict | scipy shooting / predict "
            "| exact_cycle / scipy shooting | exact A, w | solve_ivp path - exact: A, w (relative), multipliers "
            "| scipy shooting - exact (relative) A, w |\n|---|---|---|---|---|---|---|---|---|\n"
            f"| {name} | {1e3 * t_pred:.2f} | {t_ex / t_pred:.1f} | {t_py / t_pred:.1f} | {t_sp / t_pred:.1f} | "
            f"{t_ex / t_sp:.3f} | {e.amplitude:.10g}, {e.frequency:.10g} | "
            f"{(e_py.amplitude - e.amplitude) / e.amplitude:.1e}, {(e_py.frequency - e.frequency) / e.frequency:.1e}, "
            f"{mu:.1e} | {(A_sp - e.amplitude) / e.amplitude:.1e}, {(w_sp - e.frequency) / e.frequency:.1e} |\n")


def compile_seconds() -> str:
    """CPU seconds that compiling the smooth-loop integrator costs a new process on a fresh numba cache: a process
    that builds the cubic loop's model and flows it once, timed on an empty cache (it compiles) less the same on
    that cache (it loads)."""
    code = ("import time, numpy as np, control as ct, dfloop as df; from dfloop.hybrid import loop_model; "
            "loop = loop_model(ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0), 1.6, 1.7); "
            "t = time.process_time(); fl = loop.flow(np.array([0.3, 0.2, 1.0, 1.0]), 0, 0.5, monodromy=True); "
            "loop.states(fl, np.array([0.1])); print(time.process_time() - t)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(pathlib.Path(__file__).parents[1]),
                   DFLOOP_PROGRESS="0")
        env.pop("DFLOOP_COMPILED", None)
        fresh, cached = (float(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                              check=True).stdout) for _ in range(2))
    return (f"smooth-loop integrator: {fresh:.1f} s CPU on a fresh numba cache, {cached:.2f} s once cached: "
            f"compiling costs {fresh - cached:.1f} s")


def main() -> str:
    acc = ["| loop | cycle | predicted A, w | exact A, w | true error A, w | estimated A, w | true / estimated A, w "
           "| within 2x | distortion |", "|---|---|---|---|---|---|---|---|---|"]
    cost = ["| loop | predict (ms) | confidence / predict | exact_cycle / predict | method |", "|---|---|---|---|---|"]
    for name, G, N in LOOPS:
        t_pred, cycles = timed(lambda: df.predict_limit_cycles(G, N))     # warm-up (JIT compilation, caches)
        cycle_confidence(G, N, cycles[0].amplitude, cycles[0].frequency)
        exact_cycle(G, N, cycles[0])
        t_pred, cycles = timed(lambda: df.predict_limit_cycles(G, N), REPEAT)
        t_conf = t_exact = 0.0
        method = ""
        for i, c in enumerate(cycles):
            dt, conf = timed(lambda: cycle_confidence(G, N, c.amplitude, c.frequency), REPEAT)
            t_conf += dt
            dt, e = timed(lambda: exact_cycle(G, N, c), REPEAT)
            t_exact += dt
            method = e.method.split(" (")[0]
            pred = f"{c.amplitude:.5g}, {c.frequency:.5g}"
            if not e.success:
                acc.append(f"| {name} | {i} ({c.stability}) | {pred} | no orbit: {e.message.split(':')[0]} | | "
                           f"{100 * conf.amplitude_error:+.2f} %, {100 * conf.frequency_error:+.2f} % | | | "
                           f"{100 * conf.distortion:.2f} % |")
                continue
            ok = abs(e.amplitude_error) <= BRACKET * abs(conf.amplitude_error) and \
                abs(e.frequency_error) <= BRACKET * abs(conf.frequency_error)
            flag = ("yes" if ok else "no") + ("" if conf.reliable else " (distortion > 5 %: unreliable)")
            acc.append(f"| {name} | {i} ({'stable' if e.stable else 'unstable'}) | {pred} | "
                       f"{e.amplitude:.5g}, {e.frequency:.5g} | {100 * e.amplitude_error:+.2f} %, "
                       f"{100 * e.frequency_error:+.2f} % | {100 * conf.amplitude_error:+.2f} %, "
                       f"{100 * conf.frequency_error:+.2f} % | {e.amplitude_error / conf.amplitude_error:.2f}, "
                       f"{e.frequency_error / conf.frequency_error:.2f} | {flag} | "
                       f"{100 * conf.distortion:.2f} % |")
        cost.append(f"| {name} | {1e3 * t_pred:.1f} | {t_conf / t_pred:.2f} | {t_exact / t_pred:.2f} | {method} |")
    return ("# Predicted versus exact limit cycles, confidence and cost\n\n"
            "Errors are (predicted - exact) / exact. Estimated: `cycle_confidence` (one two-term harmonic-balance "
            "step); within 2x: |true| <= 2 |estimated| for both amplitude and frequency (the bracket `Confidence.bracket` "
            "claims when the distortion is at most 5 %).\n\n" + "\n".join(acc)
            + f"\n\nCost of all cycles of a loop, {'one run' if REPEAT == 1 else f'best of {REPEAT} runs'} each"
            + (" (CPU time)" if CLOCK is time.process_time else "") + ", as ratios to `predict_limit_cycles` on the same loop "
            "(timings on a shared machine vary ~2x between runs):\n\n" + "\n".join(cost) + "\n"
            + "\nSmooth element (DOP853 path): exact_cycle on the compiled integrator against the same exact_cycle on "
            "scipy's solve_ivp (DFLOOP_COMPILED=0, the path of a user's Python f) and against a plain scipy shooting of "
            "the same loop (best of 5 runs each" + (", CPU time" if CLOCK is time.process_time else "") + "; the last "
            "columns say all three reach the same orbit):\n\n" + smooth_versus_scipy())


def _pade(T: float, n: int):
    num, den = ct.pade(T, n)
    return ct.tf(num, den)


def high_order() -> str:
    """The high-order loops of tests/test_exact_high_order.py and the issue's order-12 backlash: the flow's
    realisation (order, ||A'||, its frequency response against python-control's over four decades), and
    exact_cycle's outcome, path and cost relative to the prediction (one run each after a warm-up); then the
    order-6 lag chain that keeps python-control's realisation (relative error at 100 rad/s of each)."""
    from dfloop.hybrid import loop_model, plant_matrices
    from dfloop.hybrid.realisation import conditioned

    s = ct.tf("s")
    loops = [
        ("saturation, pade-8, order 11", 6 * _pade(0.3, 8) / ((s + 1) ** 2 * (0.1 * s + 1)), df.Saturation(1.0)),
        ("backlash h=1, 5/(s(s+1)) pade-8 lag, order 11", 5 / (s * (s + 1)) * _pade(0.1, 8) / (0.05 * s + 1),
         df.Backlash(h=1.0)),
        ("dead zone, 12/(s+1)^3 pade-8, order 11", 12 / (s + 1) ** 3 * _pade(0.1, 8), df.DeadZone(0.5)),
        ("saturation, zeta 1e-4, poles 1e4 apart, pade-6, order 12",
         ct.tf([8], [1, 2, 2, 1]) * ct.tf([1], [1e-4, 1]) * ct.tf([100], [1, 2e-4 * 10, 100]) * _pade(0.2, 6),
         df.Saturation(1.0)),
        ("backlash h=0.5, 4/(s(s+1)) pade(1, 8) lags, order 12 (the issue's)",
         ct.tf([4.0], [1, 1, 0]) * _pade(1.0, 8) * ct.tf([1], [0.1, 1]) * ct.tf([1], [0.05, 1]), df.Backlash(h=0.5)),
    ]
    exact_cycle(loops[0][1], loops[0][2], df.predict_limit_cycles(loops[0][1], loops[0][2])[0])   # warm-up (JIT)
    rows = ["| loop | cycle | order, ||A'|| | realisation vs G (max relative, 0.01-100 rad/s) | outcome | path "
            "| exact_cycle / predict |", "|---|---|---|---|---|---|---|"]
    for name, G, N in loops:
        t_pred, cycles = timed(lambda: df.predict_limit_cycles(G, N))
        for i, c in enumerate(cycles):
            loop = loop_model(G, N, c.amplitude, c.frequency)
            A, B = loop.plant
            C = -loop.x_row[:loop.n]
            err = max(abs(C @ np.linalg.solve(1j * w * np.eye(loop.n) - A, B) - complex(G(1j * w))) /
                      abs(complex(G(1j * w))) for w in np.logspace(-2, 2, 40))
            t_ex, e = timed(lambda: exact_cycle(G, N, c))
            what = (f"A={e.amplitude:.6g}, w={e.frequency:.6g} ({'stable' if e.stable else 'unstable'}, "
                    f"|mu| {e.largest_multiplier:.3g})" if e.success else f"no orbit: {e.extra.get('outcome')}")
            rows.append(f"| {name} | {i} | {loop.n}, {np.linalg.norm(A, 2):.3g} | {err:.1e} | {what} | "
                        f"{e.extra.get('path', '')} | {t_ex / t_pred:.0f} |")
    G = ct.tf([1.0], np.poly(-np.array([0.3, 0.5, 0.7, 1.1, 2.0, 4.0])).real)
    A, B, C = plant_matrices(G)
    lines = "\n".join(rows)
    from dfloop.hybrid import realisation

    low, realisation.LOW_ORDER = realisation.LOW_ORDER, 0     # force the balanced realisation for the comparison
    try:
        Ab, Bb, Cb, _ = conditioned(A, B, C)
    finally:
        realisation.LOW_ORDER = low
    g = complex(G(100j))
    kept = abs(C @ np.linalg.solve(100j * np.eye(6) - A, B) - g) / abs(g)
    dense = abs(Cb @ np.linalg.solve(100j * np.eye(6) - Ab, Bb) - g) / abs(g)
    return (lines + f"\n\nOrder-6 lag chain, |G(100j)| = {abs(g):.1e}: relative error of C(jw - A)^-1 B "
            f"{kept:.1e} in python-control's realisation (kept up to order {low}), {dense:.1e} balanced.\n")


if __name__ == "__main__":
    if "--high-order" in sys.argv[1:]:     # the high-order loops only (not part of the results file)
        print(high_order())
        sys.exit(0)
    if "--compile" in sys.argv[1:]:        # the smooth-loop integrator's compile time only (not written)
        print(compile_seconds())
        sys.exit(0)
    text = main()
    print(text)
    if "--write" in sys.argv[1:]:
        out = pathlib.Path(__file__).parent / "results" / "bench_exact.md"
        out.write_text(text)
        print(f"wrote {out}")
