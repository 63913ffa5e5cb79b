"""A constant input on a delayed loop, carried by the element: the shifted time model.

With a reference r0 at the summing junction and a load at the element's output, the delayed loop reads

    s' = A s + B (y(t - T) + load),    x = r0 - C s,    y = N[x].

Written in x~ = x - r0 = -C s and y~ = y + load it is the loop without constant input, s' = A s + B y~(t - T),
x~ = -C s, around the shifted element y~ = N[x~ + r0] + load. The shift is exact (no assumption on A: an
integrator is fine) and keeps the element's kind: a piecewise-affine model stays piecewise affine (every
threshold moves by -r0, every output level by gx r0 + load), a smooth f stays smooth, an operator stays an
operator. So every delayed engine (:mod:`dfloop.hybrid.delay`, :mod:`dfloop.hybrid.dde`,
:mod:`dfloop.hybrid.dde_memory`, :mod:`dfloop.hybrid.delay_sampled`) takes a constant input unchanged, and its
results are read back with x = x~ + r0, y = y~ - load (:func:`unshift`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..describing.time_model import Guard, Mode, PiecewiseAffine, Sampled, Smooth

__all__ = ["shifted_model", "unshift"]


def shifted_model(tm, r0: float, load: float):
    """The time model of y~ = N[x~ + r0] + load (module notes) for a :class:`PiecewiseAffine`, :class:`Smooth` or
    :class:`Sampled` model ``tm``; ``tm`` itself when r0 = load = 0.

    Raises
    ------
    ValueError
        ``tm`` is another kind of model (an impact element: its masses are not a static shift), naming r0.
    """
    r0, load = float(r0), float(load)
    if r0 == 0.0 and load == 0.0:
        return tm
    if isinstance(tm, PiecewiseAffine):
        modes = [Mode(gx=m.gx, ge=m.ge, g1=m.g1 + m.gx * r0 + load, de=m.de, label=m.label,
                      guards=tuple(_guard(g, r0) for g in m.guards)) for m in tm.modes]

        def initial(x_history, xdot):
            return tm.initial(np.asarray(x_history, float) + r0, xdot)

        def response(x):
            return np.asarray(tm.response(np.asarray(x, float) + r0), float) + load

        return PiecewiseAffine(tm.name, modes, tm.n_states, initial, response)
    if isinstance(tm, Smooth):
        f, slope = tm.f, tm.slope
        return Smooth(tm.name, lambda x: np.asarray(f(np.asarray(x, float) + r0), float) + load,
                      None if slope is None else (lambda x: slope(np.asarray(x, float) + r0)))
    if isinstance(tm, Sampled):
        make = tm.make_operator

        def make_operator():
            op = make()
            return lambda x: float(op(float(x) + r0)) + load

        return Sampled(tm.name, make_operator)
    raise ValueError(f"r0 = {r0!r}, load = {load!r}: a constant input with a pure delay is supported for "
                     f"piecewise-affine, smooth and sampled elements, not for the {type(tm).__name__} model of "
                     f"{tm.name}")


def _guard(g: Guard, r0: float) -> Guard:
    reset = None if g.reset is None else (g.reset[0], g.reset[1] + g.reset[0] * r0)
    return dataclasses.replace(g, c1=g.c1 + g.cx * r0, reset=reset)


def unshift(out: dict, r0: float, load: float) -> dict:
    """An orbit's fields (a dict of :class:`dfloop.exact.ExactCycle` fields from a shifted loop) read back in the
    loop's own signals: x = x~ + r0, y = y~ - load, and ``mean`` the mean of x over the period (the harmonics
    k >= 1 are unchanged)."""
    if not out.get("success") or (r0 == 0.0 and load == 0.0):
        return out
    out = dict(out)
    out["x"] = np.asarray(out["x"], float) + r0
    out["y"] = np.asarray(out["y"], float) - load
    out["mean"] = float(np.mean(out["x"]))
    return out
