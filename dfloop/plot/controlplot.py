"""The return value of every dfloop plot function: a :class:`control.ControlPlot` (python-control's convention)."""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

__all__ = ["control_plot"]


def control_plot(groups: Sequence[Sequence[Any]], axes, legend=None) -> Any:
    """A :class:`control.ControlPlot` whose ``lines`` is a 1-D object array of the given lists of artists.

    Parameters
    ----------
    groups : sequence of sequences of matplotlib artists
        One list per kind of curve (e.g. [plant], [loci], [cycle markers]); ``lines[i]`` is ``list(groups[i])``.
    axes : matplotlib Axes or sequence of Axes
        The axes drawn into; a single Axes becomes ``axes[0, 0]``, a sequence one column (``axes[i, 0]``).
    legend : matplotlib Legend, optional

    Returns
    -------
    control.ControlPlot
        ``lines``, ``axes`` (2-D object array), ``figure``, ``legend``.
    """
    from control import ControlPlot
    from matplotlib.axes import Axes

    lines = np.empty(len(groups), dtype=object)
    for i, group in enumerate(groups):
        lines[i] = list(group)
    if isinstance(axes, Axes):
        axes = [axes]
    flat = [a for a in np.ravel(np.asarray(axes, dtype=object))]
    grid = np.asarray(axes, dtype=object)
    if grid.ndim != 2:
        grid = np.empty((len(flat), 1), dtype=object)
        for i, a in enumerate(flat):
            grid[i, 0] = a
    return ControlPlot(lines, grid, flat[0].figure, legend=legend)
