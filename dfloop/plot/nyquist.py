"""Nyquist plot of G(jw) with the -1/N locus and the predicted cycles; residual map over (A, w).

Drawn with python-control's conventions: "Real axis" / "Imaginary axis", the critical point -1 as a red
"+", arrows in the direction of increasing frequency (on G) and amplitude (on -1/N), and a
:class:`control.ControlPlot` returned. Curves break at jumps (no line bridges a discontinuity of N).
"""
from __future__ import annotations

import numpy as np

from ..describing.base import negative_inverse
from ..solve.plant import as_plant
from ..solve.predict import predict_limit_cycles
from ._curves import add_direction_arrow, curve_with_gaps
from ._labels import FREQUENCY, IMAG, REAL, amplitude_label, legend, place_labels

__all__ = ["plot_nyquist", "plot_residual_map"]

_STYLE = {"stable": dict(marker="o", mfc="C3", mec="C3"),
          "unstable": dict(marker="o", mfc="none", mec="C3"),
          "marginal": dict(marker="D", mfc="none", mec="C1"),
          "loeb-stable only": dict(marker="o", mfc="C1", mec="C3")}  # unstable real open-loop poles
_EXACT = dict(marker="*", ms=11, mfc="C4", mec="k", mew=0.6, ls="none", zorder=4)
EXACT_LABEL = "exact cycle"


def _control_plot(groups, ax, leg=None):
    """A :class:`control.ControlPlot` whose ``lines`` is a 1-D object array of the given lists of lines."""
    from control import ControlPlot

    lines = np.empty(len(groups), dtype=object)
    for i, group in enumerate(groups):
        lines[i] = list(group)
    axes = np.empty((1, 1), dtype=object)
    axes[0, 0] = ax
    return ControlPlot(lines, axes, ax.figure, legend=leg)


def _cycles_and_windows(G, N, cycles, omega, amplitude):
    if cycles is None:
        cycles = predict_limit_cycles(G, N, omega=omega, amplitude=amplitude)
    w_win = omega or getattr(cycles, "omega_window", None)
    a_win = amplitude or getattr(cycles, "amplitude_window", None)
    if w_win is None or a_win is None:
        raise ValueError("give omega and amplitude windows, or cycles returned by predict_limit_cycles")
    return cycles, tuple(map(float, w_win)), tuple(map(float, a_win))


def _view_limits(ax, points: np.ndarray, marks: np.ndarray) -> None:
    """Frame the part of the plane where the marked points (cycles, exact cycles) are (the -1/N locus may run
    off to infinity)."""
    pts = points[np.isfinite(points)]
    if marks.size:
        ref = float(np.max(np.abs(marks)))
    else:
        ref = float(np.median(np.abs(pts))) if pts.size else 1.0
    near = pts[np.abs(pts) <= 3 * ref]
    if near.size == 0:
        return
    lo_x, hi_x, lo_y, hi_y = near.real.min(), near.real.max(), near.imag.min(), near.imag.max()
    pad = 0.08 * max(hi_x - lo_x, hi_y - lo_y, ref * 1e-3)
    ax.set_xlim(lo_x - pad, hi_x + pad)
    ax.set_ylim(lo_y - pad, hi_y + pad)


