"""The exact delay engine on a randomized sample of delayed relay loops (issue 16).

Sample: ``LOOPS`` loops, seeded. Plant of order 2-8 (real poles and lightly to well damped pairs, natural
frequencies 0.2-5 rad/s, an integrator in one loop of four), gain so that the loop oscillates; pure delay
uniform in (0, 5] dominant time constants (1 / the slowest pole's modulus); a relay with M in [0.5, 2],
hysteresis in [0, 0.2] and dead zone in [0, 0.2] (each zero in one loop of three).

For each loop: ``predict_limit_cycles`` (timed) over omega in [0.02, 20] / the dominant time constant, then for
every predicted cycle (at most ``PER_LOOP`` of them, the slowest first):

- ``exact_cycle`` from the prediction (timed; the public call, with its globalisation);
- a long event-located simulation from the prediction, independent of Newton: the return map to the switch
  into +M iterated up to ``MAX_RETURNS`` times, stopping when the state (plant state and pending switch
  instants) changes by less than 1e-13 (relative) between returns; the settled orbit's frequency is
  2 pi / (return time) and its amplitude the exact fundamental of x over the last return (block exponentials).

A settled orbit is *found* when one of the loop's exact_cycle results (from any of its predictions) equals it to
1e-8 in A and w; a *miss* is a settled orbit no exact_cycle result matches. Each exact orbit's stability
verdict is checked against runs started 1e-3 (relative) off it: a stable orbit must attract (distance halved
within 30 returns, or 30 + 3 / |ln mu| returns when the largest non-trivial multiplier mu is within 10 % of 1), an
unstable one repel (distance doubled, or the switching pattern left).

Run: python benchmarks/bench_delay_exact.py [--write]   (--write writes benchmarks/results/bench_delay_exact.md)
"""
from __future__ import annotations

import math
import pathlib
import sys
import time

import control as ct
import numpy as np

import dfloop as df
from dfloop.hybrid import loop_model
from dfloop.hybrid.delay import DelayError, predicted_start, return_map
from dfloop.solve.delay import delayed

LOOPS = int(__import__("os").environ.get("BENCH_LOOPS", 40))
PER_LOOP = 4
MAX_RETURNS = 3000
SEED = 2026


def random_loop(rng):
    """(G delayed, relay, dominant time constant, description)."""
    n = int(rng.integers(2, 9))
    poles = []
    integrator = rng.random() < 0.25
    if integrator:
        poles.append(0.0)
    while len(poles) < n:
        wn = 10 ** rng.uniform(np.log10(0.2), np.log10(5.0))
        if len(poles) <= n - 2 and rng.random() < 0.4:
            z = rng.uniform(0.1, 0.9)
            poles += [-z * wn + 1j * wn * math.sqrt(1 - z * z), -z * wn - 1j * wn * math.sqrt(1 - z * z)]
        else:
            poles.append(-wn)
    poles = np.array(poles)
    nonzero = np.abs(poles[poles != 0])
    tau = 1.0 / nonzero.min()
    k = float(np.prod(nonzero)) * rng.uniform(1.0, 5.0)     # unit dc gain (per integrator, 1 / s) times 1-5
    G = ct.zpk([], poles, k)
    L = rng.uniform(0.0, 5.0) * tau
    L = max(L, 1e-3 * tau)
    M = rng.uniform(0.5, 2.0)
    hyst = 0.0 if rng.random() < 1 / 3 else rng.uniform(0.0, 0.2)
    dz = 0.0 if rng.random() < 1 / 3 else rng.uniform(0.0, 0.2)
    N = df.Relay(M=M, hysteresis=hyst, dead_zone=dz)
    desc = (f"n={n}{' (integrator)' if integrator else ''}, L={L / tau:.2f} tau, M={M:.2f}, hyst={hyst:.3f}, "
            f"dz={dz:.3f}")
    return delayed(G, L), N, tau, desc


def settle(G, N, A, w):
    """The orbit a long event-located run from the prediction settles on: (A, w, state) or (None, reason)."""
    loop = loop_model(G, N, A, w)
    try:
        s, mode, u, queue, section = predicted_start(loop, A, w)
    except DelayError as exc:
        return None, str(exc)
    horizon = 40 * 2 * math.pi / w + 2 * loop.delay
    prev = None
    for k in range(MAX_RETURNS):
        try:
            out = return_map(loop, s, mode, u, queue, section, horizon=horizon, tangent=False)
        except DelayError as exc:
            return None, str(exc)
        if out is None:
            return None, "no return (rest or no switching)"
        s1, u1, q1, t1, _, fl = out
        if np.max(np.abs(loop.x(s1))) > 1e8 * A:
            return None, "divergence"
        v1 = np.concatenate([s1, [q[0] for q in q1], [t1]])
        if prev is not None and prev.size == v1.size and np.linalg.norm(v1 - prev) <= 1e-13 * (
                np.linalg.norm(s1) + t1):
            X1 = 2j * loop.fourier(fl, t1, 2 * math.pi / t1, 1)[0]
            return (abs(X1), 2 * math.pi / t1, (s1, mode, u1, q1, section)), ""
        prev = v1
        s, u, queue = s1, u1, q1
    return None, f"not settled within {MAX_RETURNS} returns"


