"""Relay-feedback auto-tuning: the relay experiment predicted (DF and exact), estimation from a recording, tuning.

Modules: :mod:`~dfloop.autotune.models` (FOPDT / SOPDT process models), :mod:`~dfloop.autotune.cycle` (their
exact relay orbits, symmetric or biased), :mod:`~dfloop.autotune.experiment` (:func:`relay_experiment`),
:mod:`~dfloop.autotune.record` (a recorded experiment: CSV, switching instants, amplitude and period with their
uncertainty), :mod:`~dfloop.autotune.fit` (model parameters with confidence intervals by matching the exact relay
orbit), :mod:`~dfloop.autotune.rules` (Ziegler-Nichols, SIMC, AMIGO and the closed-loop check).
"""
from .cycle import RelayCycle, fopdt_biased_relay_cycle, fopdt_relay_cycle, relay_cycle
from .experiment import RelayExperiment, process_model, relay_experiment
from .models import ProcessModel, fopdt_ultimate_point
from .rules import RULES, Tuning, closed_loop_check, tune

__all__ = ["RelayExperiment", "relay_experiment", "process_model", "ProcessModel", "fopdt_ultimate_point",
           "RelayCycle", "relay_cycle", "fopdt_relay_cycle", "fopdt_biased_relay_cycle", "Tuning", "tune",
           "closed_loop_check", "RULES"]
