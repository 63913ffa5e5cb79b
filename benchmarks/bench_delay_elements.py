"""exact_cycle on delayed loops with every kind of piecewise-linear element, plants of order 2-12 (issue 16).

Sample: ``LOOPS`` loops, seeded. Plant: real poles and damped pairs (natural frequencies 0.2-5 rad/s, an
integrator in one loop of four, and in every backlash loop) times, in one loop of two, a Pade chain of order 2-6
(a second delay made rational); a pure delay uniform in (0, 5] dominant time constants; the element one of
saturation, dead zone, backlash (an element with memory), relay with hysteresis and dead zone, in turn. The gain
is set from the crossings of the negative real axis by G e^{-sT} so that the DF predicts a cycle that can attract:
saturation and relay 2-6 times the critical gain; backlash 0.85-0.98 of it (a stable linear loop around an
integrator); dead zone around (s + z)^2 / s^3 times 1-3 lags (z 0.2-0.5 of the slowest pole, at most 0.03-0.1 / T so that
the lead comes before the delay's lag, halved until the delayed loop has a range of stable gains), at a gain inside
that range, checked by the winding count (a dead zone's cycle around an ordinary plant repels).

For each loop: ``predict_limit_cycles`` (timed), then for each prediction (at most ``PER_LOOP``, slowest first)
``exact_cycle`` (timed, the public call) and an independent long run from the prediction: for relays the exact
event-located flow (the return map iterated until the state changes by < 1e-13, ``bench_delay_exact.settle``),
for the others tests/delay_truth.py (DOP853 at rtol 1e-12 with an exact delay buffer of dense outputs, the
element's switches located as events), until successive periods agree to ``SETTLE`` in A and w (at most
``RUN_PERIODS`` periods and ``RUN_STEPS`` solver steps, ``SLOW`` times that for backlash; runs that reach rest or diverge stop). A settled run is *found* when an exact_cycle result
of the loop equals it to ``MATCH`` = 1e-8 in A and w; a *miss* is a settled run no exact result matches.

Run: python benchmarks/bench_delay_elements.py [--write]   (--write writes benchmarks/results/bench_delay_elements.md)
"""
from __future__ import annotations

import math
import os
import pathlib
import sys
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")      # small matrices: threads only add hand-off cost
sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "tests"))

import control as ct
import numpy as np

import dfloop as df
from bench_delay_exact import settle
from delay_truth import DelayTruth, backlash_element, static_element
from dfloop.solve.delay import delayed

LOOPS = int(os.environ.get("BENCH_LOOPS", 32))
PER_LOOP = 2
RUN_PERIODS = 300          # bounds of a reference run: periods of the predicted frequency, solver steps
RUN_STEPS = 60_000
SLOW = 3                   # backlash runs: these times the bounds (a play's cycle attracts at ~0.95 per period) ...
SETTLE_PLAY = 2e-9         # ... settled at this (the reference's floor with the play's switch events is ~1e-9) and
                           # extrapolated to the limit of its last 40 periods (the change is r / (1 - r) short of it)
SETTLE = 1e-10             # a reference run has settled when successive periods agree to this (A and w)
MATCH = 1e-8
SEED = 16
ELEMENTS = ("saturation", "dead zone", "backlash", "relay")


