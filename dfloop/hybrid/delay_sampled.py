"""A sampled (zero-order-hold) element behind a plant with a pure delay: the exact sampled map and its run.

An element sampled at t_k = k dt holds its output y_k over [t_k, t_k + dt); the plant G(s) e^{-sT} receives it
T later, over [t_k + T, t_{k+1} + T). With T = m dt + r (m = floor(T / dt), 0 <= r < dt) the plant's input over
the step [t_j, t_{j+1}) is y_{j-m-1} on [t_j, t_j + r) and y_{j-m} on [t_j + r, t_{j+1}): piecewise constant, so
the plant is propagated exactly (two matrix exponentials per step) and the loop is the finite map

    s_{j+1} = Phi s_j + G1 y_{j-m-1} + G2 y_{j-m},     Phi = e^{A dt},
    G1 = e^{A (dt - r)} int_0^r e^{A v} B dv,          G2 = int_0^{dt - r} e^{A v} B dv,

on the state z_j = (s_j, y_{j-m-1}, ..., y_{j-1}): the plant state and the m + 1 held values pending in the delay
line. :func:`delayed_sampled_system` gives it as a linear discrete system z_{j+1} = Ad z_j + Bd y_j,
x_j = -Cd z_j (the modified z-transform of G e^{-sT} behind the hold). Two uses:

- a digital element at a physical sampling period (:func:`dfloop.hybrid.discrete.sample_delayed`: the delayed
  plant as a discrete python-control system, whose periodic orbits :mod:`dfloop.hybrid.discrete` finds exactly,
  with the pending values in the monodromy); a delay of k whole samples is G(z) z^-k, and T -> 0 is the plain
  zero-order-hold discretisation;
- an element known only through an operator (:class:`~dfloop.describing.time_model.Sampled`), which
  :class:`DelaySampledLoop` runs with the fixed step of :class:`~dfloop.hybrid.sampled.SampledLoop` (the operator
  fed the input extrapolated to mid-step) and the delay line exact; with T = 0 its steps are SampledLoop's.
"""
from __future__ import annotations

import copy
import math

import numpy as np
from scipy.linalg import expm

from ..describing.time_model import Sampled
from .run import LoopSimulation

__all__ = ["delayed_sampled_system", "DelaySampledLoop", "sampled_delay_simulation"]


def _hold(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A h}, int_0^h e^{A v} B dv): one augmented matrix exponential."""
    n = A.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n] = A, B
    E = expm(aug * h)
    return E[:n, :n], E[:n, n]


def delayed_sampled_system(A, B, C, delay: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Ad, Bd, Cd) of the exact sampled map of a plant (A, B, C) with a pure delay T behind a zero-order hold of
    period dt (module notes): z = (s, y_{j-m-1}, ..., y_{j-1}), z_{j+1} = Ad z_j + Bd y_j, c_j = Cd z_j.

    Parameters
    ----------
    A, B, C : ndarray
        The continuous, strictly proper plant (delay-free part); B and C one-dimensional.
    delay : float
        T >= 0 (s).
    dt : float
        The sampling period (s), > 0.
    """
    A, B, C = (np.asarray(a, float) for a in (A, B, C))
    n = A.shape[0]
    m = int(math.floor(delay / dt * (1 + 1e-12)))    # a whole number of samples within rounding is one
    r = max(delay - m * dt, 0.0)
    if r <= 1e-12 * dt:
        r = 0.0
    Phi, G2 = _hold(A, B, dt - r)
    if r > 0.0:
        E_r, I_r = _hold(A, B, r)
        G1 = Phi @ I_r
        Phi = Phi @ E_r
    else:
        G1 = np.zeros(n)
    size = n + m + 1
    Ad, Bd = np.zeros((size, size)), np.zeros(size)
    Ad[:n, :n] = Phi
    Ad[:n, n] = G1                       # y_{j-m-1}: the first part of the step
    if m >= 1:
        Ad[:n, n + 1] = G2               # y_{j-m}: already in the line
    else:
        Bd[:n] = G2                      # m = 0: the value held now reaches the plant within this step
    Ad[n:n + m, n + 1:n + m + 1] = np.eye(m)   # the line moves by one sample
    Bd[n + m] = 1.0                      # the new value enters at its end
    Cd = np.concatenate([C, np.zeros(m + 1)])
    return Ad, Bd, Cd


