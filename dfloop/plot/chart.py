"""Design charts: filled regions (no cycle / stable cycle / only unstable / several), traced boundary curves
labelled by kind, the nominal design point and its distance to the nearest boundary (the limit-cycle margin).

Returns a :class:`control.ControlPlot` like the Nyquist-plane plots.
"""
from __future__ import annotations

import numpy as np

from ._labels import axes_or_new, quantity

__all__ = ["plot_chart", "REGION_COLORS"]

REGION_COLORS = {"no cycle": "#ffffff", "stable cycle": "#c6dbef", "only unstable cycles": "#fcbba1",
                 "several cycles": "#d9f0a3", "continuum": "#bdbdbd"}
_BOUNDARY_STYLE = {"fold": dict(color="k", ls="-"), "linear range": dict(color="C0", ls="-"),
                   "infinity": dict(color="C3", ls="--"), "zero amplitude": dict(color="C1", ls="--"),
                   "amplitude domain": dict(color="C4", ls="-."), "jump": dict(color="C5", ls=":"),
                   "window edge": dict(color="0.5", ls=":")}


def plot_chart(result, ax=None, *, show_samples: bool = False):
    """Draw a :class:`dfloop.chart.ChartResult`.

    Parameters
    ----------
    result : ChartResult
        From :func:`dfloop.chart.design_chart`.
    ax : matplotlib Axes, optional
        Where to draw (a new figure when None).
    show_samples : bool
        Also mark the region samples (``predict_limit_cycles`` calls).

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the boundary curves; ``lines[1]``: the nominal point and its margin segment;
        ``axes[0, 0]``; ``figure``.
    """
    from control import ControlPlot
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    ax = axes_or_new(ax)
    xa, ya = result.x_axis, result.y_axis
    names = [r for r in REGION_COLORS if np.any(result.labels == r)]
    code = np.zeros(result.labels.shape)
    for i, r in enumerate(names):
        code[result.labels == r] = i
    cmap = ListedColormap([REGION_COLORS[r] for r in names] or ["#ffffff"])
    ax.pcolormesh(result.grid_x, result.grid_y, code, cmap=cmap, vmin=-0.5, vmax=max(len(names), 1) - 0.5,
                  shading="nearest", rasterized=True)
    handles = [Patch(facecolor=REGION_COLORS[r], edgecolor="0.6", label=r) for r in names]
    curves = []
    seen = set()
    for b in result.boundaries:
        st = _BOUNDARY_STYLE.get(b.kind, dict(color="k"))
        (line,) = ax.plot(b.x, b.y, lw=1.8, label=None if b.kind in seen else b.label, **st)
        seen.add(b.kind)
        curves.append(line)
    if show_samples:
        X, Y = np.meshgrid(result.sample_x, result.sample_y)
        ax.plot(X.ravel(), Y.ravel(), ls="none", marker=".", ms=3, color="0.4", label="region samples")
    marks = []
    bad = result.exact_disagreements()
    if bad:
        (p,) = ax.plot([b[0] for b in bad], [b[1] for b in bad], ls="none", marker="x", ms=7, mew=1.5,
                       color="C3", label="exact orbits: another region")
        marks.append(p)
    if result.nominal is not None:
        (p,) = ax.plot(*result.nominal, marker="*", ms=13, mfc="gold", mec="k", ls="none", zorder=5,
                       label="design point")
        marks.append(p)
        m = result.margin
        if m is not None and m.nearest is not None:
            (seg,) = ax.plot([result.nominal[0], m.nearest[0]], [result.nominal[1], m.nearest[1]], color="k",
                             lw=1, ls=(0, (2, 2)), label=f"limit-cycle margin ({m.distance:.3g} of the range)")
            marks.append(seg)
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

    for axis, spec, setter in ((ax.xaxis, xa, ax.set_xscale), (ax.yaxis, ya, ax.set_yscale)):
        setter("log" if spec.scale == "log" else "linear")
        if spec.scale == "log" and max(spec.start, spec.stop) / min(spec.start, spec.stop) < 30:
            axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(ScalarFormatter())  # plain numbers on a short log axis (not 2 x 10^0)
            axis.set_minor_formatter(NullFormatter())
    ax.set_xlim(min(xa.start, xa.stop), max(xa.start, xa.stop))
    ax.set_ylim(min(ya.start, ya.stop), max(ya.start, ya.stop))
    ax.set_xlabel(quantity(xa.name, xa.unit or "-"))
    ax.set_ylabel(quantity(ya.name, ya.unit or "-"))
    line_handles, _ = ax.get_legend_handles_labels()
    leg = ax.legend(handles=handles + line_handles, loc="best", fontsize="small", framealpha=0.9)
    lines = np.empty(2, dtype=object)
    lines[0], lines[1] = curves, marks
    axes = np.empty((1, 1), dtype=object)
    axes[0, 0] = ax
    return ControlPlot(lines, axes, ax.figure, legend=leg)