def random_loop(rng, k: int):
    kind = ELEMENTS[k % len(ELEMENTS)]
    n = int(rng.integers(2, 7)) if kind != "dead zone" else int(rng.integers(1, 4))
    poles = [0.0] if (rng.random() < 0.25 or kind == "backlash") and kind != "dead zone" else []
    while len(poles) < n:
        wn = 10 ** rng.uniform(np.log10(0.2), np.log10(5.0))
        if len(poles) <= n - 2 and rng.random() < 0.4:
            z = rng.uniform(0.1, 0.9)
            poles += [complex(-z * wn, wn * math.sqrt(1 - z * z)), complex(-z * wn, -wn * math.sqrt(1 - z * z))]
        else:
            poles.append(-wn)
    poles = np.array(poles)
    den = np.real(np.poly(poles))
    G = ct.tf([1.0], den)
    slow = float(np.min(np.abs(poles[np.abs(poles) > 0]))) if np.any(np.abs(poles) > 0) else 1.0
    G = G * float(np.prod(np.abs(poles[np.abs(poles) > 0])))            # unit gain of the lags
    factors = [G]
    pade = 0
    if rng.random() < 0.5 and kind != "dead zone":
        pade = int(rng.integers(2, 7))
        factors.append(ct.tf(*ct.pade(float(rng.uniform(0.05, 0.5)) / slow, pade)))
        G = G * factors[-1]
    T = float(rng.uniform(0.05, 5.0)) / slow
    N = {"saturation": df.Saturation(1.0), "dead zone": df.DeadZone(0.3), "backlash": df.Backlash(h=0.5),
         "relay": df.Relay(1.0, hysteresis=float(rng.uniform(0, 0.1)), dead_zone=float(rng.uniform(0, 0.1)))}[kind]
    # gain from the crossings of the negative real axis by G e^{-sT}: saturation, relay: 2-6 times the critical gain (the linear loop
    # unstable); backlash: 0.85-0.98 of it (stable linear loop: the play's cycle attracts); dead zone: inside the
    # conditionally stable range (unstable at low gain, stable at the gain: the dead zone's cycle attracts)
    w = np.logspace(-4, 2, 6000) * slow
    n_extra = 0
    if kind == "dead zone":     # conditionally stable: (s + z)^2 / s^3, the linear loop stable between two gains
        z = min(float(rng.uniform(0.2, 0.5)) * slow, float(rng.uniform(0.03, 0.1)) / T)   # lead before the delay's lag
        for _ in range(8):      # a slower lead until the delayed loop has a range of stable gains
            lead = G * ct.tf([1.0, 2 * z, z * z], [1.0, 0.0, 0.0, 0.0])
            K = _conditional_gain(lead, T, w, rng)
            if K is not None:
                break
            z *= 0.5
        else:
            raise RuntimeError("no conditionally stable range after 8 halvings of z: change SEED")
        G, n_extra = lead, 3
        factors.append(ct.tf([1.0, 2 * z, z * z], [1.0, 0.0, 0.0, 0.0]))
    else:
        resp = np.array([complex(G(1j * x)) * np.exp(-1j * x * T) for x in w])
        idx = np.flatnonzero((np.diff(np.sign(resp.imag)) != 0) & (resp.real[:-1] < 0))   # negative real axis
        mag = abs(resp[idx[0]]) if idx.size else abs(resp[0])
        K = float(rng.uniform(0.85, 0.98) if kind == "backlash" else rng.uniform(2.0, 6.0)) / mag
    desc = f"n={len(poles) + pade + n_extra} ({'pade ' + str(pade) if pade else 'no pade'}), T={T * slow:.2f} tau, {kind}"
    factors[0] = K * factors[0]
    return delayed(K * G, T), N, desc, factors


def stable_linear_loop(G, T: float, K: float, w: np.ndarray) -> bool:
    """Whether 1 + K G(s) e^{-sT} has no zero in the right half plane, G = (s + z)^2 / s^3 times stable lags (the
    argument principle on the Nyquist contour indented to the right of the triple pole at 0: along the
    indentation the phase of 1 + K L turns by -3 pi, along the big arc by 0, so the loop is stable iff the phase
    of 1 + K L(jw) turns by +3 pi / 2 from w -> 0+ to w -> infinity)."""
    ww = np.logspace(np.log10(w[0]) - 2, np.log10(w[-1]) + 2, 40000)
    d = 1.0 + K * np.array([complex(G(1j * x)) for x in ww]) * np.exp(-1j * ww * T)
    turn = float(np.sum(np.angle(d[1:] / d[:-1])))
    return abs(turn - 1.5 * math.pi) < 0.25 * math.pi


def _conditional_gain(G, T: float, w: np.ndarray, rng) -> float | None:
    """A gain K at which the delayed conditionally stable loop K G e^{-sT} is stable while a lower gain is not: as
    the dead zone's gain N(A) grows from 0 to 1 with the amplitude, the motion grows below the lower limit of the
    stable gains and shrinks above it, so the DF cycle there attracts. The stable gains are found by the winding
    count at the crossings of the negative real axis (the limits of every stable interval are among 1/|crossing|);
    None without a stable interval."""
    resp = np.array([complex(G(1j * x)) * np.exp(-1j * x * T) for x in w])
    idx = np.flatnonzero((np.diff(np.sign(resp.imag)) != 0) & (resp.real[:-1] < 0))
    limits = np.unique(1.0 / np.abs(resp[idx]))
    for lo, hi in zip(limits[:-1], limits[1:]):
        K = float(lo * (hi / lo) ** rng.uniform(0.3, 0.7))
        if stable_linear_loop(G, T, K, w):
            return K
    return None


