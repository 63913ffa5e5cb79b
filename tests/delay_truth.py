"""An independent long simulation of a delayed loop s' = A s + B u(t), u(t) = y(t - T), x = -C s, y the output of
a static element y = f(x) or of a backlash (play operator) driven by x, written apart from dfloop.hybrid.

No grid, no interpolation of node values: the plant is integrated by scipy's DOP853 (rtol ~1e-12) piece by piece,
and the delayed input is read from the pieces' own dense output (the exact delay buffer, 7th-order interpolants
at the solver's accuracy). Every instant where the input is not smooth is an integration boundary:

- the element's switches (x crossing a kink of f; a backlash engaging, x - e = +-c/2, or releasing, x' = 0) are
  events of the integration located on the dense output; the input has its kink T later;
- a piece never spans more than T (its input is then all in the past), so every switch found inside it lies
  beyond its end once delayed.

The run starts on the predicted sinusoid: x(t) = A0 sin(w0 t) for t <= 0 (the element driven by it), the plant in
the periodic state the fundamental of the delayed element output drives it to. Settled: the last ``confirm``
periods (upward zero crossings of x, events) and amplitudes (the fundamental over a period, Gauss-Legendre on
every solver step of the dense output) agree to ``settle`` (relative). Used by tests/test_dde_truth.py and
benchmarks/bench_delay_elements.py.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

__all__ = ["DelayTruth", "Settled", "static_element", "backlash_element"]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


def static_element(f, kinks):
    """A static element y = f(x) with the x values ``kinks`` where f' or f jumps (at a jump, the run reads f on
    the side x moves to)."""
    return ("static", f, np.asarray(kinks, float))


def backlash_element(clearance: float):
    """A backlash (play operator) of total clearance ``clearance``: free (y = e constant) until |x - e| reaches
    clearance / 2, then engaged (y = x -+ clearance / 2) until x turns back."""
    return ("backlash", float(clearance))


class _Budget(Exception):
    """The run's budget of right-hand-side evaluations is spent."""


@dataclass
class Settled:
    """The end of a run: amplitude of x's fundamental over the last period, frequency (rad/s), the largest change
    between the last periods, periods and time (s) simulated, and why it stopped (``reason``: "settled", "rest",
    "divergence" or "bound")."""
    amplitude: float
    frequency: float
    change: float
    periods: int
    time: float
    settled: bool
    reason: str = "bound"


