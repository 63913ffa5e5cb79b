"""Time-domain pictures of one cycle: the exact periodic orbit (:class:`dfloop.exact.ExactCycle`) and the
closed-loop runs of a verification (:class:`dfloop.verify.Verification`)."""
from __future__ import annotations

from typing import Any

import numpy as np

from ._labels import TIME, axes_or_new, legend, quantity
from .controlplot import control_plot

__all__ = ["plot_exact_cycle", "plot_verification"]


def plot_exact_cycle(exact, ax=None, *, unit: str = "") -> Any:
    """Draw the element input x over one period of an exact orbit with its switching (or impact) instants.

    Parameters
    ----------
    exact : ExactCycle
        From :func:`dfloop.exact_cycle` (read by its attributes ``t``, ``x``, ``period``,
        ``switching_times``, ``amplitude``, ``frequency``, ``stable``).
    ax : matplotlib Axes, optional
        Where to draw (a new figure's axes by default).
    unit : str
        The unit of x (the element's ``input_unit``, e.g. ``"m"``) for the axis label.

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: [the waveform (``t``, ``x``)], ``lines[1]``: [the switching instants (``switching_times``
        and x there, interpolated on the periodic waveform)].

    Raises
    ------
    ValueError
        For an ExactCycle without an orbit (``success`` False; the message says why), or an ``ax`` that is
        not a matplotlib Axes.
    """
    if not exact.success:
        raise ValueError(f"this ExactCycle has no orbit to plot ({exact.message})")
    ax = axes_or_new(ax)
    wave = ax.plot(exact.t, exact.x, color="C0", label="x(t), exact orbit")
    ts = exact.switching_times
    switches = ax.plot(ts, np.interp(ts, exact.t, exact.x, period=exact.period), ls="none", marker="o", ms=5,
                       mfc="none", mec="C3", label="switching / impact instants")
    ax.axhline(0.0, color="0.8", lw=0.5)
    ax.set_xlim(0.0, exact.period)
    ax.set_xlabel(TIME)
    ax.set_ylabel(quantity("Element input x", unit or "-"))
    ax.set_title(f"Exact orbit: A={exact.amplitude:.4g}, ω={exact.frequency:.4g} rad/s, "
                 f"{'stable' if exact.stable else 'unstable'}", fontsize=9)
    return control_plot([wave, switches], ax, legend(ax, fontsize=8))


def _outcome(side: str, run, sim, name: str) -> str:
    if sim is not None and sim.diverged:
        return f"from {side}: diverged"
    if not run.oscillating:
        return f"from {side}: came to rest"
    return f"from {side}: settled at {name}={run.amplitude:.4g}, ω={run.frequency:.4g} rad/s"


def plot_verification(verification, ax=None, *, unit: str = "", name: str = "A",
                      periods: float | None = 20) -> Any:
    """The two closed-loop runs of a verification, x(t) from inside and from outside the predicted cycle, over
    the band |x| <= A of the predicted amplitude (and the exact orbit's amplitude, when the verified cycle
    carried one).

    A stable cycle shows both runs converging onto the band's edge; an unstable one shows them leaving it.
    (A is the amplitude of x's fundamental: a distorted waveform's peaks may overshoot it slightly.)

    Parameters
    ----------
    verification : Verification
        From :func:`dfloop.verify_cycle` (read by its attributes ``runs`` (the two :class:`LoopSimulation`,
        inside then outside), ``inside``, ``outside``, ``amplitude``, ``frequency``, ``exact_amplitude``,
        ``perturbation``, ``verdict``).
    ax : matplotlib Axes, optional
    unit : str
        The unit of x (the element's ``input_unit``) for the axis label.
    name : str
        The name of x's amplitude in the legend (the element's ``input_name``, e.g. ``"X"``, ``"F"``).
    periods : float or None
        Show the first this many predicted periods of the runs, where they converge or leave (default 20;
        None: the whole runs). The legend gives where each run settled at its end.

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: [x(t) from inside, x(t) from outside]; ``lines[1]``: the band edges (+A, -A predicted,
        then +A, -A exact when known).
    """
    v = verification
    runs = getattr(v, "runs", None)
    if runs is None or len(runs) != 2:
        raise ValueError("verification carries no time responses (runs); make it with verify_cycle")
    ax = axes_or_new(ax)
    A, w = float(v.amplitude), float(v.frequency)
    T = 2 * np.pi / w
    curves = []
    t_end = max(float(r.t[-1]) for r in runs if r.t.size) if any(r.t.size for r in runs) else 0.0
    t_start = 0.0
    if periods is not None:
        if not (np.isfinite(periods) and periods > 0):
            raise ValueError(f"periods must be > 0 or None, got {periods!r}")
        t_end = min(t_end, float(periods) * T)
    for side, run, sim, color in (("inside", v.inside, runs[0], "C0"), ("outside", v.outside, runs[1], "C1")):
        keep = sim.t <= t_end
        curves += ax.plot(sim.t[keep], sim.x[keep], color=color, lw=0.7, alpha=0.9,
                          label=_outcome(side, run, sim, name))
    edges = []
    ax.axhspan(-A, A, color="C3", alpha=0.07, lw=0)
    edges += ax.plot([t_start, t_end], [A, A], color="C3", ls="--", lw=1.2,
                     label=f"predicted ±{name}, {name}={A:.4g}, ω={w:.4g} rad/s")
    edges += ax.plot([t_start, t_end], [-A, -A], color="C3", ls="--", lw=1.2)
    exact = getattr(v, "exact_amplitude", None)
    if exact is not None:
        edges += ax.plot([t_start, t_end], [exact, exact], color="C4", ls=":", lw=1.5,
                         label=f"exact orbit ±{name}, {name}={exact:.4g}")
        edges += ax.plot([t_start, t_end], [-exact, -exact], color="C4", ls=":", lw=1.5)
    ax.set_xlim(t_start, t_end)
    peak = max([np.max(np.abs(r.x[r.t <= t_end]), initial=0.0) for r in runs] + [A])
    ax.set_ylim(-1.15 * peak, 1.6 * peak)  # head room for the legend above the runs
    ax.set_xlabel(TIME)
    ax.set_ylabel(quantity("Element input x", unit or "-"))
    ax.set_title(f"Verification: {v.verdict} (starts at (1 ∓ {v.perturbation:g}) {name})", fontsize=9)
    leg = legend(ax, fontsize=7.5, loc="upper center", ncol=2)
    return control_plot([curves, edges], ax, leg)
