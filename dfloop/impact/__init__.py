"""dfloop.impact: the paper's dynamic backlash (Fig. 4).

The exact event engine of the two masses (closed-form free flight as its fast path), optional physical effects, the describing function of a run, the
tabulated describing function :class:`DynamicBacklash` (tables of :mod:`dfloop.tables`, cached on disk) and the
limit frequencies of eqs. (10), (11), (12) with their measured counterparts.

One way to each thing: :class:`DynamicBacklash` is the element a loop study uses (N(F, w) anywhere, from a
table); :func:`impact_describing_function` is one exact run with its diagnostics, and
:func:`impact_describing_function_batch` the same over a grid of (F, w) (arrays, threads, failures recorded).
Modules, lowest first: ``model`` (parameters, event and run bounds, run-setting checks, the run protocol) <-
``effects`` (the linear-mode engine's open-loop runs) <- ``kernel`` (the fast path, ``forced_motion``) <- ``extract`` (DF of a run) <- ``sampling`` (a table sample) <-
``dynamic_backlash`` (the element).
"""
from .dynamic_backlash import DynamicBacklash, prepare_many
from .effects import CoulombFriction, LoadSpring, ViscousDamping
from .extract import ImpactDF, ImpactDFBatch, impact_describing_function, impact_describing_function_batch
from .kernel import simulate as simulate_impacts
from .model import ImpactParameters
from .limits import (MeasuredLimits, beta_lower_limit, beta_of, jump_frequency, lower_limit_frequency,
                     measured_limits, no_impact_frequency, omega_of, x2_peak_excursion)

__all__ = ["simulate_impacts", "ImpactParameters", "ViscousDamping", "LoadSpring",
           "CoulombFriction", "impact_describing_function", "impact_describing_function_batch",
           "ImpactDF", "ImpactDFBatch",
           "DynamicBacklash", "prepare_many",
           "lower_limit_frequency", "no_impact_frequency", "jump_frequency",
           "beta_of", "omega_of", "beta_lower_limit", "x2_peak_excursion", "measured_limits", "MeasuredLimits"]
