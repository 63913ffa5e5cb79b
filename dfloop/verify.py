"""Closed-loop time simulation of a predicted limit cycle (loop of the paper's Fig. 1).

Reference 0, element input x = -c, element output y, plant output c = G y. The plant is a state-space
realisation updated exactly over each step for a zero-order-held y (matrix exponential); the element is
its stateful ``operator()``, called once per step with the input extrapolated to the middle of the step
(so the hold adds no half-step delay: the loop error is second order in the step for smooth elements).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .harmonics import SteadyState, steady_state
from .solve.plant import as_plant

__all__ = ["LoopSimulation", "simulate_loop", "Verification", "verify_cycle"]

_DIVERGED = 1e6  # |x| beyond this many times the start amplitude stops a run as divergent


@dataclass
class LoopSimulation:
    """Samples of a closed-loop run: times t (s), element input x and output y."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    diverged: bool


def _state_space(G):
    import control as ct

    lti = as_plant(G).lti
    if lti is None or isinstance(lti, ct.FrequencyResponseData):
        raise ValueError("G must be a python-control tf or ss system for time-domain verification")
    sys = ct.ss(lti)
    if np.any(np.asarray(sys.D) != 0):
        raise ValueError("G must be strictly proper (D = 0) for time-domain verification (algebraic loop)")
    return np.asarray(sys.A, float), np.asarray(sys.B, float)[:, 0], np.asarray(sys.C, float)[0]


def simulate_loop(G, N, amplitude: float, frequency: float, *, periods: float = 80,
                  steps_per_period: int = 400) -> LoopSimulation:
    """Run the loop from the harmonic-balance state of a cycle of the given amplitude and frequency.

    The plant starts in the steady state it would have if the element's input were exactly
    ``amplitude`` sin(``frequency`` t); the element's operator is first driven through one period of
    that sinusoid so its internal state (play, relay branch) matches. Elements with internal dynamics
    provide their own ``simulate_loop(G, amplitude, frequency, *, periods, steps_per_period)`` (the dynamic
    backlash: :func:`dfloop.impact.loop.simulate_impact_loop`), which is used instead.
    """
    from ._checks import positive

    A0, w = positive("amplitude", amplitude), positive("frequency", frequency)
    if hasattr(N, "simulate_loop"):  # elements with internal dynamics (dynamic backlash) simulate themselves
        return N.simulate_loop(G, A0, w, periods=periods, steps_per_period=steps_per_period)
    if periods <= 0 or steps_per_period < 20:
        raise ValueError("periods must be > 0 and steps_per_period >= 20")
    Am, B, C = _state_space(G)
    n = Am.shape[0]
    dt = 2 * np.pi / w / steps_per_period
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n] = Am, B
    E = expm(aug * dt)
    Phi, Gam = E[:n, :n], E[:n, n]
    Nw = N(A0, w) if N.frequency_dependent else N(A0)
    X = np.linalg.solve(1j * w * np.eye(n) - Am, B) * complex(Nw) * A0
    s = X.imag.copy()
    op = N.operator()
    for tk in np.arange(-steps_per_period, 0) * dt:
        op(A0 * np.sin(w * tk))
    steps = int(round(periods * steps_per_period))
    xs, ys = np.empty(steps), np.empty(steps)
    limit = _DIVERGED * A0
    diverged = False
    k = 0
    x_prev = -float(C @ np.linalg.solve(Phi, s))  # harmonic-balance state one step back (approx.)
    for k in range(steps):
        x = -float(C @ s)
        # the held output acts over [t_k, t_k+1]: drive the element with x extrapolated to mid-step
        # (midpoint rule, second order in dt, instead of the half-step delay of a plain sample-and-hold)
        y = op(1.5 * x - 0.5 * x_prev)
        x_prev = x
        xs[k], ys[k] = x, y
        if abs(x) > limit:
            diverged = True
            break
        s = Phi @ s + Gam * y
    m = k + 1
    return LoopSimulation(np.arange(m) * dt, xs[:m], ys[:m], diverged)


@dataclass
class Verification:
    """Outcome of :func:`verify_cycle`.

    Attributes
    ----------
    amplitude, frequency : float
        The predicted cycle (amplitude of x, rad/s).
    inside, outside : SteadyState
        Steady oscillation of x reached from starts at (1 -/+ perturbation) times the amplitude.
    perturbation : float
        Relative size of the initial offsets.
    verdict : str
        ``"stable"`` (both runs end within half the initial offset of the prediction), ``"unstable"``
        (a run ends farther from it than it started), or ``"inconclusive"``.
    """

    amplitude: float
    frequency: float
    inside: SteadyState
    outside: SteadyState
    perturbation: float
    verdict: str

    @property
    def stable(self) -> bool:
        return self.verdict == "stable"

    def __repr__(self) -> str:
        return (f"Verification({self.verdict}: predicted A={self.amplitude:.4g}, w={self.frequency:.4g}; "
                f"from inside -> A={self.inside.amplitude:.4g}, w={self.inside.frequency:.4g}; "
                f"from outside -> A={self.outside.amplitude:.4g}, w={self.outside.frequency:.4g})")


def verify_cycle(G, N, cycle, *, perturbation: float = 0.3, periods: float = 80, steps_per_period: int = 400,
                 measure_periods: int = 10) -> Verification:
    """Simulate the loop from inside and outside a predicted cycle and report whether it attracts.

    Parameters
    ----------
    cycle : LimitCycle or (amplitude, frequency)
        The prediction to check.
    perturbation : float
        Relative amplitude offset of the two starts, in (0, 1); larger than the DF's expected error.
    """
    from ._checks import in_closed_interval

    A0, w = (cycle.amplitude, cycle.frequency) if hasattr(cycle, "amplitude") else map(float, cycle)
    d = in_closed_interval("perturbation", perturbation, 1e-3, 0.95)
    runs = []
    for factor in (1 - d, 1 + d):
        sim = simulate_loop(G, N, A0 * factor, w, periods=periods, steps_per_period=steps_per_period)
        if sim.diverged:
            runs.append(SteadyState(float(np.max(np.abs(sim.x))), 0.0, 0.0, 0, False))
        else:
            runs.append(steady_state(sim.t, sim.x, measure_periods))
    offset = d * A0
    errors = [abs(r.amplitude - A0) for r in runs]
    if all(e < offset / 2 for e in errors):
        verdict = "stable"
    elif any(e > offset for e in errors):
        verdict = "unstable"
    else:
        verdict = "inconclusive"
    return Verification(A0, w, runs[0], runs[1], d, verdict)
