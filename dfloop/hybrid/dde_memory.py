"""Periodic orbits of a delayed loop around an element with memory (backlash): a delay differential equation
whose history holds the element's state, discretised, with the element's switches located exactly.

Loop: s' = A s + B u(t), u(t) = y(t - T), x = -C s, and y the output of a piecewise-affine element with a state
(:class:`~dfloop.describing.time_model.PiecewiseAffine` with ``n_states`` 1: the play operator of a backlash):
in its mode m, y = gx x + ge e + g1 and e' = de x', and the mode ends when a guard g = cx x + cxd x' + ce e + c1
crosses zero (with an optional reset of e). The element sits before the delay, so the plant's input over a step
[t_k, t_k + h] is the element's output over [t_k - T, t_k - T + h], a window in the past: the element runs T
behind the plant, on the known history of x.

**The scheme** (a method of steps on the grid t_k = k h; the same quadrature and interpolation as
:mod:`dfloop.hybrid.dde`):

- x between the grid nodes is the 4-point Lagrange cubic of the node values (h <= T / 3 keeps every node used
  in the past);
- on that cubic the element's switches are located exactly (each guard is a cubic in time on a node interval:
  its first sign change is bracketed between the critical points and bisected to rounding level) and the
  element's state is carried across them (resets included);
- the plant is integrated exactly for the input, s_{k+1} = e^{Ah} s_k + int_0^h e^{A(h - r)} B u(t_k + r) dr,
  the integral by 3-point Gauss-Legendre on each piece between the element's switches.

**State.** At step k: the plant state s_k, the node values x_{k-L}..x_{k-1} (L = ceil(T / h) + 2; x_k = -C s_k),
the element's state e at t_k - T (and its mode, discrete). One period of N steps (h = P / N) maps this state to
itself on a periodic orbit.

**Periodic orbit and multipliers.** Newton's method on (state, P) with the phase condition that the plant state
moves only across the flow at the start ((s - s_start) . s' = 0; the start's phase puts the element's window in
the middle of its longest mode on the DF's sinusoid, far from its switches), with the exact tangent of the discretised map (the element's switch instants move with the state: the
saltation of the element's switches is carried, dt* = -dg / g'). The eigenvalues of the converged tangent are
the multipliers of the discretised history: a trivial one near 1 (the autonomous orbit), the ones that decide
stability, and the rest clustered near 0. :func:`memory_orbit` solves at N and 2N nodes per period and reports
the change (the error estimate; the scheme is 4th order, measured in ``benchmarks/bench_dde_order.py``).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from ..describing.time_model import OUT_OF_RANGE, PiecewiseAffine
from .realisation import conditioned
from .run import LoopSimulation

__all__ = ["MemoryDDELoop", "memory_orbit", "memory_simulation", "DelayMemoryError"]

_GL_NODES = np.array([0.5 - math.sqrt(15) / 10, 0.5, 0.5 + math.sqrt(15) / 10])   # Gauss-Legendre on [0, 1]
_GL_WEIGHTS = np.array([5.0, 8.0, 5.0]) / 18.0
# monomial coefficients (1, th, th^2, th^3) of the 4 Lagrange weights on nodes -1, 0, 1, 2 (columns)
_W = np.array([[0.0, 1.0, 0.0, 0.0],
               [-1.0 / 3.0, -0.5, 1.0, -1.0 / 6.0],
               [0.5, -1.0, 0.5, 0.0],
               [-1.0 / 6.0, 0.5, -0.5, 1.0 / 6.0]])
_MAX_EVENTS_PER_STEP = 16
_GRAZING = 1e-12


class DelayMemoryError(RuntimeError):
    """The delayed loop with memory cannot continue: a grazing switch, chattering, or the input out of range."""


class MemoryDDELoop:
    """The loop of a plant (A, B, C) with a pure delay and a piecewise-affine element with a state (backlash):
    the loop model :func:`dfloop.hybrid.loop_model` builds for them. Its orbit by :func:`memory_orbit`, its run
    by :func:`memory_simulation` (``delay`` > 0 tells the callers)."""

    exact = True            # a converged discretisation with an error estimate (not a flow to rounding level)
    settle_periods = 0.0
    method = ("delay differential equation with the element's state in the history (method of steps: exact plant "
              "flow, element switches located exactly on the cubic history, Gauss-Legendre input; 4th order)")

    def __init__(self, A, B, C, element: PiecewiseAffine, delay: float, name: str = ""):
        # the exact flows' well-conditioned realisation from order 7 (only x = -C s leaves this model)
        self.A, self.B, self.C, _ = conditioned(*(np.asarray(a, float) for a in (A, B, C)))
        self.n = self.A.shape[0]
        self.plant = (self.A, self.B)
        self.element, self.delay, self.name = element, float(delay), name or element.name
        lam, V = np.linalg.eig(self.A)
        ok = np.linalg.cond(V) < 1e6 if self.n else False
        self._eig = (lam, V, np.linalg.inv(V)) if ok else None

    def exp(self, r: float) -> np.ndarray:
        """e^{A r} (eigen-decomposition when well conditioned, else the matrix exponential)."""
        if self._eig is None:
            return expm(self.A * r)
        lam, V, Vi = self._eig
        return ((V * np.exp(lam * r)) @ Vi).real

    def expB(self, r: float) -> np.ndarray:
        """e^{A r} B: V diag(e^{lambda r}) V^-1 B when A's eigenvectors are well conditioned (cond < 1e6), else
        the matrix exponential."""
        if self._eig is None:
            return expm(self.A * r) @ self.B
        lam, V, Vi = self._eig
        return (V @ (np.exp(lam * r) * (Vi @ self.B))).real


def _poly(c, th):
    return ((c[3] * th + c[2]) * th + c[1]) * th + c[0]


def _first_exit(c, lo: float, hi: float, tiny: float):
    """First th in [lo, hi] where the cubic sum c_i th^i turns negative (None if it stays >= 0): brackets between
    the critical points (the cubic is monotone between them) and bisects to rounding level.

    Values within ``tiny`` (the rounding of the guard's terms) count as 0, not negative: a guard that an
    element's switch has just put on its surface with zero rate (the opposite contact of a backlash released at
    an extremum of x touches it quadratically) is not crossed there."""
    pts = [lo, hi]
    a, b, cc = 3.0 * c[3], 2.0 * c[2], c[1]
    if a != 0.0:
        disc = b * b - 4.0 * a * cc
        if disc >= 0.0:
            r = math.sqrt(disc)
            pts += [(-b - r) / (2 * a), (-b + r) / (2 * a)]
    elif b != 0.0:
        pts.append(-cc / b)
    pts = sorted(p for p in pts if lo <= p <= hi)
    vals = [_poly(c, p) for p in pts]
    if vals[0] < -tiny:
        return lo
    for p0, p1, v1 in zip(pts[:-1], pts[1:], vals[1:]):
        if v1 < -tiny:
            for _ in range(200):
                mid = 0.5 * (p0 + p1)
                if mid in (p0, p1):
                    break
                if _poly(c, mid) >= 0.0:
                    p0 = mid
                else:
                    p1 = mid
            return p1
    return None


class _Scheme:
    """One step size h of the discretised delayed loop with memory (see the module notes)."""

    def __init__(self, loop: MemoryDDELoop, h: float, L: int):
        self.loop, self.h, self.L = loop, float(h), int(L)
        self.Phi = loop.exp(h)
        self.q = loop.delay / h
        if self.q < 3.0 - 1e-12:
            raise DelayMemoryError(f"the step {h:g} s exceeds a third of the delay {loop.delay:g} s")
        if math.ceil(self.q) + 2 > L:
            raise DelayMemoryError(f"the delay spans {self.q:.3g} steps, more than the {L - 2} the history holds")
        # the window [t_k - T, t_k - T + h] on node intervals: (tau_lo, tau_hi, o), o the interval's left node
        # relative to k; th = -q + tau / h - o
        b = math.ceil(-self.q)
        tb = (b + self.q) * h
        self.pieces = [(0.0, h, b)] if tb <= 1e-12 * h or tb >= h * (1 - 1e-12) else [(0.0, tb, b - 1), (tb, h, b)]
        if tb >= h * (1 - 1e-12):
            self.pieces = [(0.0, h, b - 1)]
        self.r0 = min(o for _, _, o in self.pieces) - 1      # lowest node the window reaches (relative)
        self.K = max(o for _, _, o in self.pieces) + 3 - self.r0   # nodes r0 .. r0 + K - 1
        self.E_reg = np.array([self.E(t) for t in _GL_NODES * h]) * (h * _GL_WEIGHTS)[:, None]
        # fixed for the scheme (the window sits at the same place relative to the nodes every step): the cubic's
        # coefficients on each piece, the weights of the Gauss points and of the window's ends
        self.cmats = []
        for lo, hi, o in self.pieces:
            Cm = np.zeros((4, self.K))
            Cm[:, o - 1 - self.r0:o + 3 - self.r0] = _W
            self.cmats.append((lo, hi, o, self.theta(lo, o), self.theta(hi, o), Cm))
        self.W_gl = np.array([self.local(t)[1] for t in _GL_NODES * h])
        self.w_start, self.w_end = self.local(0.0)[1], self.local(h)[1]

    def E(self, tau: float) -> np.ndarray:
        """e^{A(h - tau)} B (from the loop's eigen-decomposition of A when it is well conditioned)."""
        return self.loop.expB(self.h - tau)

    def piece(self, tau: float):
        for lo, hi, o in self.pieces:
            if tau <= hi:
                return lo, hi, o
        return self.pieces[-1]

    def theta(self, tau: float, o: int) -> float:
        return -self.q + tau / self.h - o

    def local(self, tau: float, deriv: int = 0) -> tuple[float, np.ndarray, int]:
        """(th, weights over the local nodes r0..r0+K-1 (K,), o) of x (deriv 0), x' (1) or x'' (2) at tau."""
        o = self.piece(tau)[2]
        th = self.theta(tau, o)
        if deriv == 0:
            pw = np.array([1.0, th, th * th, th ** 3])
        elif deriv == 1:
            pw = np.array([0.0, 1.0, 2 * th, 3 * th * th]) / self.h
        else:
            pw = np.array([0.0, 0.0, 2.0, 6 * th]) / self.h ** 2
        w = np.zeros(self.K)
        w[o - 1 - self.r0:o + 3 - self.r0] = pw @ _W
        return th, w, o

    def step(self, s, nodes, mode: int, e: float, tangent: bool):
        """One step: plant state s at t_k, the local node values ``nodes`` (x at r0..r0+K-1 relative to k),
        element (mode, e) at t_k - T. Returns (s', mode', e', Y, erow, events, y_start): Y (n x (K+1)) and erow
        (K+1) the tangents of s' and e' with respect to the local coordinates (nodes, e) (None without
        ``tangent``); events: (tau*, from, to); y_start the element's output at t_k - T."""
        modes = self.loop.element.modes
        n, K = self.loop.n, self.K
        h = self.h
        Kp = K + 1
        unit_e = np.zeros(Kp)
        unit_e[K] = 1.0

        def xrow(tau, d=0):
            _, w, _ = self.local(tau, d)
            return float(w @ nodes), w

        x0 = float(self.w_start @ nodes)
        e_a, x_a = e, x0
        dE_a = unit_e.copy() if tangent else None
        dX_a = np.append(self.w_start, 0.0) if tangent else None
        polys = [(lo, hi, o, th_lo, th_hi, Cm @ nodes) for lo, hi, o, th_lo, th_hi, Cm in self.cmats]
        m = modes[mode]
        y_start = m.gx * x0 + m.ge * e + m.g1
        segments, events = [], []
        tau = 0.0
        xmag = float(np.max(np.abs(nodes))) + abs(e)       # size of the terms a guard's value cancels
        while True:
            m = modes[mode]
            best = None
            for lo, hi, o, th_lo, th_hi, cx in polys:           # cx: x(th) coefficients on the piece
                if hi <= tau:
                    continue
                th_start = th_lo if tau <= lo else self.theta(tau, o)
                c0, c1, c2, c3 = cx.tolist()
                d0, d1, d2 = c1 / h, 2.0 * c2 / h, 3.0 * c3 / h
                for j, g in enumerate(m.guards):
                    a = g.cx + g.ce * m.de
                    coef = [a * c0 + g.cxd * d0 + g.ce * (e_a - m.de * x_a) + g.c1, a * c1 + g.cxd * d1,
                            a * c2 + g.cxd * d2, a * c3]
                    tiny = 1e-12 * (abs(coef[0]) + abs(coef[1]) + abs(coef[2]) + abs(coef[3]) +
                                    (abs(g.cx) + abs(g.ce)) * xmag + abs(g.c1) + abs(g.cxd) * (abs(d0) + abs(d1) + abs(d2)))
                    # quick exclusion: g at the start minus a bound of its change over the piece (th in [0, 1])
                    if _poly(coef, th_start) - (abs(coef[1]) + 2 * abs(coef[2]) + 3 * abs(coef[3])) * \
                            (th_hi - th_start) > tiny:
                        continue
                    th = _first_exit(coef, th_start, th_hi, tiny)
                    if th is not None:
                        t_ev = (th + o + self.q) * h
                        if best is None or t_ev < best[0]:
                            best = (t_ev, j)
                if best is not None:
                    break
            end = h if best is None else best[0]
            segments.append((tau, end, mode, e_a, x_a, dE_a, dX_a))
            if best is None:
                break
            if len(events) >= _MAX_EVENTS_PER_STEP:
                raise DelayMemoryError(f"more than {_MAX_EVENTS_PER_STEP} element switches in one step (chattering)")
            t_ev, j = best
            g = m.guards[j]
            if g.target == OUT_OF_RANGE:
                raise DelayMemoryError(f"the input left the range the {self.loop.name} model covers")
            xs, wx = xrow(t_ev)
            xd, wd = xrow(t_ev, 1)
            xdd, _ = xrow(t_ev, 2)
            e_minus = e_a + m.de * (xs - x_a)
            new = modes[g.target]
            e_plus = g.reset[0] * xs + g.reset[1] if g.reset is not None else e_minus
            y_minus = m.gx * xs + m.ge * e_minus + m.g1
            y_plus = new.gx * xs + new.ge * e_plus + new.g1
            if tangent:
                rx, rd = np.append(wx, 0.0), np.append(wd, 0.0)
                dg = (g.cx + g.ce * m.de) * rx + g.cxd * rd + g.ce * (dE_a - m.de * dX_a)
                gdot = (g.cx + g.ce * m.de) * xd + g.cxd * xdd
                if abs(gdot) <= _GRAZING * (abs(xd) + abs(xdd) * h + 1e-300):
                    raise DelayMemoryError(f"grazing element switch at step position {t_ev / h:.4g}: the "
                                           "tangent is undefined there")
                dt = -dg / gdot
                dx_tot = rx + xd * dt
                dE_a = g.reset[0] * dx_tot if g.reset is not None else dE_a + m.de * (dx_tot - dX_a)
                dX_a = dx_tot
                events.append((t_ev, mode, g.target, (y_minus - y_plus), dt))
            else:
                events.append((t_ev, mode, g.target, 0.0, None))
            e_a, x_a, mode, tau = e_plus, xs, g.target, t_ev
        # quadrature of the input over each segment
        s_new = self.Phi @ s
        Y = np.zeros((n, Kp)) if tangent else None
        for lo, hi, md, ea, xa, dEa, dXa in segments:
            if hi <= lo:
                continue
            mm = modes[md]
            if lo == 0.0 and hi == h:                           # no switch in the step: the fixed weights
                xq = self.W_gl @ nodes
                yq = mm.gx * xq + mm.ge * (ea + mm.de * (xq - xa)) + mm.g1
                s_new = s_new + self.E_reg.T @ yq
                if tangent:
                    Rq = np.zeros((3, Kp))
                    Rq[:, :K] = self.W_gl
                    Y += self.E_reg.T @ (mm.gx * Rq + mm.ge * (dEa[None, :] + mm.de * (Rq - dXa[None, :])))
                continue
            else:
                taus = lo + _GL_NODES * (hi - lo)
                Es = np.array([self.E(t) for t in taus]) * ((hi - lo) * _GL_WEIGHTS)[:, None]
            for tq, Eq in zip(taus, Es):
                xq, wq = xrow(tq)
                yq = mm.gx * xq + mm.ge * (ea + mm.de * (xq - xa)) + mm.g1
                s_new = s_new + Eq * yq
                if tangent:
                    rq = np.append(wq, 0.0)
                    Y += np.outer(Eq, mm.gx * rq + mm.ge * (dEa + mm.de * (rq - dXa)))
        if tangent:
            for t_ev, _, _, jump, dt in events:      # the switch instants move: the input's jump moves with them
                Y += np.outer(self.E(t_ev) * jump, dt)
        lo, hi, md, ea, xa, dEa, dXa = segments[-1]
        mm = modes[md]
        x_end = float(self.w_end @ nodes)
        e_end = ea + mm.de * (x_end - xa)
        erow = (dEa + mm.de * (np.append(self.w_end, 0.0) - dXa)) if tangent else None
        return s_new, mode, e_end, Y, erow, events, y_start


class _State:
    """The discretised state: plant s, ring of the last L node values of x, element (mode, e)."""

    def __init__(self, s, hist, mode, e):
        self.s, self.hist, self.mode, self.e = np.array(s, float), np.array(hist, float), int(mode), float(e)

    def vector(self) -> np.ndarray:
        return np.concatenate([self.s, self.hist, [self.e]])


def _run(loop: MemoryDDELoop, sc: _Scheme, st: _State, steps: int, *, tangent: bool, record: bool = False,
         diverge: float = math.inf):
    """``steps`` steps from ``st`` (hist in natural order, node -L first). Returns (end state, monodromy (D x D)
    or None, records: x at the nodes t_k, y at t_k - T, events (time from the start, from, to))."""
    n, L, C = loop.n, sc.L, loop.C
    s, mode, e = st.s.copy(), st.mode, st.e
    ring = st.hist.copy()                     # node r (relative to the current step) at slot (off + r) % L
    off = 0
    D = n + L + 1
    if tangent:
        Ms = np.zeros((n, D))
        Ms[:, :n] = np.eye(n)
        H = np.zeros((L, D))
        H[np.arange(L), n + np.arange(L)] = 1.0
        Me = np.zeros(D)
        Me[-1] = 1.0
    xs, ys, evs = [], [], []
    rel = np.arange(sc.r0, sc.r0 + sc.K)
    diverged = False
    for k in range(steps):
        slots = (off + rel) % L
        nodes = ring[slots]
        x_k = float(-C @ s)
        if record:
            xs.append(x_k)
        s_new, mode, e, Y, erow, events, y0 = sc.step(s, nodes, mode, e, tangent)
        if record:
            ys.append(y0)
            evs.extend((k * sc.h + t - loop.delay, a, b) for t, a, b, _, _ in events)
        if tangent:
            U = np.vstack([H[slots], Me[None, :]])
            new_row = -C @ Ms
            Ms = sc.Phi @ Ms + Y @ U
            Me = erow @ U
            H[off % L] = new_row
        ring[off % L] = x_k
        off += 1
        s = s_new
        if not np.all(np.isfinite(s)) or abs(float(-C @ s)) > diverge:
            diverged = True
            break
    hist = ring[(off + np.arange(-L, 0)) % L]
    out = _State(s, hist, mode, e)
    M = None
    if tangent:
        M = np.vstack([Ms, H[(off + np.arange(-L, 0)) % L], Me[None, :]])
    return out, M, (np.array(xs), np.array(ys), evs, diverged)


def _start(loop: MemoryDDELoop, A0: float, w0: float, h: float, L: int, section: bool = True,
           offset: float = 0.0) -> _State:
    """The DF's sinusoidal orbit x = A0 sin(w0 (t + t0)) as a discretised state at t = 0: x's history on the nodes,
    the plant in the periodic state the delayed fundamental of the element's response drives it to, the element in
    the state the sinusoid leaves at -T. With ``section`` the phase t0 puts the element's window (-T) in the middle
    of its longest mode on the sinusoid, so the section is far from the element's switches (a switch near it would
    change the mode found after one period as Newton moves the period); else t0 = 0."""
    tm, T = loop.element, loop.delay
    P = 2 * np.pi / w0
    theta = 2 * np.pi * np.arange(512) / 512
    y = np.asarray(tm.response(offset + A0 * np.sin(theta)), float)
    Y1 = complex(2 * np.mean(y * np.sin(theta)) + 2j * np.mean(y * np.cos(theta)))
    Y0 = float(np.mean(y))

    def element_at(t):        # (mode, e) after the sinusoid up to time t
        th = t - 4 * P + P * np.arange(4 * 256 + 1) / 256
        return tm.initial(offset + A0 * np.sin(w0 * th), A0 * w0 * math.cos(w0 * t))

    t0 = 0.0
    if section:
        modes = np.array([element_at(P * k / 64 - T)[0] for k in range(64)])
        if np.ptp(modes):
            first = int(np.flatnonzero(modes != np.roll(modes, 1))[0])
            k, best = 0, (0, 0)
            order = np.roll(np.arange(64), -first)          # start at a mode change: runs do not wrap
            while k < 64:
                j = k
                while j + 1 < 64 and modes[order[j + 1]] == modes[order[k]]:
                    j += 1
                if j - k + 1 > best[1]:
                    best = (k, j - k + 1)
                k = j + 1
            t0 = P * ((first + best[0] + 0.5 * (best[1] - 1)) % 64) / 64
    A, B = loop.A, loop.B
    X = np.linalg.solve(1j * w0 * np.eye(loop.n) - A, B) * Y1
    s = (X * np.exp(1j * w0 * (t0 - T))).imag
    if abs(Y0) > 0 and abs(np.linalg.det(A)) > 0:
        s = s - np.linalg.solve(A, B) * Y0
    hist = offset + A0 * np.sin(w0 * (t0 + h * np.arange(-L, 0)))
    mode, e = element_at(t0 - T)
    return _State(s, hist, mode, e)


def _periodic(loop, st: _State, P: float, N: int, L: int, tol: float, max_iterations: int):
    """Newton on (state, P): returns (state, P, residual, iterations, monodromy, records) or raises
    DelayMemoryError."""
    n = loop.n
    D = n + L + 1
    s_sec = st.s.copy()
    rate = None
    mode0 = st.mode
    res_prev = math.inf
    for it in range(1, max_iterations + 1):
        sc = _Scheme(loop, P / N, L)
        end, M, rec = _run(loop, sc, st, N, tangent=True, record=True)
        if rate is None:      # phase condition: no correction along the flow, (s - s_sec) . s' = 0 at the start
            one = _run(loop, sc, st, 1, tangent=False)[0]
            rate = (one.s - st.s) / np.linalg.norm(one.s - st.s)
            phase = np.zeros(D + 1)
            phase[:n] = rate
        v0, v1 = st.vector(), end.vector()
        F = np.append(v1 - v0, float(rate @ (st.s - s_sec)))
        scale = max(float(np.max(np.abs(v0))), 1e-300)
        res = float(np.max(np.abs(F))) / scale
        if end.mode != mode0:
            raise DelayMemoryError(f"Newton iteration {it}: the element is in another mode after a period")
        if res <= tol or (res <= 1e-9 and res > 0.5 * res_prev):
            return st, P, res, it, M, rec
        res_prev = res
        dP = 1e-6 * P
        vp = _run(loop, _Scheme(loop, (P + dP) / N, L), st, N, tangent=False)[0].vector()
        vm = _run(loop, _Scheme(loop, (P - dP) / N, L), st, N, tangent=False)[0].vector()
        J = np.zeros((D + 1, D + 1))
        J[:D, :D] = M - np.eye(D)
        J[:D, D] = (vp - vm) / (2 * dP)
        J[D] = phase
        try:
            d = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            raise DelayMemoryError(f"singular Jacobian at iteration {it} (a marginal orbit)") from None
        step = 1.0
        for _ in range(10):
            v_try, P_try = v0 + step * d[:D], P + step * d[D]
            trial = _State(v_try[:n], v_try[n:n + L], mode0, v_try[-1])
            try:
                e_try = _run(loop, _Scheme(loop, P_try / N, L), trial, N, tangent=False)[0]
                r_try = max(float(np.max(np.abs(e_try.vector() - v_try))),
                            abs(float(rate @ (trial.s - s_sec)))) / scale
                ok = e_try.mode == mode0 and r_try < res * (1 - 1e-4 * step)
            except DelayMemoryError:
                ok = False
            if ok:
                break
            step *= 0.5
        else:
            raise DelayMemoryError(f"Newton iteration {it}: no step reduces the residual {res:.2e}")
        st, P = trial, P_try
    raise DelayMemoryError(f"Newton did not converge in max_iterations = {max_iterations} (residual {res:.2e}); "
                           "raise max_iterations")


def _history_size(loop, N: int, P: float) -> int:
    return int(math.ceil(loop.delay * N / (0.6 * P))) + 3        # periods down to 0.6 P fit


def _refine(loop, st: _State, xs: np.ndarray, N: int, L2: int) -> _State:
    """The orbit's state on a grid twice as fine: the node history from the periodic x (spectral interpolation)."""
    N2 = 2 * N
    xf = np.fft.irfft(np.fft.rfft(xs), n=N2) * 2
    hist = xf[(np.arange(-L2, 0)) % N2]
    return _State(st.s, hist, st.mode, st.e)


TARGET = 1e-8          # the change of A and w between the last two resolutions must fall below this (relative)
MAX_NODES = 4096       # the finest resolution memory_orbit tries (steps per period)


def memory_orbit(loop: MemoryDDELoop, A0: float, w0: float, *, nodes: int = 128, target: float = TARGET,
                 max_nodes: int = MAX_NODES, tol: float = 1e-11, max_iterations: int = 40, harmonics: int = 15,
                 samples: int = 512, count: int = 8, offset: float = 0.0) -> dict:
    """The periodic orbit of a delayed loop around an element with memory (module notes), near (A0, w0).

    Solves at ``nodes``, 2 ``nodes``, 4 ``nodes``, ... steps per period (at least 4.5 P / T, so the step stays
    below a third of the delay), each from the previous orbit, until the change of A and of w between the last
    two resolutions is below ``target`` (relative) or the next would exceed ``max_nodes``. The orbit is the
    finest one and ``extra["error_estimate"]`` the last change: a bound on its error as long as the error at
    least halves per doubling (4th order: about 1/15 of it). When the target is not met within ``max_nodes`` the
    orbit is still returned, with ``extra["target_met"]`` False and the message saying so. The multipliers
    (``count`` kept, largest first) are those of the first two resolutions (``multipliers`` the finer,
    ``extra["multipliers_coarse"]`` the coarser). ``offset``: the start's mean of x (x = offset + A0 sin(w0 t)).
    Returns a dict of :class:`dfloop.exact.ExactCycle` fields (``success`` False with the reason on failure).
    """
    T = loop.delay
    P0 = 2 * math.pi / w0
    N = max(int(nodes), int(math.ceil(4.5 * P0 / T)) + 1)
    max_nodes = max(int(max_nodes), 2 * N)
    levels = []
    st, P = None, P0
    xs = None
    Nn = N
    while True:
        L = _history_size(loop, Nn, P0)
        try:
            if st is None:
                st = _start(loop, A0, w0, P / Nn, L, offset=offset)
            else:
                st = _refine(loop, st, xs, Nn // 2, L)
            st, P, res, it, M, (xs, ys, evs, _) = _periodic(loop, st, P, Nn, L, tol, max_iterations)
        except DelayMemoryError as exc:
            return dict(success=False, message=f"{Nn} steps per period: {exc}", method=_method(levels, Nn))
        mu = _eigenvalues(M, count) if len(levels) < 2 else None      # the multipliers' two resolutions
        X = 2j * np.fft.rfft(xs)[1:harmonics + 1] / Nn
        levels.append((Nn, abs(X[0]), 2 * math.pi / P, mu, res, it, X, evs, st))
        if len(levels) >= 2:
            err = (abs(levels[-1][1] / levels[-2][1] - 1), abs(levels[-1][2] / levels[-2][2] - 1))
            if max(err) <= target or 2 * Nn > max_nodes:
                break
        Nn *= 2
    Nn, A2, w2, _, res, it, X, evs, st = levels[-1]
    mu1, mu2 = levels[0][3], levels[1][3]
    met = max(err) <= target
    if not A2 > 0:
        return dict(success=False, message="the motion settles to rest: no oscillation", method=_method(levels, Nn))
    nontrivial = np.delete(mu2, int(np.argmin(np.abs(mu2 - 1.0))))
    stable = bool(np.all(np.abs(nontrivial) < 1.0))
    phase = float(np.angle(X[0]))
    shift = phase / (2 * math.pi / P)
    c = np.fft.rfft(xs) * np.exp(-1j * np.arange(xs.size // 2 + 1) * phase)
    spec = np.zeros(samples // 2 + 1, complex)
    m = min(c.size, spec.size)
    spec[:m] = c[:m]
    x_s = np.fft.irfft(spec, n=samples) * (samples / xs.size)
    y_s = np.asarray(loop.element.response(x_s), float)
    k = np.arange(1, X.size + 1)
    X = X * np.exp(-1j * k * phase)
    X[0] = abs(X[0])
    switches = np.sort(np.mod(np.array([ev[0] for ev in evs], float) + shift, P))
    msg = (f"converged in {it} Newton iteration(s), residual {res:.1e}; change from {levels[-2][0]} to {Nn} steps "
           f"per period: A {err[0]:.1e}, w {err[1]:.1e}")
    if not met:
        msg += (f" - above the target {target:g}: the finest resolution allowed is max_nodes = {max_nodes}; "
                "raise max_nodes for a smaller error")
    return dict(success=True, message=msg, method=_method(levels, Nn),
                amplitude=float(X[0].real), frequency=2 * math.pi / P, period=P, t=np.arange(samples) * (P / samples),
                x=x_s, y=y_s, switching_times=switches, harmonics=X, multipliers=mu2, stable=stable, residual=res,
                iterations=it, extra={"error_estimate": err, "target": target, "target_met": met,
                                      "multipliers_coarse": mu1, "nodes": Nn,
                                      "multiplier_nodes": (levels[0][0], levels[1][0]),
                                      "mode0": st.mode, "e0": st.e, "delay": T})


def _method(levels, Nn) -> str:
    used = [lv[0] for lv in levels] or [Nn]
    return (f"delay equation with the element's state in the history ({', '.join(map(str, used))} steps per "
            "period: exact plant flow, element switches located exactly on the cubic history, Gauss-Legendre "
            "input; 4th order, refined until the change of A and w is below the target; error estimate in extra)")


def _eigenvalues(M: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` largest eigenvalues of the monodromy (all of them for a small one)."""
    if M.shape[0] > 400:
        from scipy.sparse.linalg import eigs

        mu = eigs(M, k=min(count, M.shape[0] - 2), which="LM", return_eigenvectors=False, tol=1e-12)
    else:
        mu = np.linalg.eigvals(M)
    return mu[np.argsort(-np.abs(mu))][:count]


def memory_simulation(loop: MemoryDDELoop, amplitude: float, frequency: float, periods: float,
                      steps_per_period: int, diverge: float = 1e6) -> LoopSimulation:
    """Run the delayed loop with memory by the same scheme from the DF's sinusoidal orbit of (amplitude,
    frequency) (:func:`memory_orbit`'s start) for ``periods`` periods; x at the grid nodes, y (the element's
    output) at the same times. Stops early when |x| exceeds ``diverge`` times the amplitude."""
    P = 2 * math.pi / frequency
    steps = max(int(steps_per_period), int(math.ceil(3 * P / loop.delay)) + 1)
    h = P / steps
    L = int(math.ceil(loop.delay / h)) + 3
    sc = _Scheme(loop, h, L)
    st = _start(loop, amplitude, frequency, h, L, section=False)
    n_steps = int(math.ceil(periods * steps))
    try:
        _, _, (xs, ys, _, diverged) = _run(loop, sc, st, n_steps, tangent=False, record=True,
                                           diverge=diverge * amplitude)
    except DelayMemoryError as exc:
        raise DelayMemoryError(f"the run stopped: {exc}") from None
    t = np.arange(xs.size) * h
    # y was recorded at t_k - T: the output at the node times is the record T later (interpolated)
    y = np.interp(t, t - loop.delay, ys, left=ys[0])
    method = (f"delay equation with the element's state in the history, method of steps ({steps} steps per "
              "period; element switches located exactly, 4th order)")
    return LoopSimulation(t, xs, y, diverged, method)
