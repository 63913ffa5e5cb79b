"""The loop of a plant and an element known only through a stateful operator, run with a fixed step (not exact).

The plant is updated exactly over each step for a zero-order-held output y; the operator is called once per
step with the input extrapolated to the middle of the step (second order in the step). The "mode" of this model
is the operator's state (a private copy) and the previous input sample. No monodromy: periodic orbits of such
loops cannot be shot (:attr:`SampledLoop.exact` is False); the closed-loop driver runs them.
"""
from __future__ import annotations

import copy

import numpy as np
from scipy.linalg import expm

from ..describing.time_model import Sampled
from .loop import Flow, LoopModel

__all__ = ["SampledLoop"]


class SampledLoop(LoopModel):
    """Fixed-step model of the loop of plant (A, B, C) and a :class:`~dfloop.describing.time_model.Sampled`
    element, with step ``dt`` (s)."""

    exact = False
    settle_periods = 0.0

    def __init__(self, A, B, C, model: Sampled, dt: float, steps_per_period: int):
        self.n = n = A.shape[0]
        self.size = n + 1
        self.plant = (A, B)
        self.C, self.model, self.dt = C, model, dt
        self.x_row = np.append(-C, 0.0)
        aug = np.zeros((n + 1, n + 1))
        aug[:n, :n], aug[:n, n] = A, B
        E = expm(aug * dt)
        self.Phi, self.Gam = E[:n, :n], E[:n, n]
        self.method = (f"fixed step (zero-order hold, {steps_per_period} steps per period; {model.name} has only "
                       "an operator)")

    def start(self, s0: np.ndarray, x_history: np.ndarray):
        """Plant state s0; the operator driven by the input history; the previous input one step back."""
        op = self.model.make_operator()
        for v in x_history:
            op(float(v))
        x_prev = -float(self.C @ np.linalg.solve(self.Phi, s0))  # the plant's state one step back (approx.)
        return np.append(s0, 1.0), (op, x_prev)

    def admissible_mode(self, z, mode):
        return np.asarray(z, float), mode

    def flow(self, z0, mode0, t_end: float, *, monodromy: bool = False, max_events: int = 0) -> Flow:
        """Steps of ``dt`` from z0 covering [0, t_end) (the last step may pass t_end)."""
        if monodromy:
            raise ValueError("a sampled (fixed-step) loop has no monodromy")
        op, x_prev = copy.deepcopy(mode0[0]), mode0[1]
        s = np.asarray(z0, float)[:self.n].copy()
        steps = max(int(round(t_end / self.dt)), 1)
        xs, ys = np.empty(steps), np.empty(steps)
        for k in range(steps):
            x = -float(self.C @ s)
            # the held output acts over [t_k, t_k+1]: drive the element with x extrapolated to mid-step
            # (midpoint rule, second order in dt, instead of the half-step delay of a plain sample-and-hold)
            y = op(1.5 * x - 0.5 * x_prev)
            x_prev = x
            xs[k], ys[k] = x, y
            if not np.isfinite(x):
                break
            s = self.Phi @ s + self.Gam * y
        fl = Flow(np.append(s, 1.0), (op, x_prev), None, np.array([0.0]), np.asarray(z0, float)[None, :].copy(),
                  np.array([0]), [])
        fl.dense = (np.arange(steps) * self.dt, xs, ys)
        return fl

    def signals(self, flow: Flow, t) -> tuple[np.ndarray, np.ndarray]:
        """x and y at the step times nearest t (the samples of the fixed-step run)."""
        ts, xs, ys = flow.dense
        k = np.clip(np.rint(np.atleast_1d(t) / self.dt).astype(int), 0, ts.size - 1)
        return xs[k], ys[k]
