"""An independent reference: the impact system integrated by scipy's ``solve_ivp`` with terminal events.

This is the "typical user" implementation (restart at each impact with law (8)) that the kernel is checked
and benchmarked against. It is generic, slow, and cannot follow chattering (it misses short bounces).
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["simulate_solve_ivp"]


def simulate_solve_ivp(m1: float, m2: float, h: float, restitution: float, force: float, omega: float,
                       t_end: float, *, rtol: float = 1e-12, atol: float | None = None, max_impacts: int = 100_000,
                       method: str = "DOP853", extra_force1=None) -> dict:
    """Impacts of the two-mass system from rest (x1 = 0, g = h/2), via ``solve_ivp`` restarted at each impact.

    Parameters
    ----------
    m1, m2, h, restitution, force, omega : float
        As in :func:`dfloop.impact.kernel.simulate` (SI units).
    t_end : float
        End time (s).
    rtol, atol : float
        Integrator tolerances (atol defaults to 1e-14 h).
    max_impacts : int
        Bound on the number of restarts; reaching it raises RuntimeError.
    extra_force1 : callable, optional
        ``f(t, x1, v1)``: an extra force on M1 (N), e.g. damping or a spring, for effect checks.

    Returns
    -------
    dict
        ``t`` (impact times), ``side`` (0 = A, 1 = B), ``v1_post``, ``v2_post`` and ``sol``: a callable
        t -> state [x1, v1, x2, v2] (dense output pieced together).
    """
    atol = 1e-14 * h if atol is None else atol
    M = m1 + m2

    def rhs(t, y):
        a1 = 0.0 if extra_force1 is None else extra_force1(t, y[0], y[1]) / m1
        return [y[1], a1, y[3], force * np.cos(omega * t) / m2]

    def side_a(t, y):
        return y[2] - y[0]

    def side_b(t, y):
        return y[2] - y[0] - h

    side_a.terminal, side_a.direction = True, -1
    side_b.terminal, side_b.direction = True, 1
    y = np.array([0.0, 0.0, 0.5 * h, 0.0])
    t = 0.0
    times, sides, v1s, v2s, pieces, starts = [], [], [], [], [], []
    while t < t_end:
        if len(times) >= max_impacts:
            raise RuntimeError(f"max_impacts = {max_impacts} reached at t = {t:.6g} s")
        sol = solve_ivp(rhs, (t, t_end), y, method=method, rtol=rtol, atol=atol, events=(side_a, side_b),
                        dense_output=True)
        pieces.append(sol.sol)
        starts.append(t)
        if sol.status != 1:
            break
        which = 0 if sol.t_events[0].size else 1
        t = float(sol.t_events[which][0])
        x1, v1, x2, v2 = sol.y_events[which][0]
        v1n = (v1 * (m1 - restitution * m2) + v2 * (1 + restitution) * m2) / M
        v2n = (v1 * (1 + restitution) * m1 + v2 * (m2 - restitution * m1)) / M
        y = np.array([x1, v1n, x1 + (0.0 if which == 0 else h), v2n])
        times.append(t)
        sides.append(which)
        v1s.append(v1n)
        v2s.append(v2n)
    starts_arr = np.array(starts)

    def evaluate(tq):
        tq = np.atleast_1d(np.asarray(tq, dtype=float))
        k = np.searchsorted(starts_arr, tq, side="right") - 1
        out = np.empty((4, tq.size))
        for i in np.unique(k):
            m = k == i
            out[:, m] = pieces[i](tq[m])
        return out

    return {"t": np.array(times), "side": np.array(sides, dtype=np.int8), "v1_post": np.array(v1s),
            "v2_post": np.array(v2s), "sol": evaluate}
