"""How an element behaves in time: the vocabulary of :meth:`DescribingFunction.time_model`.

The exact engines (:mod:`dfloop.hybrid`) never look at an element's type. They ask the element for its time
model and build the loop from what it returns, one of:

- :class:`PiecewiseAffine`: finitely many modes; in each the output is affine in the element's input x and its
  own state e (the driven side of a backlash), y = gx x + ge e + g1, the state moves as e' = de x', and the mode
  is left when a guard g = cx x + cxd x' + ce e + c1 (>= 0 inside the mode) crosses zero; the guard names the
  next mode and an optional reset e := rx x + r1. Relays (hysteresis, dead zone), the play operator (backlash),
  saturation, dead zone, quantizer, preloaded spring, Coulomb + viscous friction. Run exactly (matrix
  exponentials between switches located to rounding level).
- :class:`Smooth`: a static y = f(x) with f smooth (cubic stiffness, a user's f). Run on DOP853.
- :class:`Impact`: the two-mass clearance element of the paper (dynamic backlash): masses, clearance,
  restitution and effects. Run on the exact linear-mode impact engine.
- :class:`Sampled`: only a stateful operator ``op(x) -> y`` (a user's hysteretic element). Simulated with a
  fixed step (not exact; no periodic-orbit shooting).

Every model also gives ``response(x)``: the element's output over one period of periodic input samples (after
one warm-up period), which :mod:`dfloop.solve.confidence` uses (None for :class:`Impact`, whose response depends on
frequency). A user-defined element implements ``time_model(amplitude)`` returning one of these.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["Guard", "Mode", "PiecewiseAffine", "Smooth", "Impact", "Sampled", "relay_model", "play_model",
           "static_model", "impact_model", "fresh_copy", "OUT_OF_RANGE"]

OUT_OF_RANGE = -1            # guard target: the input left the range the model covers (quantizer)
_AFFINE_RTOL = 1e-12         # a static output counts as affine on an interval when 5 samples agree to this
_RANGE = 64.0                # levels of an unbounded staircase (quantizer) modelled up to this many amplitudes


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
class PiecewiseAffine:
    """A piecewise-affine element: ``modes``, number of element states (0 or 1), its start rule and response.

    ``initial(x_history, xdot) -> (mode, e)``: the mode and element state after the element has been driven
    by the samples ``x_history`` (ending at the current input), given the current input rate ``xdot``.
    ``response(x) -> y``: output over one period of periodic input samples (periodic regime).
    """

    name: str
    modes: list
    n_states: int
    initial: Callable = field(repr=False)
    response: Callable = field(repr=False)


@dataclass
class Smooth:
    """A static element y = f(x) with a smooth f (vectorised over x); ``slope`` f'(x), if known; ``form`` the
    element's compiled form (kind name, parameters: its ``compiled_form()``) when f is a built-in one that the
    compiled integrator (:mod:`dfloop.hybrid.smooth_compiled`) evaluates itself, else None."""

    name: str
    f: Callable = field(repr=False)
    slope: Callable | None = field(default=None, repr=False)
    form: tuple | None = field(default=None, repr=False)

    def response(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self.f(x), dtype=float)


@dataclass
class Impact:
    """The two-mass clearance element (dynamic backlash): masses m1, m2 (kg), clearance h (m), restitution,
    effects (:mod:`dfloop.impact.effects`) and the relative post-impact speed below which a chatter sticks."""

    name: str
    m1: float
    m2: float
    h: float
    restitution: float
    effects: tuple = ()
    chatter_tol: float = 1e-9
    response = None


@dataclass
class Sampled:
    """An element known only through a stateful operator: ``make_operator()`` returns a fresh ``op(x) -> y``
    at rest (rate-independent). Simulated with a fixed step; not exact."""

    name: str
    make_operator: Callable = field(repr=False)

    def response(self, x: np.ndarray) -> np.ndarray:
        op = self.make_operator()
        for v in x:                          # warm-up period: the state of the periodic regime
            op(float(v))
        return np.array([op(float(v)) for v in x])


# --------------------------------------------------------------------------------------------------- relay


def relay_model(M: float, on: float, off: float, name: str, make_operator: Callable) -> PiecewiseAffine:
    """Relay of level M switching on at |x| > ``on`` and off at |x| < ``off`` (modes -M, 0, +M).

    ``make_operator()`` returns the element's own operator at rest; it sets the start mode from a history."""
    down, zero, up = 0, 1, 2
    full_swing = off <= -on          # hysteresis relay without dead zone: +M -> -M directly
    modes = [
        Mode(g1=-M, guards=(Guard(cx=-1.0, c1=-off, target=up if full_swing else zero),), label="-M"),
        Mode(g1=0.0, guards=(Guard(cx=-1.0, c1=on, target=up), Guard(cx=1.0, c1=on, target=down)), label="0"),
        Mode(g1=M, guards=(Guard(cx=1.0, c1=-off, target=down if full_swing else zero),), label="+M"),
    ]

    def initial(x_history, xdot):
        op = make_operator()
        for x in x_history:
            op(x)
        return op.state + 1, 0.0

    def response(x):
        from ._operators_core import relay_response   # numba: loaded on first use only

        return relay_response(np.ascontiguousarray(x, dtype=float), M, on, off)

    return PiecewiseAffine(name, modes, 0, initial, response)


