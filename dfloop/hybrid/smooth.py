"""The closed loop of a strictly proper plant and a smooth (not piecewise-linear) static element.

Same interface as :class:`dfloop.hybrid.loop.HybridLoop` (augmented state z = [s, 1], one mode), integrated by
scipy's DOP853 (8th order) at rtol 1e-12, with the variational equation Phi' = (A - B f'(x) C) Phi alongside
for the monodromy (f' from the time model, or by central differences, relative accuracy ~1e-10). Not exact:
used for elements such as :class:`~dfloop.describing.static.CubicStiffness` or a user's f, and said so in every
result.

The flows of all shooting nodes run as one ODE system (:meth:`SmoothLoop.flow_many`: one DOP853 run, the element
evaluated on every node's input in one vectorised call), and the period's flow is joined from the node flows
(:meth:`SmoothLoop.join`) instead of being integrated again: the shooting's cost is then a few integrations over
1/m of a period.
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


class SmoothLoop(LoopModel):
    """Loop of plant (A, B, C) and a static element y = f(x), integrated with DOP853 (not exact)."""

    exact = True           # flows carry a monodromy (variational equation): periodic orbits can be shot
    settle_periods = 0.0
    batched = True         # flow_many integrates all nodes at once
    switching = False      # one mode: no switches to keep away from the shooting nodes

    def __init__(self, A, B, C, f: Callable, name: str, time_scale: float, slope: Callable | None = None, *,
                 r0: float = 0.0, load: float = 0.0):
        self.r0, self.load = float(r0), float(load)   # x = r0 - C s, the plant driven by f(x) + load
        self.n = A.shape[0]
        self.size = self.n + 1
        self.plant = (A, B)
        self.A, self.B, self.C, self.f, self.name = A, B, C, f, name
        self.x_row = np.append(-C, self.r0)
        self.max_step = time_scale / _MAX_STEPS_PER_SCALE
        self.method = f"DOP853 (rtol {RTOL:g}; {name} is not piecewise linear, so not exact)"
        self._slope = slope if slope is not None else self._central_slope

    def x(self, z) -> np.ndarray:
        return np.asarray(z) @ self.x_row

    def output(self, z, mode=0) -> np.ndarray:
        return np.asarray(self.f(self.x(z)), dtype=float)

    def _central_slope(self, x: np.ndarray) -> np.ndarray:
        d = 1e-5 * (1.0 + np.abs(x))
        return (np.asarray(self.f(x + d), float) - np.asarray(self.f(x - d), float)) / (2.0 * d)

    def field(self, z, mode: int = 0) -> np.ndarray:
        s = z[:self.n]
        return np.append(self.A @ s + self.B * (float(self.f(np.array(self.r0 - self.C @ s))) + self.load), 0.0)

    def admissible_mode(self, z, mode: int = 0):
        return np.asarray(z, float), 0

    def start(self, s0, x_history) -> tuple[np.ndarray, int]:
        return np.append(s0, 1.0), 0

    def flow(self, z0, mode0: int, t_end: float, *, monodromy: bool = False, max_events: int = 0) -> Flow:
        return self.flow_many([z0], [mode0], t_end, monodromy=monodromy)[0]

    def flow_many(self, zs, modes, t_end, *, monodromy: bool = False, max_events: int = 0) -> list:
        """Flows of every start state in ``zs`` over [0, t_end], as one DOP853 run.

        Flows with ``monodromy`` (the shooting's Newton steps) carry no dense output (it costs a third of the
        step); :meth:`join` integrates the converged nodes once more, without the variational equation, for it.
        """
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

    def join(self, flows: list, period: float, *, max_events: int = 0) -> Flow:
        """The flow over one period from the consecutive node flows (each over period / m): monodromies
        multiplied, dense outputs chained."""
        tau = period / len(flows)
        M = np.eye(self.size)
        for fl in flows:
            M = fl.monodromy @ M
        dense = self.flow_many([fl.z0[0] for fl in flows], [0] * len(flows), tau)
        return Flow(flows[-1].z, 0, M, np.array([0.0]), flows[0].z0, np.array([0]), [],
                    dense=_Joined([fl.dense for fl in dense], tau))

    def states(self, flow: Flow, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        s = flow.dense(t)[:self.n].T
        return np.column_stack([s, np.ones(t.size)])

    def signals(self, flow: Flow, t) -> tuple[np.ndarray, np.ndarray]:
        """Element input x and output y at times t within the flow's span."""
        z = self.states(flow, t)
        return self.x(z), self.output(z)

    def fourier(self, flow: Flow, t_end: float, omega: float, harmonics: int) -> np.ndarray:
        """(1/T) int x e^{-j k w t} dt, k = 1..harmonics, from max(1024, 8 harmonics) samples of the dense output
        (periodic trapezoid: spectral accuracy for the smooth periodic orbit)."""
        m = max(1024, 8 * harmonics)
        t = np.arange(m) * (t_end / m)
        x = self.x(self.states(flow, t))
        k = np.arange(1, harmonics + 1)[:, None]
        return (np.exp(-1j * k * omega * t[None, :]) @ x) / m
