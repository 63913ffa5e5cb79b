"""Piecewise-linear (hybrid) models of the static and hysteretic elements of :mod:`dfloop.describing`.

An element model is a finite set of modes. In each mode the output is affine in the element's input x and in
the element's own state e (the driven side of a backlash), y = gx x + ge e + g1, the state moves as
e' = de x', and the mode is left when one of its guard functions g = cx x + cxd x' + ce e + c1 (>= 0 inside the
mode) crosses zero; the guard names the next mode and an optional reset e := rx x + r1. The closed loop
(:mod:`dfloop.hybrid.loop`) turns these element-level coefficients into rows over the loop's state.

:func:`element_model` maps an element object to its model (or None when the element is not piecewise linear):

- :class:`~dfloop.describing.static.Relay` (hysteresis, dead zone, both): modes -M, 0, +M, the element's
  switching rule (:class:`~dfloop.describing.static.RelayOperator`).
- :class:`~dfloop.describing.static.Backlash` (the play operator): free, engaged rising, engaged falling.
- Any :class:`~dfloop.describing.static.StaticElement` (and a static :class:`~dfloop.describing.numeric.NumericDF`)
  whose output is affine between its breakpoints (checked numerically): saturation, dead zone, quantizer,
  preloaded spring, Coulomb + viscous friction. One mode per interval between breakpoints.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["Guard", "Mode", "ElementModel", "element_model"]

OUT_OF_RANGE = -1            # guard target: the input left the range the model covers (quantizer)
_AFFINE_RTOL = 1e-12         # a static output counts as affine on an interval when 5 samples agree to this
_QUANTIZER_RANGE = 64.0      # quantizer levels modelled up to this many times the starting amplitude


@dataclass(frozen=True)
class Guard:
    """g = cx x + cxd x' + ce e + c1 >= 0 inside the mode; crossing zero switches to ``target``."""

    cx: float = 0.0
    cxd: float = 0.0
    ce: float = 0.0
    c1: float = 0.0
    target: int = OUT_OF_RANGE
    reset: tuple | None = None   # (rx, r1): e := rx x + r1 on the switch


@dataclass(frozen=True)
class Mode:
    """Output y = gx x + ge e + g1, element state e' = de x', and the guards that end the mode."""

    gx: float = 0.0
    ge: float = 0.0
    g1: float = 0.0
    de: float = 0.0
    guards: tuple = ()
    label: str = ""


@dataclass
class ElementModel:
    """A piecewise-linear element: ``modes``, number of element states (0 or 1), and its start rule.

    ``initial(x_history, xdot) -> (mode, e)``: the mode and element state after the element has been driven
    by the samples ``x_history`` (ending at the current input), given the current input rate ``xdot``.
    """

    name: str
    modes: list
    n_states: int
    initial: Callable = field(repr=False)


# --------------------------------------------------------------------------------------------------- relay


def _relay(M: float, on: float, off: float, name: str) -> ElementModel:
    from ..describing.static import RelayOperator

    down, zero, up = 0, 1, 2
    full_swing = off <= -on          # hysteresis relay without dead zone: +M -> -M directly
    modes = [
        Mode(g1=-M, guards=(Guard(cx=-1.0, c1=-off, target=up if full_swing else zero),), label="-M"),
        Mode(g1=0.0, guards=(Guard(cx=-1.0, c1=on, target=up), Guard(cx=1.0, c1=on, target=down)), label="0"),
        Mode(g1=M, guards=(Guard(cx=1.0, c1=-off, target=down if full_swing else zero),), label="+M"),
    ]

    def initial(x_history, xdot):
        op = RelayOperator(M, on, off)
        for x in x_history:
            op(x)
        return op.state + 1, 0.0

    return ElementModel(name, modes, 0, initial)


# ------------------------------------------------------------------------------------------------- backlash


def _play(h: float, k: float, name: str) -> ElementModel:
    from ..describing.static import PlayOperator

    free, rising, falling = 0, 1, 2
    half = 0.5 * h
    modes = [
        Mode(ge=k, de=0.0, label="free", guards=(
            Guard(cx=-1.0, ce=1.0, c1=half, target=rising, reset=(1.0, -half)),     # x - e reaches +h/2
            Guard(cx=1.0, ce=-1.0, c1=half, target=falling, reset=(1.0, half)))),   # x - e reaches -h/2
        # engaged: x' >= 0 (resp. <= 0); the release re-projects e = x -/+ h/2 (exact on the orbit, and it keeps
        # perturbations that leave the contact constraint physical)
        Mode(ge=k, de=1.0, label="engaged +", guards=(Guard(cxd=1.0, target=free, reset=(1.0, -half)),)),
        Mode(ge=k, de=1.0, label="engaged -", guards=(Guard(cxd=-1.0, target=free, reset=(1.0, half)),)),
    ]

    def initial(x_history, xdot):
        op = PlayOperator(h, k)
        for x in x_history:
            op(x)
        x, e = float(x_history[-1]), op.center
        tol = 1e-9 * h
        if x - e >= half - tol and xdot > 0:
            return rising, x - half
        if x - e <= -half + tol and xdot < 0:
            return falling, x + half
        return free, e

    return ElementModel(name, modes, 1, initial)


