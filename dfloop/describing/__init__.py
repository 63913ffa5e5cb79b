"""Describing-function objects: one protocol, analytic static elements, numeric DFs, compositions."""
from .base import DescribingFunction, negative_inverse
from .composition import LinearThenStatic, MassBacklash
from .numeric import NumericDF
from .static import (
    Backlash,
    CoulombViscousFriction,
    CubicStiffness,
    DeadZone,
    PlayOperator,
    PreloadedSpring,
    Quantizer,
    Relay,
    RelayOperator,
    Saturation,
    StaticElement,
)

__all__ = [
    "DescribingFunction",
    "negative_inverse",
    "StaticElement",
    "Backlash",
    "PlayOperator",
    "Saturation",
    "DeadZone",
    "Relay",
    "RelayOperator",
    "CubicStiffness",
    "Quantizer",
    "PreloadedSpring",
    "CoulombViscousFriction",
    "NumericDF",
    "LinearThenStatic",
    "MassBacklash",
]