class DelayTruth:
    """The loop (A, B, C) (x = -C s), delay T > 0, element (``static_element`` / ``backlash_element``)."""

    def __init__(self, A, B, C, delay, element, rtol=1e-12):
        self.A, self.B, self.C = (np.asarray(a, float) for a in (A, B, C))
        self.B, self.C = self.B.reshape(-1), self.C.reshape(-1)
        self.T, self.el, self.rtol = float(delay), element, rtol
        self.starts, self.pieces = [], []          # history of x: piece k covers [starts[k], next start)
        self.sw_t, self.sw = [], []                # element switches: time, (mode, e) from that time on
        self.breaks = []                           # input kinks still ahead (switch times + T)

    # ---- the history -------------------------------------------------------------------------------------
    def x_at(self, t):
        if t <= 0.0:
            return self.A0 * math.sin(self.w0 * t)
        k = bisect.bisect_right(self.starts, t) - 1
        return float(-self.C @ self.pieces[k](t))

    def y_at(self, t):
        x = self.x_at(t)
        if self.el[0] == "static":
            for b in self.el[2]:   # on a kink (a delayed switch: a piece's first point), the side x moves to
                tiny = 1e-9 * (1.0 + abs(b))
                if abs(x - b) <= tiny:   # (f may jump there: Coulomb friction, a preload)
                    side = -math.copysign(1.0, self.x_at(t - 1e-9 * self.T) - b)   # away from where it was
                    return float(self.el[1](b + side * 1e-12 * (1.0 + abs(b))))
            return float(self.el[1](x))
        k = bisect.bisect_right(self.sw_t, t) - 1
        mode, e = self.sw[k]
        half = 0.5 * self.el[1]
        return e if mode == 0 else x - half if mode == 1 else x + half

    def u(self, t):
        return self.y_at(t - self.T)

    # ---- the element on a known x ------------------------------------------------------------------------
    def _guards(self, mode, e):
        """Event functions g(t, s) of the element's switches out of ``mode`` (zero at the switch)."""
        if self.el[0] == "static":
            return [(lambda t, s, b=b: float(-self.C @ s) - b) for b in self.el[2]]
        half = 0.5 * self.el[1]
        if mode == 0:
            return [lambda t, s: float(-self.C @ s) - e - half, lambda t, s: float(-self.C @ s) - e + half]
        sign = 1.0 if mode == 1 else -1.0
        return [lambda t, s: sign * float(-self.C @ (self.A @ s + self.B * self.u(t)))]

    def _switch(self, t, x, j):
        """Record the element's switch at t (guard j of the current mode) and the input's kink at t + T."""
        if self.el[0] == "backlash":
            mode, e = self.sw[-1]
            half = 0.5 * self.el[1]
            if mode == 0:
                new = (1, x - half) if j == 0 else (2, x + half)
            else:
                new = (0, x - half if mode == 1 else x + half)
            self.sw_t.append(t)
            self.sw.append(new)
        bisect.insort(self.breaks, t + self.T)

    def _initial(self, A0, w0):
        """The element driven by x = A0 sin(w0 t) for t <= 0, from a maximum of x two periods before -T: its
        switches located by brentq (the input kinks they cause after t = 0 are kept as breaks)."""
        P = 2 * math.pi / w0
        half = 0.5 * self.el[1] if self.el[0] == "backlash" else 0.0
        t0 = (math.floor((-self.T - 2 * P) / P) + 0.25) * P          # a maximum of x
        self.sw_t, self.sw = [-math.inf], [(0, A0 - half)]
        xs = lambda t: A0 * math.sin(w0 * t)
        grid = np.linspace(t0, 0.0, int(64 * (-t0) / P) + 2)
        for a, b in zip(grid[:-1], grid[1:]):
            while a < b:
                mode, e = self.sw[-1]
                if self.el[0] == "static":
                    gs = [lambda t, k=k: xs(t) - k for k in self.el[2]]
                elif mode == 0:
                    gs = [lambda t: xs(t) - e - half, lambda t: xs(t) - e + half]
                else:
                    sign = 1.0 if mode == 1 else -1.0
                    gs = [lambda t: sign * math.cos(w0 * t)]
                hits = [(brentq(g, a, b, xtol=1e-15, rtol=1e-15), j) for j, g in enumerate(gs) if g(a) * g(b) < 0]
                if not hits:
                    break
                tj, j = min(hits)
                self._switch(tj, xs(tj), j)
                a = tj + 1e-12 * P

    # ---- the run -----------------------------------------------------------------------------------------
    def run(self, A0, w0, *, max_periods=400, settle=1e-11, confirm=3, max_steps=10 ** 7):
        """Run from the prediction (A0, w0) until settled, at rest (amplitude < 1e-9 A0) or diverging (> 1e4 A0),
        or until ``max_periods`` (of w0) or ``max_steps`` solver steps (13 ``max_steps`` evaluations) have passed."""
        self.A0, self.w0 = float(A0), float(w0)
        P0 = 2 * math.pi / w0
        self.breaks = [self.T]                    # the start's x(0) differs from the sinusoid's
        self._initial(A0, w0)
        # plant state: the periodic response to the fundamental of the element's output on the sinusoid
        th = 2 * math.pi * np.arange(4096) / 4096
        xx = A0 * np.sin(th)
        if self.el[0] == "static":
            yy = self.el[1](xx)
        else:                                     # the play operator on the samples (two periods, the last kept)
            half, e, yy = 0.5 * self.el[1], 0.0, np.empty(4096)
            for rep in range(2):
                for i, xi in enumerate(xx):
                    e = min(max(e, xi - half), xi + half)
                    yy[i] = e
        Y1 = complex(2 * np.mean(yy * np.sin(th)) + 2j * np.mean(yy * np.cos(th)))
        Y0 = float(np.mean(yy))
        n = self.A.shape[0]
        X = np.linalg.solve(1j * w0 * np.eye(n) - self.A, self.B) * Y1
        s = (X * np.exp(-1j * w0 * self.T)).imag
        if abs(Y0) > 0 and abs(np.linalg.det(self.A)) > 1e-12:
            s = s - np.linalg.solve(self.A, self.B) * Y0
        t = 0.0
        atol = self.rtol * 1e-2 * max(float(np.max(np.abs(s))), 1e-300)
        self.starts, self.pieces = [], []
        ups = self.ups = []                        # upward zero crossings of x
        evals = [0]

        def rhs(t, s):
            evals[0] += 1
            if evals[0] > 13 * max_steps:       # DOP853: 12 evaluations a step (bounds a piece that stalls)
                raise _Budget
            return self.A @ s + self.B * self.u(t)

        up = lambda t, s: float(-self.C @ s)
        up.direction = 1.0
        t_end = max_periods * P0
        result = None
        steps = 0
        while t < t_end and steps < max_steps:
            nb = bisect.bisect_right(self.breaks, t * (1 + 1e-15) + 1e-300)
            del self.breaks[:nb]
            stop = min(t + self.T, self.breaks[0] if self.breaks else math.inf, t_end)
            mode = self.sw[-1][0] if self.sw else 0
            guards = self._guards(mode, self.sw[-1][1] if self.sw else 0.0)
            for j, g in enumerate(guards):       # a backlash's switch changes its guards: terminal
                g.terminal = self.el[0] == "backlash"
                if self.el[0] == "backlash":      # engage + upward, engage - downward, release: x' turns back
                    g.direction = (1.0 if j == 0 else -1.0) if mode == 0 else -1.0
            try:
                sol = solve_ivp(rhs, (t, stop), s, method="DOP853", rtol=self.rtol, atol=atol, dense_output=True,
                                events=[up] + guards)
            except _Budget:
                break
            end = float(sol.t[-1])
            steps += sol.t.size - 1
            self.starts.append(t)
            self.pieces.append(sol.sol)
            for tu in sol.t_events[0]:
                if not ups or tu > ups[-1] + 1e-9 * P0:
                    ups.append(float(tu))
                    result = self._check(ups, settle, confirm)
                    if result is not None and (result.settled or result.change == math.inf):
                        return result
            hits = sorted((float(te), j) for j, tev in enumerate(sol.t_events[1:]) for te in tev)
            if self.el[0] == "static":
                for te, j in hits:
                    self._switch(te, self.x_at(te), j)
            elif sol.status == 1:
                te, j = hits[0]
                self._switch(te, self.x_at(te), j)
            s = sol.y[:, -1]
            if not np.all(np.isfinite(s)) or np.max(np.abs(s)) > 1e8:
                return Settled(math.nan, math.nan, math.inf, len(ups), t, False, "divergence")
            t = end
        return result or Settled(math.nan, math.nan, math.inf, len(ups), t, False)

    def _check(self, ups, settle, confirm):
        if len(ups) < confirm + 2:
            return None
        per = np.diff(ups[-(confirm + 2):])
        amps = [self.fundamental(ups[-i - 2], ups[-i - 1]) for i in range(confirm + 1)]
        if not 1e-9 * self.A0 < amps[0] < 1e4 * self.A0:     # at rest or diverging: stop (not settled)
            return Settled(amps[0], 2 * math.pi / per[-1], math.inf, len(ups) - 1, ups[-1], False,
                           "rest" if amps[0] <= 1e-9 * self.A0 else "divergence")
        change = max(float(np.max(np.abs(np.diff(per)))) / per[-1],
                     max(abs(a / amps[0] - 1) for a in amps[1:]))
        return Settled(amps[0], 2 * math.pi / per[-1], change, len(ups) - 1, ups[-1], change < settle,
                       "settled" if change < settle else "bound")

    def limit(self, periods: int = 40):
        """(A, w, correction) of the run's last ``periods`` periods extrapolated to their limit. A motion that
        converges slowly (multiplier r near 1) has successive periods agreeing long before it reaches its limit: the
        distance left is the change times r / (1 - r). The per-period amplitudes and periods are fitted by
        L + c r^k (one r for both, scanned on a fine grid; L and c by linear least squares for each r);
        ``correction`` is the larger relative |L - last value|."""
        ups = self.ups[-(periods + 1):]
        P = np.diff(ups)
        A = np.array([self.fundamental(a, b) for a, b in zip(ups[:-1], ups[1:])])
        k = np.arange(P.size, dtype=float)
        best = (math.inf, A[-1], P[-1])
        for r in np.concatenate([np.linspace(0.05, 0.95, 91), 1 - np.logspace(-1.3, -3, 60)]):
            M = np.stack([np.ones_like(k), r ** (k - k[-1])], axis=1)
            fit = [np.linalg.lstsq(M, y / y[-1], rcond=None) for y in (A, P)]
            res = sum(float(np.sum((M @ f[0] - y / y[-1]) ** 2)) for f, y in zip(fit, (A, P)))
            if res < best[0]:
                best = (res, fit[0][0][0] * A[-1], fit[1][0][0] * P[-1])
        _, A_lim, P_lim = best
        return A_lim, 2 * math.pi / P_lim, max(abs(A_lim / A[-1] - 1), abs(P_lim / P[-1] - 1))

    def fundamental(self, a, b):
        """|2/P int_a^b x e^{-iwt} dt| over one period [a, b]: 8-point Gauss-Legendre on every solver step."""
        P = b - a
        w = 2 * math.pi / P
        total = 0.0j
        k0 = bisect.bisect_right(self.starts, a) - 1
        for sol in self.pieces[k0:]:
            edges = np.clip(sol.ts, a, b)
            for lo, hi, interp in zip(edges[:-1], edges[1:], sol.interpolants):
                if hi <= lo:
                    continue
                tq = 0.5 * (lo + hi) + 0.5 * (hi - lo) * _GL_X
                xq = -(self.C @ interp(tq))
                total += 0.5 * (hi - lo) * np.sum(_GL_W * xq * np.exp(-1j * w * (tq - a)))
        return abs(2.0 / P * total)
