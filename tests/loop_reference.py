"""An independent event-located simulation of a plant (A, B, C) closed through a piecewise-linear element, for the
exact-cycle tests: scipy's DOP853 between switches, each switch located by solve_ivp's own event root finding, the
element written out here (not dfloop's time model, flow or switch logic).

Elements: ``("relay", M, a)`` (hysteresis: +M after x rises through a, -M after it falls through -a),
``("saturation", L)``, ``("dead zone", d)``, ``("backlash", h)`` (total clearance h, unit slope; engaged while
|x - e| = h/2 and x pushes, e held otherwise). The element input is x = -C s, its output y drives s' = A s + B y.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

MAX_SEGMENTS = 20_000


class Reference:
    def __init__(self, A, B, C, element, *, rtol=1e-12, atol=1e-14):
        self.A, self.B, self.C = np.asarray(A, float), np.asarray(B, float), np.asarray(C, float)
        self.kind, self.p = element[0], element[1:]
        self.rtol, self.atol = rtol, atol

    # mode: relay -> +1 / -1 (output sign); static -> region -1, 0, +1; backlash -> (0 free, +1 / -1 engaged), e
    def x(self, s):
        return -self.C @ s

    def xdot(self, s, y):
        return -self.C @ (self.A @ s + self.B * y)

    def output(self, s, mode, e=0.0):
        x = self.x(s)
        k = self.kind
        if k == "relay":
            return self.p[0] * mode
        if k == "saturation":
            return float(np.clip(x, -self.p[0], self.p[0]))
        if k == "dead zone":
            return float(x - np.clip(x, -self.p[0], self.p[0]))
        h2 = 0.5 * self.p[0]
        return x - mode * h2 if mode != 0 else e

    def initial_mode(self, s, e=None, rising=True):
        x = self.x(s)
        k = self.kind
        if k == "relay":
            a = self.p[1]
            return 1 if (x > a or (x > -a and rising)) else -1
        if k in ("saturation", "dead zone"):
            L = self.p[0]
            return 1 if x > L else (-1 if x < -L else 0)
        return 0

    def _events(self, mode, e):
        k = self.kind
        if k == "relay":
            a = self.p[1]
            ev = (lambda t, s: self.x(s) + a) if mode > 0 else (lambda t, s: self.x(s) - a)
            ev.direction = -1.0 if mode > 0 else 1.0
            return [ev], [-mode]
        if k in ("saturation", "dead zone"):
            L = self.p[0]
            if mode == 0:
                up, down = (lambda t, s: self.x(s) - L), (lambda t, s: self.x(s) + L)
                up.direction, down.direction = 1.0, -1.0
                return [up, down], [1, -1]
            ev = lambda t, s: self.x(s) - mode * L
            ev.direction = -float(mode)
            return [ev], [0]
        h2 = 0.5 * self.p[0]
        if mode == 0:
            up, down = (lambda t, s: self.x(s) - e - h2), (lambda t, s: self.x(s) - e + h2)
            up.direction, down.direction = 1.0, -1.0
            return [up, down], [1, -1]
        ev = lambda t, s: self.xdot(s, self.x(s) - mode * h2)
        ev.direction = -float(mode)
        return [ev], [0]

    def run(self, s0, mode, t_end, *, e=0.0, samples=None):
        """(s(t_end), mode, e, events [(t, new mode)], dense pieces [(t0, t1, sol)])."""
        s, t = np.array(s0, float), 0.0
        events, pieces = [], []
        for _ in range(MAX_SEGMENTS):
            evs, targets = self._events(mode, e)
            for ev in evs:
                ev.terminal = True
            m, ee = mode, e
            sol = solve_ivp(lambda _t, z: self.A @ z + self.B * self.output(z, m, ee), (t, t_end), s,
                            method="DOP853", rtol=self.rtol, atol=self.atol, events=evs, dense_output=True)
            pieces.append((t, float(sol.t[-1]), sol.sol, mode, e))
            s, t = sol.y[:, -1], float(sol.t[-1])
            hit = [i for i, te in enumerate(sol.t_events) if te.size]
            if not hit or t >= t_end:
                return s, mode, e, events, pieces
            new = targets[hit[0]]
            if self.kind == "backlash":
                if new == 0:        # release: the driven side stays where the contact left it
                    e = self.x(s) - mode * 0.5 * self.p[0]
            mode = new
            events.append((t, mode))
        raise RuntimeError(f"more than {MAX_SEGMENTS} segments")

    def x_of(self, pieces, t):
        t = np.atleast_1d(t)
        out = np.empty(t.size)
        for t0, t1, sol, mode, e in pieces:
            m = (t >= t0) & (t <= t1)
            if np.any(m):
                out[m] = -self.C @ sol(t[m])
        return out

    def states_of(self, pieces, t):
        t = np.atleast_1d(t)
        out = np.empty((t.size, self.A.shape[0]))
        for t0, t1, sol, mode, e in pieces:
            m = (t >= t0) & (t <= t1)
            if np.any(m):
                out[m] = sol(t[m]).T
        return out


def element_of(N):
    """The reference element for a dfloop element (relay with hysteresis, saturation, dead zone, backlash)."""
    name = type(N).__name__
    if name == "Relay":
        return ("relay", N.M, N.hysteresis)            # switches at x = +-hysteresis
    if name == "Saturation":
        return ("saturation", N.limit)
    if name == "DeadZone":
        return ("dead zone", N.delta)
    if name == "Backlash":
        return ("backlash", N.h)
    raise ValueError(name)
