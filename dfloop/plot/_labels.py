"""Text on plots: axis labels in one unit style, legends without repeats, point labels that do not overlap."""
from __future__ import annotations

import math

import numpy as np

FREQUENCY = "Frequency [rad/s]"
TIME = "Time [s]"
REAL, IMAG = "Real axis", "Imaginary axis"  # python-control's Nyquist labels

_RADII = (8.0, 20.0, 34.0, 50.0, 70.0, 95.0)  # label offsets tried, in points
_ANGLES = (45.0, 135.0, -45.0, -135.0, 90.0, -90.0, 0.0, 180.0)  # degrees
_MARKER_HALF = 5.0  # half-size (points) of the box kept free around every anchor point
_GAP = 1.5  # clearance (points) kept around every label


def quantity(name: str, unit: str = "") -> str:
    """An axis label ``"name [unit]"`` (just ``name`` when there is no unit)."""
    return f"{name} [{unit}]" if unit else name


def amplitude_label(N) -> str:
    """Axis label of an element's input amplitude, e.g. ``"Amplitude X [m]"``."""
    return quantity(f"Amplitude {N.input_name}", N.input_unit)


def plane_unit(N) -> str:
    """Unit of the Nyquist plane of G(jw) and -1/N (both in element input per element output, since G N is
    dimensionless): N/m for an element driven by a force whose output is a position (``input_unit`` "N": the
    masses with backlash), "-" for elements whose input and output share a unit."""
    return "N/m" if getattr(N, "input_unit", "") == "N" else "-"


def plane_labels(ax, N) -> None:
    """python-control's "Real axis" / "Imaginary axis", with the plane's unit (:func:`plane_unit`)."""
    unit = plane_unit(N)
    ax.set_xlabel(quantity(REAL, unit))
    ax.set_ylabel(quantity(IMAG, unit))


def axes_or_new(ax, name: str = "ax"):
    """The given matplotlib Axes, or a new figure's axes when ``ax`` is None; ``ValueError`` naming ``name``
    for anything else (a figure, an array of axes, a python-control ControlPlot)."""
    from matplotlib.axes import Axes

    if ax is None:
        import matplotlib.pyplot as plt

        return plt.figure().add_subplot()
    if not isinstance(ax, Axes):
        raise ValueError(f"{name} must be a matplotlib Axes or None, got {type(ax).__name__} {ax!r:.60}")
    return ax


_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*")


def distinct_styles(n: int):
    """(colours, markers) for ``n`` curves that a reader tells apart: the ten qualitative colours of
    matplotlib's ``tab10`` (ten or fewer curves), otherwise a perceptually ordered map (``viridis``) for an
    ordered family, each curve with its own marker shape as a second cue."""
    import matplotlib.pyplot as plt

    n = max(int(n), 1)
    colors = [plt.cm.tab10(k % 10) for k in range(n)] if n <= 10 else list(plt.cm.viridis(np.linspace(0, 0.9, n)))
    return colors, [_MARKERS[k % len(_MARKERS)] for k in range(n)]


def ordered_colors(n: int):
    """``n`` colours of one ordered family (a parameter's values, increasing): ``viridis`` from dark blue to
    yellow-green, so neighbours differ and the order reads from the colour."""
    import matplotlib.pyplot as plt

    return list(plt.cm.viridis(np.linspace(0.0, 0.88, max(int(n), 1)))) if n > 1 else ["C0"]


def plain_log_ticks(axis) -> None:
    """Plain numbers on a logarithmic axis (1, 2, 5, 10, 20, ...; no 6x10^0 labels): major ticks at 1, 2 and
    5 per decade, unlabelled minor ticks."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))   # 0.5, 1, 2 (no trailing zeros)
    axis.set_minor_formatter(NullFormatter())


def legend(ax, skip=(), **kwargs):
    """A legend with one entry per distinct label (the first handle drawn with it, leaving out the artists in
    ``skip``); None if no labels."""
    seen = {}
    for handle, label in zip(*ax.get_legend_handles_labels()):
        if any(handle is h for h in skip):
            continue
        seen.setdefault(label, handle)
    if not seen:
        return None
    return ax.legend(list(seen.values()), list(seen.keys()), **kwargs)


def case_labels(cases):
    """Legend labels that show only what varies between cases, and the shared part for a title.

    Parameters
    ----------
    cases : sequence of dict
        One dict per curve, ``{parameter name: formatted value}`` (e.g. ``{"eps": "0.5", "F": "50 N"}``).

    Returns
    -------
    labels : list of str
        ``"name=value"`` pairs of the parameters whose values differ between cases, joined by ", ".
    common : str
        The parameters every case shares, ``"F=50 N"``-style (empty when none), for a title.

    Examples
    --------
    >>> case_labels([{"eps": "0.1", "F": "50 N"}, {"eps": "0.2", "F": "50 N"}])
    (['eps=0.1', 'eps=0.2'], 'F=50 N')
    """
    cases = [dict(c) for c in cases]
    names = list(dict.fromkeys(k for c in cases for k in c))
    varying = [k for k in names if len({c.get(k) for c in cases}) > 1]
    common = ", ".join(f"{k}={cases[0][k]}" for k in names if k not in varying and k in cases[0])
    labels = [", ".join(f"{k}={c[k]}" for k in varying if k in c) for c in cases]
    return labels, common


def _renderer(fig):
    """A renderer for text extents on any backend (Agg canvases have one; others get one from a dry run)."""
    if hasattr(fig.canvas, "get_renderer"):
        return fig.canvas.get_renderer()
    return fig._get_renderer()  # matplotlib >= 3.6, as used by its own layout engines


def _overlaps(box, boxes) -> bool:
    return any(box.x0 < b.x1 and b.x0 < box.x1 and box.y0 < b.y1 and b.y0 < box.y1 for b in boxes)


def _curve_points(ax, curves, frame):
    """Screen coordinates (pixels) of the curves' finite samples inside ``frame``, as an (n, 2) array."""
    pts = [np.column_stack([np.real(z), np.imag(z)]) for z in curves if np.size(z)]
    if not pts:
        return np.empty((0, 2))
    xy = np.concatenate(pts)
    xy = xy[np.isfinite(xy).all(axis=1)]
    screen = ax.transData.transform(xy) if xy.size else np.empty((0, 2))
    inside = (screen[:, 0] >= frame.x0) & (screen[:, 0] <= frame.x1) & (screen[:, 1] >= frame.y0) \
        & (screen[:, 1] <= frame.y1)
    return screen[inside]


