"""The closed loop of a strictly proper plant and a smooth (not piecewise-linear) static element.

Same interface as :class:`dfloop.hybrid.loop.HybridLoop` (augmented state z = [s, 1], one mode), integrated by
DOP853 (8th order) at rtol 1e-12, with the variational equation Phi' = (A - B f'(x) C) Phi alongside for the
monodromy (f' from the time model, or by central differences, relative accuracy ~1e-10). Not exact: used for
elements such as :class:`~dfloop.describing.static.CubicStiffness` or a user's f, and said so in every result.

One integrator per element: a built-in smooth element (its time model carries the compiled form, kind and
parameters as the compiled prediction pipeline encodes them) runs on the compiled DOP853 of
:mod:`dfloop.hybrid.smooth_compiled` (each node its own integration in one numba call, every flow with its dense
output); a user's Python f runs on scipy's ``solve_ivp`` DOP853, all shooting nodes as one ODE system
(:meth:`SmoothLoop.flow_many`: the element evaluated on every node's input in one vectorised call).
``DFLOOP_COMPILED=0`` selects scipy's for every element (the reference path,
:func:`dfloop.solve.compiled.enabled`). Either way the period's flow is joined from the node flows
(:meth:`SmoothLoop.join`): the shooting's cost is a few integrations over 1/m of a period.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp

from .loop import Flow, HybridError, LoopModel

__all__ = ["SmoothLoop"]

RTOL = 1e-12
_MAX_STEPS_PER_SCALE = 16   # max_step = time scale / this (steps are error-controlled below it)


class _Block:
    """Dense output of one node's rows [offset, offset + n) of a joint integration."""

    def __init__(self, sol, offset: int, n: int):
        self.sol, self.offset, self.n = sol, offset, n

    def __call__(self, t):
        return self.sol(t)[self.offset:self.offset + self.n]


