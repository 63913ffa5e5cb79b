"""Exact flow of a loop with a pure delay and a piecewise-constant element (relays, quantizer).

Loop of the paper's Fig. 1 with a plant G(s) e^{-sT} (:class:`dfloop.solve.delay.DelayedSystem`): plant state s
(s' = A s + B u, c = C s, strictly proper), element input x = -c, element output y, and the plant input is the
element output T seconds earlier, u(t) = y(t - T). When the element's output is piecewise constant (every mode
of its :class:`~dfloop.describing.time_model.PiecewiseAffine` time model has y = constant: relays with hysteresis and dead zone, the
quantizer), the delay line holds finitely many pending switches, so the loop is a finite-dimensional hybrid
system with state (s, y's mode, u, the pending switch instants of u in (t, t + T]):

- between events u is constant and s(t + h) = e^{Ah} s + (int_0^h e^{A r} dr) B u exactly (one augmented
  matrix exponential);
- an element switch is a root of a guard g = cx x + c1 of the current mode (x through a threshold); it is
  bracketed on steps of 1/32 of the plant's fastest time scale (a minimum of g between two samples is located
  from g' and checked too) and refined to rounding level by Brent's method on the exact flow; the new output
  level is queued to reach the plant at t + T;
- a queued switch reaches the plant at its instant: u jumps.

The tangent (variational) flow is carried along on request: perturbations of s and of the pending switch
instants. A switch of u at tau from level a to b adds B (a - b) d tau to d s (the saltation of a delayed
switch); an element switch does not move s (u is continuous there) but its instant moves by
d t* = -(r . d s) / (r . f) (r: the guard's row, f = A s + B u), which becomes the perturbation of the new
pending switch. With T = 0 the two compose to the usual saltation matrix I + (f+ - f-) r^T / (r . f-).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq

from ..describing.time_model import OUT_OF_RANGE, PiecewiseAffine
from .dde import DDELoop, dde_orbit, dde_simulation
from .constant import unshift
from .dde_memory import DelayMemoryError, MemoryDDELoop, memory_orbit, memory_simulation
from .delay_impact import DelayImpactError, DelayImpactLoop, impact_orbit, impact_simulation
from .delay_sampled import DelaySampledLoop, sampled_delay_simulation
from .run import LoopSimulation

__all__ = ["DelayLoop", "DelayFlow", "DelayError", "piecewise_constant", "predicted_start", "return_map",
           "delay_orbit", "delay_periodic_orbit", "delay_simulation", "split_delay", "STEPS_PER_SCALE"]

STEPS_PER_SCALE = 32
_BLOCK = 32                   # steps sampled at once
_GRAZING = 1e-10              # |r.f| below this fraction of |r||f| at a switch: grazing (tangent undefined)
_CLOCK_ROUNDING = 64 * np.finfo(float).eps   # rounding of absolute instants, relative to the time elapsed


class DelayError(RuntimeError):
    """The delayed flow cannot continue: input out of the modelled range, grazing switch, or an event bound."""


def split_delay(G) -> tuple[object, float]:
    """(delay-free part, delay T in s) of a plant: a plant with a pure delay
    (:class:`dfloop.solve.delay.DelayedSystem`) carries its rational part as ``system`` and T as ``delay`` (a
    :class:`dfloop.solve.plant.Plant` made from one, as ``delay_free``); any other plant is returned as it is,
    with T = 0. (Read by attribute: the engines sit above the solver's layer, which defines the classes.)"""
    system, delay = getattr(G, "system", None), getattr(G, "delay", None)
    if system is None and delay:
        system = getattr(G, "delay_free", None)
    if system is None or delay is None:
        return G, 0.0
    return system, float(delay)


def piecewise_constant(model) -> bool:
    """True when the time model is :class:`PiecewiseAffine` and every mode has a constant output and plain
    threshold guards on x (relays with hysteresis and dead zone, the quantizer)."""
    if not isinstance(model, PiecewiseAffine) or model.n_states:
        return False
    for m in model.modes:
        if m.gx != 0.0 or m.ge != 0.0 or m.de != 0.0:
            return False
        for g in m.guards:
            if g.cxd != 0.0 or g.ce != 0.0 or g.reset is not None:
                return False
    return True


@dataclass
class DelayFlow:
    """Result of :meth:`DelayLoop.flow` from time 0.

    ``t``: end time (s); ``s``, ``mode``, ``u``, ``queue``: end state (queue: list of [instant, level] of the
    pending switches of u, instants absolute); ``segments``: (start time, plant state, u) of every interval
    with constant u; ``switches``: (time, from mode, to mode) of every element switch; ``tangent``: the
    variational matrix d(s, queue instants)(end) / d(s, queue instants)(0) (or None); ``rate``: A s + B u at
    the end; ``stopped``: the flow ended on the requested section event; ``diverged``: |x| passed the bound.
    """

    t: float
    s: np.ndarray
    mode: int
    u: float
    queue: list
    segments: list = field(default_factory=list)
    switches: list = field(default_factory=list)
    tangent: np.ndarray | None = None
    rate: np.ndarray | None = None
    stopped: bool = False
    diverged: bool = False
    guard_row: np.ndarray | None = None
    mode0: int = 0


class DelayLoop:
    """The loop of a plant (A, B, C) with a pure delay and a piecewise-constant element: the loop model
    :func:`dfloop.hybrid.loop_model` builds for a :class:`~dfloop.solve.delay.DelayedSystem` plant.

    Its state is not one vector z (the delay line holds a varying number of pending switches), so it has its own
    orbit finder (:func:`delay_orbit`, Newton on the return map) and run (:func:`delay_simulation`);
    ``delay`` > 0 tells the callers (every other loop model has ``delay`` = 0).

    Parameters
    ----------
    A, B, C : ndarray
        Strictly proper plant (the delay-free part).
    element : PiecewiseAffine
        The element's time model, piecewise constant (:func:`piecewise_constant`).
    delay : float
        The delay T (s), >= 0.
    time_scale : float
        Longest step (s) times 32, e.g. the expected period; steps are also bounded by the plant's fastest
        time constant.
    """

    exact = True            # an exact flow: periodic orbits can be found (by delay_orbit)
    settle_periods = 0.0

    def __init__(self, A, B, C, element: PiecewiseAffine, delay: float, time_scale: float):
        if not piecewise_constant(element):
            raise ValueError(f"N: the {element.name} model is not piecewise constant; the exact delay flow needs "
                             "an element whose output is constant between switches (relay, quantizer)")
        self.A, self.B, self.C = (np.asarray(a, float) for a in (A, B, C))
        self.n = n = self.A.shape[0]
        self.element, self.delay = element, float(delay)
        self.method = (f"exact delay flow (T = {self.delay:g} s: matrix exponentials between events, element "
                       "switches located to rounding level and delayed exactly)")
        self.plant = (self.A, self.B)
        self.levels = np.array([m.g1 for m in element.modes], float)
        self.rows, self.consts, self.targets = [], [], []
        for m in element.modes:
            self.rows.append(np.array([-g.cx * self.C for g in m.guards]).reshape(-1, n))
            self.consts.append(np.array([g.c1 for g in m.guards], float))
            self.targets.append([g.target for g in m.guards])
        lam = np.abs(np.linalg.eigvals(self.A)) if n else np.zeros(0)
        lam = lam[lam > 1e-12 * max(lam.max(initial=0.0), 1e-300)]
        scale = min(time_scale, float(1.0 / lam.max()) if lam.size else time_scale)
        self.dt = scale / STEPS_PER_SCALE
        big = np.zeros((n + 1, n + 1))
        big[:n, :n], big[:n, n] = self.A, self.B
        E = expm(big * self.dt)
        Phi, Gam = E[:n, :n], E[:n, n]
        self.Phik = np.empty((_BLOCK, n, n))
        self.Gamk = np.empty((_BLOCK, n))
        P, Gk = np.eye(n), np.zeros(n)
        for k in range(_BLOCK):
            Gk = Phi @ Gk + Gam
            P = Phi @ P
            self.Phik[k], self.Gamk[k] = P, Gk
        self._big = big

    # ----------------------------------------------------------------------------------------- helpers

    def x(self, s) -> np.ndarray:
        """Element input x = -C s (last axis of s)."""
        return -(np.asarray(s) @ self.C)

    def propagate(self, s: np.ndarray, u: float, h: float) -> np.ndarray:
        """Plant state after h >= 0 seconds at constant input u (exact)."""
        if h == 0.0:
            return np.array(s, float)
        E = expm(self._big * h)
        return E[:self.n, :self.n] @ s + E[:self.n, self.n] * u

    def states(self, flow: DelayFlow, t) -> np.ndarray:
        """Plant states at times t (within the flow's span), one row per time."""
        t = np.atleast_1d(np.asarray(t, float))
        starts = np.array([seg[0] for seg in flow.segments])
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, starts.size - 1)
        out = np.empty((t.size, self.n))
        for i, ti in enumerate(t):
            t0, s0, u = flow.segments[k[i]]
            out[i] = self.propagate(s0, u, ti - t0)
        return out

    def output(self, flow: DelayFlow, t) -> np.ndarray:
        """Element output y at times t (from the recorded element switches; the start mode before the first)."""
        t = np.atleast_1d(np.asarray(t, float))
        times = np.array([sw[0] for sw in flow.switches])
        modes = np.array([flow.mode0] + [sw[2] for sw in flow.switches], int)
        k = np.searchsorted(times, t, side="right")
        return self.levels[modes[k]]

    def fourier(self, flow: DelayFlow, t_end: float, omega: float, harmonics: int) -> np.ndarray:
        """Exact (1/T) int_0^T x(t) e^{-jkwt} dt, k = 1..harmonics, T = t_end (block exponentials per segment)."""
        n = self.n
        N = n + 1
        starts = [seg[0] for seg in flow.segments]
        ends = starts[1:] + [t_end]
        out = np.zeros(harmonics, complex)
        big = np.zeros((2 * N, 2 * N), complex)
        big[N:, :N] = np.eye(N)
        row = np.append(-self.C, 0.0)
        for (t0, s0, u), t1 in zip(flow.segments, ends):
            t1 = min(t1, t_end)
            if t1 <= t0:
                continue
            Au = np.zeros((N, N))
            Au[:n, :n], Au[:n, n] = self.A, self.B * u
            z0 = np.append(s0, 1.0)
            for k in range(1, harmonics + 1):
                big[:N, :N] = Au - 1j * k * omega * np.eye(N)
                y = expm(big * (t1 - t0)) @ np.concatenate([z0, np.zeros(N)])
                out[k - 1] += np.exp(-1j * k * omega * t0) * (row @ y[N:])
        return out / t_end

    # ------------------------------------------------------------------------------------- event search

    def _guards(self, S: np.ndarray, mode: int) -> np.ndarray:
        return S @ self.rows[mode].T + self.consts[mode]

    def _next_switch(self, s, u, mode, span):
        """First guard root of ``mode`` within (0, span] at constant u: (h, guard index, state there), or
        (None, -1, None)."""
        rows, consts = self.rows[mode], self.consts[mode]
        if rows.shape[0] == 0:
            return None, -1, None
        ra = rows @ self.A
        rb = rows @ self.B
        h0, s_left = 0.0, np.array(s, float)
        g_left = rows @ s_left + consts
        d_left = ra @ s_left + rb * u
        while h0 < span:
            k = min(_BLOCK, int(math.ceil((span - h0) / self.dt)))
            S = self.Phik[:k] @ s_left + self.Gamk[:k] * u
            G = S @ rows.T + consts
            D = S @ ra.T + rb * u
            Gp, Dp = np.vstack([g_left, G]), np.vstack([d_left, D])
            a, b = Gp[:-1], Gp[1:]
            cross = (a >= 0.0) & (b < 0.0)
            dip = (a >= 0.0) & (b >= 0.0) & (Dp[:-1] < 0.0) & (Dp[1:] > 0.0)
            if h0 == 0.0:
                # started outside the mode: switch now when moving further out; a start a rounding error
                # outside while moving in (just after a switch through the same threshold) is no event
                out0 = (a[0] < 0.0) & (d_left <= 0.0)
                cross[0] = (cross[0] & (a[0] >= 0.0)) | out0
            for i in np.flatnonzero((cross | dip).any(axis=1)):
                best, best_j = math.inf, -1
                for j in np.flatnonzero(cross[i] | dip[i]):
                    if cross[i, j]:
                        tau = self._refine(s_left, u, i, j, mode, self.dt, outside=a[i, j] < 0.0)
                    else:
                        hm, gm = self._minimum(s_left, u, i, j, mode)
                        if gm >= 0.0:
                            continue
                        tau = self._refine(s_left, u, i, j, mode, hm)
                    if tau < best:
                        best, best_j = tau, int(j)
                if best_j >= 0:
                    h = h0 + i * self.dt + best
                    if h > span:
                        return None, -1, None
                    return h, best_j, self._state_in_step(s_left, u, i, best)
            h0 += k * self.dt
            s_left, g_left, d_left = S[-1], G[-1], D[-1]
        return None, -1, None

    def _state_in_step(self, s_left, u, i, tau):
        """State at tau (0 <= tau <= dt) into step i of a block started at s_left."""
        base = s_left if i == 0 else (self.Phik[i - 1] @ s_left + self.Gamk[i - 1] * u)
        return self.propagate(base, u, tau)

    def _g(self, s_left, u, i, j, mode, tau):
        return float(self.rows[mode][j] @ self._state_in_step(s_left, u, i, tau) + self.consts[mode][j])

    def _minimum(self, s_left, u, i, j, mode):
        """(time into step i, guard value) at the minimum of guard j inside step i."""
        r, rb = self.rows[mode][j] @ self.A, float(self.rows[mode][j] @ self.B)

        def dg(tau):
            return float(r @ self._state_in_step(s_left, u, i, tau) + rb * u)

        tau = brentq(dg, 0.0, self.dt, xtol=1e-15 * self.dt, rtol=8.9e-16)
        return tau, self._g(s_left, u, i, j, mode, tau)

    def _refine(self, s_left, u, i, j, mode, hi, outside=False):
        """Time into step i of the first root of guard j (g >= 0 at the step's start, < 0 at ``hi``)."""
        if outside:
            return 0.0
        g = lambda v: self._g(s_left, u, i, j, mode, v)   # noqa: E731
        tau = brentq(g, 0.0, hi, xtol=1e-15 * self.dt, rtol=8.9e-16)
        # the first point at or past the root (g <= 0 there), so the switch is never taken a hair early
        for _ in range(64):
            if g(tau) <= 0.0 or tau >= hi:
                break
            tau = min(hi, tau + 4.5e-16 * max(tau, self.dt))
        return tau

    # ---------------------------------------------------------------------------------------------- flow

    def flow(self, s0, mode0: int, u0: float, queue0, t_end: float, *, tangent: bool = False,
             stop_after: int = 0, section: tuple | None = None, max_events: int = 100_000,
             diverge: float = math.inf) -> DelayFlow:
        """Flow from (s0, mode0, u0, queue0) at t = 0 until ``t_end`` (s), or until the ``stop_after``-th element
        switch matching ``section`` = (from mode, to mode) when given.

        ``queue0``: pending switches of u as [instant, level] with instants in (0, T], sorted. ``tangent``:
        carry the variational matrix with respect to (s0, queue0 instants). ``diverge``: stop when |x| exceeds
        it (sampled at the events and the segment ends).

        Raises
        ------
        DelayError
            The input left the modelled range (quantizer), a grazing switch with ``tangent``, or more than
            ``max_events`` events (raise it for longer runs).
        """
        n = self.n
        s = np.array(s0, float)
        mode, u = int(mode0), float(u0)
        queue = [[float(a), float(b)] for a, b in queue0]
        t = 0.0
        W = np.eye(n + len(queue)) if tangent else None
        flow = DelayFlow(0.0, s, mode, u, queue)
        flow.mode0 = mode
        flow.segments.append((0.0, s.copy(), u))
        events, hits = 0, 0
        while t < t_end:
            t_stop = min(queue[0][0], t_end) if queue else t_end
            h, j, s_new = self._next_switch(s, u, mode, t_stop - t)
            if h is not None:
                if W is not None:
                    W[:n] = expm(self.A * h) @ W[:n]
                t += h
                s = s_new
                target = self.targets[mode][j]
                if target == OUT_OF_RANGE:
                    raise DelayError(f"at t = {t:.6g} s the input x = {float(self.x(s)):.6g} left the range the "
                                     f"{self.element.name} model covers")
                r = self.rows[mode][j]
                f = self.A @ s + self.B * u
                if W is not None:
                    rf = float(r @ f)
                    if abs(rf) <= _GRAZING * np.linalg.norm(r) * np.linalg.norm(f):
                        raise DelayError(f"grazing switch at t = {t:.6g} s (the guard is tangent to the flow): "
                                         "the tangent flow is undefined there")
                    W = np.vstack([W, -(r @ W[:n]) / rf])
                queue.append([t + self.delay, float(self.levels[target])])
                flow.switches.append((t, mode, target))
                prev = mode
                mode = target
                events += 1
                if section is not None and (prev, target) == tuple(section):
                    hits += 1
                    if hits >= stop_after:
                        flow.stopped = True
                        flow.guard_row = r
                        break
            else:
                dt_ = t_stop - t
                s = self.propagate(s, u, dt_)
                if W is not None:
                    W[:n] = expm(self.A * dt_) @ W[:n]
                t = t_stop
                if queue and queue[0][0] <= t:
                    inst, level = queue.pop(0)
                    if W is not None:
                        W[:n] += np.outer(self.B * (u - level), W[n])
                        W = np.delete(W, n, axis=0)
                    u = level
                    flow.segments.append((t, s.copy(), u))
                    events += 1
            if events > max_events:
                raise DelayError(f"max_events = {max_events} events reached at t = {t:.6g} s (raise max_events "
                                 "for longer runs; many switches in a short time mean chattering)")
            if abs(float(self.x(s))) > diverge:
                flow.diverged = True
                break
        flow.t, flow.s, flow.mode, flow.u, flow.queue, flow.tangent = t, s, mode, u, queue, W
        flow.rate = self.A @ s + self.B * u
        return flow

    def sample(self, flow: DelayFlow, t: np.ndarray) -> np.ndarray:
        """Plant states at sorted times t within the flow's span (one exponential per segment, then steps of
        the uniform spacing of t when it is uniform)."""
        t = np.asarray(t, float)
        out = np.empty((t.size, self.n))
        starts = np.array([seg[0] for seg in flow.segments])
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, starts.size - 1)
        step = float(t[1] - t[0]) if t.size > 1 else 0.0
        uniform = t.size > 2 and np.allclose(np.diff(t), step, rtol=1e-9, atol=0.0)
        if uniform:
            big = expm(self._big * step)
            Ps, Gs = big[:self.n, :self.n], big[:self.n, self.n]
        bounds = np.flatnonzero(np.diff(np.concatenate([[-1], k, [k[-1] + 1 if k.size else 0]])))
        for a_, b_ in zip(bounds[:-1], bounds[1:]):
            t0, s0, u = flow.segments[k[a_]]
            z = self.propagate(s0, u, t[a_] - t0)
            out[a_] = z
            for i in range(a_ + 1, b_):
                z = Ps @ z + Gs * u if uniform else self.propagate(s0, u, t[i] - t0)
                out[i] = z
        return out


