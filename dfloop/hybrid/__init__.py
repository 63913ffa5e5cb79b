"""dfloop.hybrid: the exact linear-mode event engine for loops with piecewise-linear elements.

Between switching instants the loop of a strictly proper plant and a piecewise-linear element (relays,
saturation, dead zone, backlash, quantizer, ...) is a linear ODE z' = A_m z of the augmented state
z = [plant state, element state, 1], solved with the matrix exponential; switches are roots of linear guard
functions located to rounding level. Elements that are not piecewise linear run on DOP853 instead.
"""
from .elements import ElementModel, Guard, Mode, element_model
from .loop import Flow, HybridError, HybridLoop, plant_matrices
from .smooth import SmoothLoop

__all__ = ["ElementModel", "Guard", "Mode", "element_model", "Flow", "HybridError", "HybridLoop",
           "plant_matrices", "SmoothLoop", "loop_model"]


def loop_model(G, N, amplitude: float, frequency: float):
    """The loop of plant G and element N as a simulation model, and a description of its method.

    Returns ``(model, method)``: a :class:`HybridLoop` (exact) when N is piecewise linear, a
    :class:`SmoothLoop` (DOP853) when N is another static element, ``(None, reason)`` when N has no
    time-domain model here. ``amplitude`` and ``frequency`` (rad/s) size the steps and ranges.
    """
    import math

    from ..describing.numeric import NumericDF
    from ..describing.static import StaticElement

    A, B, C = plant_matrices(G)
    time_scale = 2.0 * math.pi / frequency
    model = element_model(N, amplitude)
    if model is not None:
        return (HybridLoop(A, B, C, model, time_scale),
                "exact (matrix exponential between switches, switches located to rounding level)")
    if isinstance(N, StaticElement) or (isinstance(N, NumericDF) and not N.hysteretic):
        f = N.output if isinstance(N, StaticElement) else N.element
        return (SmoothLoop(A, B, C, f, type(N).__name__, time_scale),
                f"DOP853 (rtol {1e-12:g}; {type(N).__name__} is not piecewise linear, so not exact)")
    return None, f"{type(N).__name__} has no piecewise-linear or static time-domain model"
