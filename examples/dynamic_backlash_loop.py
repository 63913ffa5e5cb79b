"""A PD-controlled two-mass drive with dynamic backlash: predict its limit cycle, then verify it in time.

Loop (the paper's Fig. 1): the force on M2 is u = -C(s) x1, where x1 is the load position (M1) and
C(s) = (Kp + Kd s) / (tau s + 1)^2 is a PD controller with a second-order roll-off. Seen from the
element (force -> x1) the rest of the loop is G = C. The dynamic backlash (M1 = M2 = 1 kg, h = 0.1 m,
eps = 0.5) is a tabulated DF N(F, w); the gains are chosen so that G(j w0) = -1/N(F0, w0) at a point of
the regular (period-1) band, and the solver must find that cycle and its stability on its own.

Verification: ``verify_cycle`` runs a closed-loop time simulation of the masses, impacts (eqs. 8a/8b) and
controller (:func:`dfloop.verify.simulate_loop` on the exact impact engine, events located to rounding) from 10 %
inside and outside the predicted force amplitude, and measures the steady frequency and force amplitude.

Run:  python examples/dynamic_backlash_loop.py
"""
from __future__ import annotations

import math
import time

import control as ct

from dfloop.impact.dynamic_backlash import DynamicBacklash
from dfloop.solve import predict_limit_cycles
from dfloop.verify import verify_cycle

M1, M2, H, EPS = 1.0, 1.0, 0.1, 0.5
W0, BETA0 = 31.5, 0.32                   # design point: inside the period-1 band 1/4 < beta < 0.375
TAU = 1.0 / (3.0 * W0)                   # roll-off at three times the cycle frequency
F_MAX = 60.0                             # largest force amplitude searched (N)


def design(nl: DynamicBacklash) -> ct.TransferFunction:
    """PD gains putting G(j W0) on -1/N(F0, W0) with F0 = BETA0 M2 h W0^2."""
    f0 = BETA0 * M2 * H * W0 ** 2
    target = complex(nl.negative_inverse(f0, W0))
    pd = target * (1j * W0 * TAU + 1) ** 2          # Kp + j W0 Kd
    kp, kd = pd.real, pd.imag / W0
    if kp <= 0 or kd <= 0:
        raise RuntimeError("design point needs positive PD gains")
    return ct.tf([kd, kp], [TAU ** 2, 2 * TAU, 1])


def main() -> None:
    nl = DynamicBacklash(M1, M2, H, EPS, progress=True)
    G = design(nl)
    print("controller seen by the element: G(s) =", G)
    t0 = time.perf_counter()
    # a natural window: forces 5..60 N, frequencies from 5 rad/s up to the no-impact limit w_L of the
    # largest force; it contains the N = 0 region (w > w_L(F)) and every regime jump of the table
    omega = (5.0, 2.0 * math.sqrt(F_MAX / (H * M2)))
    cycles = predict_limit_cycles(G, nl, omega=omega, amplitude=(5.0, F_MAX))
    print(f"prediction took {time.perf_counter() - t0:.2f} s; {len(cycles)} cycle(s), "
          f"{len(cycles.jump_crossings)} jump crossing(s)")
    print(cycles)
    for c in cycles:
        print(" ", c, f"valid={c.valid}, N error estimate={c.n_error:.2e}")
    for c in cycles:
        t0 = time.perf_counter()
        check = verify_cycle(G, nl, c, perturbation=0.1)   # masses, impacts and controller in time
        print(f"closed-loop simulation ({time.perf_counter() - t0:.1f} s): {check}")
        sim = check.inside
        print(f"  DF prediction vs simulation: omega {c.frequency:.3f} vs {sim.frequency:.3f} rad/s "
              f"({100 * (sim.frequency / c.frequency - 1):+.2f} %), F {c.amplitude:.3f} vs {sim.amplitude:.3f} N "
              f"({100 * (sim.amplitude / c.amplitude - 1):+.2f} %)")

if __name__ == "__main__":
    main()