# ----------------------------------------------------------------------------------------------- starts


def _sinusoid_switches(loop: DelayLoop, A0: float, w0: float, t0: float, t1: float, mode: int, offset: float = 0.0):
    """Element switches (time, from, to) driven by x = offset + A0 sin(w0 t) on [t0, t1] from ``mode``, located by
    bisection to rounding level; returns (switches, mode at t1)."""
    P = 2.0 * math.pi / w0
    ts = np.linspace(t0, t1, int(math.ceil((t1 - t0) / P * 4096)) + 2)
    xs = offset + A0 * np.sin(w0 * ts)
    out = []
    i = 0
    while i < ts.size - 1:
        nxt = None
        for j, gd in enumerate(loop.element.modes[mode].guards):
            r_c, c, tgt = gd.cx, gd.c1, gd.target
            g0, g1 = r_c * xs[i] + c, r_c * xs[i + 1] + c
            if g0 >= 0.0 > g1:
                tc = brentq(lambda t: r_c * (offset + A0 * math.sin(w0 * t)) + c, ts[i], ts[i + 1], xtol=1e-15 * P)
                if nxt is None or tc < nxt[0]:
                    nxt = (tc, j, tgt)
        if nxt is None:
            i += 1
            continue
        tc, j, tgt = nxt
        if tgt == OUT_OF_RANGE:
            raise DelayError(f"the predicted input (amplitude {A0:g}) leaves the range the element model covers")
        out.append((tc, mode, tgt))
        mode = tgt
        # a new mode may have to switch again in the same sample interval (not for thresholds on a sinusoid)
        i += 1
    return out, mode