class _Joined:
    """Dense output of consecutive node flows of length tau each."""

    def __init__(self, pieces, tau: float):
        self.pieces, self.tau = pieces, tau

    def __call__(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        k = np.clip((t // self.tau).astype(int), 0, len(self.pieces) - 1)
        out = None
        for i in np.unique(k):
            m = k == i
            vals = self.pieces[i](t[m] - i * self.tau)
            if out is None:
                out = np.empty((vals.shape[0], t.size))
            out[:, m] = vals
        return out


class _Steps:
    """Dense output of a compiled flow: its DOP853 steps (rows of :func:`~dfloop.hybrid.smooth_compiled.flows`)."""

    def __init__(self, rows: np.ndarray, n: int, start: np.ndarray):
        self.rows, self.n, self.start = rows, n, start

    def values(self, t) -> np.ndarray:
        """The plant state at times t: (len(t), n)."""
        t = np.ascontiguousarray(np.atleast_1d(np.asarray(t, float)))
        if self.rows.shape[0] == 0:       # a flow of length 0
            return np.repeat(self.start[None, :], t.size, axis=0)
        from .smooth_compiled import dense_values

        return dense_values(self.rows, self.n, t)

    def __call__(self, t):
        return self.values(t).T


def _compiled_element(form):
    """(kind code, parameters) of a built-in smooth element the compiled integrator takes, or None (no compiled
    form, a kind it does not take, or ``DFLOOP_COMPILED=0``)."""
    if form is None:
        return None
    from ..solve.compiled import enabled
    from ..solve.compiled.kinds import KINDS

    kind = KINDS.get(form[0])
    if kind is None or not enabled():
        return None
    from .smooth_compiled import SMOOTH_KINDS

    return (kind, np.ascontiguousarray(form[1], float)) if kind in SMOOTH_KINDS else None


_T0, _MODE0 = np.zeros(1), np.zeros(1, int)   # the one segment of a smooth flow (shared, never written)
_ANNOUNCED: list = []    # [True] once the compile announcement was made or found unnecessary in this process


class SmoothLoop(LoopModel):
    """Loop of plant (A, B, C) and a static element y = f(x), integrated with DOP853 (not exact).

    ``form``: the element's compiled form (kind name, parameters) of :mod:`dfloop.solve.compiled.kinds`, for the
    compiled integrator (:mod:`dfloop.hybrid.smooth_compiled`); None (a Python f): scipy's ``solve_ivp``.
    """

    exact = True           # flows carry a monodromy (variational equation): periodic orbits can be shot
    settle_periods = 0.0
    batched = True         # flow_many integrates all nodes at once
    switching = False      # one mode: no switches to keep away from the shooting nodes

    def __init__(self, A, B, C, f: Callable, name: str, time_scale: float, slope: Callable | None = None, *,
                 r0: float = 0.0, load: float = 0.0, form: tuple | None = None):
        self.r0, self.load = float(r0), float(load)   # x = r0 - C s, the plant driven by f(x) + load
        self.n = A.shape[0]
        self.size = self.n + 1
        self.plant = (A, B)
        self.A, self.B, self.C, self.f, self.name = A, B, C, f, name
        self.x_row = np.append(-C, self.r0)
        self.max_step = time_scale / _MAX_STEPS_PER_SCALE
        self.method = f"DOP853 (rtol {RTOL:g}; {name} is not piecewise linear, so not exact)"
        self._slope = slope if slope is not None else self._central_slope
        self._compiled = _compiled_element(form)
        self.compiled = self._compiled is not None    # runs on the compiled integrator (else scipy's solve_ivp)
        self._fields: dict = {}
        self._samples = None     # (flow, t_end, x samples, their FFT or None) of the latest fourier

    def x(self, z) -> np.ndarray:
        return np.asarray(z) @ self.x_row

    def output(self, z, mode=0) -> np.ndarray:
        return np.asarray(self.f(self.x(z)), dtype=float)

    def _central_slope(self, x: np.ndarray) -> np.ndarray:
        d = 1e-5 * (1.0 + np.abs(x))
        return (np.asarray(self.f(x + d), float) - np.asarray(self.f(x - d), float)) / (2.0 * d)

    def field(self, z, mode: int = 0) -> np.ndarray:
        """z' at z; for the start and end states of the latest compiled flows the integrator's own value."""
        out = np.zeros(self.size)
        s = np.asarray(z, float)[:self.n]
        known = self._fields.get(id(z))
        if known is not None and known[0] is z and known[1] == s.tobytes():   # that array, unchanged since
            out[:self.n] = known[2]
            return out
        out[:self.n] = self.A @ s + self.B * (float(self.f(np.array(self.r0 - self.C @ s))) + self.load)
        return out

    def admissible_mode(self, z, mode: int = 0):
        return np.asarray(z, float), 0

    def start(self, s0, x_history) -> tuple[np.ndarray, int]:
        return np.append(s0, 1.0), 0

    def flow(self, z0, mode0: int, t_end: float, *, monodromy: bool = False, max_events: int = 0) -> Flow:
        return self.flow_many([z0], [mode0], t_end, monodromy=monodromy)[0]

    def flow_many(self, zs, modes, t_end, *, monodromy: bool = False, max_events: int = 0) -> list:
        """Flows of every start state in ``zs`` over [0, t_end], as one DOP853 run.

        Compiled (a built-in element): each node its own integration, every flow with its dense output. Scipy's
        (a Python f): flows with ``monodromy`` (the shooting's Newton steps) carry no dense output (it costs a
        third of the step); :meth:`join` integrates the converged nodes once more, without the variational
        equation, for it.
        """
        if self._compiled is not None:
            return self._flow_compiled(zs, t_end, monodromy)
        ends = np.broadcast_to(np.asarray(t_end, float), (len(zs),))
        if np.ptp(ends) > 0:       # different spans: one run each
            return [self.flow_many([z], [0], te, monodromy=monodromy)[0] for z, te in zip(zs, ends)]
        t_end = float(ends[0])
        n, m = self.n, len(zs)
        width = n + n * n if monodromy else n
        S0 = np.array([np.asarray(z, float)[:n] for z in zs])
        A, B, C = self.A, self.B, self.C
        f, slope, r0, load = self.f, self._slope, self.r0, self.load

        def rhs(t, u):
            U = u.reshape(m, width)
            s = U[:, :n]
            x = r0 - s @ C
            ds = s @ A.T + np.outer(np.asarray(f(x), float) + load, B)
            if not monodromy:
                return ds.ravel()
            P = U[:, n:].reshape(m, n, n)
            # (A - B f'(x) C) P = A P - B (f'(x) (C P))
            sCP = np.asarray(slope(x), float)[:, None] * (C @ P)
            dP = A @ P - B[None, :, None] * sCP[:, None, :]
            out = np.empty((m, width))
            out[:, :n] = ds
            out[:, n:] = dP.reshape(m, n * n)
            return out.ravel()

        U0 = S0 if not monodromy else np.concatenate([S0, np.tile(np.eye(n).ravel(), (m, 1))], axis=1)
        scale = max(float(np.max(np.abs(S0))), 1e-300)
        sol = solve_ivp(rhs, (0.0, t_end), U0.ravel(), method="DOP853", rtol=RTOL, atol=RTOL * scale,
                        max_step=self.max_step, dense_output=not monodromy)
        end = sol.y[:, -1].reshape(m, width)
        if not sol.success or not np.all(np.isfinite(end)):
            raise HybridError(f"DOP853 failed: {sol.message}")
        flows = []
        for i in range(m):
            M = None
            if monodromy:
                M = np.eye(self.size)
                M[:n, :n] = end[i, n:].reshape(n, n)
            flows.append(Flow(np.append(end[i, :n], 1.0), 0, M, np.array([0.0]), np.append(S0[i], 1.0)[None, :],
                              np.array([0]), [], dense=None if monodromy else _Block(sol.sol, i * width, n)))
        return flows

    def _flow_compiled(self, zs, t_end, monodromy: bool) -> list:
        from . import smooth_compiled as sc

        n, m, size = self.n, len(zs), self.size
        S0 = np.array([z[:n] for z in zs], float)
        ends = np.full(m, t_end, float) if np.ndim(t_end) == 0 else np.ascontiguousarray(t_end, float)
        if ends.shape != (m,):
            raise ValueError(f"t_end must be one span or one per start state ({m}), got {ends.size}")
        kind, params = self._compiled
        if not _ANNOUNCED:
            sc.announce()
            _ANNOUNCED.append(True)
        end, fields, status, _, rows, starts = sc.flows(self.A, self.B, self.C, self.r0, self.load, kind, params, S0,
                                                        ends, monodromy, RTOL, RTOL * max(np.abs(S0).max(), 1e-300),
                                                        self.max_step, sc.MAX_STEPS)
        if status.any():
            bad = int(np.flatnonzero(status)[0])
            raise HybridError(f"DOP853 failed on node {bad} of {m}: {sc.failure(int(status[bad]))}")
        Z0 = np.ones((m, 1, size))
        Z0[:, 0, :n] = S0
        Z = np.ones((m, size))
        Z[:, :n] = end[:, :n]
        M = [None] * m
        if monodromy:
            M = np.zeros((m, size, size))
            M[:, :n, :n] = end[:, n:].reshape(m, n, n)
            M[:, n, n] = 1.0
        memo = self._fields = {}      # the field at every flow's ends, as the integrator computed it (see field)
        flows = []
        at = starts.tolist()
        for i, span in enumerate(ends.tolist()):
            z = Z[i]
            flows.append(Flow(z, 0, M[i], _T0, Z0[i], _MODE0, [], dense=_Steps(rows[at[i]:at[i + 1]], n, S0[i]),
                              span=span))
            memo[id(z)] = (z, end[i, :n].tobytes(), fields[i, 1])
            memo[id(zs[i])] = (zs[i], S0[i].tobytes(), fields[i, 0])
        return flows

    def join(self, flows: list, period: float, *, max_events: int = 0) -> Flow:
        """The flow over one period from the consecutive node flows (each over period / m): monodromies
        multiplied, dense outputs chained (compiled flows carry theirs; scipy's are integrated once more)."""
        tau = period / len(flows)
        M = np.eye(self.size)
        for fl in flows:
            M = fl.monodromy @ M
        if self._compiled is not None:
            offsets = np.concatenate([[0.0], np.cumsum([fl.span for fl in flows])[:-1]])
            rows = np.concatenate([fl.dense.rows for fl in flows])
            rows[:, 0] += np.repeat(offsets, [fl.dense.rows.shape[0] for fl in flows])
            return Flow(flows[-1].z, 0, M, np.array([0.0]), flows[0].z0, np.array([0]), [],
                        dense=_Steps(rows, self.n, flows[0].z0[0, :self.n]), span=float(period))
        dense = self.flow_many([fl.z0[0] for fl in flows], [0] * len(flows), tau)
        return Flow(flows[-1].z, 0, M, np.array([0.0]), flows[0].z0, np.array([0]), [],
                    dense=_Joined([fl.dense for fl in dense], tau))

    def states(self, flow: Flow, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        z = np.ones((t.size, self.size))
        z[:, :self.n] = flow.dense.values(t) if isinstance(flow.dense, _Steps) else flow.dense(t)[:self.n].T
        return z

    def signals(self, flow: Flow, t) -> tuple[np.ndarray, np.ndarray]:
        """Element input x and output y at times t within the flow's span."""
        z = self.states(flow, t)
        return self.x(z), self.output(z)

    def fourier(self, flow: Flow, t_end: float, omega: float, harmonics: int) -> np.ndarray:
        """(1/T) int x e^{-j k w t} dt, k = 1..harmonics, from max(1024, 8 harmonics) samples of the dense output
        (periodic trapezoid: spectral accuracy for the smooth periodic orbit); one FFT when w T is a whole number
        of turns (the orbit's own harmonics, w = 0 for the mean)."""
        m = max(1024, 8 * harmonics)
        t = np.arange(m) * (t_end / m)
        seen = self._samples
        if seen is not None and seen[0] is flow and seen[1] == t_end and seen[2].size == m:
            x, spectrum = seen[2], seen[3]     # the same period sampled again (the mean after the harmonics)
        else:
            x, spectrum = self.x(self.states(flow, t)), None
        turns = omega * t_end / (2.0 * np.pi)
        p = round(turns)
        if abs(turns - p) <= 1e-12 * max(1.0, abs(turns)) and 0 <= p * harmonics < m // 2:
            spectrum = np.fft.rfft(x) / m if spectrum is None else spectrum
            self._samples = (flow, t_end, x, spectrum)
            return spectrum[p * np.arange(1, harmonics + 1)]
        self._samples = (flow, t_end, x, spectrum)
        out = np.empty(harmonics, complex)
        step = np.exp(-1j * omega * t)         # e^{-j k w t} by powers: one complex exponential per sample
        turn = step.copy()
        for k in range(harmonics):
            out[k] = turn @ x
            turn *= step
        return out / m
