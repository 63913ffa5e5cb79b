"""Digital loops: the error of the describing-function prediction next to its time, and the exact methods' time.

For each sampled-data loop (a continuous plant behind a zero-order hold with a relay or a quantizer, a digital
filter loop with a quantizer, a saturated loop) the table gives the DF prediction of the stable cycle
(:func:`dfloop.predict_limit_cycles` on G(e^{jw dt})), its time, the exact orbit of the map
(:func:`dfloop.exact_cycle`, which runs the map from the prediction and solves the periodic equations of the
output sequence, or shoots on the P-fold map) with its time, the DF's relative errors, the samples per period and
the phase spread of the sampled DF that the confidence reports. A second table times the exhaustive enumeration
(:func:`dfloop.hybrid.discrete.discrete_orbits`) of every orbit of period <= P_max, with the nodes it examined and
whether it completed within its work bound; the quantizer rows run both searches (``method``: "lattice", the
default for a quantizer, and "intervals", the level-by-level search with a bound on |x|).

Run: python benchmarks/bench_digital.py [--write]   (--write also writes benchmarks/results/bench_digital.md)
"""
from __future__ import annotations

import pathlib
import sys
import time

import control as ct

import dfloop as df
from dfloop.hybrid.discrete import discrete_orbits

ZOH3 = ct.tf([1.0], [1.0, 3.0, 3.0, 1.0])
LOOPS = [  # (name, G, N, amplitude window or None)
    ("relay dz 0.05, 1/(s+1)^3 ZOH dt=0.2", ct.sample_system(ZOH3, 0.2), df.Relay(1.0, dead_zone=0.05), None),
    ("relay dz 0.05, 1/(s+1)^3 ZOH dt=0.05", ct.sample_system(ZOH3, 0.05), df.Relay(1.0, dead_zone=0.05), None),
    ("quantizer 0.05, 5.6/(s+1)^3 ZOH dt=0.2", 5.6 * ct.sample_system(ZOH3, 0.2), df.Quantizer(0.05), (0.026, 1.0)),
    ("quantizer 0.05, 5.6/(s+1)^3 ZOH dt=0.1", 5.6 * ct.sample_system(ZOH3, 0.1), df.Quantizer(0.05), (0.026, 1.0)),
    ("saturation 1, 1.5/(z^2+0.3)", ct.tf([1.5], [1.0, 0.0, 0.3], 1.0), df.Saturation(1.0), None),
]
ENUMERATIONS = [  # (name, G, N, max_period, bound)
    ("rounding, -0.85/z (first order)", ct.tf([0.85], [1.0, 0.0], 1.0), df.Quantizer(1.0), 20, 20.0),
    ("quantizer 1, (0.9z+0.3)/(z^2-0.2z+0.45)", ct.tf([0.9, 0.3], [1.0, -0.2, 0.45], 1.0), df.Quantizer(1.0), 10, 4.0),
    ("relay, z^-5 (pure delay)", ct.tf([1.0], [1, 0, 0, 0, 0, 0], 1.0), df.Relay(1.0, dead_zone=0.5), 10, None),
    ("relay dz 0.05, 1/(s+1)^3 ZOH dt=0.2", ct.sample_system(ZOH3, 0.2), df.Relay(1.0, dead_zone=0.05), 12, None),
]
LATTICE = [  # (name, G, step, periods, bound of the interval search): slow plants sampled fast
    ("quantizer 0.05, 5.6/(s+1)^3 ZOH dt=0.6", 5.6 * ct.sample_system(ZOH3, 0.6), 0.05, range(1, 10), 0.3),
    ("quantizer 0.05, 5.6/(s+1)^3 ZOH dt=0.2", 5.6 * ct.sample_system(ZOH3, 0.2), 0.05, range(1, 17), 0.15),
    ("quantizer 0.05, 5.6/(s+1)^3 ZOH dt=0.2", 5.6 * ct.sample_system(ZOH3, 0.2), 0.05, [18, 19, 20], 0.15),
]


def _timed(f):
    t0 = time.perf_counter()
    out = f()
    return out, time.perf_counter() - t0


def main(argv: list[str]) -> str:
    lines = ["# Digital loops: DF error vs time, exact orbits", "",
             "Command: `python benchmarks/bench_digital.py --write`", "",
             "| loop | DF A | DF w [rad/s] | DF time [s] | exact A | exact w [rad/s] | samples/period | exact time [s] "
             "| DF error A | DF error w | sampled-DF spread |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    df.predict_limit_cycles(*LOOPS[0][1:3])    # warm-up (imports, JIT)
    for name, G, N, amp in LOOPS:
        cycles, t_df = _timed(lambda: df.predict_limit_cycles(G, N, amplitude=amp))
        stable = [c for c in cycles if c.stability == "stable"]
        if not stable:
            lines.append(f"| {name} | (no stable cycle predicted) | | {t_df:.3f} | | | | | | | |")
            continue
        c = stable[0]
        ex, t_ex = _timed(lambda: df.exact_cycle(G, N, c))
        conf = c.confidence
        if not ex.success:
            lines.append(f"| {name} | {c.amplitude:.5g} | {c.frequency:.5g} | {t_df:.3f} | not found | | | {t_ex:.3f} "
                         f"| | | {conf.sampled_spread:.3g} |")
            continue
        lines.append(f"| {name} | {c.amplitude:.5g} | {c.frequency:.5g} | {t_df:.3f} | {ex.amplitude:.5g} | "
                     f"{ex.frequency:.5g} | {ex.extra['samples_per_period']} | {t_ex:.3f} | "
                     f"{100 * ex.amplitude_error:+.2f} % | {100 * ex.frequency_error:+.2f} % | "
                     f"{100 * conf.sampled_spread:.3g} % |")
    lines += ["", "| enumeration | P_max | bound | orbits | oscillating | nodes | complete | time [s] |",
              "|---|---|---|---|---|---|---|---|"]
    for name, G, N, P_max, bound in ENUMERATIONS:
        res, t = _timed(lambda: discrete_orbits(G, N, max_period=P_max, bound=bound))
        lines.append(f"| {name} | {P_max} | {bound if bound is not None else 'all levels'} | {len(res)} | "
                     f"{len(res.oscillating())} | {res.nodes} | {'yes' if res.complete else 'no (' + res.message[:60] + '...)'} "
                     f"| {t:.3f} |")
    lines += ["", "| quantizer loop | periods | method | orbits | oscillating | nodes or LPs | complete | time [s] |",
              "|---|---|---|---|---|---|---|---|"]
    for name, G, step, periods, bound in LATTICE:
        for method, b in (("lattice", None), ("intervals", bound)):
            res, t = _timed(lambda: discrete_orbits(G, df.Quantizer(step), max_period=max(periods), periods=periods,
                                                    bound=b, method=method))
            span = f"{min(periods)}..{max(periods)}"
            lines.append(f"| {name} | {span} | {method}{'' if b is None else f' (bound {b:g})'} | {len(res)} | "
                         f"{len(res.oscillating())} | {res.nodes} | {'yes' if res.complete else 'no'} | {t:.2f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if "--write" in argv:
        out = pathlib.Path(__file__).resolve().parent / "results" / "bench_digital.md"
        out.write_text(text)
        print("wrote", out)
    return text


if __name__ == "__main__":
    main(sys.argv[1:])