def predicted_start(loop: DelayLoop, A0: float, w0: float, section: tuple | None = None, bias: float = 0.0):
    """Loop state just after an element switch on the predicted orbit x = bias + A0 sin(w0 t).

    The element is driven by the sinusoid (its switches located exactly); the plant state is the exact
    periodic response, (I - e^{AP}) s = int e^{A(P - r)} B u(r) dr (least squares when G has an integrator),
    to the delayed piecewise-constant output those switches give.

    Returns (s, mode, u, queue, section): queue holds the pending switches [instant, level] (instants
    relative to the section switch, in (0, T]); ``section`` = (from mode, to mode) of the switch (default:
    the switch into the highest output level).
    """
    P = 2.0 * math.pi / w0
    T = loop.delay
    span = T + 3.0 * P
    offset = bias - getattr(loop, "r0", 0.0)       # the element's input of a shifted model is x - r0
    mode0 = int(loop.element.initial(np.full(1, offset), 0.0)[0])   # at x = bias (any mode works after a period)
    sw, _ = _sinusoid_switches(loop, A0, w0, -span, P, mode0, offset)
    if not sw:
        raise DelayError(f"the predicted input x = {bias:g} + {A0:g} sin({w0:g} t) never switches the element")
    if section is None:
        top = max(loop.levels[to] for _, _, to in sw)
        section = next((f, to) for _, f, to in reversed(sw) if loop.levels[to] == top)
    late = [e for e in sw if e[0] > -span + P + T and (e[1], e[2]) == tuple(section)]
    if not late:
        raise DelayError("the predicted input does not take the section switch again")
    ts = late[-1][0]
    queue = [[t - ts + T, float(loop.levels[to])] for t, _, to in sw if ts - T < t <= ts]
    before = [to for t, _, to in sw if t <= ts - T]
    u0 = float(loop.levels[before[-1]]) if before else float(loop.levels[mode0])
    # plant input over [ts, ts + P): u0, then the queued levels (and the cycle's later switches, delayed)
    times = [t + T for t, _, _ in sw if ts - T < t <= ts + P - T]
    levels = [float(loop.levels[to]) for t, _, to in sw if ts - T < t <= ts + P - T]
    n = loop.n
    Phi = np.eye(n)
    F = np.zeros(n)
    t_prev, u = ts, u0
    for tk, lk in zip(times + [ts + P], levels + [None]):
        E = expm(loop._big * (tk - t_prev))
        F = E[:n, :n] @ F + E[:n, n] * u
        Phi = E[:n, :n] @ Phi
        t_prev = tk
        if lk is not None:
            u = lk
    s = np.linalg.lstsq(np.eye(n) - Phi, F, rcond=1e-12)[0]
    return s, int(section[1]), u0, queue, tuple(section)


