"""The one dispatcher from (G, N) to a loop model, and the start of a loop on a predicted cycle."""
from __future__ import annotations

import math

import numpy as np

from ..describing.time_model import Impact, PiecewiseAffine, Sampled, Smooth
from .dde import DDELoop, static_map
from .dde_memory import MemoryDDELoop
from .constant import shifted_model
from .delay import DelayLoop, piecewise_constant, split_delay
from .delay_impact import DelayImpactLoop
from .delay_sampled import DelaySampledLoop
from .impact import ImpactLoop
from .loop import HybridLoop, plant_matrices, plant_system
from .sampled import SampledLoop
from .smooth import SmoothLoop

__all__ = ["loop_model", "harmonic_balance_state", "input_history", "start_on_prediction"]

HISTORY_SAMPLES = 256    # samples of the predicted sinusoid that set the element's state (relay branch, play)


def loop_model(G, N, amplitude: float, frequency: float, *, steps_per_period: int = 400,
               what: str = "the exact flow", r0: float = 0.0, load: float = 0.0):
    """The loop of plant G and element N as a loop model (the one dispatcher on the element's time model).

    Parameters
    ----------
    G : python-control tf or ss, or :class:`~dfloop.solve.delay.DelayedSystem`
        The plant (strictly proper, except around an impact element whose output x1 is a state). With a pure
        delay T > 0 (``delayed(G, T)``) the loop is a :class:`DelayLoop` (exact delay flow) for elements whose
        output is piecewise constant (relays with hysteresis and dead zone, quantizer), a
        :class:`~dfloop.hybrid.dde.DDELoop` (the delay differential equation, discretised) for other static
        elements (saturation, dead zone, cubic stiffness, ...), a :class:`~dfloop.hybrid.dde_memory.MemoryDDELoop`
        (the same with the element's state in the history) for piecewise-affine elements with memory (backlash),
        a :class:`~dfloop.hybrid.delay_sampled.DelaySampledLoop` (fixed step, the delay line exact) for an element
        known only through an operator, a :class:`~dfloop.hybrid.delay_impact.DelayImpactLoop` (the delay equation
        with impacts, a method of steps on the impact engine) for an impact element.
    N : DescribingFunction
        The element; its ``time_model(amplitude)`` says how it behaves in time.
    amplitude, frequency : float
        Scale of the motion (element input units, rad/s): sizes the steps and ranges.
    steps_per_period : int
        The step of a sampled (fixed-step) loop, per period of ``frequency``.
    what : str
        The caller's name for error messages.
    r0, load : float
        Constant input: a reference r0 at the summing junction (x = r0 - c) and a load added to the element's
        output before the plant: piecewise-affine and smooth elements without delay (the loop's constant state);
        with a pure delay every element but an impact element (the shifted element of
        :mod:`dfloop.hybrid.constant`; the model keeps ``r0`` and ``load`` to read its results back).

    Raises
    ------
    ValueError
        N has no time model (naming N), or G is not a suitable plant (naming G), or G has a delay and N's time
        model is none of the above (naming N), or a constant input on an impact or (without delay) a sampled
        element (naming r0).
    """
    if not callable(getattr(N, "time_model", None)):
        raise ValueError(f"N must be a DescribingFunction (with time_model()), got {type(N).__name__}")
    try:
        tm = N.time_model(amplitude)
    except NotImplementedError as exc:
        raise ValueError(f"N: {type(N).__name__} has no time-domain model ({exc}); implement its "
                         "time_model() (dfloop.describing.time_model) or operator()") from None
    time_scale = 2.0 * math.pi / frequency
    G, delay = split_delay(G)
    constant = {"r0": float(r0), "load": float(load)}
    if (r0 != 0.0 or load != 0.0) and delay == 0.0 and not isinstance(tm, (PiecewiseAffine, Smooth)):
        raise ValueError(f"r0 = {r0!r}, load = {load!r}: a constant input is supported for piecewise-affine and "
                         f"smooth elements (and any but impact elements behind a pure delay), not for "
                         f"{type(N).__name__} ({type(tm).__name__})")
    if delay > 0.0:
        return _delay_model(G, N, tm, delay, time_scale, steps_per_period, what, amplitude=amplitude, **constant)
    if isinstance(tm, Impact):
        A, B, C, D = plant_system(G, what=what)
        model = ImpactLoop(A, B, C, D, tm, amplitude, frequency)
    else:
        A, B, C = plant_matrices(G, what=what)
        if isinstance(tm, PiecewiseAffine):
            model = HybridLoop(A, B, C, tm, time_scale, **constant)
        elif isinstance(tm, Smooth):
            model = SmoothLoop(A, B, C, tm.f, tm.name, time_scale, tm.slope, form=tm.form, **constant)
        elif isinstance(tm, Sampled):
            model = SampledLoop(A, B, C, tm, time_scale / steps_per_period, steps_per_period)
        else:
            raise ValueError(f"N: {type(N).__name__}.time_model() returned {type(tm).__name__}, not one of "
                             "PiecewiseAffine, Smooth, Impact, Sampled (dfloop.describing.time_model)")
    model.response = tm.response   # the element's periodic response: the biased start's mean and fundamental
    return model


