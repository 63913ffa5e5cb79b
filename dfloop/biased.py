"""The exact periodic orbit of a loop with a constant input (and a load), next to a biased-cycle prediction.

The loop e = r0 - y, u = f(e) + load, y = G u is the standard loop of :func:`dfloop.exact_cycle` (x = -y) with the
shifted static element g(x) = f(x + r0) + load, whose time model is piecewise affine or smooth as f's is; so the
exact engine (matrix exponentials between switches located to rounding, Floquet multipliers with saltation
matrices) runs unchanged, and the bias of e is the orbit's mean of x plus r0. Stability is then decided by the
exact orbit's multipliers, not by the reduced DF map (docs/bias_forced.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._checks import finite
from .describing.dual_input import DualInputDF
from .describing.numeric import NumericDF
from .errors import DfloopError
from .exact import ExactCycle, exact_cycle

__all__ = ["ExactBiasedCycle", "exact_biased_cycle"]


@dataclass(frozen=True)
class ExactBiasedCycle:
    """The exact orbit of a biased loop.

    Attributes
    ----------
    exact : ExactCycle
        The orbit of the shifted loop (x = e - r0): its period, waveforms, harmonics, multipliers.
    bias : float or None
        Mean of the element's input e over the orbit (None when no orbit was found).
    amplitude, frequency : float or None
        Fundamental amplitude of e and angular frequency (rad/s) of the orbit.
    stable : bool or None
        From the Floquet multipliers.
    predicted : (float, float, float)
        The (bias, amplitude, frequency) the search started from.
    """

    exact: ExactCycle
    bias: float | None
    amplitude: float | None
    frequency: float | None
    stable: bool | None
    predicted: tuple

    @property
    def success(self) -> bool:
        return bool(self.exact.success)

    def __repr__(self) -> str:
        if not self.success:
            return f"ExactBiasedCycle(not found: {self.exact.message})"
        b, a, w = self.predicted
        return (f"ExactBiasedCycle(bias={self.bias:.8g}, amplitude={self.amplitude:.8g}, frequency="
                f"{self.frequency:.8g} rad/s, {'stable' if self.stable else 'unstable'}; DF: bias {b:.6g}, "
                f"amplitude {(a - self.amplitude) / self.amplitude:+.2%}, frequency {(w - self.frequency) / self.frequency:+.2%})")


def exact_biased_cycle(G, element, cycle, *, r0: float = 0.0, load: float = 0.0, settle_periods: float = 30.0,
                       **options) -> ExactBiasedCycle:
    """The exact periodic orbit of the loop with constant input ``r0`` (and ``load``) near a biased prediction.

    Parameters
    ----------
    G : python-control tf or ss
        The plant, as for :func:`dfloop.exact_cycle`.
    element : StaticElement, DualInputDF with a ``function``, or callable
        A memoryless element (the shift needs its static map); a callable f(x) may come with ``options["breakpoints"]``
        (signed levels).
    cycle : BiasedCycle or (bias, amplitude, frequency)
        The prediction.
    r0, load : float
        As for :func:`dfloop.solve.bias.predict_biased_cycles`.
    settle_periods : float
        Periods flowed from the prediction before shooting (default 30: the engine's start is a centred sinusoid,
        so the motion must first find its bias; an unstable orbit needs 0 and a start close to it).
    **options
        Passed to :func:`dfloop.exact_cycle` (``tol``, ``max_iterations``, ...), except ``breakpoints``.

    Returns
    -------
    ExactBiasedCycle

    Raises
    ------
    ValueError
        An element with memory (no static map to shift), bad r0 or load.
    """
    r0, load = finite("r0", r0), finite("load", load)
    breakpoints = options.pop("breakpoints", None)
    dual = element if isinstance(element, DualInputDF) else DualInputDF(element, breakpoints=breakpoints)
    if dual.function is None:
        raise DfloopError(f"element {element!r} has memory: the exact biased orbit needs a static map f(x) "
                          "(relays with hysteresis and backlash are not shifted yet)")
    f = dual.function
    levels = np.abs(np.asarray(dual.breakpoints, float) - r0)

    def shifted(x):
        return np.asarray(f(np.asarray(x, float) + r0), float) + load

    if isinstance(cycle, tuple):
        B, A, w = (float(v) for v in cycle)
    else:
        B, A, w = cycle.bias, cycle.amplitude, cycle.frequency
    ex = exact_cycle(G, NumericDF(shifted, breakpoints=levels if levels.size else None), (A, w),
                     settle_periods=settle_periods, **options)
    if not ex.success:
        return ExactBiasedCycle(ex, None, None, None, None, (B, A, w))
    bias = float(np.mean(ex.x)) + r0
    return ExactBiasedCycle(ex, bias, float(ex.amplitude), float(ex.frequency), bool(ex.stable), (B, A, w))
