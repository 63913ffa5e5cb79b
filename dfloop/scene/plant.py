"""Plants of scenes: python-control systems, with an optional pure delay (:class:`~dfloop.solve.delay.DelayedSystem`)."""
from __future__ import annotations

from typing import Any

from ..solve.delay import delayed
from .errors import Problem, SceneError, dotted

__all__ = ["make_plant", "series"]


def make_plant(spec: Any, loc: tuple = ("plant",)) -> Any:
    """A python-control system, or a :class:`~dfloop.solve.delay.DelayedSystem` when ``delay > 0``, from a
    validated plant table."""
    import control as ct

    try:
        if spec.type == "tf":
            system = ct.tf(spec.num, spec.den)
        elif spec.type == "zpk":
            system = ct.zpk(spec.zeros, spec.poles, spec.gain)
        else:
            system = ct.ss(spec.A, spec.B, spec.C, spec.D)
    except (ValueError, TypeError, ZeroDivisionError) as err:
        raise SceneError(None, Problem(dotted(loc), f"python-control rejects this {spec.type} system: {err}")) \
            from None
    if system.ninputs != 1 or system.noutputs != 1:
        raise SceneError(None, Problem(dotted(loc), f"must be SISO, got {system.noutputs}x{system.ninputs}"))
    from ..solve.plant import MAX_ORDER  # the solver's bound, checked at load rather than after the others ran

    order = system.nstates if isinstance(system, ct.StateSpace) else max(len(system.num[0][0]), len(system.den[0][0])) - 1
    if order > MAX_ORDER:
        raise SceneError(None, Problem(dotted(loc), f"order {order} is above the solver's bound of {MAX_ORDER}; "
                                                    "reduce the model first (e.g. control.balred)"))
    return delayed(system, spec.delay) if spec.delay > 0 else system


def series(controller: Any, plant: Any) -> Any:
    """The loop controller * plant; delays add up (the result is delayed if either part is)."""
    return controller * plant