def _describing(N):
    """N(F, w) of an element (its amplitude-only value for an element that is not frequency dependent)."""
    if getattr(N, "frequency_dependent", False):
        return lambda F, w: complex(N(F, w))
    return lambda F, w: complex(N(F))


def _delay_model(G, N, tm, delay, time_scale, steps_per_period, what, r0, load, amplitude):
    """The loop model of a plant with a pure delay T > 0; a constant input rides on the shifted element
    (:mod:`dfloop.hybrid.constant`), and the model keeps r0 and load to read its results back."""
    if isinstance(tm, Impact) and r0 == 0.0 and load == 0.0:   # masses driven through the delayed plant
        A, B, C, D = plant_system(G, what=what)
        model = DelayImpactLoop(A, B, C, D, tm, delay, amplitude, 2.0 * math.pi / time_scale)
        model.describing = _describing(N)
        model.r0, model.load = 0.0, 0.0
        return model
    A, B, C = plant_matrices(G, what=what)
    tm = shifted_model(tm, r0, load)
    if piecewise_constant(tm):     # relays, quantizer: the exact delay flow
        model = DelayLoop(A, B, C, tm, delay, time_scale)
    elif isinstance(tm, Sampled):  # an operator: fixed step, the delay line exact
        model = DelaySampledLoop(A, B, C, tm, delay, time_scale / steps_per_period, steps_per_period)
    else:
        f, kinks = static_map(tm)
        if f is not None:              # sloped or smooth static elements: the delay differential equation
            model = DDELoop(A, B, C, f, kinks, delay, tm.name)
        elif isinstance(tm, PiecewiseAffine) and tm.n_states == 1:   # memory (backlash): its state in the history
            model = MemoryDDELoop(A, B, C, tm, delay)
        else:
            raise ValueError(f"N: {type(N).__name__} with a pure delay in G is not supported here: its "
                             f"{type(tm).__name__} time model is none that the delay engines take (piecewise constant, "
                             "static, piecewise affine with one state, smooth, impact, or an operator); use "
                             "delayed(G, T).pade(n) for an approximation")
    model.r0, model.load = r0, load
    return model


def harmonic_balance_state(loop, N, amplitude: float, frequency: float, t: float = 0.0,
                           bias: float = 0.0) -> np.ndarray:
    """Plant state at time t of the orbit x = bias + amplitude sin(frequency t) that the DF assumes.

    With a bias or a constant input (``loop.r0``, ``loop.load``) the element's mean output m and fundamental come
    from its periodic response to that input (``loop.response``), and the plant's mean state s solves
    A s + B (m + load) = 0 with r0 - C s = bias in the least-squares sense (exactly with an integrator, where A
    alone does not fix s)."""
    A, B = loop.plant
    r0, load = getattr(loop, "r0", 0.0), getattr(loop, "load", 0.0)
    if bias != 0.0 or r0 != 0.0 or load != 0.0:
        return _biased_state(loop, amplitude, frequency, t, bias, r0, load)
    memo = getattr(loop, "_harmonic_balance", None)   # the shooting's nodes share the phasor: one solve for all
    if memo is not None and memo[0] is A and memo[1] is N and memo[2] == (amplitude, frequency):
        X = memo[3]
    else:
        n_val = complex(N(amplitude, frequency) if N.frequency_dependent else N(amplitude))
        X = np.linalg.solve(1j * frequency * np.eye(A.shape[0]) - A, B) * n_val * amplitude
        loop._harmonic_balance = (A, N, (amplitude, frequency), X)
    return (X * np.exp(1j * frequency * t)).imag.copy()


def _biased_state(loop, amplitude, frequency, t, bias, r0, load) -> np.ndarray:
    A, B = loop.plant
    C = -loop.x_row[:A.shape[0]]
    theta = 2.0 * math.pi * np.arange(HISTORY_SAMPLES) / HISTORY_SAMPLES
    y = np.asarray(loop.response(bias + amplitude * np.sin(theta)), float)
    m = float(np.mean(y))
    fundamental = 2j * np.mean(y * np.exp(-1j * theta))            # y ~ m + Im(fundamental e^{j theta})
    X = np.linalg.solve(1j * frequency * np.eye(A.shape[0]) - A, B) * fundamental
    stacked = np.vstack([A, C[None, :]])
    s_mean = np.linalg.lstsq(stacked, np.append(-B * (m + load), r0 - bias), rcond=None)[0]
    return s_mean + (X * np.exp(1j * frequency * t)).imag


def input_history(amplitude: float, frequency: float, t: float, bias: float = 0.0) -> np.ndarray:
    """Samples of the predicted input bias + amplitude sin(frequency t') over the period before time t."""
    T = 2.0 * math.pi / frequency
    return bias + amplitude * np.sin(frequency * (t + T * (np.arange(HISTORY_SAMPLES) / HISTORY_SAMPLES - 1.0)))


def start_on_prediction(loop, N, amplitude: float, frequency: float, t: float = 0.0, bias: float = 0.0):
    """(z, mode) at time t of the predicted orbit x = bias + amplitude sin(frequency t): the plant in its
    harmonic-balance state, the element in the state the predicted input leaves (the masses of an impact element
    at rest, gap centred)."""
    return loop.start(harmonic_balance_state(loop, N, amplitude, frequency, t, bias),
                      input_history(amplitude, frequency, t, bias))