def plot_nyquist(G, N, cycles=None, ax=None, *, omega=None, amplitude=None, n_loci: int = 5):
    """Plot G(jw), the -1/N locus and the predicted limit cycles on the Nyquist plane.

    Parameters
    ----------
    G, N : plant and describing function, as for :func:`~dfloop.predict_limit_cycles`.
    cycles : LimitCycles, optional
        Result of ``predict_limit_cycles``; computed here when omitted. Stable cycles are drawn
        filled, unstable hollow, marginal as diamonds, each labelled with amplitude and frequency
        (labels never overlap: crowded ones are listed beside the axes); jump crossings of a
        discontinuous N (not cycles) as orange crosses. A cycle carrying a converged exact orbit
        (``predict_limit_cycles(..., exact=True)``) gets a second marker, a purple star at G(j w_exact) on
        G's curve (one "exact cycle" legend entry; labels keep clear of it).
    ax : matplotlib Axes, optional
    omega, amplitude : (lo, hi), optional
        Windows to draw (default: those of ``cycles``).
    n_loci : int
        For a frequency-dependent N, the -1/N(A, w) locus is drawn at this many frequencies of the
        window plus at each cycle's frequency (a family of curves).

    Returns
    -------
    control.ControlPlot
        ``lines`` is a 1-D array of lists of Line2D: [G(jw)], [-1/N loci], [cycle markers],
        [jump-crossing markers], [exact-cycle markers], [the -1 marker]; ``axes[0, 0]`` the axes, ``figure``
        the figure.
    """
    import matplotlib.pyplot as plt

    cycles, (w_lo, w_hi), (a_lo, a_hi) = _cycles_and_windows(G, N, cycles, omega, amplitude)
    if ax is None:
        ax = plt.figure().add_subplot()
    plant = as_plant(G)
    w = np.unique(np.concatenate([np.geomspace(w_lo, w_hi, 2000),
                                  plant.feature_frequencies[(plant.feature_frequencies >= w_lo)
                                                            & (plant.feature_frequencies <= w_hi)]]))
    _, g = curve_with_gaps(plant, w)
    g_lines = ax.plot(g.real, g.imag, color="C0", label="G(jω)")
    # log-spaced over the window, plus points crowding the lower edge where -1/N may run off to infinity
    A = np.unique(np.concatenate([np.geomspace(a_lo, a_hi, 1000),
                                  a_lo + (min(a_hi, 10 * a_lo) - a_lo) * np.geomspace(1e-9, 1.0, 400)]))
    points, loci = [g, np.array([-1.0 + 0j])], []
    if N.frequency_dependent:
        freqs = np.unique(np.concatenate([np.geomspace(w_lo, w_hi, n_loci), [c.frequency for c in cycles]]))
        for k, wf in enumerate(freqs):
            _, loc = curve_with_gaps(lambda a, wf=wf: negative_inverse(N, a, wf), A)
            loci += ax.plot(loc.real, loc.imag, color="C2", alpha=0.4 + 0.6 * k / max(len(freqs) - 1, 1), lw=1,
                            label=f"-1/N(A, ω={wf:.3g} rad/s)")
            points.append(loc)
    else:
        _, loc = curve_with_gaps(lambda a: negative_inverse(N, a), A)
        loci += ax.plot(loc.real, loc.imag, color="C2", label="-1/N(A)")
        points.append(loc)
    markers = [ax.plot([c.G.real], [c.G.imag], ls="none", ms=8, mew=1.5, zorder=3, **_STYLE[c.stability])[0]
               for c in cycles]
    jumps = list(getattr(cycles, "jump_crossings", ()))
    jump_markers = [ax.plot([j.G.real], [j.G.imag], ls="none", marker="x", ms=8, mew=1.5, color="C1", zorder=3)[0]
                    for j in jumps]
    exact = [c.exact for c in cycles if getattr(c, "exact", None) is not None and c.exact.success]
    g_exact = plant(np.array([e.frequency for e in exact], dtype=float)) if exact else np.empty(0, complex)
    exact_markers = [ax.plot([p.real], [p.imag], label=EXACT_LABEL if k == 0 else None, **_EXACT)[0]
                     for k, p in enumerate(g_exact)]
    critical = ax.plot([-1.0], [0.0], "r+", ms=10, mew=1.5, zorder=4, label="-1")
    _view_limits(ax, np.concatenate(points + [g_exact]), np.array([c.G for c in cycles] + list(g_exact)))
    ax.axhline(0, color="0.8", lw=0.5)
    ax.axvline(0, color="0.8", lw=0.5)
    ax.set_xlabel(REAL)
    ax.set_ylabel(IMAG)
    add_direction_arrow(ax, g, "C0")
    for loc in loci:
        add_direction_arrow(ax, loc.get_xdata() + 1j * loc.get_ydata(), loc.get_color())
    leg = legend(ax, fontsize=8)
    place_labels(ax, [(c.G.real, c.G.imag) for c in cycles] + [(j.G.real, j.G.imag) for j in jumps],
                 [f"A={c.amplitude:.3g}, ω={c.frequency:.3g} rad/s\n{c.stability}" for c in cycles]
                 + [f"jump of N at A={j.amplitude:.3g}, ω={j.frequency:.3g} rad/s\n(no cycle)" for j in jumps],
                 ["black"] * len(cycles) + ["C1"] * len(jumps),
                 avoid=[(p.real, p.imag) for p in g_exact])
    return _control_plot([g_lines, loci, markers, jump_markers, exact_markers, critical], ax, leg)


def plot_residual_map(G, N, cycles=None, ax=None, *, omega=None, amplitude=None, shape=(200, 200)):
    """Map of log10 |1 + G N| / (1 + |G N|) over (A, w), with the zero lines of Re and Im of 1 + G N.

    A limit cycle sits where the two zero lines cross; the crossing angle shows how well conditioned
    (and, by its orientation, how stable) it is. Without explicit windows the map spans a decade
    around the cycles (within the search windows).

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the cycle markers; the map is ``axes[0, 0].collections[0]``.
    """
    import matplotlib.pyplot as plt

    given_w, given_a = omega, amplitude
    cycles, (w_lo, w_hi), (a_lo, a_hi) = _cycles_and_windows(G, N, cycles, omega, amplitude)
    if cycles:  # zoom to a decade around the cycles unless windows were given
        if given_a is None:
            amps = [c.amplitude for c in cycles]
            a_lo, a_hi = max(a_lo, min(amps) / 10), min(a_hi, max(amps) * 10)
        if given_w is None:
            freqs = [c.frequency for c in cycles]
            w_lo, w_hi = max(w_lo, min(freqs) / 10), min(w_hi, max(freqs) * 10)
    if ax is None:
        ax = plt.figure().add_subplot()
    A = np.geomspace(a_lo, a_hi, int(shape[0]))
    w = np.geomspace(w_lo, w_hi, int(shape[1]))
    g = as_plant(G)(w)
    n = N(A[:, None], w[None, :]) if N.frequency_dependent else N(A)[:, None]
    P = n * g[None, :]
    R = 1 + P
    rel = np.log10(np.maximum(np.abs(R) / (1 + np.abs(P)), 1e-16))
    mesh = ax.pcolormesh(w, A, rel, shading="auto", cmap="viridis")
    ax.contour(w, A, R.real, levels=[0], colors="w", linewidths=1)
    ax.contour(w, A, R.imag, levels=[0], colors="C3", linewidths=1, linestyles="--")
    markers = [ax.plot([c.frequency], [c.amplitude], ls="none", ms=8, mew=1.5, zorder=3, **_STYLE[c.stability])[0]
               for c in cycles]
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(FREQUENCY)
    ax.set_ylabel(amplitude_label(N))
    ax.set_title("1 + GN = 0 where Re = 0 (white) meets Im = 0 (red dashed)", fontsize=9)
    ax.figure.colorbar(mesh, ax=ax, label="log10 |1+GN| / (1+|GN|)")
    return _control_plot([markers], ax)