def _resting_start(loop: DelayLoop, bias: float):
    """The start when the predicted input x = bias + A0 sin(w0 t) never switches the element (a run from inside a
    dead zone or a hysteresis): the element holds the output it has at x = bias, so the plant's periodic response
    is its equilibrium under that constant input, A s + B u = 0 (least squares with an integrator); no pending
    switch. Returns (s, mode, u, queue)."""
    offset = bias - getattr(loop, "r0", 0.0)
    mode = int(loop.element.initial(np.full(1, offset), 0.0)[0])
    u = float(loop.levels[mode])
    s = np.linalg.lstsq(loop.A, -loop.B * u, rcond=1e-12)[0]
    return s, mode, u, []


# --------------------------------------------------------------------------------------- the return map


def return_map(loop: DelayLoop, s, mode: int, u: float, queue, section: tuple, *, horizon: float,
               tangent: bool = True, max_events: int = 100_000):
    """One return to the section switch: (s1, u1, queue1 relative to the return, period, Jacobian, flow).

    The Jacobian is that of (s, queue instants) -> (s1, queue1 instants) on the section: the end perturbation
    is taken at the perturbed return instant (d t1 = a . d s1, a = -r / (r . f)), so d s1 -> (I + f a) d s1 and
    every pending instant moves by -d t1. None when the flow does not return within ``horizon`` seconds.
    """
    fl = loop.flow(s, mode, u, queue, horizon, tangent=tangent, stop_after=1, section=section,
                   max_events=max_events)
    if not fl.stopped:
        return None
    t1 = fl.t
    # a pending instant is t_switch + T - t1 <= T; the clock's rounding (eps t1, not small against a tiny T) can
    # put the section switch's own instant a hair above T: clamp it back
    q1 = [[min(inst - t1, loop.delay), lev] for inst, lev in fl.queue]
    J = None
    if tangent:
        n = loop.n
        f, r = fl.rate, fl.guard_row
        a = -r / float(r @ f)
        Pr = np.eye(n + len(q1))
        Pr[:n, :n] += np.outer(f, a)
        Pr[n:, :n] -= a[None, :]
        J = Pr @ fl.tangent
    return fl.s.copy(), fl.u, q1, t1, J, fl