# ------------------------------------------------------------------------------------------------- backlash


def play_model(h: float, k: float, name: str, make_operator: Callable) -> PiecewiseAffine:
    """Play operator of total clearance h and slope k (modes free, engaged rising, engaged falling)."""
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
        op = make_operator()
        for x in x_history:
            op(x)
        x, e = float(x_history[-1]), op.center
        tol = 1e-9 * h
        if x - e >= half - tol and xdot > 0:
            return rising, x - half
        if x - e <= -half + tol and xdot < 0:
            return falling, x + half
        return free, e

    def response(x):
        from ._operators_core import play_response   # numba: loaded on first use only

        return play_response(np.ascontiguousarray(x, dtype=float), h, k)

    return PiecewiseAffine(name, modes, 1, initial, response)


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
        tol = _AFFINE_RTOL * (np.max(np.abs(y)) + scale * abs(slope) + 1e-300)
        if not np.all(np.isfinite(y)) or np.max(np.abs(fit - y)) > tol:
            return None
        pieces.append((slope, intercept))
    return pieces


def static_model(f: Callable, breakpoints, name: str, amplitude: float, *,
                 unbounded_levels: bool = False) -> PiecewiseAffine | Smooth:
    """The time model of a static odd element y = f(x): piecewise affine when f is affine between its
    breakpoints (checked numerically at 5 points per piece), :class:`Smooth` otherwise.

    Parameters
    ----------
    f : callable
        Vectorised y = f(x).
    breakpoints : array_like, callable or None
        Levels >= 0 where f or f' jumps (mirrored to negative x); a callable is called with the largest
        amplitude modelled.
    amplitude : float
        Amplitude scale of the motion (sizes the affinity check and the range of an unbounded staircase).
    unbounded_levels : bool
        f has infinitely many breakpoints (quantizer): levels are modelled up to 64 ``amplitude``; a motion
        leaving that range stops the flow with a message.
    """
    a_max = _RANGE * amplitude
    if breakpoints is None:
        levels = np.empty(0)
    elif callable(breakpoints):
        levels = np.asarray(breakpoints(a_max), dtype=float)
    else:
        levels = np.asarray(breakpoints, dtype=float)
    levels = np.unique(np.concatenate([-levels, levels])) if levels.size else levels
    if unbounded_levels:
        levels = np.concatenate([[-a_max], levels, [a_max]])
    scale = max(amplitude, float(np.max(np.abs(levels), initial=0.0)))
    pieces = _affine_pieces(f, levels, scale, unbounded_levels)
    if pieces is None:
        return Smooth(name, f)
    n = len(pieces)
    modes = []
    for i, (slope, intercept) in enumerate(pieces):
        guards = []
        if i > 0:         # x >= levels[i - 1]
            target = (i - 1) if (i > 1 or not unbounded_levels) else OUT_OF_RANGE
            guards.append(Guard(cx=1.0, c1=-levels[i - 1], target=target))
        if i < n - 1:     # x <= levels[i]
            target = (i + 1) if (i < n - 2 or not unbounded_levels) else OUT_OF_RANGE
            guards.append(Guard(cx=-1.0, c1=levels[i], target=target))
        modes.append(Mode(gx=slope, g1=intercept, guards=tuple(guards), label=f"piece {i}"))

    def initial(x_history, xdot):
        x = float(x_history[-1])
        i = int(np.searchsorted(levels, x, side="right" if xdot >= 0 else "left"))
        return i, 0.0

    def response(x):
        return np.asarray(f(x), dtype=float)

    return PiecewiseAffine(name, modes, 0, initial, response)


def fresh_copy(operator) -> Callable:
    """A factory of independent copies of a stateful operator given at rest (for :class:`Sampled`)."""
    return lambda: copy.deepcopy(operator)


def impact_model(N) -> Impact | None:
    """The element's :class:`Impact` model (masses, clearance, restitution, effects) when it is an impact element
    (the dynamic backlash, or a user's element with such a time model), else None: the test to use instead of a
    type check on the element."""
    try:
        tm = N.time_model(1.0)
    except (NotImplementedError, AttributeError):
        return None
    return tm if isinstance(tm, Impact) else None
