"""Plots of the impact system: time responses (paper's Figs. 10-14) and collision maps (paper's Fig. 9)."""
from __future__ import annotations

import numpy as np

from ._labels import FREQUENCY, TIME, legend

__all__ = ["plot_time_response", "plot_collision_map"]

_LABELS = {"x1": "Position x1 [m]", "x2": "Position x2 [m]", "v1": "Velocity dx1/dt [m/s]",
           "v2": "Velocity dx2/dt [m/s]", "gap": "Gap x2 - x1 [m]"}


def plot_time_response(traj, quantity: str = "v1", ax=None, t_range=None, samples: int = 4000):
    """Plot ``quantity`` ("x1", "x2", "v1", "v2" or "gap") of a trajectory against time.

    Velocities jump at impacts: every segment is drawn separately, so jumps are not bridged by lines.

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

    Returns
    -------
    matplotlib.axes.Axes
    """
    import matplotlib.pyplot as plt

    if quantity not in _LABELS:
        raise ValueError(f"quantity must be one of {sorted(_LABELS)}, got {quantity!r}")
    lo, hi = (0.0, traj.t_end) if t_range is None else (float(t_range[0]), float(t_range[1]))
    if not 0.0 <= lo < hi <= traj.t_end:
        raise ValueError(f"t_range must satisfy 0 <= start < end <= t_end = {traj.t_end}")
    if ax is None:
        _, ax = plt.subplots()
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
    ax.plot(t_plot, y_plot, lw=0.8, label=f"eps = {p.restitution:g}, w = {p.omega:g} rad/s")
    ax.set_xlabel(TIME)
    ax.set_ylabel(_LABELS[quantity])
    return ax


def plot_collision_map(m1: float, m2: float, h: float, force: float, omega, restitutions, *, side: str = "A",
                       ax=None, **df_options):
    """Longest run of consecutive collisions on one side vs frequency, one line per restitution (Fig. 9).

    Irregular (non-periodic) points are drawn as open markers.

    Parameters
    ----------
    m1, m2, h, force : float
        Masses (kg), clearance (m), force amplitude (N).
    omega : array_like
        Frequencies (rad/s).
    restitutions : sequence of float
        Coefficients of restitution, one line each.
    side : {"A", "B"}
    ax : matplotlib Axes, optional
    **df_options
        Passed to :func:`dfloop.impact.extract.impact_describing_function_batch`.

    Returns
    -------
    matplotlib.axes.Axes
    """
    import matplotlib.pyplot as plt

    from ..impact.extract import impact_describing_function_batch

    if side not in ("A", "B"):
        raise ValueError(f"side must be 'A' or 'B', got {side!r}")
    w = np.asarray(omega, dtype=float)
    if ax is None:
        _, ax = plt.subplots()
    for eps in restitutions:
        res = impact_describing_function_batch(m1, m2, h, eps, force, w, **df_options)
        runs = res.max_run_A if side == "A" else res.max_run_B
        line, = ax.plot(w, runs, "-", lw=0.8, label=f"eps = {eps:g}")
        irregular = ~res.regular
        ax.plot(w[~irregular], runs[~irregular], "o", ms=3, color=line.get_color())
        ax.plot(w[irregular], runs[irregular], "o", ms=4, mfc="none", color=line.get_color())
    ax.set_xlabel(FREQUENCY)
    ax.set_ylabel(f"Consecutive collisions on side {side}, n_{side}")
    legend(ax)
    return ax