def _pack(s, queue):
    return np.concatenate([s, [q[0] for q in queue]])


def delay_orbit(loop: DelayLoop | DDELoop | MemoryDDELoop, A0: float, w0: float, *, tol: float = 1e-11, max_iterations: int = 40,
                harmonics: int = 15, samples: int = 512, max_events: int = 100_000, max_deviation: float = 0.5,
                start=None, bias: float = 0.0, settle_periods: float = 0.0) -> dict:
    """:func:`delay_periodic_orbit` (:func:`~dfloop.hybrid.dde.dde_orbit` for a
    :class:`~dfloop.hybrid.dde.DDELoop`, :func:`~dfloop.hybrid.dde_memory.memory_orbit` for a
    :class:`~dfloop.hybrid.dde_memory.MemoryDDELoop`) with the prediction's errors and the ``max_deviation`` test: a dict of the
    fields of :class:`dfloop.exact.ExactCycle` (``ExactCycle(**delay_orbit(...))``).

    A loop with a constant input (``loop.r0``, ``loop.load``: :mod:`dfloop.hybrid.constant`) is solved around its
    shifted element and read back (x, y and ``mean`` in the loop's own signals); ``bias`` is the predicted mean of
    x, where the exact delay flow's start sits (x = bias + A0 sin(w0 t)). ``settle_periods`` > 0: on the delay
    equation of a static element (:class:`~dfloop.hybrid.dde.DDELoop`) Newton starts from the motion settled
    after that many periods; the other delayed loops start on the prediction.

    Raises
    ------
    ValueError
        ``loop`` is a :class:`~dfloop.hybrid.delay_sampled.DelaySampledLoop` (an element known only through an
        operator: a fixed-step run, no exact orbit), naming N.
    """
    if isinstance(loop, DelaySampledLoop):
        raise ValueError(f"N: {loop.model.name} is known only through a sampled operator ({loop.method}): "
                         "exact_cycle needs an exact time model (piecewise affine, smooth or impact; implement "
                         "time_model(), see dfloop.describing.time_model)")
    r0, load = getattr(loop, "r0", 0.0), getattr(loop, "load", 0.0)
    if isinstance(loop, DelayImpactLoop):   # masses and impacts: the method of steps on the impact engine
        out = impact_orbit(loop, A0, w0, tol=max(tol, 1e-10), max_iterations=max_iterations, harmonics=harmonics,
                           samples=samples)
    elif isinstance(loop, DDELoop):   # a static element with sloped pieces or a smooth one: the delay equation
        out = dde_orbit(loop, A0, w0, harmonics=harmonics, samples=samples, settle_periods=settle_periods)
    elif isinstance(loop, MemoryDDELoop):   # an element with memory (backlash): its state in the history
        out = memory_orbit(loop, A0, w0, tol=max(tol, 1e-12), max_iterations=max_iterations, harmonics=harmonics,
                           samples=samples, offset=bias - r0)
    else:
        if start is None and bias != 0.0:
            try:
                start = predicted_start(loop, A0, w0, bias=bias)
            except DelayError as exc:
                return dict(success=False, message=f"no start on the prediction: {exc}", method=loop.method,
                            predicted=(A0, w0))
        out = delay_periodic_orbit(loop, A0, w0, tol=tol, max_iterations=max_iterations, harmonics=harmonics,
                                   samples=samples, max_events=max_events, start=start)
    out = unshift(out, r0, load)
    out["predicted"] = (A0, w0)
    if not out["success"]:
        return {k: out[k] for k in ("success", "message", "predicted", "method", "residual", "iterations")
                if k in out}
    A, w = out["amplitude"], out["frequency"]
    out["amplitude_error"], out["frequency_error"] = (A0 - A) / A, (w0 - w) / w
    deviation = max(abs(math.log(A / A0)), abs(math.log(w / w0)))
    if deviation > max_deviation:
        return dict(success=False, predicted=(A0, w0), method=out["method"], residual=out["residual"],
                    iterations=out["iterations"], extra={"another_orbit": out},
                    message=f"Newton converged to another orbit (A={A:.6g}, w={w:.6g} rad/s, "
                            f"{'stable' if out['stable'] else 'unstable'}), farther from the prediction than "
                            f"max_deviation = {max_deviation:g} in log(A) or log(w): the predicted cycle may not "
                            "exist as a true orbit; raise max_deviation to accept it")
    return out


