"""Nyquist plot of G(jw) with the -1/N locus and the predicted cycles; residual map over (A, w).

Drawn with python-control's conventions: "Real axis" / "Imaginary axis", the critical point -1 as a red
"+", arrows in the direction of increasing frequency (on G) and amplitude (on -1/N), and a
:class:`control.ControlPlot` returned. Curves break at jumps (no line bridges a discontinuity of N).

Both functions draw a :class:`~dfloop.solve.result.LimitCycles` they are given: the result knows its plant
(``plant_response``, G(jw) as a callable of omega in rad/s) and its element, so this module computes nothing
and imports nothing from the solver.
"""
from __future__ import annotations

import numpy as np

from ..describing.base import negative_inverse
from ._curves import add_direction_arrow, curve_with_gaps
from ._labels import FREQUENCY, amplitude_label, legend, place_labels, plain_log_ticks, plane_labels
from .controlplot import control_plot

__all__ = ["plot_nyquist", "plot_residual_map", "EXACT_LABEL"]

_STYLE = {"stable": dict(marker="o", mfc="C3", mec="C3"),
          "unstable": dict(marker="o", mfc="none", mec="C3"),
          "marginal": dict(marker="D", mfc="none", mec="C1"),
          "loeb-stable only": dict(marker="o", mfc="C1", mec="C3")}  # unstable real open-loop poles
_KIND_LABEL = {"stable": "stable cycle (filled)", "unstable": "unstable cycle (hollow)",
               "marginal": "marginal cycle (diamond)", "loeb-stable only": "Loeb-stable only (unstable open loop)"}
_EXACT = dict(marker="*", ms=11, mfc="C4", mec="k", mew=0.6, ls="none", zorder=4)
EXACT_LABEL = "exact orbit, G(jω) at its frequency"
CRITICAL_LABEL = "-1 (critical point)"
JUMP_LABEL = "jump of N crossed (no cycle)"
_CLUSTER = 0.06  # points closer than this fraction of the view's span form one crowded group
_CROWDED = 0.12  # a group smaller than this fraction of the view gets a zoomed inset


def _loop_of(cycles):
    """(plant, element) recorded on a LimitCycles; ValueError saying what to pass otherwise."""
    plant = getattr(cycles, "plant_response", None)
    element = getattr(cycles, "element", None)
    if plant is None or element is None:
        raise ValueError("cycles must be the LimitCycles returned by predict_limit_cycles (it records the plant "
                         f"and element to draw); got {type(cycles).__name__}")
    return plant, element


def _windows(cycles, omega, amplitude):
    w_win = omega if omega is not None else getattr(cycles, "omega_window", None)
    a_win = amplitude if amplitude is not None else getattr(cycles, "amplitude_window", None)
    out = []
    for name, win in (("omega", w_win), ("amplitude", a_win)):
        try:
            lo, hi = (float(v) for v in win)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a (lo, hi) window, got {win!r}") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise ValueError(f"{name} window must be positive and increasing; got {win!r}")
        out.append((lo, hi))
    return out


def _view(points: np.ndarray, marks: np.ndarray):
    """Limits framing what matters: the marked points (cycles, exact orbits), -1 and the origin, padded; the
    curves run through the frame (a -1/N locus may run off to infinity). Without marks: -1 and the curves'
    middle range."""
    keys = np.concatenate([marks, [-1.0 + 0j, 0j]])
    if not marks.size:
        pts = points[np.isfinite(points)]
        ref = float(np.median(np.abs(pts))) if pts.size else 1.0
        keys = np.concatenate([keys, pts[np.abs(pts) <= 3 * ref]])
    lo_x, hi_x, lo_y, hi_y = keys.real.min(), keys.real.max(), keys.imag.min(), keys.imag.max()
    span = max(hi_x - lo_x, hi_y - lo_y, 1e-3)
    pad = 0.18 * span
    return (lo_x - pad, hi_x + pad), (lo_y - pad, hi_y + pad)


def _crowded_group(marks: np.ndarray, span: float) -> np.ndarray:
    """Indices of the largest group of marks that lie so close together (relative to the view) that their
    markers and labels would overlap: single-linkage groups at _CLUSTER x span, kept when the group's size is
    below _CROWDED x span. Empty when nothing crowds."""
    n = marks.size
    group = np.arange(n)
    for i in range(n):  # union-find by relabelling (n is the number of cycles: small)
        for j in range(i):
            if abs(marks[i] - marks[j]) < _CLUSTER * span and group[i] != group[j]:
                group[group == group[i]] = group[j]
    best = np.empty(0, int)
    for g in np.unique(group):
        idx = np.flatnonzero(group == g)
        ext = max(np.ptp(marks[idx].real), np.ptp(marks[idx].imag)) if idx.size else 0.0
        if idx.size >= 2 and ext < _CROWDED * span and idx.size > best.size:
            best = idx
    return best


