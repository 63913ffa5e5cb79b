"""Names, units and nominal values of a scene's swept parameters (``[sweep]``, ``[chart]``).

A parameter is a dotted path into the scene (``"plant.num.0"``, ``"element.h"``, ``"plant.delay"``). Reports, CSV
headers and plot axes show a name and a unit instead (``gain K``, ``clearance h [m]``, ``delay T [s]``): given
in the scene (``name``, ``unit``), or derived here from the path.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["ParameterLabel", "parameter_label", "nominal_value"]

# element keys whose values are input levels (same unit as the element's input amplitude)
_LEVEL_WORDS = {"h": "clearance h", "limit": "saturation limit", "delta": "dead zone delta",
                "dead_zone": "dead zone d", "hysteresis": "hysteresis a", "step": "quantization step"}
_OTHER_WORDS = {"M": ("relay output M", ""), "k": ("slope k", ""), "restitution": ("restitution eps", ""),
                "k1": ("stiffness k1", "N/m"), "k3": ("cubic stiffness k3", "N/m^3"), "m1": ("mass m1", "kg"),
                "m2": ("mass m2", "kg"), "F0": ("preload F0", "N")}


@dataclass(frozen=True)
class ParameterLabel:
    """How a swept parameter is shown.

    Attributes
    ----------
    name : str
        E.g. ``"gain K"``.
    unit : str
        E.g. ``"m"``; empty for a dimensionless parameter.
    gain : bool
        True for a loop gain (margins are then also given in dB).
    """

    name: str
    unit: str = ""
    gain: bool = False

    @property
    def axis(self) -> str:
        """``name [unit]`` (just the name without a unit)."""
        return self.name + (f" [{self.unit}]" if self.unit else "")


def _node(data: dict, parts: list[str]) -> Any:
    node: Any = data
    for part in parts:
        node = node[int(part)] if isinstance(node, list) else node.get(part)
        if node is None:
            return None
    return node


def parameter_label(data: dict, path: str, name: str | None = None, unit: str | None = None) -> ParameterLabel:
    """The name and unit of the number at ``path`` in a scene's data (``name``/``unit`` override them).

    Derived names: a one-coefficient numerator or a zpk ``gain`` of the plant or controller is ``gain K``
    (dimensionless, margins in dB); ``delay`` is ``delay T [s]``; an element's thresholds (``h``, ``limit``,
    ``delta``, ``dead_zone``, ``hysteresis``, ``step``) carry the element's input unit; other keys keep their
    path.
    """
    parts = path.split(".")
    gain = False
    derived, derived_unit = path, ""
    root = parts[0]
    if root in ("plant", "controller") and len(parts) >= 2:
        section = data.get(root, {})
        if parts[1] == "delay":
            derived, derived_unit = "delay T", "s"
        elif parts[1] == "gain" or (parts[1] == "num" and len(section.get("num", [])) == 1):
            derived, gain = "gain K", True
    elif root == "element" and len(parts) == 2:
        key = parts[1]
        if key in _LEVEL_WORDS:
            derived, derived_unit = _LEVEL_WORDS[key], _element_unit(data.get("element", {}))
        elif key in _OTHER_WORDS:
            derived, derived_unit = _OTHER_WORDS[key]
    return ParameterLabel(name or derived, derived_unit if unit is None else unit, gain)


def _element_unit(table: dict) -> str:
    from .elements import registry

    cls = registry().get(table.get("type")) if isinstance(table.get("type"), str) else None
    return getattr(cls, "input_unit", "") if cls is not None else ""


def nominal_value(data: dict, path: str) -> float | None:
    """The number at ``path`` in the scene as written (the nominal design point), or None if it is left at
    the element's default."""
    value = _node(data, path.split("."))
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None