# --------------------------------------------------------------------------------------------- static PWL


def _affine_pieces(f: Callable, levels: np.ndarray, scale: float, bounded: bool):
    """(slope, intercept) of f on each interval between sorted ``levels`` (outer ones unbounded), or None.

    ``bounded``: the two outer intervals lie outside the modelled range (not checked, never entered)."""
    edges = np.concatenate([[-np.inf], levels, [np.inf]])
    pieces = []
    for i, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        if bounded and i in (0, len(edges) - 2):
            pieces.append((0.0, 0.0))
            continue
        if np.isinf(lo) and np.isinf(hi):
            pts = scale * np.array([-1.7, -0.6, 0.1, 0.9, 2.3])
        elif np.isinf(lo):
            pts = hi - scale * np.array([0.1, 0.35, 0.8, 1.6, 3.1])
        elif np.isinf(hi):
            pts = lo + scale * np.array([0.1, 0.35, 0.8, 1.6, 3.1])
        else:
            pts = lo + (hi - lo) * np.array([0.1, 0.3, 0.55, 0.7, 0.9])
        y = np.asarray(f(pts), dtype=float)
        slope = (y[-1] - y[0]) / (pts[-1] - pts[0])
        intercept = y[0] - slope * pts[0]
        fit = slope * pts + intercept
        if not np.all(np.isfinite(y)) or np.max(np.abs(fit - y)) > _AFFINE_RTOL * (np.max(np.abs(y)) + scale * abs(slope) + 1e-300):
            return None
        pieces.append((slope, intercept))
    return pieces


def _static(f: Callable, levels: np.ndarray, name: str, scale: float, bounded: bool) -> ElementModel | None:
    pieces = _affine_pieces(f, levels, scale, bounded)
    if pieces is None:
        return None
    n = len(pieces)
    modes = []
    for i, (slope, intercept) in enumerate(pieces):
        guards = []
        if i > 0:         # x >= levels[i - 1]
            guards.append(Guard(cx=1.0, c1=-levels[i - 1], target=(i - 1) if (i > 1 or not bounded) else OUT_OF_RANGE))
        if i < n - 1:     # x <= levels[i]
            guards.append(Guard(cx=-1.0, c1=levels[i], target=(i + 1) if (i < n - 2 or not bounded) else OUT_OF_RANGE))
        modes.append(Mode(gx=slope, g1=intercept, guards=tuple(guards), label=f"piece {i}"))

    def initial(x_history, xdot):
        x = float(x_history[-1])
        i = int(np.searchsorted(levels, x, side="right" if xdot >= 0 else "left"))
        return i, 0.0

    return ElementModel(name, modes, 0, initial)


def element_model(N, amplitude: float) -> ElementModel | None:
    """The piecewise-linear model of element ``N``, or None when N is not piecewise linear.

    Parameters
    ----------
    N : DescribingFunction
        The element.
    amplitude : float
        Amplitude scale of the motion (sizes the range of the quantizer's levels and the affinity check).
    """
    from ..describing.numeric import NumericDF
    from ..describing.static import Backlash, PlayOperator, Quantizer, Relay, RelayOperator, StaticElement

    name = type(N).__name__
    if isinstance(N, Relay):
        return _relay(N.M, N.on_level, N.off_level, name)
    if isinstance(N, Backlash):
        return _play(N.h, N.k, name)
    if isinstance(N, NumericDF) and N.hysteretic:
        op = N.element
        if isinstance(op, RelayOperator):
            return _relay(op.M, op.on, op.off, name)
        if isinstance(op, PlayOperator):
            return _play(op.h, op.k, name)
        return None
    if isinstance(N, (StaticElement, NumericDF)):
        f = N.output if isinstance(N, StaticElement) else N.element
        bp = N.breakpoints if isinstance(N, StaticElement) else N.breakpoints
        bounded = isinstance(N, Quantizer)
        a_max = _QUANTIZER_RANGE * amplitude
        if bp is None:
            levels = np.empty(0)
        elif callable(bp):
            levels = np.asarray(bp(a_max), dtype=float)
        else:
            levels = np.asarray(bp, dtype=float)
        levels = np.unique(np.concatenate([-levels, levels])) if levels.size else levels
        if bounded:
            levels = np.concatenate([[-a_max], levels, [a_max]])
        return _static(f, levels, name, max(amplitude, float(np.max(np.abs(levels), initial=0.0))), bounded)
    return None