class DelaySampledLoop:
    """The loop of a plant (A, B, C) with a pure delay and an element known only through an operator, run with a
    fixed step ``dt``: the loop model :func:`dfloop.hybrid.loop_model` builds for a delayed plant and a
    :class:`~dfloop.describing.time_model.Sampled` element. Not exact (``exact`` False: no periodic-orbit
    shooting, as for the undelayed :class:`~dfloop.hybrid.sampled.SampledLoop`); run by
    :func:`sampled_delay_simulation`."""

    exact = False
    settle_periods = 0.0

    def __init__(self, A, B, C, model: Sampled, delay: float, dt: float, steps_per_period: int):
        self.A, self.B, self.C = (np.asarray(a, float) for a in (A, B, C))
        self.n = self.A.shape[0]
        self.plant = (self.A, self.B)
        self.model, self.delay, self.dt = model, float(delay), float(dt)
        self.Ad, self.Bd, self.Cd = delayed_sampled_system(self.A, self.B, self.C, self.delay, self.dt)
        self.pending = self.Ad.shape[0] - self.n          # m + 1 held values in the delay line
        self.method = (f"fixed step (zero-order hold, {steps_per_period} steps per period; {model.name} has only "
                       f"an operator) with the delay T = {self.delay:g} s exact ({self.pending} held values pending "
                       "in the delay line, matrix exponentials between their arrivals)")

    def start(self, amplitude: float, frequency: float):
        """(z, operator, previous input) on the predicted orbit x = amplitude sin(frequency t) at t = 0: the plant
        in the harmonic-balance state of the delayed fundamental of the operator's output, the delay line holding
        the outputs of the samples t_j < 0 it still carries, the operator driven by two periods of samples."""
        P = 2.0 * math.pi / frequency
        k = int(math.ceil(2.0 * P / self.dt)) + self.pending + 1
        tj = self.dt * np.arange(-k - 1, 0)
        xs = amplitude * np.sin(frequency * tj)
        op = self.model.make_operator()
        ys = np.array([op(1.5 * xs[i] - 0.5 * xs[i - 1]) for i in range(1, xs.size)])
        # fundamental of the held output over the last period (a zero-order hold delays it by dt / 2)
        last = slice(ys.size - int(round(P / self.dt)), ys.size)
        th = frequency * tj[1:][last]
        Y1 = 2.0 * complex(np.mean(ys[last] * np.sin(th)) + 1j * np.mean(ys[last] * np.cos(th)))
        Y0 = float(np.mean(ys[last]))
        X = np.linalg.solve(1j * frequency * np.eye(self.n) - self.A, self.B) * Y1
        s = (X * np.exp(-1j * frequency * (self.delay + 0.5 * self.dt))).imag
        if Y0 != 0.0 and abs(np.linalg.det(self.A)) > 0.0:
            s = s - np.linalg.solve(self.A, self.B) * Y0
        z = np.concatenate([s, ys[ys.size - self.pending:]])
        return z, op, float(xs[-1])

    def run(self, z0, op, x_prev: float, steps: int, diverge: float = math.inf):
        """``steps`` steps of the map from (z0, op, x_prev): (x_k, y_k of each step, end z, op, x_prev, diverged).
        The operator is a private copy."""
        op = copy.deepcopy(op)
        z = np.asarray(z0, float).copy()
        xs, ys = np.empty(steps), np.empty(steps)
        diverged = False
        for k in range(steps):
            x = -float(self.Cd @ z)
            y = float(op(1.5 * x - 0.5 * x_prev))        # the midpoint rule of SampledLoop
            x_prev = x
            xs[k], ys[k] = x, y
            if not (math.isfinite(x) and abs(x) <= diverge):
                diverged = True
                return xs[:k + 1], ys[:k + 1], z, op, x_prev, diverged
            z = self.Ad @ z + self.Bd * y
        return xs, ys, z, op, x_prev, diverged


def sampled_delay_simulation(loop: DelaySampledLoop, amplitude: float, frequency: float, periods: float,
                             diverge: float = 1e6) -> LoopSimulation:
    """Run a :class:`DelaySampledLoop` from the predicted orbit of (amplitude, frequency) for ``periods`` periods:
    x and y at the step times t_k = k dt; stops early when |x| passes ``diverge`` times the amplitude."""
    P = 2.0 * math.pi / frequency
    z, op, x_prev = loop.start(amplitude, frequency)
    steps = max(int(math.ceil(periods * P / loop.dt)), 1)
    xs, ys, _, _, _, diverged = loop.run(z, op, x_prev, steps, diverge * amplitude)
    return LoopSimulation(np.arange(xs.size) * loop.dt, xs, ys, diverged, loop.method)
