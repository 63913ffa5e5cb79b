"""Biased cycles next to their exact orbits: :func:`dfloop.solve.bias.predict_biased_cycles` with each cycle's exact
periodic orbit attached.

The exact orbit comes from the one engine: :func:`dfloop.exact_cycle` with the loop's constant input (``r0`` at the
summing junction, ``load`` at the element's output, both carried by the loop model's constant state, so the flow
stays exact) and the predicted bias (the shooting starts on x = B + A sin(w t), so unstable biased cycles are found
as stable ones). The exact orbit's Floquet multipliers decide the stability; the prediction's own ``stability`` is
the Loeb criterion on the reduced map (docs/bias_forced.md).
"""
from __future__ import annotations

import dataclasses

from .describing.dual_input import DualInputDF
from .exact import exact_cycle
from .solve.bias import BiasedCycles, predict_biased_cycles

__all__ = ["biased_cycles"]


def biased_cycles(G, element, *, r0: float = 0.0, load: float = 0.0, amplitude, exact: bool = True,
                  exact_options: dict | None = None, **options) -> BiasedCycles:
    """Every biased cycle of the loop with a constant input, each with its exact orbit.

    Parameters
    ----------
    G : python-control tf or ss
        The plant (strictly proper), or ``delayed(G, T)`` (the exact orbit then runs on the delay flow).
    element : DescribingFunction, DualInputDF or callable
        As for :func:`~dfloop.solve.bias.predict_biased_cycles`; the exact orbit runs the element's time model
        (a static map given as a callable or :meth:`DualInputDF.piecewise_affine` runs as a
        :class:`~dfloop.NumericDF` with its breakpoints).
    r0, load : float
        Reference at the summing junction and load at the element's output.
    amplitude : (float, float)
        Amplitude window of the element's input.
    exact : bool
        Attach each cycle's exact orbit (``cycle.exact``, an :class:`~dfloop.exact.ExactCycle` whose ``mean`` is
        the exact bias); False: the prediction only.
    exact_options : dict, optional
        Passed to :func:`dfloop.exact_cycle` (``tol``, ``nodes``, ``settle_periods``, ...).
    **options
        Passed to :func:`~dfloop.solve.bias.predict_biased_cycles` (``bias``, ``omega``, ``dc_gain``, grids).

    Returns
    -------
    BiasedCycles
        As the prediction, each :class:`~dfloop.solve.bias.BiasedCycle` with ``exact`` set.
    """
    from ._checks import flag

    dual = element if isinstance(element, DualInputDF) else DualInputDF(element)
    cycles = predict_biased_cycles(G, dual, r0=r0, load=load, amplitude=amplitude, **options)
    if not flag("exact", exact):
        return cycles
    N = dual.describing_function
    found = [dataclasses.replace(c, exact=exact_cycle(G, N, c, r0=r0, load=load, **(exact_options or {})))
             for c in cycles]
    return BiasedCycles(found, cycles.r0, cycles.dc_gain, cycles.amplitude_window, cycles.bias_window,
                        cycles.omega_window, cycles.bias_monotone, cycles.branches, cycles.gaps)
