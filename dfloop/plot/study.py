"""Studies of an element alone (no loop), as a scene's ``[figure]`` stage computes them: families of -1/N(A, w)
curves (Nyquist plane or log-log), time-response panels of the impact system, collision maps.

:func:`plot_element_study` draws a :class:`dfloop.scene.figure.FigureData` (read by its attributes: ``kind``,
``title``, ``parameter``, ``curves`` with ``x``, ``y``, ``ok``, ``amplitude``, ``value``, ``omega``,
``note``; ``input_name``, ``input_unit``) with the same conventions as every other dfloop plot: legends that
show only what varies (what all curves share goes into the title, once), one ordered colour per curve of a
family, units in brackets, and a :class:`control.ControlPlot` returned.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ._labels import FREQUENCY, TIME, case_labels, legend, ordered_colors, plain_log_ticks
from .controlplot import control_plot
from .impact import plot_collision_map, plot_time_response

__all__ = ["plot_element_study", "study_labels"]


def study_labels(data) -> tuple[list[str], str, str | None]:
    """Legend entry per curve (only the parameters that vary), the part every curve shares (for the title),
    and a legend title.

    The parameter is named by its last component (``element.restitution`` -> ``restitution``) and the
    amplitude by the element's input name and unit (``F=50 N``). When only one quantity varies, the entries
    are its values and its name is the legend title (``restitution``: ``0.1``, ``0.2``, ...).
    """
    unit = f" {data.input_unit}" if data.input_unit else ""
    cases = []
    for c in data.curves:
        case = {} if data.parameter is None else {data.parameter.rsplit(".", 1)[-1]: f"{c.value:g}"}
        case[data.input_name] = f"{c.amplitude:g}{unit}"
        cases.append(case)
    labels, common = case_labels(cases)
    if len(data.curves) == 1 and not labels[0]:
        return [common], common, None
    varying = [k for k in cases[0] if len({c.get(k) for c in cases}) > 1]
    if len(varying) == 1:
        return [c[varying[0]] for c in cases], common, varying[0]
    return labels, common, None


def _title(data, common: str, extra: str = "") -> str:
    # what every curve shares, once (unless the scene's title already says it)
    said = all(part.split("=", 1)[-1] in data.title.replace(" = ", "=") for part in common.split(", ")) \
        if common else True
    shared = f"every curve: {common}" if common and len(data.curves) > 1 and not said else ""
    return "\n".join(s for s in (data.title, "; ".join(p for p in (shared, extra) if p)) if s)


def _z_unit(data) -> str:
    return " [N/m]" if data.input_unit == "N" else " [-]"


def _nyquist(data, ax):
    from ._labels import IMAG, REAL, axes_or_new

    ax = axes_or_new(ax)
    labels, common, legend_title = study_labels(data)
    lines, dots = [], []
    for curve, color, label in zip(data.curves, ordered_colors(len(data.curves)), labels):
        z = curve.y
        lines += ax.plot(np.where(curve.ok, z.real, np.nan), np.where(curve.ok, z.imag, np.nan), color=color,
                         lw=1.2, label=label)
        dots += ax.plot(z.real[~curve.ok], z.imag[~curve.ok], ".", color=color, ms=1.5, alpha=0.35)
    ax.set_xlabel(f"{REAL}: Re{{-1/N}}{_z_unit(data)}")
    ax.set_ylabel(f"{IMAG}: Im{{-1/N}}{_z_unit(data)}")
    irregular = any(not np.all(c.ok) for c in data.curves)
    ax.set_title(_title(data, common, "dots: irregular motion (N is an average)" if irregular else ""), fontsize=9)
    ax.grid(True, alpha=0.3)
    leg = legend(ax, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                 title=legend_title, title_fontsize=8)
    return control_plot([lines, dots], ax, leg)


def _loglog(data, ax):
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    labels, common, legend_title = study_labels(data)
    lines, dots = [], []
    for curve, color, label in zip(data.curves, ordered_colors(len(data.curves)), labels):
        for a, part in zip(ax, (curve.y.real, curve.y.imag)):
            lines += a.loglog(curve.x, np.where(curve.ok, np.abs(part), np.nan), color=color, lw=1.2, label=label)
            dots += a.loglog(curve.x[~curve.ok], np.abs(part[~curve.ok]), ".", color=color, ms=1.5, alpha=0.35)
    for a, name in zip(ax, ("|Re{-1/N}|", "|Im{-1/N}|")):
        a.set_xlabel(FREQUENCY)
        a.set_ylabel(name + _z_unit(data))
        plain_log_ticks(a.xaxis)
        a.grid(True, which="both", alpha=0.3)
    leg = legend(ax[1], fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                 title=legend_title, title_fontsize=8)
    irregular = any(not np.all(c.ok) for c in data.curves)
    ax[0].figure.suptitle(_title(data, common, "dots: irregular motion" if irregular else ""), fontsize=10)
    return control_plot([lines, dots], list(ax), leg)


def _time(data, ax):
    import matplotlib.pyplot as plt

    frequencies = list(dict.fromkeys(c.omega for c in data.curves))
    values = list(dict.fromkeys(c.value for c in data.curves))
    if ax is None:
        _, ax = plt.subplots(len(frequencies), len(values), squeeze=False, sharex="row",
                             figsize=(4.4 * len(values), 2.8 * len(frequencies) + 0.7), constrained_layout=True)
    ax = np.asarray(ax, dtype=object).reshape(len(frequencies), len(values))
    labels, common, legend_title = study_labels(data)
    lines = []
    name = data.parameter.rsplit(".", 1)[-1] if data.parameter else ""
    for curve, label in zip(data.curves, labels):
        a = ax[frequencies.index(curve.omega), values.index(curve.value)]
        traj = getattr(curve, "trajectory", None)
        if traj is not None:  # the motion itself: velocity jumps at the impacts left unbridged
            lines += plot_time_response(traj, "v1", ax=a, t_range=(float(curve.x[0]), float(curve.x[-1])),
                                        samples=curve.x.size, label=label, color="C0").lines[0]
        else:
            lines += a.plot(curve.x, curve.y, lw=0.8, color="C0", label=label)
        head = f"ω={curve.omega:g} rad/s" + ("" if data.parameter is None else f", {name}={curve.value:g}")
        a.set_title(head + "\n" + curve.note, fontsize=7,
                    color="firebrick" if "not applicable" in curve.note else "black")
        a.set_xlabel(TIME, fontsize=8)
        a.set_ylabel("Velocity dx1/dt [m/s]", fontsize=8)
        a.tick_params(labelsize=7)
        a.grid(True, alpha=0.3)
    ax.flat[0].figure.suptitle(_title(data, common), fontsize=10)
    return control_plot([lines], ax)


def _collisions(data, ax):
    labels, common, legend_title = study_labels(data)
    w = data.curves[0].x
    if any(c.x.shape != w.shape or np.any(c.x != w) for c in data.curves):
        raise ValueError("collisions curves must share one frequency grid")
    return plot_collision_map(w, [c.y for c in data.curves], [c.ok for c in data.curves], labels, ax=ax,
                              title=_title(data, common, "open circles: irregular motion"),
                              legend_title=legend_title)


_KINDS = {"nyquist": _nyquist, "loglog": _loglog, "time_response": _time, "collisions": _collisions}


def plot_element_study(data, ax=None) -> Any:
    """Draw a scene's ``[figure]`` study (:class:`dfloop.scene.figure.FigureData`).

    Parameters
    ----------
    data : FigureData
        Its ``kind`` picks the picture: ``nyquist`` (-1/N curves on the plane, untrusted points as faint dots),
        ``loglog`` (|Re| and |Im| of -1/N against w, two axes), ``time_response`` (dx1/dt(t) panels: rows =
        frequencies, columns = parameter values; a curve that carries its ``trajectory`` is drawn by
        :func:`plot_time_response`, jumps unbridged), ``collisions`` (:func:`plot_collision_map`).
    ax : matplotlib Axes, optional
        One axes (nyquist, collisions), two (loglog) or a 2-D array (time_response); new ones by default.

    Returns
    -------
    control.ControlPlot
    """
    kind = getattr(data, "kind", None)
    if kind not in _KINDS:
        raise ValueError(f"data.kind must be one of {sorted(_KINDS)}, got {kind!r}")
    if not data.curves:
        raise ValueError("data has no curves to draw")
    return _KINDS[kind](data, ax)
