"""Plots of the impact system: time responses (paper's Figs. 10-14) and collision maps (paper's Fig. 9).

Both draw what they are given (a trajectory, computed run lengths) and return a :class:`control.ControlPlot`.
"""
from __future__ import annotations

import numpy as np

from ._labels import FREQUENCY, TIME, axes_or_new, distinct_styles, legend, plain_log_ticks
from .controlplot import control_plot

__all__ = ["plot_time_response", "plot_collision_map"]

_LABELS = {"x1": "Position x1 [m]", "x2": "Position x2 [m]", "v1": "Velocity dx1/dt [m/s]",
           "v2": "Velocity dx2/dt [m/s]", "gap": "Gap x2 - x1 [m]"}


def plot_time_response(traj, quantity: str = "v1", ax=None, t_range=None, samples: int = 4000, *, label=None,
                       color=None):
    """Plot ``quantity`` ("x1", "x2", "v1", "v2" or "gap") of a trajectory against time.

    Velocities jump at impacts: every segment is drawn separately, so the curve never bridges a jump; a faint
    dotted connector shows each jump.

    Parameters
    ----------
    traj : Trajectory
        From :func:`dfloop.impact.kernel.simulate`.
    quantity : str
        What to plot (SI units).
    ax : matplotlib Axes, optional
    t_range : (float, float), optional
        Time window (s); default the whole run.
    samples : int
        Uniform samples in the window (segment ends are added).
    label : str, optional
        Legend entry (default: the restitution and forcing frequency).
    color : matplotlib colour, optional

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the response (one Line2D, NaN-separated at the impacts); ``lines[1]``: the jumps, as faint
        dotted vertical connectors from the value just before each impact to the value just after.
    """

    if quantity not in _LABELS:
        raise ValueError(f"quantity must be one of {sorted(_LABELS)}, got {quantity!r}")
    lo, hi = (0.0, traj.t_end) if t_range is None else (float(t_range[0]), float(t_range[1]))
    if not 0.0 <= lo < hi <= traj.t_end:
        raise ValueError(f"t_range must satisfy 0 <= start < end <= t_end = {traj.t_end}")
    ax = axes_or_new(ax)
    starts = traj.t0[(traj.t0 > lo) & (traj.t0 < hi)]
    t = np.union1d(np.linspace(lo, hi, int(samples)), starts)
    before = np.nextafter(starts, -np.inf)
    t_all = np.concatenate([t, before])
    order = np.argsort(t_all, kind="stable")
    t_all = t_all[order]
    y = traj.evaluate(t_all)[quantity]
    # break the line between the end of one segment and the start of the next
    is_break = np.concatenate([np.zeros(t.size, bool), np.ones(before.size, bool)])[order]
    y_plot = y.astype(float).copy()
    t_plot = t_all.copy()
    idx = np.flatnonzero(is_break) + 1
    t_plot = np.insert(t_plot, idx, np.nan)
    y_plot = np.insert(y_plot, idx, np.nan)
    p = traj.params
    line = ax.plot(t_plot, y_plot, lw=0.8, color=color,
                   label=f"eps = {p.restitution:g}, ω = {p.omega:g} rad/s" if label is None else label)
    # each jump as a faint dotted connector between its two sides, so the eye can follow the motion while the
    # curve itself never bridges a discontinuity
    y_left = y[is_break]  # the value just before each impact (t_start - 1 ulp), in time order
    y_right = traj.evaluate(starts)[quantity]
    jumps = ax.plot(np.column_stack([starts, starts, np.full(starts.size, np.nan)]).ravel(),
                    np.column_stack([y_left, y_right, np.full(starts.size, np.nan)]).ravel(),
                    ls=":", lw=0.6, color=line[0].get_color(), alpha=0.45)
    ax.set_xlabel(TIME)
    ax.set_ylabel(_LABELS[quantity])
    return control_plot([line, jumps], ax)


def plot_collision_map(omega, runs, regular=None, labels=None, *, side: str = "A", ax=None, title: str = "",
                       legend_title: str | None = None):
    """Longest run of consecutive collisions on one side vs frequency, one curve per case (the paper's Fig. 9).

    Draws what it is given (compute the runs with
    :func:`dfloop.impact.extract.impact_describing_function_batch`: its ``max_run_A`` / ``max_run_B`` and
    ``regular``). Each case has its own colour and marker; irregular (non-periodic) points are open markers.
    The frequency axis is logarithmic with plain tick labels (5, 10, 20, ... rad/s).

    Parameters
    ----------
    omega : array_like
        Frequencies (rad/s), shared by every case.
    runs : array_like, shape (cases, len(omega)) or (len(omega),)
        Longest run of consecutive collisions on ``side`` at each frequency.
    regular : array_like of bool, same shape as ``runs``, optional
        True where the motion is periodic (default: everywhere).
    labels : sequence of str, optional
        Legend entry per case (e.g. from :func:`case_labels`); no legend without.
    side : {"A", "B"}
    ax : matplotlib Axes, optional
    title : str
        Axes title.
    legend_title : str, optional
        Title of the legend (e.g. the name of the quantity whose values ``labels`` are).

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the curves (one Line2D per case), ``lines[1]``: the irregular-point markers.
    """
    if side not in ("A", "B"):
        raise ValueError(f"side must be 'A' or 'B', got {side!r}")
    w = np.asarray(omega, dtype=float).ravel()
    y = np.atleast_2d(np.asarray(runs, dtype=float))
    ok = np.ones(y.shape, bool) if regular is None else np.atleast_2d(np.asarray(regular, dtype=bool))
    if y.shape[1] != w.size or ok.shape != y.shape:
        raise ValueError(f"runs must have shape (cases, {w.size}) like omega, and regular the shape of runs; "
                         f"got runs {y.shape}, regular {ok.shape}")
    if labels is not None and len(labels) != y.shape[0]:
        raise ValueError(f"labels must give one entry per case ({y.shape[0]}), got {len(labels)}")
    ax = axes_or_new(ax)
    curves, open_marks = [], []
    for k, (yk, okk, color, marker) in enumerate(zip(y, ok, *distinct_styles(y.shape[0]))):
        curves += ax.plot(w, yk, "-", color=color, marker=marker, ms=3.5, markevery=max(w.size // 12, 1), lw=1.0,
                          label=None if labels is None else labels[k])
        open_marks += ax.plot(w[~okk], yk[~okk], ls="none", marker="o", ms=4, mfc="none", mec=color, mew=0.7)
    ax.set_xscale("log")
    plain_log_ticks(ax.xaxis)
    ax.set_xlabel(FREQUENCY)
    ax.set_ylabel(f"Consecutive collisions on side {side}, n_{side} [-]")
    if title:
        ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    leg = legend(ax, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                 title=legend_title, title_fontsize=8) if labels is not None else None
    return control_plot([curves, open_marks], ax, leg)