def reference(G, N, c, factors):
    """The orbit a long run from the prediction c settles on: (A, w), or None with the reason. ``factors``: the
    plant's factors (lags, Pade chain, lead), realised each on its own and in series for the run (the companion
    form of the whole product spans 1e11 in its states on a Pade-chain plant, beyond what rtol 1e-12 holds)."""
    if isinstance(N, df.Relay):           # the exact event-located flow, its return map iterated to 1e-13
        out, why = settle(G, N, c.amplitude, c.frequency)
        return (out[0], out[1]) if out else None, why or "settled"
    ss = ct.ss(factors[0])
    for f in factors[1:]:
        ss = ct.series(ss, ct.ss(f))
    factor = SLOW if isinstance(N, df.Backlash) else 1
    if isinstance(N, df.Backlash):
        el = backlash_element(N.h)
    else:
        bp = np.asarray(N.breakpoints(64 * c.amplitude), float)
        el = static_element(lambda x: np.asarray(N.output(np.asarray(x, float)), float),
                            np.unique(np.concatenate([-bp, bp])))
    truth = DelayTruth(ss.A, ss.B, ss.C, G.delay, el)
    try:
        run = truth.run(c.amplitude, c.frequency, settle=SETTLE_PLAY if factor > 1 else SETTLE,
                        max_periods=RUN_PERIODS * factor, max_steps=RUN_STEPS * factor)
    except ValueError as exc:             # scipy's event location (brentq) on a guard met at a step's end
        return None, f"reference failed: {exc}"
    if run.settled and factor > 1:      # slow convergence: the limit of the last 40 periods (tests/delay_truth.py)
        A_lim, w_lim, correction = truth.limit(40)
        return (A_lim, w_lim), f"settled (extrapolated by {correction:.1e})"
    if run.settled:
        return (run.amplitude, run.frequency), "settled"
    if run.reason != "bound":
        return None, run.reason
    return None, f"not settled in {RUN_PERIODS * factor} periods or {RUN_STEPS * factor} steps (change {run.change:.1e})"


def run_loop(G, N, factors):
    df.predict_limit_cycles(G, N)                     # warm-up (the first call loads the compiled solver)
    t0 = time.perf_counter()
    cycles = df.predict_limit_cycles(G, N)
    t_pred = time.perf_counter() - t0
    picks = sorted(cycles, key=lambda c: c.frequency)[:PER_LOOP]
    exacts, t_exact, settled, unsettled, failed, errs = [], [], [], 0, 0, []
    for c in picks:
        t0 = time.perf_counter()
        e = df.exact_cycle(G, N, c)
        t_exact.append(time.perf_counter() - t0)
        exacts.append(e)
        ref, why = reference(G, N, c, factors)
        if ref is not None:
            settled.append(ref)
        elif why.startswith("not settled"):
            unsettled += 1
        elif why.startswith("reference failed"):
            failed += 1
    found = [e for e in exacts if e.success]
    misses = []
    for A, w in settled:
        d = [max(abs(e.amplitude / A - 1), abs(e.frequency / w - 1)) for e in found]
        if d and min(d) < MATCH:
            errs.append(min(d))
        else:
            misses.append((A, w))
    ests = [max(e.extra["error_estimate"]) for e in found if "error_estimate" in e.extra]
    return dict(predicted=len(cycles), checked=len(picks), found=len(found), settled=len(settled), misses=misses,
                unsettled=unsettled, failed=failed, errs=errs, ests=ests, t_pred=t_pred,
                ratio=float(np.mean(t_exact) / t_pred) if t_exact else math.nan)