def delay_periodic_orbit(loop: DelayLoop, A0: float, w0: float, *, tol: float = 1e-11, max_iterations: int = 40,
                         harmonics: int = 15, samples: int = 512, max_events: int = 100_000, start=None) -> dict:
    """The periodic orbit of a delayed loop with a piecewise-constant element, near a predicted (A0, w0).

    Newton's method on the return map to a section switch (the element's switch into its highest level): the
    unknowns are the plant state and the pending switch instants in the delay line at the switch; the
    Jacobian is the exact tangent of the event-located flow (saltation of the delayed switches included).
    The fixed point is a true orbit (every crossing on the way is an event of the flow, so no extra crossing
    can be missed); its Floquet multipliers are the eigenvalues of the converged Jacobian, with the trivial
    multiplier 1 of the autonomous flow added (the section removes it from the map).

    ``start``: optional (s, mode, u, queue, section) to start from instead of the prediction.

    Returns a dict: ``success``, ``message``, ``method`` and, on success, the fields of an
    :class:`dfloop.exact.ExactCycle` (amplitude, frequency, period, t, x, y, switching_times, harmonics,
    multipliers, stable, residual, iterations, extra).
    """
    method = loop.method
    P0 = 2.0 * math.pi / w0
    try:
        s, mode, u, queue, section = start if start is not None else predicted_start(loop, A0, w0)
    except DelayError as exc:
        return dict(success=False, message=f"no start on the prediction: {exc}", method=method)
    horizon = 20.0 * P0 + 2.0 * loop.delay
    residual, it = math.inf, 0
    for it in range(1, max_iterations + 1):
        try:
            out = return_map(loop, s, mode, u, queue, section, horizon=horizon, max_events=max_events)
        except DelayError as exc:
            return dict(success=False, message=f"Newton iteration {it}: {exc}", method=method, residual=residual,
                        iterations=it)
        if out is None:
            return dict(success=False, message=f"Newton iteration {it}: the motion does not return to the "
                        f"section switch within {horizon:.4g} s (it decays to rest or stops switching)",
                        method=method, residual=residual, iterations=it)
        s1, u1, q1, t1, J, fl = out
        v0, v1 = _pack(s, queue), _pack(s1, q1)
        scale = max(float(np.linalg.norm(s)), 1e-300) + t1
        same = len(q1) == len(queue) and u1 == u and all(a[1] == b[1] for a, b in zip(q1, queue))
        previous = residual
        residual = float(np.linalg.norm(v1 - v0)) / scale if same else math.inf
        if same and (residual <= tol or (residual <= 1e-9 and residual > 0.5 * previous)):
            break
        if not same:
            # the switching pattern changed within one return: take the returned state as the new start
            s, u, queue = s1, u1, q1
            continue
        if it == max_iterations:
            return dict(success=False, message=f"Newton did not converge in max_iterations = {max_iterations} "
                        f"(residual {residual:.2e} > tol = {tol:g}); raise max_iterations", method=method,
                        residual=residual, iterations=it)
        try:
            delta = np.linalg.solve(J - np.eye(J.shape[0]), -(v1 - v0))
        except np.linalg.LinAlgError:
            return dict(success=False, message=f"singular Jacobian at iteration {it} (a multiplier equal to 1: "
                        "a marginal orbit)", method=method, residual=residual, iterations=it)
        step, accepted = 1.0, False
        # pending instants must stay in (0, T]; the section switch's own instant is T to rounding, which is relative
        # to the clock (eps times the period), not to T: a tiny delay gets that slack, then the instant is clamped
        slack = _CLOCK_ROUNDING * (t1 + loop.delay)
        for _ in range(9):
            v = v0 + step * delta
            s_try = v[:loop.n]
            q_try = [[float(min(ti, loop.delay)), q[1]] for ti, q in zip(v[loop.n:], queue)]
            if all(0.0 < ti <= loop.delay + slack for ti in v[loop.n:]) and \
                    all(q_try[i][0] <= q_try[i + 1][0] for i in range(len(q_try) - 1)):
                try:
                    o = return_map(loop, s_try, mode, u, q_try, section, horizon=horizon, tangent=False,
                                   max_events=max_events)
                except DelayError:
                    o = None
                if o is not None:
                    ok = len(o[2]) == len(q_try) and o[1] == u
                    r_try = (float(np.linalg.norm(_pack(o[0], o[2]) - v)) /
                             (max(float(np.linalg.norm(s_try)), 1e-300) + o[3])) if ok else math.inf
                    if r_try < residual or residual < 1e-9:
                        s, queue, accepted = s_try, q_try, True
                        break
            step *= 0.5
        if not accepted:
            return dict(success=False, message=f"Newton iteration {it}: no step reduces the residual "
                        f"{residual:.2e}", method=method, residual=residual, iterations=it)
    else:
        return dict(success=False, message=f"no consistent return in max_iterations = {max_iterations} (the "
                    "switching pattern kept changing between returns); raise max_iterations", method=method,
                    residual=residual, iterations=max_iterations)
    return _orbit_fields(loop, fl, J, s, mode, u, queue, section, t1, residual, it, harmonics, samples, method)


