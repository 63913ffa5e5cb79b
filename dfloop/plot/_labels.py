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


def legend(ax, **kwargs):
    """A legend with one entry per distinct label (the first handle drawn with it); None if no labels."""
    seen = {}
    for handle, label in zip(*ax.get_legend_handles_labels()):
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


def place_labels(ax, anchors, texts, colors=None, *, fontsize: float = 8.0, avoid=()):
    """Annotate each anchor point (data coordinates) with its text where it overlaps no other label.

    Offsets are tried from close to far in eight directions (a thin leader line joins distant labels to
    their point); a label must lie inside the axes and keep clear of every anchor's marker. ``colors`` gives
    one text colour per label (default black); ``avoid`` lists further points (data coordinates) whose
    markers no label may cover (unlabelled markers, e.g. the exact cycles). Labels that
    find no free place are listed in one block to the right of the axes instead (never drawn on top of
    each other).

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
    drawn, overflow = [], []
    colors = ["black"] * len(texts) if colors is None else list(colors)
    for (x, y), text, color in zip(anchors, texts, colors):
        for r in _RADII:
            for ang in _ANGLES:
                dx, dy = r * math.cos(math.radians(ang)), r * math.sin(math.radians(ang))
                ann = ax.annotate(
                    text, (x, y), xytext=(dx, dy), textcoords="offset points", fontsize=fontsize, color=color,
                    ha="left" if dx > 1e-9 else ("right" if dx < -1e-9 else "center"),
                    va="bottom" if dy > 1e-9 else ("top" if dy < -1e-9 else "center"),
                    arrowprops=dict(arrowstyle="-", lw=0.5, color="0.5", shrinkA=0, shrinkB=2) if r > _RADII[0] else None)
                ann.update_positions(renderer)
                box = Text.get_window_extent(ann, renderer).padded(_GAP * scale)  # text only, not its leader
                if frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1 \
                        and not _overlaps(box, taken):
                    taken.append(box)
                    drawn.append(ann)
                    break
                ann.remove()
            else:
                continue
            break
        else:
            overflow.append(text.replace("\n", " "))
    if overflow:
        drawn.append(ax.annotate("not labelled (crowded):\n" + "\n".join(overflow), (1.02, 1.0),
                                 xycoords="axes fraction", va="top", ha="left", fontsize=fontsize - 1))
    return drawn
