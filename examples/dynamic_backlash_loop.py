"""A PD-controlled two-mass drive with dynamic backlash: predict its limit cycle, then verify it in time.

Loop (DESIGN.md Fig. 1): the force on M2 is u = -C(s) x1, where x1 is the load position (M1) and
C(s) = (Kp + Kd s) / (tau s + 1)^2 is a PD controller with a second-order roll-off. Seen from the
element (force -> x1) the rest of the loop is G = C. The dynamic backlash (M1 = M2 = 1 kg, h = 0.1 m,
eps = 0.5) is a tabulated DF N(F, w); the gains are chosen so that G(j w0) = -1/N(F0, w0) at a point of
the regular (period-1) band, and the solver must find that cycle and its stability on its own.

Verification: a closed-loop time simulation of the masses, impacts (eqs. 8a/8b) and controller
(scipy ``solve_ivp`` restarted at each impact), measuring the frequency and the force amplitude of the
fundamental in steady state.

Run:  python examples/dynamic_backlash_loop.py
"""
from __future__ import annotations

import math
import time

import control as ct
import numpy as np
from scipy.integrate import solve_ivp

from dfloop.impact.dynamic_backlash import DynamicBacklash
from dfloop.solve import predict_limit_cycles

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


def closed_loop(G: ct.TransferFunction, periods: float, max_impacts: int = 200_000):
    """Closed-loop simulation from a small kick; returns times, x1 and u = -G x1 on a uniform grid."""
    ss = ct.ss(G)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    nc = A.shape[0]

    def rhs(t, z):
        x1, v1, x2, v2, c = z[0], z[1], z[2], z[3], z[4:]
        u = -(C @ c + D[:, 0] * x1)[0]
        return np.concatenate([[v1, 0.0, v2, u / M2], A @ c + B[:, 0] * x1])

    def side_a(t, z):                   # gap x2 - x1 = 0
        return z[2] - z[0]

    def side_b(t, z):                   # gap = h
        return z[2] - z[0] - H

    side_a.terminal = side_b.terminal = True
    side_a.direction, side_b.direction = -1, 1
    t_end = periods * 2 * math.pi / W0
    z = np.zeros(4 + nc)
    z[2] = 0.5 * H                       # centred gap
    z[1] = 0.3                           # a kick on the load starts the oscillation
    t, ts, zs, impacts = 0.0, [], [], 0
    while t < t_end:
        sol = solve_ivp(rhs, (t, t_end), z, events=(side_a, side_b), rtol=1e-10, atol=1e-12,
                        max_step=0.02 / W0 * 2 * math.pi, dense_output=False)
        ts.append(sol.t)
        zs.append(sol.y)
        t, z = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            break
        impacts += 1
        if impacts > max_impacts:
            raise RuntimeError(f"max_impacts = {max_impacts} reached at t = {t:.4g} s")
        v1, v2 = z[1], z[3]
        z[1] = (v1 * (M1 - EPS * M2) + v2 * (1 + EPS) * M2) / (M1 + M2)
        z[3] = (v1 * (1 + EPS) * M1 + v2 * (M2 - EPS * M1)) / (M1 + M2)
        z[2] = z[0] + (0.0 if sol.t_events[0].size else H)
    t = np.concatenate(ts)
    y = np.concatenate(zs, axis=1)
    grid = np.linspace(t[0], t[-1], 200_000)
    x1 = np.interp(grid, t, y[0])
    c = np.array([np.interp(grid, t, y[4 + k]) for k in range(nc)])
    u = -(C @ c + D[:, 0:1] * x1)[0]
    return grid, x1, u, impacts


def fundamental(t, s, tail: float = 0.5):
    """Frequency (rad/s) and amplitude of the fundamental of s over the last ``tail`` of the run."""
    keep = t >= t[0] + (1 - tail) * (t[-1] - t[0])
    t, s = t[keep], s[keep] - s[keep].mean()
    up = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    tc = t[up] - s[up] * (t[up + 1] - t[up]) / (s[up + 1] - s[up])
    w = 2 * math.pi * (len(tc) - 1) / (tc[-1] - tc[0])
    m = (t >= tc[0]) & (t <= tc[-1])
    dt = np.gradient(t[m])
    a = 2 / (tc[-1] - tc[0]) * np.sum(s[m] * np.exp(-1j * w * t[m]) * dt)
    return w, abs(a)


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
    t0 = time.perf_counter()
    t, x1, u, impacts = closed_loop(G, periods=400)
    w_sim, f_sim = fundamental(t, u)
    print(f"closed-loop simulation ({impacts} impacts, {time.perf_counter() - t0:.1f} s): "
          f"omega = {w_sim:.3f} rad/s, force fundamental = {f_sim:.3f} N")
    for c in cycles:
        print(f"  DF prediction vs simulation: omega {c.frequency:.3f} vs {w_sim:.3f} rad/s "
              f"({100 * (w_sim / c.frequency - 1):+.2f} %), F {c.amplitude:.3f} vs {f_sim:.3f} N "
              f"({100 * (f_sim / c.amplitude - 1):+.2f} %)")


if __name__ == "__main__":
    main()