def _orbit_fields(loop, fl, J, s, mode, u, queue, section, P, residual, it, harmonics, samples, method) -> dict:
    w = 2.0 * math.pi / P
    X = 2j * loop.fourier(fl, P, w, harmonics)
    phase = float(np.angle(X[0]))
    shift = phase / w
    k = np.arange(1, harmonics + 1)
    X = X * np.exp(-1j * k * phase)
    X[0] = abs(X[0])
    t_new = np.arange(samples) * (P / samples)
    t_old = np.mod(t_new - shift, P)
    order = np.argsort(t_old)
    states = np.empty((samples, loop.n))
    states[order] = loop.states(fl, t_old[order])
    x = loop.x(states)
    y = loop.output(fl, t_old)
    switches = np.sort(np.mod(np.array([sw[0] for sw in fl.switches]) + shift, P))
    mu = np.linalg.eigvals(J)
    mu = mu[np.abs(mu) > 1e-12]
    mu = np.concatenate([[1.0 + 0j], mu])
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    others = np.abs(np.linalg.eigvals(J))
    stable = bool(np.all(others < 1.0))
    msg = (f"converged in {it} Newton iteration(s) on the return map, residual {residual:.1e}; "
           f"{len(queue)} pending switch(es) in the delay line at the section")
    return dict(success=True, message=msg, method=method, amplitude=float(X[0].real), frequency=w, period=P,
                t=t_new, x=x, y=y, switching_times=switches, harmonics=X, multipliers=mu, stable=stable,
                residual=residual, iterations=it,
                extra={"s0": np.array(s), "mode0": mode, "u0": u, "queue0": [list(q) for q in queue],
                       "section": section, "delay": loop.delay})


