"""Plants of scenes: python-control systems, with an optional pure delay (:class:`~dfloop.solve.delay.DelayedSystem`);
a delayed plant in a digital loop becomes the exact sampled map of G e^{-sT} behind the hold."""
from __future__ import annotations

from typing import Any

from ..solve.delay import DelayedSystem, delayed
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
    dt = getattr(spec, "dt", None)
    if getattr(spec, "discrete", False) and dt is None:
        raise SceneError(None, Problem(dotted(loc + ("discrete",)), "discrete = true needs the sampling period dt"))
    if dt is not None:   # a digital loop (dfloop.solve.sampled): G(z), by a zero-order hold or given in z
        if spec.discrete:
            if spec.delay > 0:
                raise SceneError(None, Problem(dotted(loc + ("delay",)), "a delay in seconds and a system given in z "
                                               "(discrete = true) together are not supported; give the delay as z^-k"))
            system = ct.ss(system.A, system.B, system.C, system.D, dt) if isinstance(system, ct.StateSpace) else \
                ct.tf(system.num[0][0], system.den[0][0], dt)
        elif spec.delay > 0:
            system = _sampled(delayed(system, spec.delay), dt, loc)
        else:
            system = ct.sample_system(system, dt, "zoh")
    return delayed(system, spec.delay) if spec.delay > 0 and dt is None else system


def _sampled(plant: DelayedSystem, dt: float, loc: tuple) -> Any:
    """G e^{-sT} behind a zero-order hold of period dt: the exact sampled map
    (:func:`dfloop.hybrid.discrete.sample_delayed`, the pending held values in its state)."""
    from ..hybrid.discrete import sample_delayed

    try:
        return sample_delayed(plant, dt)
    except ValueError as err:
        raise SceneError(None, Problem(dotted(loc), f"cannot sample the delayed plant at dt = {dt:g} s: {err}")) \
            from None


def series(controller: Any, plant: Any) -> Any:
    """The loop controller * plant; delays add up (the result is delayed if either part is). A digital controller
    and a continuous plant: the plant is sampled behind a zero-order hold at the controller's period (with a delay,
    exactly: :func:`dfloop.hybrid.discrete.sample_delayed`)."""
    import control as ct

    c_dt, p_dt = (getattr(p, "dt", 0) or 0 for p in (controller, plant))
    if c_dt and isinstance(plant, DelayedSystem):   # the exact sampled map of G e^{-sT} behind the hold
        plant = _sampled(plant, c_dt, ("plant",))
    elif c_dt and not p_dt:
        plant = ct.sample_system(plant, c_dt, "zoh")
    elif c_dt and p_dt and c_dt != p_dt:
        raise SceneError(None, Problem("controller.dt", f"the controller's sampling period {c_dt:g} s differs from "
                                       f"the plant's {p_dt:g} s"))
    return controller * plant
