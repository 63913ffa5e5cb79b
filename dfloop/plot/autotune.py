"""A recorded relay experiment against the fitted model's exact relay orbit (:class:`dfloop.autotune.fit.ModelFit`)."""
from __future__ import annotations

from typing import Any

from ._labels import TIME, quantity
from .controlplot import control_plot

__all__ = ["plot_relay_fit"]


def plot_relay_fit(fit, ax=None, *, cycles: float | None = 3.0, unit: str = "-") -> Any:
    """The recorded process output (dots) and relay output against the fitted model's exact orbit (lines).

    Parameters
    ----------
    fit : ModelFit
        From :func:`dfloop.autotune.fit.fit_relay_record` (read by its attributes: ``record``, ``fitted_output``,
        ``cycle``, ``t0``, ``model``, ``features``).
    ax : sequence of two matplotlib Axes, optional
        (output axes, relay axes); a new figure with two stacked panels by default.
    cycles : float or None
        Show the last ``cycles`` periods of the fitted span (None: the whole record).
    unit : str
        Unit of y and u for the axis labels ("-": deviation variables without a unit).

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: recorded y, ``lines[1]``: fitted orbit's y, ``lines[2]``: recorded u and the orbit's u;
        ``axes[0, 0]`` the output panel, ``axes[1, 0]`` the relay panel.
    """
    import matplotlib.pyplot as plt
    import numpy as np

    rec = fit.record
    if ax is None:
        _, ax = plt.subplots(2, 1, figsize=(7.0, 5.0), sharex=True, height_ratios=[3, 1], constrained_layout=True)
    ax_y, ax_u = ax
    t_end = fit.features.t_end
    t_start = fit.features.t_start if cycles is None else max(fit.features.t_start, t_end - cycles * fit.cycle.period)
    keep = (rec.t >= t_start) & (rec.t <= t_end)
    t = rec.t[keep]
    tt = np.linspace(t_start, t_end, 4000)
    data = ax_y.plot(t, rec.y[keep], ".", ms=3, color="0.55", label="recorded y (noisy)")
    model = ax_y.plot(tt, fit.fitted_output(tt), "-", color="C0", lw=1.8,
                      label=f"exact relay orbit of the fitted {fit.model.kind}")
    a = rec.hysteresis
    guides = []
    if a > 0:
        guides += ax_y.plot([tt[0], tt[-1]], [a, a], ":", color="C3", lw=0.8,
                            label=f"relay switching levels \u00b1{a:g}")
        guides += ax_y.plot([tt[0], tt[-1]], [-a, -a], ":", color="C3", lw=0.8)
    ax_y.set_ylabel(quantity("Process output y", unit))
    lo, hi = float(np.min(rec.y[keep])), float(np.max(rec.y[keep]))
    ax_y.set_ylim(lo - 0.05 * (hi - lo), hi + 0.45 * (hi - lo))      # room for the legend above the data
    ax_y.legend(loc="upper left", fontsize="small", ncol=2, framealpha=0.9)
    ax_y.set_title(f"Relay record against the fitted {fit.model.kind}'s exact orbit", fontsize="medium")
    u_rec = ax_u.step(t, rec.u[keep], where="post", color="0.55", label="recorded u")
    u_fit = ax_u.plot(tt, fit.cycle.relay_output(tt - fit.t0), "-", color="C0", lw=1.0, label="fitted orbit's u")
    ax_u.set_ylabel(quantity("Relay u", unit))
    ax_u.set_xlabel(TIME)
    span = rec.high - rec.low
    ax_u.set_ylim(rec.low - 0.2 * span, rec.high + 0.9 * span)
    ax_u.legend(loc="upper left", fontsize="small", ncol=2, framealpha=0.9)
    return control_plot([data, model, u_rec + u_fit], [ax_y, ax_u], legend=ax_y.get_legend())