def delay_simulation(loop: DelayLoop | DDELoop | MemoryDDELoop | DelaySampledLoop, amplitude: float, frequency: float,
                     periods: float, steps_per_period: int, diverge: float = 1e6, max_events: int = 10_000_000,
                     bias: float = 0.0) -> LoopSimulation:
    """Run the delayed loop from the predicted orbit of (amplitude, frequency) (:func:`predicted_start`, time 0
    at the switch into the element's highest level) for ``periods`` periods; x and y sampled uniformly. A
    :class:`~dfloop.hybrid.dde.DDELoop` runs its method of steps instead (:func:`dde_simulation`), a
    :class:`~dfloop.hybrid.dde_memory.MemoryDDELoop` its own (:func:`memory_simulation`), a
    :class:`~dfloop.hybrid.delay_sampled.DelaySampledLoop` its fixed step with the exact delay line
    (:func:`~dfloop.hybrid.delay_sampled.sampled_delay_simulation`, x and y at its step times).

    With a constant input (``loop.r0``, ``loop.load``) x and y are the loop's own signals (the shifted element's
    read back, :mod:`dfloop.hybrid.constant`); the exact delay flow starts on x = ``bias`` + amplitude sin(w t).

    Returns the :class:`~dfloop.hybrid.run.LoopSimulation`; the run stops early when |x| exceeds ``diverge``
    times the amplitude.
    """
    r0, load = getattr(loop, "r0", 0.0), getattr(loop, "load", 0.0)
    if isinstance(loop, DelayImpactLoop):
        try:
            sim = impact_simulation(loop, amplitude, frequency, periods, steps_per_period, diverge)
        except DelayImpactError as exc:
            raise DelayError(str(exc)) from None
    elif isinstance(loop, DDELoop):
        sim = dde_simulation(loop, amplitude, frequency, periods, steps_per_period, diverge)
    elif isinstance(loop, DelaySampledLoop):
        sim = sampled_delay_simulation(loop, amplitude, frequency, periods, diverge)
    elif isinstance(loop, MemoryDDELoop):
        try:
            sim = memory_simulation(loop, amplitude, frequency, periods, steps_per_period, diverge)
        except DelayMemoryError as exc:
            raise DelayError(str(exc)) from None
    else:
        P = 2.0 * math.pi / frequency
        try:
            s, mode, u, queue, _ = predicted_start(loop, amplitude, frequency, bias=bias)
        except DelayError as exc:
            if "never switches" not in str(exc):
                raise
            s, mode, u, queue = _resting_start(loop, bias)
        t_end = periods * P
        fl = loop.flow(s, mode, u, queue, t_end, max_events=max_events, diverge=diverge * amplitude)
        t = np.arange(int(math.floor(fl.t / P * steps_per_period)) + 1) * (P / steps_per_period)
        t = t[t <= fl.t]
        x = loop.x(loop.sample(fl, t))
        y = loop.output(fl, t)
        sim = LoopSimulation(t, x, y, fl.diverged, loop.method)
    if r0 != 0.0 or load != 0.0:
        sim = LoopSimulation(sim.t, sim.x + r0, sim.y - load, sim.diverged, sim.method)
    return sim
