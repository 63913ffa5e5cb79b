"""Closed-loop time simulation of a predicted limit cycle (loop of the paper's Fig. 1).

Reference 0, element input x = -c, element output y, plant output c = G y. The loop is the one loop model
:func:`dfloop.hybrid.loop_model` builds from the element's time model, run by the one closed-loop driver
(:func:`dfloop.hybrid.simulate`): for piecewise-affine elements (relays, saturation, dead zone, backlash,
quantizer, ...) the matrix exponential between switching instants located to rounding level; for the dynamic
backlash the exact impact engine; for smooth static elements DOP853 at rtol 1e-12. No fixed step:
``steps_per_period`` only sets the sampling of the returned signals. An element known only through a stateful
``operator()`` (a user's hysteretic element) runs with a fixed step: the plant is updated exactly over each step
for a zero-order-held y, the operator called once per step with the input extrapolated to the middle of the step
(second order in the step); the result's ``method`` says which.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._blas import single_threaded_blas
from .harmonics import SteadyState, steady_state
from .hybrid import LoopSimulation, loop_model, simulate, start_on_prediction

__all__ = ["LoopSimulation", "simulate_loop", "Verification", "verify_cycle"]

_DIVERGED = 1e6  # |x| beyond this many times the start amplitude stops a run as divergent


def _run_options(periods, steps_per_period) -> tuple[float, int]:
    from ._checks import in_closed_interval, positive

    periods = positive("periods", periods)
    steps = in_closed_interval("steps_per_period", steps_per_period, 20, 10**7)
    if steps != int(steps):
        raise ValueError(f"steps_per_period must be an integer, got {steps_per_period!r}")
    return periods, int(steps)


@single_threaded_blas
def simulate_loop(G, N, amplitude: float, frequency: float, *, periods: float = 80,
                  steps_per_period: int = 400) -> LoopSimulation:
    """Run the loop from the harmonic-balance state of a cycle of the given amplitude and frequency.

    The plant starts in the steady state it would have if the element's input were exactly
    ``amplitude`` sin(``frequency`` t); the element's state (play, relay branch) is the one that sinusoid
    leaves after a period; the masses of a dynamic backlash start at rest with the gap centred.

    Parameters
    ----------
    G : python-control tf or ss
        The plant (strictly proper, except around a dynamic backlash).
    N : DescribingFunction
        The element (any element with a time model or an operator).
    amplitude, frequency : float
        The cycle to start from (element input units, rad/s), > 0.
    periods : float
        Length of the run in periods of ``frequency``, finite and > 0.
    steps_per_period : int
        Samples per period of the returned signals (>= 20); the step of the fixed-step fallback only.

    Returns
    -------
    LoopSimulation
        Uniform samples of x and y; ``diverged`` when |x| passed 1e6 times ``amplitude`` (the run stops there).
    """
    from ._checks import positive

    A0, w = positive("amplitude", amplitude), positive("frequency", frequency)
    periods, steps_per_period = _run_options(periods, steps_per_period)
    loop = loop_model(G, N, A0, w, steps_per_period=steps_per_period)
    z, mode = start_on_prediction(loop, N, A0, w)
    return simulate(loop, z, mode, 2 * np.pi / w, periods, steps_per_period, limit=_DIVERGED * A0)


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
    message : str
        What the runs found, in words: where they settled (amplitude, frequency, how periodic), or that they
        diverged or decayed to rest.
    method : str
        How the loop was simulated (exact flow, DOP853, fixed step, impact engine).
    """

    amplitude: float
    frequency: float
    inside: SteadyState
    outside: SteadyState
    perturbation: float
    verdict: str
    message: str = ""
    method: str = ""

    @property
    def stable(self) -> bool:
        return self.verdict == "stable"

    def plot(self, ax=None, *, unit: str = ""):
        """Draw where each run started and where it settled, against the predicted amplitude.

        A verification keeps the steady states of its two runs, not their signals: each run is drawn as a line
        from its start amplitude (1 -/+ ``perturbation``) A (at "start") to the amplitude it settled at (at
        "steady state"; the largest |x| reached for a diverged run, the residual |x| for one that decayed),
        the prediction as a dashed horizontal line. Both runs ending on the line: a stable cycle.

        Parameters
        ----------
        ax : matplotlib Axes, optional
        unit : str
            The unit of x (the element's ``input_unit``) for the axis label.

        Returns
        -------
        matplotlib Axes
            ``ax.lines`` [run from inside, run from outside, predicted amplitude] (as for
            :meth:`dfloop.ExactCycle.plot`); each run's ``get_ydata()`` is (start amplitude, settled amplitude).
        """
        from .plot._labels import axes_or_new, legend, quantity

        ax = axes_or_new(ax)
        for name, run, factor, color in (("inside", self.inside, 1 - self.perturbation, "C0"),
                                         ("outside", self.outside, 1 + self.perturbation, "C1")):
            end = (f"A={run.amplitude:.4g}, ω={run.frequency:.4g} rad/s" if run.oscillating
                   else f"no oscillation (|x| {run.amplitude:.3g})")
            ax.plot([0.0, 1.0], [factor * self.amplitude, run.amplitude], marker="o", color=color,
                             label=f"from {name}: {end}")
        ax.axhline(self.amplitude, color="C3", ls="--", lw=1,
                   label=f"predicted A={self.amplitude:.4g}, ω={self.frequency:.4g} rad/s")
        ax.set_xticks([0.0, 1.0], ["start", "steady state"])
        ax.set_xlim(-0.15, 1.15)
        ax.set_ylabel(quantity("Amplitude of x", unit))
        ax.set_title(f"Verification: {self.verdict}", fontsize=9)
        legend(ax, fontsize=8)
        return ax

    def __repr__(self) -> str:
        return (f"Verification({self.verdict}: predicted A={self.amplitude:.4g}, w={self.frequency:.4g}; "
                f"from inside -> A={self.inside.amplitude:.4g}, w={self.inside.frequency:.4g}; "
                f"from outside -> A={self.outside.amplitude:.4g}, w={self.outside.frequency:.4g}"
                + (f"; {self.message}" if self.message else "") + ")")