def verdict_agrees(G, N, e) -> bool | None:
    """Stable orbits attract runs started 1e-3 off, unstable ones repel them (return-map runs)."""
    ex = e.extra
    loop = loop_model(G, N, e.amplitude, e.frequency)
    s0, q0 = ex["s0"], [list(q) for q in ex["queue0"]]
    rng = np.random.default_rng(0)
    d = rng.standard_normal(s0.size)
    d *= 1e-3 * np.linalg.norm(s0) / np.linalg.norm(d)
    s, queue, u = s0 + d, [list(q) for q in q0], ex["u0"]
    d0 = np.linalg.norm(d)
    mu = e.largest_multiplier
    returns = 30 if mu == 0 or abs(math.log(mu)) > 0.1 else min(3000, 30 + int(3.0 / abs(math.log(mu))))
    for _ in range(returns):
        try:
            out = return_map(loop, s, ex["mode0"], u, queue, ex["section"], horizon=50 * e.period + 2 * loop.delay,
                             tangent=False)
        except DelayError:
            return not e.stable
        if out is None or len(out[2]) != len(q0) or out[1] != ex["u0"]:
            return not e.stable          # the run left the orbit's switching pattern
        s, u, queue = out[0], out[1], out[2]
        dist = np.linalg.norm(s - s0) + sum(abs(a[0] - b[0]) for a, b in zip(queue, q0)) * np.linalg.norm(s0)
        if e.stable and dist < 0.5 * d0:
            return True
        if not e.stable and dist > 2 * d0:
            return True
    return False


def run_sample(loops: int = LOOPS, seed: int = SEED, per_loop: int = PER_LOOP):
    rng = np.random.default_rng(seed)
    rows, stats = [], dict(loops=0, predicted=0, exact=0, settled=0, found=0, misses=0, verdicts=0, agree=0,
                           ratios=[])
    for i in range(loops):
        G, N, tau, desc = random_loop(rng)
        t0 = time.perf_counter()
        cycles = df.predict_limit_cycles(G, N, omega=(0.02 / tau, 20.0 / tau))
        t_pred = time.perf_counter() - t0
        stats["loops"] += 1
        chosen = sorted(cycles, key=lambda c: c.frequency)[:per_loop]
        stats["predicted"] += len(chosen)
        results, t_exact = [], 0.0
        for c in chosen:
            t0 = time.perf_counter()
            e = df.exact_cycle(G, N, c)
            t_exact += time.perf_counter() - t0
            results.append(e)
            if e.success:
                stats["exact"] += 1
                ok = verdict_agrees(G, N, e)
                stats["verdicts"] += 1
                stats["agree"] += bool(ok)
        if chosen:
            stats["ratios"].append(t_exact / len(chosen) / t_pred)
        settled_here, missed_here = 0, 0
        for c in chosen:
            orbit, why = settle(G, N, c.amplitude, c.frequency)
            if orbit is None:
                continue
            A, w, _ = orbit
            stats["settled"] += 1
            settled_here += 1
            match = any(e.success and abs(e.amplitude / A - 1) <= 1e-8 and abs(e.frequency / w - 1) <= 1e-8
                        for e in results)
            stats["found" if match else "misses"] += 1
            missed_here += not match
        rows.append(f"| {i} | {desc} | {len(cycles)} | {sum(e.success for e in results)}/{len(chosen)} | "
                    f"{settled_here} | {missed_here} | {1e3 * t_pred:.0f} | "
                    f"{(t_exact / max(len(chosen), 1)) / t_pred:.2f} |")
    return rows, stats


def main() -> str:
    df.predict_limit_cycles(delayed(ct.tf([1], [1, 1]), 0.5), df.Relay(1.0), omega=(0.1, 10))   # warm-up
    t0 = time.perf_counter()
    rows, st = run_sample()
    total = time.perf_counter() - t0
    r = np.array(st["ratios"])
    head = [
        f"Sample: {st['loops']} random delayed relay loops (seed {SEED}; order 2-8, delay (0, 5] dominant time "
        f"constants, relays with hysteresis / dead zone), at most {PER_LOOP} predictions each (slowest first).",
        "",
        f"- predictions checked: {st['predicted']}; exact orbits found near them: {st['exact']}",
        f"- long event-located runs that settled on an orbit: {st['settled']}; found by exact_cycle to 1e-8 in A "
        f"and w: {st['found']}; **misses: {st['misses']}**",
        f"- stability verdicts checked by runs started 1e-3 off the orbit: {st['verdicts']}; agreeing: {st['agree']}",
        f"- time of one exact_cycle / time of predict_limit_cycles on the same loop: median {np.median(r):.2f}, "
        f"max {r.max():.2f} (per loop: mean over its predictions)",
        f"- whole sample: {total:.1f} s",
        "",
        "| # | loop | predicted | exact found | runs settled | misses | predict (ms) | exact / predict |",
        "|---|---|---|---|---|---|---|---|",
    ]
    return "\n".join(head + rows) + "\n"


if __name__ == "__main__":
    text = main()
    print(text)
    if "--write" in sys.argv:
        out = pathlib.Path(__file__).parent / "results" / "bench_delay_exact.md"
        out.write_text("# Exact delay engine: randomized sample\n\nCommand: `python benchmarks/bench_delay_exact.py "
                       "--write`\n\n" + text)
