"""The closed loop of a strictly proper plant and a smooth (not piecewise-linear) static element.

Same interface as :class:`dfloop.hybrid.loop.HybridLoop` (augmented state z = [s, 1], one mode), integrated by
scipy's DOP853 (8th order) at rtol 1e-12, with the variational equation Phi' = (A - B f'(x) C) Phi alongside
for the monodromy (f' by central differences, relative accuracy ~1e-10). Not exact: used for elements such as
:class:`~dfloop.describing.static.CubicStiffness` or a user's f, and said so in every result.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp

from .loop import Flow, HybridError

__all__ = ["SmoothLoop"]

RTOL = 1e-12
_MAX_STEPS_PER_SCALE = 64   # max_step = time scale / this


class SmoothLoop:
    """Loop of plant (A, B, C) and a static element y = f(x), integrated with DOP853 (not exact)."""

    exact = True           # flows carry a monodromy (variational equation): periodic orbits can be shot
    settle_periods = 0.0

    def __init__(self, A, B, C, f: Callable, name: str, time_scale: float):
        self.n = A.shape[0]
        self.size = self.n + 1
        self.A, self.B, self.C, self.f, self.name = A, B, C, f, name
        self.x_row = np.append(-C, 0.0)
        self.max_step = time_scale / _MAX_STEPS_PER_SCALE
        self.method = f"DOP853 (rtol {RTOL:g}; {name} is not piecewise linear, so not exact)"

    def x(self, z) -> np.ndarray:
        return np.asarray(z) @ self.x_row

    def output(self, z, mode=0) -> np.ndarray:
        return np.asarray(self.f(self.x(z)), dtype=float)

    def _slope(self, x: float) -> float:
        d = 1e-5 * (1.0 + abs(x))
        return float((self.f(np.array(x + d)) - self.f(np.array(x - d))) / (2.0 * d))

    def field(self, z, mode: int = 0) -> np.ndarray:
        s = z[:self.n]
        return np.append(self.A @ s + self.B * float(self.f(np.array(-self.C @ s))), 0.0)

    def admissible_mode(self, z, mode: int = 0):
        return np.asarray(z, float), 0

    def start(self, s0, x_history) -> tuple[np.ndarray, int]:
        return np.append(s0, 1.0), 0

    def flow(self, z0, mode0: int, t_end: float, *, monodromy: bool = False, max_events: int = 0) -> Flow:
        n = self.n
        z0 = np.asarray(z0, float)

        def rhs(t, u):
            s = u[:n]
            x = -self.C @ s
            ds = self.A @ s + self.B * float(self.f(np.array(x)))
            if not monodromy:
                return ds
            J = self.A - np.outer(self.B * self._slope(x), self.C)
            return np.concatenate([ds, (J @ u[n:].reshape(n, n)).ravel()])

        u0 = z0[:n] if not monodromy else np.concatenate([z0[:n], np.eye(n).ravel()])
        scale = max(float(np.max(np.abs(z0[:n]))), 1e-300)
        sol = solve_ivp(rhs, (0.0, t_end), u0, method="DOP853", rtol=RTOL, atol=RTOL * scale,
                        max_step=self.max_step, dense_output=True)
        if not sol.success or not np.all(np.isfinite(sol.y[:, -1])):
            raise HybridError(f"DOP853 failed: {sol.message}")
        z = np.append(sol.y[:n, -1], 1.0)
        M = None
        if monodromy:
            M = np.eye(self.size)
            M[:n, :n] = sol.y[n:, -1].reshape(n, n)
        return Flow(z, 0, M, np.array([0.0]), z0[None, :].copy(), np.array([0]), [], dense=sol.sol)

    def states(self, flow: Flow, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        s = flow.dense(t)[:self.n].T
        return np.column_stack([s, np.ones(t.size)])

    def signals(self, flow: Flow, t) -> tuple[np.ndarray, np.ndarray]:
        """Element input x and output y at times t within the flow's span."""
        z = self.states(flow, t)
        return self.x(z), self.output(z)

    def fourier(self, flow: Flow, t_end: float, omega: float, harmonics: int) -> np.ndarray:
        """(1/T) int x e^{-j k w t} dt, k = 1..harmonics, from 4096 samples of the dense output (periodic
        trapezoid: spectral accuracy for the smooth periodic orbit)."""
        m = 4096
        t = np.arange(m) * (t_end / m)
        x = self.x(self.states(flow, t))
        k = np.arange(1, harmonics + 1)[:, None]
        return (np.exp(-1j * k * omega * t[None, :]) @ x) / m
