"""Plots: -1/N loci, Nyquist plots with predicted cycles, residual maps, impact time responses and maps.

Every function takes ``ax=None`` (a new figure when None). The Nyquist-plane plots (``plot_nyquist``,
``plot_loci``, ``plot_residual_map``) follow python-control's conventions and return a
:class:`control.ControlPlot` (``lines``, ``axes``, ``figure``); the impact plots return the axes.
"""
from ._curves import curve_with_gaps
from ._labels import case_labels
from .impact import plot_collision_map, plot_time_response
from .loci import plot_loci
from .nyquist import plot_nyquist, plot_residual_map

__all__ = ["case_labels", "curve_with_gaps", "plot_loci", "plot_nyquist", "plot_residual_map", "plot_time_response", "plot_collision_map"]
