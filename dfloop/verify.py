"""Closed-loop time simulation of a predicted limit cycle (loop of the paper's Fig. 1).

Reference 0, element input x = -c, element output y, plant output c = G y. The loop runs on the exact flow of
:mod:`dfloop.hybrid`: for piecewise-linear elements (relays, saturation, dead zone, backlash, quantizer, ...)
the matrix exponential between switching instants located to rounding level; for other static elements DOP853
at rtol 1e-12. No fixed step: ``steps_per_period`` only sets the sampling of the returned signals. An element
with neither model but a stateful ``operator()`` (a user's hysteretic element) falls back to a fixed-step run:
the plant is updated exactly over each step for a zero-order-held y, the operator called once per step with the
input extrapolated to the middle of the step (second order in the step); the result's ``method`` says which.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ._blas import single_threaded_blas
from .describing.interop import as_element
from .harmonics import SteadyState, steady_state

__all__ = ["LoopSimulation", "simulate_loop", "Verification", "verify_cycle"]

_DIVERGED = 1e6  # |x| beyond this many times the start amplitude stops a run as divergent
MAX_PERIODS = 100_000  # bound on the length of a run (about 1 ms of work per period and run)
MAX_SAMPLES = 10**7  # bound on periods * steps_per_period (the returned signals)
_MAX_SWITCHES_PER_PERIOD = 100_000  # bound on switches in one period of a run (sliding motion hits it)


@dataclass
class LoopSimulation:
    """Samples of a closed-loop run: times t (s), element input x and output y."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    diverged: bool
    method: str = ""


def _run_options(periods, steps_per_period) -> tuple[float, int]:
    from ._checks import in_closed_interval, positive

    periods = in_closed_interval("periods", periods, 0.0, MAX_PERIODS)
    if periods == 0:
        raise ValueError(f"periods must be > 0, got {periods}")
    steps = in_closed_interval("steps_per_period", steps_per_period, 20, 10**7)
    if steps != int(steps):
        raise ValueError(f"steps_per_period must be an integer, got {steps_per_period!r}")
    samples = periods * steps
    if samples > MAX_SAMPLES:  # t, x, y of every sample are kept: 24 bytes each, plus the run's work arrays
        raise ValueError(f"periods * steps_per_period = {periods:g} * {int(steps)} = {samples:.3g} samples exceeds "
                         f"the bound of {MAX_SAMPLES:.0e} (about {48 * samples / 2**30:.2g} GiB of signals); lower "
                         "periods or steps_per_period")
    return periods, int(steps)


@single_threaded_blas
def simulate_loop(G, N, amplitude: float, frequency: float, *, periods: float = 80,
                  steps_per_period: int = 400) -> LoopSimulation:
    """Run the loop from the harmonic-balance state of a cycle of the given amplitude and frequency.

    The plant starts in the steady state it would have if the element's input were exactly
    ``amplitude`` sin(``frequency`` t); the element's state (play, relay branch) is the one that sinusoid
    leaves after a period. Elements with internal dynamics provide their own
    ``simulate_loop(G, amplitude, frequency, *, periods, steps_per_period)`` (the dynamic backlash:
    :func:`dfloop.impact.loop.simulate_impact_loop`), which is used instead.

    Parameters
    ----------
    periods : float
        Length of the run in periods of ``frequency``, in (0, ``MAX_PERIODS`` = 1e5].
    steps_per_period : int
        Samples per period of the returned signals (>= 20); the step of the fixed-step fallback only.
        ``periods * steps_per_period`` is at most ``MAX_SAMPLES`` (1e7).
    """
    from ._checks import scale

    N = as_element(N)  # anything else (a number, None) is a ValueError naming N, before any work
    A0, w = scale("amplitude", amplitude), scale("frequency", frequency)
    periods, steps_per_period = _run_options(periods, steps_per_period)
    if hasattr(N, "simulate_loop"):  # elements with internal dynamics (dynamic backlash) simulate themselves
        return N.simulate_loop(G, A0, w, periods=periods, steps_per_period=steps_per_period)
    from .hybrid import loop_model

    loop, method = loop_model(G, N, A0, w)
    if loop is None:
        return _fixed_step(G, N, A0, w, periods, steps_per_period)
    return _exact_run(loop, method, G, N, A0, w, periods, steps_per_period)


def _exact_run(loop, method, G, N, A0, w, periods, steps_per_period) -> LoopSimulation:
    """The loop on the exact (or DOP853) flow, one period at a time, sampled uniformly."""
    from .exact import _harmonic_balance_state, _history
    from .hybrid import HybridError, plant_matrices

    T = 2 * np.pi / w
    z, mode = loop.start(_harmonic_balance_state(plant_matrices(G), N, A0, w), _history(A0, w, 0.0))
    n_periods = int(np.ceil(periods))
    ts, xs, ys = [], [], []
    limit = _DIVERGED * A0
    diverged = False
    for p in range(n_periods):
        span = min(T, periods * T - p * T)
        try:
            fl = loop.flow(z, mode, span, max_events=_MAX_SWITCHES_PER_PERIOD)
        except HybridError as exc:
            raise RuntimeError(f"the loop cannot be simulated past t = {p * T:.6g} s: {exc}") from None
        tk = np.arange(int(round(span / T * steps_per_period))) * (T / steps_per_period)
        zk = loop.states(fl, tk)
        seg = np.clip(np.searchsorted(fl.t0, tk, side="right") - 1, 0, fl.t0.size - 1)
        ts.append(p * T + tk)
        xs.append(loop.x(zk))
        ys.append(loop.output(zk, fl.modes[seg]))
        z, mode = fl.z, fl.mode
        if not np.all(np.isfinite(z)) or np.max(np.abs(xs[-1]), initial=0.0) > limit:
            diverged = True
            break
    x = np.concatenate(xs)
    keep = np.isfinite(x) & (np.abs(x) <= limit) if diverged else slice(None)
    return LoopSimulation(np.concatenate(ts)[keep], x[keep], np.concatenate(ys)[keep], diverged, method)


def _fixed_step(G, N, A0, w, periods, steps_per_period) -> LoopSimulation:
    """Fixed-step run with the element's operator (elements without a piecewise-linear or static model)."""
    from .hybrid import plant_matrices

    Am, B, C = plant_matrices(G, what="time-domain verification")
    n = Am.shape[0]
    dt = 2 * np.pi / w / steps_per_period
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n] = Am, B
    E = expm(aug * dt)
    Phi, Gam = E[:n, :n], E[:n, n]
    Nw = N(A0, w) if N.frequency_dependent else N(A0)
    X = np.linalg.solve(1j * w * np.eye(n) - Am, B) * complex(Nw) * A0
    s = X.imag.copy()
    try:
        op = N.operator()
    except NotImplementedError:
        raise ValueError(f"N: {type(N).__name__} has no time-domain model (no piecewise-linear or static "
                         "model, no operator)") from None
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
    return LoopSimulation(np.arange(m) * dt, xs[:m], ys[:m], diverged,
                          f"fixed step (zero-order hold, {steps_per_period} steps per period; "
                          f"{type(N).__name__} has only an operator)")


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
        Length of each run in predicted periods, in (0, 1e5]; ``periods * steps_per_period`` <= 1e7.
    steps_per_period : int
        Samples per period of the runs (the step only of the fixed-step fallback, see :func:`simulate_loop`).
    measure_periods : int
        Periods at the end of each run over which the steady oscillation is measured.
    """
    from ._checks import in_closed_interval
    from .exact import cycle_argument

    N = as_element(N)
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
