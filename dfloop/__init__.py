"""dfloop: describing-function prediction of limit cycles in nonlinear feedback loops.

The top level is the curated API a control engineer uses: the elements, the prediction, the exact and simulated
checks of a predicted cycle, sweeps and batches, the Nyquist picture, scenes, and the errors. Everything else
is imported from its subpackage (``dfloop.impact``, ``dfloop.tables``, ``dfloop.solve``, ``dfloop.plot``,
``dfloop.scene``, ...), where it is listed in that module's ``__all__``.

The namespace is lazy: ``import dfloop`` loads nothing heavy (no python-control, scipy.signal, matplotlib or
numba); each public name is imported from its module on first use (PEP 562). ``_EXPORTS`` lists, per module,
the names taken from it (each one in that module's ``__all__``: ``tests/test_interop_imports.py`` checks it),
so ``from dfloop import X``, ``dfloop.X`` and ``dir(dfloop)`` all work as with eager imports.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

_EXPORTS: dict[str, tuple[str, ...]] = {
    # elements: N(A) or N(A, w), and what python-control or a callable becomes
    "dfloop.describing": (
        "DescribingFunction", "Backlash", "PlayOperator", "Saturation", "DeadZone", "Relay", "RelayOperator",
        "CubicStiffness", "Quantizer", "PreloadedSpring", "CoulombViscousFriction", "NumericDF", "LinearThenStatic",
        "MassBacklash"),
    "dfloop.describing.interop": ("as_element", "to_control", "control_loop"),
    "dfloop.impact": ("DynamicBacklash", "ViscousDamping", "LoadSpring", "CoulombFriction"),
    # prediction, and the checks of a predicted cycle
    "dfloop.solve": ("predict_limit_cycles", "LimitCycle", "LimitCycles", "ContinuumError"),
    "dfloop.solve.delay": ("delayed",),
    "dfloop.exact": ("ExactCycle", "exact_cycle"),
    "dfloop.hybrid.discrete": ("discrete_orbits",),
    "dfloop.verify": ("simulate_loop", "Verification", "verify_cycle"),
    "dfloop.solve.confidence": ("Confidence", "cycle_confidence"),
    # many loops: a parameter sweep, a batch
    "dfloop.continuation": ("sweep", "SweepResult"),
    "dfloop.batch": ("predict_many",),
    "dfloop.chart": ("design_chart",),
    # the picture, the scene files
    "dfloop.plot": ("plot_nyquist",),
    "dfloop.scene": ("SceneError", "load_scene", "run_scene"),
    "dfloop.errors": ("DfloopError", "EventLimitError", "CacheWarning"),
}
_SUBMODULES = ("describing", "impact", "tables", "solve", "verify", "plot", "harmonics", "progress", "scene", "cli",
               "cache_admin", "errors", "exact", "confidence", "hybrid", "batch", "continuation", "chart", "autotune")

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
