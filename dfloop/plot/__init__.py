"""Plots: the one plotting layer of dfloop. Every result's ``.plot()`` delegates here.

Every function takes ``ax=None`` (a new figure when None), draws what it is given (results, computed data:
nothing is solved or simulated here) and returns a :class:`control.ControlPlot` (``lines``, ``axes``,
``figure``), python-control's convention. Modules: ``nyquist`` (``plot_nyquist``, ``plot_residual_map``: a
``LimitCycles``), ``loci`` (``plot_loci``: an element), ``orbit`` (``plot_exact_cycle``, ``plot_verification``),
``sweep`` (``plot_sweep``), ``study`` (``plot_element_study``: a scene's ``[figure]``), ``impact``
(``plot_time_response``, ``plot_collision_map``), ``controlplot`` (``control_plot``, to build the return value).
"""
from ._curves import curve_with_gaps
from ._labels import case_labels
from .impact import plot_collision_map, plot_time_response
from .loci import plot_loci
from .nyquist import plot_nyquist, plot_residual_map

__all__ = ["case_labels", "curve_with_gaps", "plot_loci", "plot_nyquist", "plot_residual_map", "plot_time_response", "plot_collision_map"]
