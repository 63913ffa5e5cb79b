"""The DF forced response against frequency (:class:`dfloop.solve.forced.ForcedResponse`)."""
from __future__ import annotations

from typing import Any

from ._labels import quantity
from .controlplot import control_plot

__all__ = ["plot_forced_response"]

_STYLE = {True: dict(color="C0", ls="-"), False: dict(color="C3", ls="--")}


def plot_forced_response(result, ax=None, *, output: bool = False) -> Any:
    """Amplitude of the element's input (or of the plant's output) against the forcing frequency.

    Stable solutions solid, unstable dashed; each jump as an arrow from the fold to the stable solution the
    response jumps to (upward or downward), labelled by the sweep direction that meets it.

    Parameters
    ----------
    result : ForcedResponse
        From :func:`dfloop.solve.forced.forced_response` (read by its attributes: ``branches()``, ``jumps``,
        ``R``, ``amplitude_name``, ``amplitude_unit``).
    ax : matplotlib Axes, optional
        A new figure by default.
    output : bool
        Plot the plant output's amplitude |G N| A instead of the element input's A (jump arrows then omitted,
        since the jump targets are element-input amplitudes).

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the branch curves, ``lines[1]``: the jump arrows; ``axes[0, 0]``.
    """
    import matplotlib.pyplot as plt
    import numpy as np

    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
    curves, arrows, seen = [], [], set()
    for branch in result.branches():
        # split each branch where its stability changes, so that each piece has one style
        start = 0
        for i in range(1, len(branch) + 1):
            if i == len(branch) or branch[i].stable != branch[start].stable:
                piece = branch[start:i]
                stable = piece[0].stable
                label = None if stable in seen else ("stable" if stable else "unstable")
                seen.add(stable)
                w = [p.omega for p in piece]
                y = [p.output_amplitude if output else p.amplitude for p in piece]
                curves += ax.plot(w, y, label=label, marker="." if len(piece) == 1 else None, **_STYLE[stable])
                start = i
    if not output:
        labelled = False
        for jump in result.jumps:
            if jump.target is None:
                continue
            arrows.append(ax.annotate("", xy=(jump.omega, jump.target), xytext=(jump.omega, jump.amplitude),
                                      arrowprops=dict(arrowstyle="->", color="k", lw=1.2)))
            curves += ax.plot([jump.omega], [jump.amplitude], "ko", ms=4,
                              label=None if labelled else "jump (fold)")
            labelled = True
    name = "output amplitude" if output else f"Amplitude {result.amplitude_name}"
    ax.set_ylabel(quantity(name, result.amplitude_unit or "-"))
    ax.set_xlabel(quantity("Forcing frequency ω", "rad/s"))
    ax.set_title(f"DF forced response, R = {result.R:g}")
    ax.set_xlim(float(np.min(result.omega)), float(np.max(result.omega)))
    leg = ax.legend(loc="best", fontsize="small") if seen else None
    return control_plot([curves, arrows], ax, leg)
