"""dfloop.impact: exact event-driven impact kernel (paper's Fig. 4), optional effects, DF extraction."""
from .effects import CoulombFriction, LoadSpring, ViscousDamping
from .extract import (ImpactDF, ImpactDFBatch, describing_function_from_trajectory, impact_describing_function,
                      impact_describing_function_batch)
from .kernel import EventLimitError, ImpactParameters
from .kernel import simulate as simulate_impacts

__all__ = ["simulate_impacts", "ImpactParameters", "EventLimitError", "ViscousDamping", "LoadSpring",
           "CoulombFriction", "impact_describing_function", "impact_describing_function_batch",
           "describing_function_from_trajectory", "ImpactDF", "ImpactDFBatch"]
