"""dfloop: describing-function prediction of limit cycles in nonlinear feedback loops.

The package namespace is lazy: ``import dfloop`` loads nothing heavy (no python-control, scipy.signal,
matplotlib or numba); each public name is imported from its module on first use (PEP 562). The table below
lists, per module, that module's ``__all__`` (``tests/test_interop_imports.py`` checks that they agree), so
``from dfloop import X``, ``dfloop.X`` and ``dir(dfloop)`` all work as with eager imports.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

_EXPORTS: dict[str, tuple[str, ...]] = {
    "dfloop.describing": (
        "DescribingFunction", "negative_inverse", "StaticElement", "Backlash", "PlayOperator", "Saturation",
        "DeadZone", "Relay", "RelayOperator", "CubicStiffness", "Quantizer", "PreloadedSpring",
        "CoulombViscousFriction", "NumericDF", "LinearThenStatic", "MassBacklash"),
    "dfloop.describing.interop": ("as_element", "ControlDescribingFunction"),
    "dfloop.impact": (
        "simulate_impacts", "ImpactParameters", "EventLimitError", "ViscousDamping", "LoadSpring",
        "CoulombFriction", "impact_describing_function", "impact_describing_function_batch",
        "describing_function_from_trajectory", "ImpactDF", "ImpactDFBatch", "DynamicBacklash", "prepare_many",
        "cache_dir", "static_limit_frequency", "lower_limit_frequency", "no_impact_frequency", "jump_frequency",
        "beta_of", "omega_of", "beta_lower_limit", "x2_peak_excursion", "measured_limits", "MeasuredLimits",
        "Table1D", "Table2D", "TableSettings", "Samples"),
    "dfloop.solve": (
        "predict_limit_cycles", "LimitCycle", "LimitCycles", "JumpCrossing", "Plant", "as_plant",
        "graphical_stability", "GridReport", "ContinuumError"),
    "dfloop.solve.delay": ("DelayedSystem", "delayed"),
    "dfloop.verify": ("LoopSimulation", "simulate_loop", "Verification", "verify_cycle"),
    "dfloop.plot": ("case_labels", "curve_with_gaps", "plot_loci", "plot_nyquist", "plot_residual_map",
                    "plot_time_response", "plot_collision_map"),
    "dfloop.scene": ("Scene", "SceneError", "Problem", "SceneLoop", "SceneReport", "load_scene", "run_scene",
                     "build", "find_scene", "shipped_scenes", "scene_reference"),
    "dfloop.cache_admin": ("CacheFile", "CacheInfo", "cache_info", "clear_cache"),
    "dfloop.errors": ("DfloopError", "CacheWarning"),
    "dfloop.impact.loop": ("simulate_impact_loop", "impact_loop_orbit", "ImpactLoopOrbit"),
    "dfloop.exact": ("ExactCycle", "exact_cycle"),
    "dfloop.confidence": ("Confidence", "cycle_confidence"),
    "dfloop.continuation": ("sweep", "SweepResult", "Branch", "SweepEvent"),
    "dfloop.batch": ("predict_many", "run_batch"),
}
_SUBMODULES = ("describing", "impact", "solve", "verify", "plot", "harmonics", "progress", "scene", "cli", "cache_admin", "errors", "exact", "confidence", "hybrid", "batch")

_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
__all__ = [*_WHERE, "__version__"]


def __getattr__(name: str):
    module = _WHERE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module), name)
        globals()[name] = value  # later lookups skip this function
        return value
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'dfloop' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__, *_SUBMODULES})