def _draw_curves(ax, g, loci, cycles, jumps, g_exact, *, labelled: bool):
    """Plant, loci, markers and -1 into ``ax``; returns the artists by group."""
    lab = (lambda s: s) if labelled else (lambda s: None)
    g_lines = ax.plot(g.real, g.imag, color="C0", label=lab("G(jω)"))
    loc_lines = []
    for z, ok, color, name in loci:
        trusted = z if ok is None else np.where(ok, z, complex(np.nan, np.nan))
        loc_lines += ax.plot(trusted.real, trusted.imag, color=color, lw=1.1, label=lab(name))
    for z, ok, color, _ in loci:  # untrusted values (the element says its N is an average there): faint dots
        if ok is not None and np.any(~ok & np.isfinite(z)):
            bad = z[~ok & np.isfinite(z)]
            loc_lines += ax.plot(bad.real, bad.imag, ls="none", marker=".", ms=2, color=color, alpha=0.4)
    seen = set()
    markers = []
    for c in cycles:
        name = None if c.stability in seen else _KIND_LABEL[c.stability]
        seen.add(c.stability)
        markers += ax.plot([c.G.real], [c.G.imag], ls="none", ms=8, mew=1.5, zorder=3, label=lab(name),
                           **_STYLE[c.stability])
    jump_markers = [ax.plot([j.G.real], [j.G.imag], ls="none", marker="x", ms=8, mew=1.5, color="C1", zorder=3,
                            label=lab(JUMP_LABEL if k == 0 else None))[0] for k, j in enumerate(jumps)]
    exact_markers = [ax.plot([p.real], [p.imag], label=lab(EXACT_LABEL if k == 0 else None), **_EXACT)[0]
                     for k, p in enumerate(g_exact)]
    critical = ax.plot([-1.0], [0.0], "r+", ms=10, mew=1.5, zorder=4, label=lab(CRITICAL_LABEL))
    ax.axhline(0, color="0.8", lw=0.5)
    ax.axvline(0, color="0.8", lw=0.5)
    return g_lines, loc_lines, markers, jump_markers, exact_markers, critical


def _inset_corner(ax, curves, size: float, keep):
    """The corner of ``ax`` (axes fraction) whose inset box of ``size`` covers none of the points ``keep``
    (markers, -1) and the fewest curve samples."""
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    best, where = None, None
    # margins keep the inset's own tick labels (left of and below its box) inside the main axes
    lo_x, lo_y, hi = 0.13, 0.12, 0.02
    for fx, fy in ((1 - size - hi, lo_y), (lo_x, lo_y), (1 - size - hi, 1 - size - 0.06), (lo_x, 1 - size - 0.06)):
        n = 0
        for z in curves:
            u, v = (z.real - x0) / (x1 - x0), (z.imag - y0) / (y1 - y0)
            n += int(np.count_nonzero((u > fx) & (u < fx + size) & (v > fy) & (v < fy + size)))
        u, v = (keep.real - x0) / (x1 - x0), (keep.imag - y0) / (y1 - y0)
        n += 10**9 * int(np.count_nonzero((u > fx - 0.03) & (u < fx + size + 0.03) & (v > fy - 0.03)
                                          & (v < fy + size + 0.03)))
        if best is None or n < best:
            best, where = n, (fx, fy)
    return where, best < 10**9


def _label_texts(cycles, jumps, N):
    """Cycle labels in the element's own amplitude name and unit (``X=1.01 m``, ``F=31.8 N``); with exact orbits
    computed, each label carries the cycle's verdict (confirmed / artefact / not checked)."""
    name = getattr(N, "input_name", "A") or "A"
    unit = f" {N.input_unit}" if getattr(N, "input_unit", "") else ""
    return ([f"{name}={c.amplitude:.3g}{unit}, ω={c.frequency:.3g} rad/s\n{c.stability}"
             + (f", {c.verdict.kind}" if getattr(c, "exact", None) is not None else "") for c in cycles]
            + [f"jump of N at {name}={j.amplitude:.3g}{unit}, ω={j.frequency:.3g} rad/s\n(no cycle)" for j in jumps])


