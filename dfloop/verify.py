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

from dataclasses import dataclass, field

import numpy as np

from ._blas import single_threaded_blas
from .describing.interop import as_element
from .harmonics import SteadyState, steady_state
from .hybrid import LoopSimulation, delay_simulation, loop_model, simulate, start_on_prediction
from .hybrid.discrete import is_discrete
from .hybrid.discrete_run import discrete_simulation

__all__ = ["LoopSimulation", "simulate_loop", "Verification", "verify_cycle"]

_DIVERGED = 1e6  # |x| beyond this many times the start amplitude stops a run as divergent
MAX_PERIODS = 100_000  # bound on the length of a run (about 1 ms of work per period and run)
MAX_SAMPLES = 10**7  # bound on periods * steps_per_period (the returned signals)


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
                  steps_per_period: int = 400, r0: float = 0.0, load: float = 0.0,
                  bias: float = 0.0) -> LoopSimulation:
    """Run the loop from the harmonic-balance state of a cycle of the given amplitude and frequency.

    The plant starts in the steady state it would have if the element's input were exactly
    ``amplitude`` sin(``frequency`` t); the element's state (play, relay branch) is the one that sinusoid
    leaves after a period; the masses of a dynamic backlash start at rest with the gap centred.

    Parameters
    ----------
    G : python-control tf or ss, or ``delayed(G, T)``
        The plant (strictly proper, except around a dynamic backlash); with a pure delay, a piecewise-constant
        element runs on the exact delay flow (:func:`dfloop.hybrid.delay_simulation`: the plant starts in the
        exact periodic response to the delayed output of the predicted sinusoid, time 0 at the element's switch
        into its highest level).
    N : DescribingFunction
        The element (any element with a time model or an operator).
    amplitude, frequency : float
        The cycle to start from (element input units, rad/s), > 0.
    periods : float
        Length of the run in periods of ``frequency``, in (0, ``MAX_PERIODS`` = 1e5].
    steps_per_period : int
        Samples per period of the returned signals (>= 20); the step of the fixed-step fallback only.
        ``periods * steps_per_period`` is at most ``MAX_SAMPLES`` (1e7).
    r0, load, bias : float
        A constant input (reference r0 at the summing junction, load at the element's output) and the start's
        mean of x: the run starts on x = bias + amplitude sin(frequency t) (:func:`dfloop.hybrid.loop_model`).

    Returns
    -------
    LoopSimulation
        Uniform samples of x and y; ``diverged`` when |x| passed 1e6 times ``amplitude`` (the run stops there).
    """
    from ._checks import scale

    N = as_element(N)  # anything else (a number, None) is a ValueError naming N, before any work
    A0, w = scale("amplitude", amplitude), scale("frequency", frequency)
    periods, steps_per_period = _run_options(periods, steps_per_period)
    from ._checks import finite

    r0, load, bias = finite("r0", r0), finite("load", load), finite("bias", bias)
    if is_discrete(G):   # a digital loop (with or without a delay behind the hold) is a map: run it exactly
        return discrete_simulation(G, N, A0, w, periods, r0=r0, load=load, bias=bias, diverge=_DIVERGED)
    loop = loop_model(G, N, A0 + abs(bias), w, steps_per_period=steps_per_period, r0=r0, load=load)
    if loop.delay > 0:   # a pure delay: the exact delay flow from the predicted orbit's switches
        return delay_simulation(loop, A0, w, periods, steps_per_period, diverge=_DIVERGED, bias=bias)
    z, mode = start_on_prediction(loop, N, A0, w, bias=bias)
    return simulate(loop, z, mode, 2 * np.pi / w, periods, steps_per_period, limit=_DIVERGED * (A0 + abs(bias)))


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
        diverged or came to rest (and where: x at rest).
    method : str
        How the loop was simulated (exact flow, DOP853, fixed step, impact engine).
    runs : (LoopSimulation, LoopSimulation) or None
        The two runs' time series (from inside, from outside): what :meth:`plot` draws.
    exact_amplitude : float or None
        Amplitude of the exact orbit the verified cycle carried (``predict_limit_cycles(..., exact=True)``),
        None without one.
    means : (float or None, float or None)
        Mean of x over the whole periods in the last tenth of each run (its bias; None for a diverged run).
    """

    amplitude: float
    frequency: float
    inside: SteadyState
    outside: SteadyState
    perturbation: float
    verdict: str
    message: str = ""
    method: str = ""
    runs: tuple | None = field(default=None, compare=False, repr=False)
    exact_amplitude: float | None = None
    means: tuple = (None, None)

    @property
    def stable(self) -> bool:
        return self.verdict == "stable"

    def to_dict(self) -> dict:
        """One flat row: ``amplitude``, ``frequency``, ``verdict``, ``perturbation``, ``message``, ``method`` and
        each run's steady state as ``inside_amplitude``, ``inside_frequency``, ``inside_periodicity``,
        ``inside_n_periods``, ``inside_oscillating``, ``inside_mean`` (``outside_...`` likewise)."""
        from dataclasses import asdict

        from .export import flat

        return flat({"amplitude": self.amplitude, "frequency": self.frequency, "verdict": self.verdict,
                     "perturbation": self.perturbation, "message": self.message, "method": self.method,
                     "inside": {**asdict(self.inside), "mean": self.means[0]},
                     "outside": {**asdict(self.outside), "mean": self.means[1]}})

    def to_csv(self, path) -> None:
        """Write :meth:`to_dict` as a one-row CSV file."""
        from .export import write_csv

        write_csv(path, [self.to_dict()])

    def plot(self, ax=None, *, unit: str = "", name: str = "A", periods: float | None = 20):
        """The two runs x(t) over the band of the predicted (and exact) amplitude:
        :func:`dfloop.plot.orbit.plot_verification`. Returns a :class:`control.ControlPlot`."""
        from .plot.orbit import plot_verification

        return plot_verification(self, ax, unit=unit, name=name, periods=periods)

    def __repr__(self) -> str:
        # one readable line per fact: the verdict, the prediction, then each run's outcome once (``message``)
        words = self.message or (f"from inside: amplitude={self.inside.amplitude:.4g}; from outside: "
                                 f"amplitude={self.outside.amplitude:.4g}")
        return (f"Verification({self.verdict}: predicted amplitude={self.amplitude:.4g}, "
                f"frequency={self.frequency:.4g} rad/s; {words}" + (f"; {self.method}" if self.method else "") + ")")


def _describe(run: SteadyState, sim: LoopSimulation, A0: float, d: float) -> str:
    """One run's outcome in words (what the signal did, not what a model of it would say)."""
    if sim.diverged:
        return f"diverged (|x| beyond {_DIVERGED:.0e} times the start amplitude)"
    if not run.oscillating:
        # no zero crossing left: say where x ended and whether it still moves; a backlash or dead-zone loop rests
        # anywhere in the element's dead band (output 0), not at x = 0
        tail = sim.x[-max(sim.x.size // 10, 1):]
        x_end, y_end = float(sim.x[-1]), float(sim.y[-1])
        if float(np.max(np.abs(tail - x_end))) <= 1e-9 * max(A0, abs(x_end)):
            where = f"came to rest at x = {x_end:.4g}"
            if y_end == 0.0 and x_end != 0.0:
                where += " (element output 0 there: inside its play or dead band)"
            return where
        return f"stopped oscillating (no zero crossing in the last tenth of the run), x = {x_end:.4g} at the end"
    where = "near the prediction" if abs(run.amplitude - A0) < d * A0 / 2 else "away from the prediction"
    return (f"settled {where}: amplitude={run.amplitude:.4g}, frequency={run.frequency:.4g} rad/s "
            f"({'periodic' if run.periodicity < 1e-3 else f'periodicity {run.periodicity:.2g}'})")


def _final_mean(sim: LoopSimulation) -> float:
    """Mean of x over the whole periods in the last tenth of a run (between its first and last upward crossings of
    the tail's mean level; the tail's plain mean when it does not oscillate)."""
    from .harmonics import upward_crossings

    k = max(sim.x.size // 10, 2)
    t, x = sim.t[-k:], sim.x[-k:]
    c = upward_crossings(t, x, float(np.mean(x)))
    if c.size < 2:
        return float(np.mean(x))
    inner = (t > c[0]) & (t < c[-1])
    ts = np.concatenate([[c[0]], t[inner], [c[-1]]])
    xs = np.interp(ts, t, x)
    return float(np.sum(0.5 * (xs[1:] + xs[:-1]) * np.diff(ts)) / (c[-1] - c[0]))


@single_threaded_blas
def verify_cycle(G, N, cycle, *, perturbation: float = 0.3, periods: float = 80, steps_per_period: int = 400,
                 measure_periods: int = 10, r0: float = 0.0, load: float = 0.0,
                 bias: float | None = None) -> Verification:
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
    r0, load : float
        A constant input (reference at the summing junction, load at the element's output).
    bias : float or None
        The predicted mean of x (None: ``cycle.bias`` of a :class:`~dfloop.solve.bias.BiasedCycle`, else 0). The
        runs start on x = bias + (1 -/+ perturbation) A sin(w t), and each steady oscillation is measured about
        its own mean (``Verification.means``).
    """
    from ._checks import in_closed_interval
    from .exact import cycle_argument
    from .impact._effects_core import admissible, propagate, rows_on_zero, scan_steps
    from .progress import announce_compile

    announce_compile("verify_cycle", 25, admissible, propagate, rows_on_zero, scan_steps)  # bench_startup.py

    N = as_element(N)
    A0, w = cycle_argument(cycle)
    d = in_closed_interval("perturbation", perturbation, 1e-3, 0.95)
    periods, steps_per_period = _run_options(periods, steps_per_period)
    measure_periods = int(in_closed_interval("measure_periods", measure_periods, 1, 10**6))
    bias = getattr(cycle, "bias", 0.0) if bias is None else bias
    runs, words, method, sims, means = [], [], "", [], []
    for factor in (1 - d, 1 + d):
        sim = simulate_loop(G, N, A0 * factor, w, periods=periods, steps_per_period=steps_per_period, r0=r0,
                            load=load, bias=bias)
        sims.append(sim)
        method = sim.method
        means.append(None if sim.diverged else _final_mean(sim))
        if sim.diverged:
            runs.append(SteadyState(float(np.max(np.abs(sim.x))), 0.0, 0.0, 0, False))
        else:   # measured about the run's final mean (0 for a symmetric loop without constant input)
            centre = means[-1] if (r0 != 0.0 or load != 0.0 or bias != 0.0) else 0.0
            runs.append(steady_state(sim.t, sim.x - centre, measure_periods))
        words.append(_describe(runs[-1], sim, A0, d))
    offset = d * A0
    errors = [abs(r.amplitude - A0) for r in runs]
    if all(e < offset / 2 for e in errors):
        verdict = "stable"
    elif any(e > offset for e in errors):
        verdict = "unstable"
    else:
        verdict = "inconclusive"
    message = f"from inside: {words[0]}; from outside: {words[1]}"
    ex = getattr(cycle, "exact", None)
    exact_amplitude = float(ex.amplitude) if ex is not None and ex.success else None
    return Verification(A0, w, runs[0], runs[1], d, verdict, message, method, tuple(sims), exact_amplitude,
                        tuple(means))
