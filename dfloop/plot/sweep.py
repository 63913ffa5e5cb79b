"""Branches of limit cycles against a swept parameter (:class:`dfloop.continuation.SweepResult`)."""
from __future__ import annotations

from typing import Any

import numpy as np

from ._labels import quantity
from .controlplot import control_plot

__all__ = ["plot_sweep"]

_BRANCH = {"stable": dict(color="C0", ls="-"), "unstable": dict(color="C3", ls="--"),
           "marginal": dict(color="C1", ls=":")}
_EVENTS = {"fold": dict(marker="o", color="k", ls="none", ms=5),
           "birth": dict(marker="^", color="C2", ls="none", ms=7),
           "death": dict(marker="v", color="C2", ls="none", ms=7),
           "continuum": dict(marker="|", color="0.3", ls="none", ms=12),
           "entry": dict(marker="x", color="0.3", ls="none"), "exit": dict(marker="x", color="0.3", ls="none"),
           "stability change": dict(marker="s", color="C2", ls="none", ms=5),
           "lost": dict(marker="*", color="C1", ls="none", ms=8)}


def plot_sweep(result, ax=None) -> Any:
    """Amplitude and frequency of every branch against the swept parameter.

    Stable branches solid, unstable dashed, marginal dotted; folds as black dots, window entries and exits as
    crosses, births and deaths as green triangles (none drawn for a birth at A -> inf), a continuum at one
    parameter value as a bar, stability changes as green squares, lost branches as stars. The parameter axis is labelled with
    the result's ``parameter`` and ``unit`` (``"K [-]"``-style).

    Parameters
    ----------
    result : SweepResult
        From :func:`dfloop.sweep` (read by its attributes: ``branches``, ``events``, ``values``, ``parameter``,
        ``unit``, ``amplitude_name``, ``amplitude_unit``).
    ax : pair of matplotlib Axes, optional
        (amplitude, frequency); new ones sharing the parameter axis by default.

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: branch curves on the amplitude axes, ``lines[1]`` on the frequency axes, ``lines[2]``:
        event markers; ``axes[0, 0]`` amplitude, ``axes[1, 0]`` frequency.
    """
    import matplotlib.pyplot as plt
    from matplotlib.axes import Axes

    if ax is None:
        _, ax = plt.subplots(2, 1, sharex=True, figsize=(6.4, 6.0), constrained_layout=True)
    try:
        ax_a, ax_w = ax
    except (TypeError, ValueError):
        raise ValueError(f"ax must be a pair of Axes (amplitude, frequency), got {type(ax).__name__}") from None
    if not (isinstance(ax_a, Axes) and isinstance(ax_w, Axes)):
        raise ValueError(f"ax must be a pair of Axes (amplitude, frequency), got {ax!r:.60}")
    seen: set = set()
    on_a, on_w, marks = [], [], []
    order = ("stable", "unstable", "marginal")
    for b in sorted(result.branches, key=lambda b: order.index(b.kind)):
        label = None if b.kind in seen else f"{b.kind} cycles"
        seen.add(b.kind)
        on_a += ax_a.plot(b.parameter, b.amplitude, label=label, **_BRANCH[b.kind])
        on_w += ax_w.plot(b.parameter, b.frequency, **_BRANCH[b.kind])
    for kind, style in _EVENTS.items():
        ev = [e for e in result.events if e.kind == kind and 0 < e.amplitude < np.inf]  # A -> inf: no mark
        if ev:
            label = "window edge" if kind in ("entry", "exit") else kind
            label = None if label in seen else label
            seen.add(label)
            marks += ax_a.plot([e.parameter for e in ev], [e.amplitude for e in ev], label=label, **style)
            marks += ax_w.plot([e.parameter for e in ev], [e.frequency for e in ev], **style)
    ax_a.set_ylabel(quantity(f"Amplitude {result.amplitude_name}", result.amplitude_unit or "-"))
    ax_w.set_ylabel(quantity("Frequency ω", "rad/s"))
    ax_w.set_xlabel(quantity(result.parameter, result.unit or "-"))
    for a, attr in ((ax_a, "amplitude"), (ax_w, "frequency")):
        vals = np.concatenate([getattr(b, attr) for b in result.branches]) if result.branches else np.empty(0)
        if vals.size and vals.max() > 20 * vals.min():
            a.set_yscale("log")
    lo, hi = sorted((float(result.values[0]), float(result.values[-1])))
    ax_w.set_xlim(lo, hi)
    leg = ax_a.legend(loc="best", fontsize="small") if seen else None
    return control_plot([on_a, on_w, marks], [ax_a, ax_w], leg)