def _crosses(box, points) -> bool:
    return bool(np.any((points[:, 0] >= box.x0) & (points[:, 0] <= box.x1) & (points[:, 1] >= box.y0)
                       & (points[:, 1] <= box.y1)))


def place_labels(ax, anchors, texts, colors=None, *, fontsize: float = 8.0, avoid=(), curves=(), keep_clear=(),
                 overflow_at=(1.02, 1.0), unplaced=None, tags=None, angles=None):
    """Annotate each anchor point (data coordinates) with its text where it overlaps no other label.

    Offsets are tried from close to far in eight directions (a thin leader line joins distant labels to
    their point); a label must lie inside the axes and keep clear of every anchor's marker. ``colors`` gives
    one text colour per label (default black); ``avoid`` lists further points (data coordinates) whose
    markers no label may cover (unlabelled markers, e.g. the exact cycles); ``curves`` lists complex arrays
    (data coordinates, x + jy) of drawn curves: a place that crosses none of their samples is preferred, one
    that crosses a curve is taken only when no clear place exists; ``keep_clear`` lists artists (e.g. an
    inset's axes) no label may cover. Labels that find no free place are listed in one block outside the
    axes at ``overflow_at`` (axes fraction of its upper-left corner; never drawn on top of each other), or,
    when a list is given as ``unplaced``, appended to it (one text per label, on one line) for the caller to
    list. ``tags`` gives a short tag per label (e.g. ``"#3"``): a label that finds no place is replaced on the
    plot by its tag, and listed as ``"#3: <label>"``, so every point stays identifiable. ``angles`` (degrees)
    overrides the order in which directions are tried (default: the diagonals first).

    Returns
    -------
    list of matplotlib.text.Annotation
        The labels drawn next to their points (the overflow block, if any, is the last element).
    """
    renderer = _renderer(ax.figure)
    scale = ax.figure.dpi / 72.0
    frame = ax.get_window_extent(renderer)
    points = list(anchors) + list(avoid)
    screen = ax.transData.transform(np.asarray(points, dtype=float).reshape(-1, 2)) if points else []
    from matplotlib.text import Text
    from matplotlib.transforms import Bbox

    taken = [Bbox.from_extents(x - _MARKER_HALF * scale, y - _MARKER_HALF * scale, x + _MARKER_HALF * scale,
                               y + _MARKER_HALF * scale) for x, y in screen]
    taken += [a.get_window_extent(renderer) for a in keep_clear]
    lines = _curve_points(ax, curves, frame)
    drawn, overflow = [], []
    colors = ["black"] * len(texts) if colors is None else list(colors)
    tags = [None] * len(texts) if tags is None else list(tags)

    def attempt(x, y, text, color, passes=(True, False), angles=_ANGLES if angles is None else tuple(angles)):
        for strict in passes:  # first clear of every curve, then clear of labels and markers only
            for r in _RADII:
                for ang in angles:
                    dx, dy = r * math.cos(math.radians(ang)), r * math.sin(math.radians(ang))
                    ann = ax.annotate(
                        text, (x, y), xytext=(dx, dy), textcoords="offset points", fontsize=fontsize, color=color,
                        ha="left" if dx > 1e-9 else ("right" if dx < -1e-9 else "center"),
                        va="bottom" if dy > 1e-9 else ("top" if dy < -1e-9 else "center"),
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8),
                        arrowprops=dict(arrowstyle="-", lw=0.5, color="0.5", shrinkA=0, shrinkB=2)
                        if r > _RADII[0] else None)
                    ann.update_positions(renderer)
                    box = Text.get_window_extent(ann, renderer).padded(_GAP * scale)  # text only, not its leader
                    if frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1 \
                            and not _overlaps(box, taken) and not (strict and _crosses(box, lines)):
                        taken.append(box)
                        return ann
                    ann.remove()
        return None

    for (x, y), text, color, tag in zip(anchors, texts, colors, tags):
        placed = attempt(x, y, text, color)
        if placed is None and tag:  # crowded: a short tag on the plot, the full label in the list
            # a tag is short: as close as labels allow, straight above or below its point first (beside it, it
            # could be read as its neighbour's on a row of markers)
            placed = attempt(x, y, tag, color, passes=(False,), angles=(90.0, -90.0) + _ANGLES[:4] + (0.0, 180.0))
            if placed is not None:
                overflow.append(f"{tag}: " + text.replace("\n", " "))
        elif placed is None:
            overflow.append(text.replace("\n", " "))
        if placed is not None:
            drawn.append(placed)
    if unplaced is not None:
        unplaced.extend(overflow)
    elif overflow:
        drawn.append(ax.annotate("crowded:\n" + "\n".join(overflow), overflow_at,
                                 xycoords="axes fraction", va="bottom" if overflow_at[1] < 0.5 else "top",
                                 ha="left", fontsize=fontsize - 1))
    return drawn
