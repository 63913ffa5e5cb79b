"""Plots: -1/N loci, Nyquist plots with predicted cycles, residual maps, impact time responses and maps.

Every function takes ``ax=None`` (a new figure when None) and returns the axes.
"""
from .impact import plot_collision_map, plot_time_response
from .loci import plot_loci
from .nyquist import plot_nyquist, plot_residual_map

__all__ = ["plot_loci", "plot_nyquist", "plot_residual_map", "plot_time_response", "plot_collision_map"]
