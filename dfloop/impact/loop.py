"""Closed-loop time simulation of the paper's two-mass impact element inside a feedback loop.

Loop of the paper's Fig. 1: the element's input is the force on M2, x = -c, its output is x1, and the linear
part closes the loop, c = G x1. The masses move freely between impacts (plus the force on M2), impacts follow
eqs. (8a)/(8b), and the plant's state integrates alongside; ``solve_ivp`` (rtol 1e-10) is restarted at every
impact found by its terminal events. This is an independent check of a DF prediction, not the exact kernel:
the force is not sinusoidal here, so the kernel's closed-form flights do not apply. Chattering loops (small
eps, sticking) make it restart without end and hit ``max_impacts``, which raises.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["simulate_impact_loop"]


def _plant_matrices(G):
    import control as ct

    from ..solve.plant import as_plant

    lti = as_plant(G).lti
    if lti is None or isinstance(lti, ct.FrequencyResponseData):
        raise ValueError("G must be a python-control tf or ss system for time-domain verification")
    sys = ct.ss(lti)
    return tuple(np.asarray(m, float) for m in (sys.A, sys.B[:, 0], sys.C[0], sys.D[0, 0]))


def simulate_impact_loop(G, element, amplitude: float, frequency: float, *, periods: float = 80,
                         steps_per_period: int = 400, max_impacts: int = 200_000):
    """Simulate the loop around a :class:`~dfloop.impact.dynamic_backlash.DynamicBacklash` element.

    Parameters
    ----------
    G : python-control tf or ss
        The rest of the loop, from x1 (m) to c (N); the force on M2 is -c.
    element : DynamicBacklash
        The paper's model (no effects): masses, clearance and restitution are taken from it.
    amplitude, frequency : float
        Force amplitude (N) and frequency (rad/s) of the cycle to start from: the plant starts in the state
        it would have if the force were exactly ``amplitude`` sin(``frequency`` t) and x1 had the DF's
        fundamental; the masses start at rest with the gap centred (the model's initial state).
    periods, steps_per_period : float, int
        Length of the run in periods of ``frequency`` and the uniform sampling of the returned signals.
    max_impacts : int
        Bound on the number of impacts (restarts); reaching it raises RuntimeError.

    Returns
    -------
    dfloop.verify.LoopSimulation
        Uniform samples of the element input x = -c (N) and output y = x1 (m).
    """
    from .._checks import positive
    from ..verify import LoopSimulation

    if element.effects:
        raise ValueError("effects: the impact-loop simulation covers the paper's model only (no effects)")
    A0, w = positive("amplitude", amplitude), positive("frequency", frequency)
    if periods <= 0 or steps_per_period < 20:
        raise ValueError("periods must be > 0 and steps_per_period >= 20")
    m1, m2, h, eps = element.m1, element.m2, element.h, element.restitution
    A, B, C, D = _plant_matrices(G)
    nc = A.shape[0]
    x1_phasor = complex(element(A0, w)) * A0                  # x1's fundamental for x = A0 sin(w t)
    s0 = (np.linalg.solve(1j * w * np.eye(nc) - A, B) * x1_phasor).imag

    def rhs(t, z):
        force = -(C @ z[4:] + D * z[0])
        return np.concatenate([[z[1], 0.0, z[3], force / m2], A @ z[4:] + B * z[0]])

    def side_a(t, z):  # gap x2 - x1 reaches 0
        return z[2] - z[0]

    def side_b(t, z):  # gap reaches h
        return z[2] - z[0] - h

    side_a.terminal = side_b.terminal = True
    side_a.direction, side_b.direction = -1, 1
    period = 2 * math.pi / w
    t_end = periods * period
    z = np.concatenate([[0.0, 0.0, 0.5 * h, 0.0], s0])
    t, ts, zs, impacts = 0.0, [], [], 0
    limit = 1e6 * (A0 + 1.0)
    diverged = False
    while t < t_end:
        sol = solve_ivp(rhs, (t, t_end), z, events=(side_a, side_b), rtol=1e-10, atol=1e-12 * h,
                        max_step=period / 50)
        ts.append(sol.t)
        zs.append(sol.y)
        t, z = sol.t[-1], sol.y[:, -1].copy()
        if not np.all(np.isfinite(z)) or np.max(np.abs(C @ sol.y[4:] + D * sol.y[0])) > limit:
            diverged = True
            break
        if sol.status != 1:
            break
        impacts += 1
        if impacts > max_impacts:
            raise RuntimeError(f"max_impacts = {max_impacts} reached at t = {t:.6g} s (chattering impacts?)")
        v1, v2 = z[1], z[3]
        z[1] = (v1 * (m1 - eps * m2) + v2 * (1 + eps) * m2) / (m1 + m2)
        z[3] = (v1 * (1 + eps) * m1 + v2 * (m2 - eps * m1)) / (m1 + m2)
        z[2] = z[0] + (0.0 if sol.t_events[0].size else h)   # exactly on the wall it hit
    tt = np.concatenate(ts)
    zz = np.concatenate(zs, axis=1)
    grid = np.arange(0.0, tt[-1], period / steps_per_period)
    x1 = np.interp(grid, tt, zz[0])
    c = np.array([np.interp(grid, tt, zz[4 + k]) for k in range(nc)])
    return LoopSimulation(grid, -(C @ c + D * x1), x1, diverged)