def main() -> str:
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(SEED)
    rows = ["| # | loop | predicted | exact found / checked | runs settled (not within bound) | max diff A, w | "
            "misses | max error estimate | predict (ms) | exact / predict |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    total = dict(checked=0, found=0, settled=0, misses=0, unsettled=0, failed=0)
    per_kind = {k: [0, 0] for k in ELEMENTS}               # settled runs, misses
    ratios, errs, ests = [], [], []
    t_all = time.perf_counter()
    for k in range(LOOPS):
        G, N, desc, factors = random_loop(rng, k)
        r = run_loop(G, N, factors)
        for key in ("checked", "found", "settled", "unsettled", "failed"):
            total[key] += r[key]
        total["misses"] += len(r["misses"])
        kind = ELEMENTS[k % len(ELEMENTS)]
        per_kind[kind][0] += r["settled"]
        per_kind[kind][1] += len(r["misses"])
        ratios.append(r["ratio"])
        errs += r["errs"]
        ests += r["ests"]
        miss = "; ".join(f"A={a:.6g}, w={w:.6g}" for a, w in r["misses"]) or "0"
        rows.append(f"| {k} | {desc} | {r['predicted']} | {r['found']}/{r['checked']} | {r['settled']} "
                    f"({r['unsettled']}) | {max(r['errs']):.1e} |" if r["errs"] else
                    f"| {k} | {desc} | {r['predicted']} | {r['found']}/{r['checked']} | {r['settled']} "
                    f"({r['unsettled']}) | - |")
        rows[-1] += (f" {miss} | {max(r['ests']):.1e} |" if r["ests"] else f" {miss} | - |") + \
            f" {1e3 * r['t_pred']:.0f} | {r['ratio']:.2f} |"
        print(rows[-1], flush=True)
    ratios = np.array([x for x in ratios if math.isfinite(x)])
    kinds = ", ".join(f"{k} {v[0]} ({v[1]} missed)" for k, v in per_kind.items())
    head = [f"Sample: {LOOPS} random delayed loops (seed {SEED}; order 2-12 with Pade chains, delay (0, 5] dominant "
            f"time constants; saturation, dead zone, backlash, relay in turn), at most {PER_LOOP} predictions each. "
            "Gains: saturation and relay 2-6 times the critical gain; backlash 0.85-0.98 of it around a plant with "
            "an integrator; dead zone in the conditionally stable range of (s + z)^2 / s^3 times the lags (so that "
            "their cycles can attract).",
            "",
            "Reference runs from each prediction, independent of exact_cycle: relays on the exact event-located "
            "flow (the return map iterated until the state changes by < 1e-13, bench_delay_exact.py); the others "
            f"by tests/delay_truth.py (DOP853, rtol 1e-12, exact delay buffer of dense outputs, element switches as "
            f"events) until successive periods agree to {SETTLE:g}, at most {RUN_PERIODS} periods and {RUN_STEPS} steps (backlash: {SLOW} times that, settled at {SETTLE_PLAY:g}, the "
            "floor of the reference with the play's switch events, then extrapolated to the limit of its last 40 "
            "periods, fitted by L + c r^k: a cycle that attracts at r ~ 0.94 per period is still 15 changes short "
            "of its limit when successive periods agree).",
            "",
            f"- predictions checked: {total['checked']}; exact orbits found near them: {total['found']}",
            f"- reference runs that settled on an oscillation: {total['settled']} ({kinds}); not settled within the "
            f"bound: {total['unsettled']}; reference runs that failed (scipy's event location): {total['failed']}; the "
            "others went to rest or diverged",
            f"- found by exact_cycle to {MATCH:g} in A and w: {total['settled'] - total['misses']}; "
            f"**misses: {total['misses']}**; largest difference {max(errs) if errs else math.nan:.1e}",
            f"- exact_cycle's error estimates (delay equation loops): largest {max(ests) if ests else math.nan:.1e}",
            f"- time of one exact_cycle / time of predict_limit_cycles: median {np.median(ratios):.2f}, max "
            f"{np.max(ratios):.2f}",
            f"- whole sample: {time.perf_counter() - t_all:.1f} s", ""]
    return "\n".join(head + rows) + "\n"


if __name__ == "__main__":
    text = main()
    print(text)
    if "--write" in sys.argv:
        out = pathlib.Path(__file__).parent / "results" / "bench_delay_elements.md"
        env = f"BENCH_LOOPS={LOOPS} " if LOOPS != 32 else ""
        out.write_text("# Delayed loops with every piecewise-linear element: randomized sample\n\nCommand: "
                       f"`{env}python benchmarks/bench_delay_elements.py --write`\n\n" + text)