def plot_nyquist(cycles, ax=None, *, omega=None, amplitude=None, n_loci: int = 5, inset: bool = True):
    """Plot G(jw), the -1/N locus and the predicted limit cycles on the Nyquist plane.

    For a discrete-time plant (``dt`` > 0) the curve is G(e^{jw dt}) for w in the window (0 < w < pi/dt).

    Parameters
    ----------
    cycles : LimitCycles
        Result of :func:`~dfloop.predict_limit_cycles` (it records the plant and element drawn). Stable cycles
        are drawn filled, unstable hollow, marginal as diamonds, each labelled with amplitude and frequency
        (labels overlap no other label, marker or curve where a free place exists; crowded ones are listed
        beside the axes); jump crossings of a discontinuous N (not cycles) as orange crosses. A cycle carrying a
        converged exact orbit (``predict_limit_cycles(..., exact=True)``) gets a purple star at G(j w_exact)
        on G's curve. The legend (beside the axes) names every kind of marker drawn.
    ax : matplotlib Axes, optional
    omega, amplitude : (lo, hi), optional
        Windows to draw (default: those of ``cycles``); rad/s and the element's input unit.
    n_loci : int
        For a frequency-dependent N, the locus -1/N(A, w) over the frequency window is drawn at this many
        amplitudes of the window (but none within 10 % of a cycle's) plus at each cycle's amplitude A* (G(jw)
        meets that curve at the cycle, both at its frequency w*): a family of curves, one colour each from an ordered map, labelled with its amplitude,
        with an arrow along increasing w; values the element does not trust (``validity`` False: irregular
        motion, where N is an average) are drawn as faint dots of the curve's colour.
    inset : bool
        Frame the cycles, -1 and the origin; when some of them crowd into a small part of that view (markers
        within a few percent of it), add a zoomed inset around them and label them there.

    Returns
    -------
    control.ControlPlot
        ``lines`` is a 1-D array of lists of Line2D: [G(jw)], [-1/N loci (then their untrusted dots, if any)],
        [cycle markers],
        [jump-crossing markers], [exact-cycle markers], [the -1 marker]; ``axes[0, 0]`` the axes (an inset, if
        drawn, is ``axes[0, 0].child_axes[0]``), ``figure`` the figure.
    """
    import matplotlib.pyplot as plt

    from ._labels import axes_or_new

    plant, N = _loop_of(cycles)
    (w_lo, w_hi), (a_lo, a_hi) = _windows(cycles, omega, amplitude)
    n_loci = int(n_loci)
    if n_loci < 1:
        raise ValueError(f"n_loci must be >= 1, got {n_loci!r}")
    ax = axes_or_new(ax)
    feat = np.asarray(getattr(plant, "feature_frequencies", np.empty(0)), dtype=float)
    w = np.unique(np.concatenate([np.geomspace(w_lo, w_hi, 2000), feat[(feat >= w_lo) & (feat <= w_hi)],
                                  [c.frequency for c in cycles]]))
    _, g = curve_with_gaps(plant, w)
    # log-spaced over the window, plus points crowding the lower edge where -1/N may run off to infinity
    A = np.unique(np.concatenate([np.geomspace(a_lo, a_hi, 1000),
                                  a_lo + (min(a_hi, 10 * a_lo) - a_lo) * np.geomspace(1e-9, 1.0, 400)]))
    loci = []
    if N.frequency_dependent:
        # one locus over the frequency window per amplitude: each cycle's (G(jw) meets -1/N(A*, w) at the cycle,
        # both at w*) and n_loci amplitudes spanning the window; untrusted values (irregular motion) as dots
        own_a = np.array([c.amplitude for c in cycles], dtype=float)
        grid = np.geomspace(a_lo, a_hi, n_loci)
        # a window amplitude within 10 % of a cycle's would draw a second, nearly identical curve: left out
        grid = grid[[not np.any(np.abs(a / own_a - 1) < 0.1) for a in grid]] if own_a.size else grid
        amps = np.unique(np.concatenate([grid, own_a]))
        colors = plt.cm.viridis(np.linspace(0.05, 0.85, amps.size)) if amps.size > 1 else ["C2"]
        own = {float(c.amplitude) for c in cycles}
        unit = f" {N.input_unit}" if N.input_unit else ""
        for a_f, color in zip(amps, colors):
            w_f, loc = curve_with_gaps(lambda x, a_f=a_f: negative_inverse(N, a_f, x), w)
            ok = np.zeros(w_f.size, bool)
            fin = np.isfinite(w_f)
            ok[fin] = np.asarray(N.validity(a_f, w_f[fin]), bool)
            tag = " (a cycle's amplitude)" if float(a_f) in own else ""
            loci.append((loc, ok, color, f"-1/N({N.input_name}={a_f:.3g}{unit}, ω){tag}"))
    else:
        _, loc = curve_with_gaps(lambda a: negative_inverse(N, a), A)
        loci.append((loc, None, "C2", "-1/N(A)"))
    jumps = list(getattr(cycles, "jump_crossings", ()))
    exact = [c.exact for c in cycles if getattr(c, "exact", None) is not None and c.exact.success]
    g_exact = plant(np.array([e.frequency for e in exact], dtype=float)) if exact else np.empty(0, complex)
    groups = _draw_curves(ax, g, loci, cycles, jumps, g_exact, labelled=True)
    dt = getattr(plant, "dt", None)
    if dt:   # a discrete-time plant: G(e^{jw dt}) on 0 < w < pi/dt (dfloop.solve.sampled)
        groups[0][0].set_label(f"G(e^{{jωΔt}}), Δt={dt:g} s, ω < π/Δt")
    marks = np.array([c.G for c in cycles] + [j.G for j in jumps] + list(g_exact), dtype=complex)
    xlim, ylim = _view(np.concatenate([g] + [z for z, _, _, _ in loci]), marks)
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    plane_labels(ax, N)
    curves = [g] + [z for z, _, _, _ in loci]
    hidden = []  # a locus of the family that runs outside the view gets no legend entry
    for line in groups[1]:
        z = line.get_xdata() + 1j * line.get_ydata()
        if not np.any((z.real >= xlim[0]) & (z.real <= xlim[1]) & (z.imag >= ylim[0]) & (z.imag <= ylim[1])):
            hidden.append(line)
    add_direction_arrow(ax, g, "C0")
    for line in groups[1]:
        if line.get_linestyle() not in ("None", "none", ""):
            add_direction_arrow(ax, line.get_xdata() + 1j * line.get_ydata(), line.get_color())
    leg = legend(ax, skip=hidden, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    anchors = [c.G for c in cycles] + [j.G for j in jumps]
    texts = _label_texts(cycles, jumps, N)
    colors = ["black"] * len(cycles) + ["C1"] * len(jumps)
    tags = [f"#{i}" for i in range(len(cycles))] + [f"j{i}" for i in range(len(jumps))]
    keys = np.array(anchors + list(g_exact) + [-1.0 + 0j], dtype=complex)
    group = _crowded_group(keys, max(xlim[1] - xlim[0], ylim[1] - ylim[0])) if inset else np.empty(0, int)
    crowd = group[group < len(anchors)]  # the labelled points of the crowded group
    unplaced: list[str] = []
    if crowd.size >= 1:
        sel = keys[group]
        cx, cy = 0.5 * (sel.real.min() + sel.real.max()), 0.5 * (sel.imag.min() + sel.imag.max())
        half = max(np.ptp(sel.real), np.ptp(sel.imag), 0.02 * (xlim[1] - xlim[0]))  # the group fills the middle half
        for size in (0.44, 0.38, 0.32):  # the largest inset that covers no marker
            (fx, fy), clear = _inset_corner(ax, curves, size, keys)
            if clear:
                break
        axins = ax.inset_axes([fx, fy, size, size])
        _draw_curves(axins, g, loci, cycles, jumps, g_exact, labelled=False)
        axins.set_xlim(cx - half, cx + half)
        axins.set_ylim(cy - half, cy + half)
        axins.tick_params(labelsize=6)
        axins.set_title("zoom", fontsize=7, pad=2)
        ax.indicate_inset_zoom(axins, edgecolor="0.4")
        inside = set(crowd.tolist())
        inset_points = [(anchors[i].real, anchors[i].imag) for i in crowd]
        inset_avoid = [(p.real, p.imag) for p in g_exact]
        if crowd.size <= 2:  # room for full labels (a number, and the label listed, where there is not)
            place_labels(axins, inset_points, [texts[i] for i in crowd], [colors[i] for i in crowd], fontsize=6.5,
                         avoid=inset_avoid, curves=curves, unplaced=unplaced, tags=[tags[i] for i in crowd])
        else:  # several points: each carries its number only (right above or below it, over the curves), the
            # full labels are listed beside the axes (long labels in a small inset would cross each other)
            place_labels(axins, inset_points, [tags[i] for i in crowd], [colors[i] for i in crowd], fontsize=7,
                         avoid=inset_avoid, unplaced=unplaced, angles=(90.0, -90.0, 45.0, 135.0, -45.0, -135.0))
            unplaced += [f"{tags[i]}: " + texts[i].replace("\n", " ") for i in crowd]
        rest = [i for i in range(len(anchors)) if i not in inside]
        place_labels(ax, [(anchors[i].real, anchors[i].imag) for i in rest], [texts[i] for i in rest],
                     [colors[i] for i in rest], avoid=[(p.real, p.imag) for p in g_exact]
                     + [(anchors[i].real, anchors[i].imag) for i in crowd], curves=curves,
                     keep_clear=[axins], unplaced=unplaced, tags=[tags[i] for i in rest])
    else:
        place_labels(ax, [(p.real, p.imag) for p in anchors], texts, colors,
                     avoid=[(p.real, p.imag) for p in g_exact], curves=curves, unplaced=unplaced, tags=tags)
    if unplaced:
        ax.annotate("crowded cycles, by their number (#) on the plot:\n" + "\n".join(unplaced), (1.02, 0.0),
                    xycoords="axes fraction",
                    va="bottom", ha="left", fontsize=7)
    return control_plot(groups, ax, leg)


def plot_residual_map(cycles, ax=None, *, omega=None, amplitude=None, shape=(200, 200)):
    """Map of log10 |1 + G N| / (1 + |G N|) over (A, w), with the zero lines of Re and Im of 1 + G N.

    A limit cycle sits where the two zero lines cross; the crossing angle shows how well conditioned
    (and, by its orientation, how stable) it is. Without explicit windows the map spans a decade
    around the cycles (within the search windows).

    Parameters
    ----------
    cycles : LimitCycles
        Result of :func:`~dfloop.predict_limit_cycles` (it records the plant and element).
    ax : matplotlib Axes, optional
    omega, amplitude : (lo, hi), optional
        Windows of the map (rad/s; the element's input unit).
    shape : (int, int)
        Samples in amplitude and frequency.

    Returns
    -------
    control.ControlPlot
        ``lines[0]``: the cycle markers; the map is ``axes[0, 0].collections[0]``.
    """
    from ._labels import axes_or_new

    plant, N = _loop_of(cycles)
    (w_lo, w_hi), (a_lo, a_hi) = _windows(cycles, omega, amplitude)
    if cycles:  # zoom to a decade around the cycles unless windows were given
        if amplitude is None:
            amps = [c.amplitude for c in cycles]
            a_lo, a_hi = max(a_lo, min(amps) / 10), min(a_hi, max(amps) * 10)
        if omega is None:
            freqs = [c.frequency for c in cycles]
            w_lo, w_hi = max(w_lo, min(freqs) / 10), min(w_hi, max(freqs) * 10)
    ax = axes_or_new(ax)
    A = np.geomspace(a_lo, a_hi, int(shape[0]))
    w = np.geomspace(w_lo, w_hi, int(shape[1]))
    g = plant(w)
    n = N(A[:, None], w[None, :]) if N.frequency_dependent else N(A)[:, None]
    P = n * g[None, :]
    R = 1 + P
    rel = np.log10(np.maximum(np.abs(R) / (1 + np.abs(P)), 1e-16))
    mesh = ax.pcolormesh(w, A, rel, shading="auto", cmap="viridis")
    ax.contour(w, A, R.real, levels=[0], colors="w", linewidths=1)
    ax.contour(w, A, R.imag, levels=[0], colors="C3", linewidths=1, linestyles="--")
    seen = set()
    markers = []
    for c in cycles:
        name = None if c.stability in seen else _KIND_LABEL[c.stability]
        seen.add(c.stability)
        markers += ax.plot([c.frequency], [c.amplitude], ls="none", ms=8, mew=1.5, zorder=3, label=name,
                           **_STYLE[c.stability])
    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        if hi / lo <= 1e3:   # a short log axis: plain numbers (0.5, 1, 2), not 6x10^-1
            plain_log_ticks(axis)
    ax.set_xlabel(FREQUENCY)
    ax.set_ylabel(amplitude_label(N))
    ax.set_title("1 + GN = 0 where Re = 0 (white) meets Im = 0 (red dashed)", fontsize=9)
    ax.figure.colorbar(mesh, ax=ax, label="log10 |1+GN| / (1+|GN|) [-]")
    leg = legend(ax, fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.17), ncol=3, borderaxespad=0.0)
    return control_plot([markers], ax, leg)