def _describe(run: SteadyState, diverged: bool, A0: float, w: float, d: float) -> str:
    if diverged:
        return "diverged"
    if not run.oscillating:
        return f"decayed to rest (|x| <= {run.amplitude:.3g})"
    where = "near the prediction" if abs(run.amplitude - A0) < d * A0 / 2 else "elsewhere"
    return (f"settled {where}: A={run.amplitude:.4g}, w={run.frequency:.4g} rad/s "
            f"({'periodic' if run.periodicity < 1e-3 else f'periodicity {run.periodicity:.2g}'})")


@single_threaded_blas
def verify_cycle(G, N, cycle, *, perturbation: float = 0.3, periods: float = 80, steps_per_period: int = 400,
                 measure_periods: int = 10) -> Verification:
    """Simulate the loop from inside and outside a predicted cycle and report whether it attracts.

    Parameters
    ----------
    cycle : LimitCycle or (amplitude, frequency)
        One prediction to check (a list of cycles raises ``ValueError``: pass one, e.g. ``cycles[0]``).
    perturbation : float
        Relative amplitude offset of the two starts, in [1e-3, 0.95]; larger than the DF's expected error.
    periods : float
        Length of each run in predicted periods, finite and > 0.
    steps_per_period : int
        Samples per period of the runs (the step only of the fixed-step fallback, see :func:`simulate_loop`).
    measure_periods : int
        Periods at the end of each run over which the steady oscillation is measured.
    """
    from ._checks import in_closed_interval
    from .exact import cycle_argument

    A0, w = cycle_argument(cycle)
    d = in_closed_interval("perturbation", perturbation, 1e-3, 0.95)
    periods, steps_per_period = _run_options(periods, steps_per_period)
    measure_periods = int(in_closed_interval("measure_periods", measure_periods, 1, 10**6))
    runs, words, method = [], [], ""
    for factor in (1 - d, 1 + d):
        sim = simulate_loop(G, N, A0 * factor, w, periods=periods, steps_per_period=steps_per_period)
        method = sim.method
        if sim.diverged:
            runs.append(SteadyState(float(np.max(np.abs(sim.x))), 0.0, 0.0, 0, False))
        else:
            runs.append(steady_state(sim.t, sim.x, measure_periods))
        words.append(_describe(runs[-1], sim.diverged, A0, w, d))
    offset = d * A0
    errors = [abs(r.amplitude - A0) for r in runs]
    if all(e < offset / 2 for e in errors):
        verdict = "stable"
    elif any(e > offset for e in errors):
        verdict = "unstable"
    else:
        verdict = "inconclusive"
    message = f"from inside: {words[0]}; from outside: {words[1]}"
    return Verification(A0, w, runs[0], runs[1], d, verdict, message, method)
