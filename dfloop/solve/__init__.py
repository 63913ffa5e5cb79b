"""dfloop.solve: limit-cycle prediction (roots of 1 + G N = 0), Loeb stability, plant adapter."""
from .errors import ContinuumError
from .plant import Plant, as_plant
from .predict import predict_limit_cycles
from .result import GridReport, JumpCrossing, LimitCycle, LimitCycles
from .stability import graphical_stability

__all__ = ["predict_limit_cycles", "LimitCycle", "LimitCycles", "JumpCrossing", "Plant", "as_plant",
           "graphical_stability", "GridReport", "ContinuumError"]
