"""dfloop.impact: the paper's dynamic backlash (Fig. 4).

The exact event-driven impact kernel, optional physical effects, DF extraction from a run, the tabulated
describing function :class:`DynamicBacklash` (similarity-law tables, cached on disk) and the limit frequencies
of eqs. (5), (10), (11), (12) with their measured counterparts.
"""
from .cache import cache_dir
from .dynamic_backlash import DynamicBacklash, prepare_many
from .effects import CoulombFriction, LoadSpring, ViscousDamping
from .extract import (ImpactDF, ImpactDFBatch, describing_function_from_trajectory, impact_describing_function,
                      impact_describing_function_batch)
from .kernel import simulate as simulate_impacts
from .model import ImpactParameters
from .limits import (MeasuredLimits, beta_lower_limit, beta_of, jump_frequency, lower_limit_frequency,
                     measured_limits, no_impact_frequency, omega_of, static_limit_frequency, x2_peak_excursion)
from .table import Samples, Table1D, TableSettings
from .table2d import Table2D

__all__ = ["simulate_impacts", "ImpactParameters", "ViscousDamping", "LoadSpring",
           "CoulombFriction", "impact_describing_function", "impact_describing_function_batch",
           "describing_function_from_trajectory", "ImpactDF", "ImpactDFBatch",
           "DynamicBacklash", "prepare_many", "cache_dir",
           "static_limit_frequency", "lower_limit_frequency", "no_impact_frequency", "jump_frequency",
           "beta_of", "omega_of", "beta_lower_limit", "x2_peak_excursion", "measured_limits", "MeasuredLimits",
           "Table1D", "Table2D", "TableSettings", "Samples"]
