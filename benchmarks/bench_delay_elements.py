"""exact_cycle on delayed loops with every kind of piecewise-linear element, plants of order 2-12 (issue 16).

Sample: ``LOOPS`` loops, seeded. Plant: real poles and damped pairs (natural frequencies 0.2-5 rad/s, an
integrator in one loop of four) times, in one loop of two, a Pade chain of order 2-6 (a second delay made
rational), so the order is 2-12; a pure delay uniform in (0, 5] dominant time constants; the element one of
saturation, dead zone, backlash (an element with memory), relay with hysteresis and dead zone, in turn; gain so
that the DF predicts a cycle.

For each loop: ``predict_limit_cycles`` (timed), then for each prediction (at most ``PER_LOOP``, slowest first)
``exact_cycle`` (timed, the public call) and a long run from the prediction (``simulate_loop``: the exact delay
flow for the relay, the method of steps of the delay equation for the others, ``RUN_PERIODS`` periods at
``STEPS`` steps per period), measured over its last 10 periods. A settled run (periodicity < 1e-6, amplitude above
1e-6 of the start: not at rest) is *found*
when an exact_cycle result of the loop equals it to ``MATCH`` in A and w (the run's own measure - linear
interpolation of crossings at ``STEPS`` samples per period - and the delay equation's discretisation limit the
agreement to about 1e-6; the relay's exact flow would give 1e-8, see bench_delay_exact.py); a *miss* is a settled
run no exact result matches.

Run: python benchmarks/bench_delay_elements.py [--write]   (--write writes benchmarks/results/bench_delay_elements.md)
"""
from __future__ import annotations

import math
import pathlib
import sys
import time
import warnings

import control as ct
import numpy as np

import dfloop as df
from dfloop.harmonics import steady_state
from dfloop.solve.delay import delayed
from dfloop.verify import simulate_loop

LOOPS = int(__import__("os").environ.get("BENCH_LOOPS", 32))
PER_LOOP = 2
RUN_PERIODS = 150
STEPS = 512
MATCH = 2e-5
SEED = 16
ELEMENTS = ("saturation", "dead zone", "backlash", "relay")


def random_loop(rng, k: int):
    n = int(rng.integers(2, 7))
    poles = [0.0] if rng.random() < 0.25 else []
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
    pade = 0
    if rng.random() < 0.5:
        pade = int(rng.integers(2, 7))
        G = G * ct.tf(*ct.pade(float(rng.uniform(0.05, 0.5)) / slow, pade))
    T = float(rng.uniform(0.05, 5.0)) / slow
    kind = ELEMENTS[k % len(ELEMENTS)]
    N = {"saturation": df.Saturation(1.0), "dead zone": df.DeadZone(0.3), "backlash": df.Backlash(h=0.5),
         "relay": df.Relay(1.0, hysteresis=float(rng.uniform(0, 0.1)), dead_zone=float(rng.uniform(0, 0.1)))}[kind]
    # gain: the loop gain at the phase crossover of G e^{-sT} times a margin above the element's threshold
    w = np.logspace(-3, 2, 4000) * slow
    resp = np.array([complex(G(1j * x)) * np.exp(-1j * x * T) for x in w])
    phase = np.unwrap(np.angle(resp))
    idx = np.flatnonzero(np.diff(np.sign(phase + np.pi)))
    mag = abs(resp[idx[0]]) if idx.size else abs(resp[0])
    K = float(rng.uniform(2.0, 6.0)) / mag
    desc = f"n={len(poles) + pade} ({'pade ' + str(pade) if pade else 'no pade'}), T={T * slow:.2f} tau, {kind}"
    return delayed(K * G, T), N, desc


def run_loop(G, N):
    t0 = time.perf_counter()
    cycles = df.predict_limit_cycles(G, N)
    t_pred = time.perf_counter() - t0
    picks = sorted(cycles, key=lambda c: c.frequency)[:PER_LOOP]
    exacts, t_exact, settled = [], [], []
    for c in picks:
        t0 = time.perf_counter()
        e = df.exact_cycle(G, N, c)
        t_exact.append(time.perf_counter() - t0)
        exacts.append(e)
        try:
            sim = simulate_loop(G, N, c.amplitude, c.frequency, periods=RUN_PERIODS, steps_per_period=STEPS)
        except (RuntimeError, ValueError):
            continue
        if sim.diverged:
            continue
        st = steady_state(sim.t, sim.x, 10)
        if st.oscillating and st.periodicity < 1e-6 and st.amplitude > 1e-6 * c.amplitude:   # not rest
            settled.append((st.amplitude, st.frequency))
    found = [e for e in exacts if e.success]
    misses = [s for s in settled if not any(abs(e.amplitude / s[0] - 1) < MATCH and abs(e.frequency / s[1] - 1) < MATCH
                                            for e in found)]
    return dict(predicted=len(cycles), checked=len(picks), found=len(found), settled=len(settled), misses=misses,
                t_pred=t_pred, ratio=float(np.mean(t_exact) / t_pred) if t_exact else math.nan)


def main() -> str:
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(SEED)
    rows = ["| # | loop | predicted | exact found / checked | runs settled | misses | predict (ms) | exact / predict |",
            "|---|---|---|---|---|---|---|---|"]
    total = dict(checked=0, found=0, settled=0, misses=0)
    ratios = []
    t_all = time.perf_counter()
    for k in range(LOOPS):
        G, N, desc = random_loop(rng, k)
        r = run_loop(G, N)
        for key in ("checked", "found", "settled"):
            total[key] += r[key]
        total["misses"] += len(r["misses"])
        ratios.append(r["ratio"])
        miss = "; ".join(f"A={a:.6g}, w={w:.6g}" for a, w in r["misses"]) or "0"
        rows.append(f"| {k} | {desc} | {r['predicted']} | {r['found']}/{r['checked']} | {r['settled']} | {miss} | "
                    f"{1e3 * r['t_pred']:.0f} | {r['ratio']:.2f} |")
        print(rows[-1], flush=True)
    ratios = np.array([x for x in ratios if math.isfinite(x)])
    head = [f"Sample: {LOOPS} random delayed loops (seed {SEED}; order 2-12 with Pade chains, delay (0, 5] dominant "
            f"time constants; saturation, dead zone, backlash, relay in turn), at most {PER_LOOP} predictions each.",
            "",
            f"- predictions checked: {total['checked']}; exact orbits found near them: {total['found']}",
            f"- long runs from the predictions that settled (periodicity < 1e-6): {total['settled']}; found by "
            f"exact_cycle to {MATCH:g} in A and w: {total['settled'] - total['misses']}; **misses: {total['misses']}**",
            f"- time of one exact_cycle / time of predict_limit_cycles: median {np.median(ratios):.2f}, max "
            f"{np.max(ratios):.2f}",
            f"- whole sample: {time.perf_counter() - t_all:.1f} s", ""]
    return "\n".join(head + rows) + "\n"


if __name__ == "__main__":
    text = main()
    print(text)
    if "--write" in sys.argv:
        out = pathlib.Path(__file__).parent / "results" / "bench_delay_elements.md"
        out.write_text("# Delayed loops with every piecewise-linear element: randomized sample\n\nCommand: "
                       "`python benchmarks/bench_delay_elements.py --write`\n\n" + text)
