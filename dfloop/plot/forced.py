"""The DF forced response against frequency (:class:`dfloop.solve.forced.ForcedResponse`)."""
from __future__ import annotations

from typing import Any

from ._labels import quantity
from .controlplot import control_plot

__all__ = ["plot_forced_response", "plot_jump_region"]

_STYLE = {True: dict(color="C0", ls="-"), False: dict(color="C3", ls="--")}


def plot_forced_response(result, ax=None, *, output: bool = False, exact=None) -> Any:
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
    exact : ExactForcedResponse, optional
        From :func:`dfloop.hybrid.forced.exact_forced_response`: the exact orbits at the forcing period on top
        (filled circles stable, open circles unstable, by their multipliers), and a cross at the DF amplitude
        where the exact response has no orbit at the forcing period (subharmonic or not periodic).

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the branch curves, ``lines[1]``: the jump arrows, ``lines[2]``: the exact points;
        ``axes[0, 0]``.
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
    marks = []
    if exact is not None:
        pts = exact.flat()
        groups = (("exact, stable", "o", "k", [p for p in pts if p.periodic and p.stable]),
                  ("exact, unstable", "o", "none", [p for p in pts if p.periodic and not p.stable]),
                  ("exact: no orbit at the forcing period", "x", "C3", [p for p in pts if not p.periodic]))
        for label, marker, face, group in groups:
            if not group:
                continue
            y = [(p.output_amplitude if output else p.amplitude) if p.periodic else p.predicted for p in group]
            marks += ax.plot([p.omega for p in group], y, ls="none", marker=marker, ms=5, mfc=face,
                             mec="C3" if marker == "x" else "k", color="C3" if marker == "x" else "k", label=label)
        seen.add("exact")
    name = "output amplitude" if output else f"Amplitude {result.amplitude_name}"
    ax.set_ylabel(quantity(name, result.amplitude_unit or "-"))
    ax.set_xlabel(quantity("Forcing frequency ω", "rad/s"))
    ax.set_title(f"DF forced response, R = {result.R:g}")
    ax.set_xlim(float(np.min(result.omega)), float(np.max(result.omega)))
    leg = ax.legend(loc="best", fontsize="small") if seen else None
    return control_plot([curves, arrows, marks], ax, leg)


def plot_jump_region(region, ax=None) -> Any:
    """The jump-resonance region in the (forcing frequency, forcing amplitude) plane.

    For each forcing amplitude R with jumps, the multi-valued band between its lowest and highest fold frequency
    is shaded, and each fold marked (triangles pointing right: met sweeping up; left: sweeping down).

    Parameters
    ----------
    region : JumpRegion
        From :func:`dfloop.solve.forced.jump_region` (read by its attributes ``R``, ``folds`` and ``band(i)``).
    ax : matplotlib Axes, optional
        A new figure by default.

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the fold markers, ``lines[1]``: the shaded band; ``axes[0, 0]``.
    """
    import matplotlib.pyplot as plt
    import numpy as np

    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
    rows = [(float(r), region.band(i)) for i, r in enumerate(region.R) if region.band(i) is not None]
    markers, fills = [], []
    if rows:
        R = np.array([r for r, _ in rows])
        lo = np.array([b[0] for _, b in rows])
        hi = np.array([b[1] for _, b in rows])
        fills.append(ax.fill_betweenx(R, lo, hi, color="C0", alpha=0.25, lw=0, label="multi-valued (jumps)"))
    for sweep, marker in (("up", ">"), ("down", "<")):
        pts = [(j.omega, float(r)) for r, folds in zip(region.R, region.folds) for j in folds if j.sweep == sweep]
        if pts:
            markers += ax.plot(*zip(*pts), ls="none", marker=marker, color="k", ms=5,
                               label=f"jump sweeping {sweep}")
    ax.set_xlabel(quantity("Forcing frequency ω", "rad/s"))
    ax.set_ylabel(quantity("Forcing amplitude R", "-"))
    ax.set_title("Jump-resonance region")
    ax.set_ylim(0.0, float(np.max(region.R)) * 1.05)
    leg = ax.legend(loc="best", fontsize="small") if rows else None
    if not rows:
        ax.text(0.5, 0.5, "no jump on the frequency grid", transform=ax.transAxes, ha="center")
    return control_plot([markers, fills], ax, leg)
