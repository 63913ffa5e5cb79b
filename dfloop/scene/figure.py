"""The ``[figure]`` stage of scenes: a study of the element alone (no loop), computed then drawn.

Kinds (see :class:`dfloop.scene.schema.Figure`):

- ``nyquist`` / ``loglog``: -1/N(A, w) over a log-spaced frequency grid, per input amplitude A and value of the
  optional parameter. Points where the element says its value is not trustworthy (``validity`` False: irregular
  motion of dynamic backlash) are drawn as faint dots, except those more than twice as far from the origin as
  every trusted one (counted in the curve's note); points where N = 0 (-1/N infinite) are dropped.
- ``time_response``: dx1/dt(t) of the two-mass impact system driven by F cos(w t) from rest
  (:func:`dfloop.impact.kernel.simulate`), one panel per (w, parameter value), with the steady motion's period
  detected over the window; panels with w below the paper's eq. (10) lower limit are marked.
- ``collisions``: the longest run of consecutive impacts on side A (the paper's n_A, Fig. 9) vs w.

:func:`figure_data` computes the numbers (a :class:`FigureData`, testable on its own); its ``plot`` draws them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import Problem, SceneError

__all__ = ["Curve", "FigureData", "figure_data", "figure_spec"]

SAMPLES_PER_PERIOD = 200  # time_response: points per forcing period on the drawn curve


@dataclass(frozen=True, repr=False)
class Curve:
    """One curve of a figure.

    Attributes
    ----------
    amplitude : float
        Input amplitude A of the element (N for backlash with masses).
    value : float or None
        Value of the figure's parameter (None without one).
    x : numpy.ndarray
        Frequencies w (rad/s), or times t (s) for ``time_response``.
    y : numpy.ndarray
        -1/N (complex, N/m for backlash with masses), dx1/dt (m/s), or n_A (impacts).
    ok : numpy.ndarray
        Boolean per point: the element's value is trustworthy (periodic motion) there.
    omega : float or None
        Forcing frequency (rad/s) of a ``time_response`` panel.
    note : str
        What the curve's motion is (period, irregular) and whether the paper's model applies.
    trajectory : Trajectory or None
        ``time_response``: the simulated motion (:func:`dfloop.impact.kernel.simulate`), drawn with its velocity
        jumps at the impacts unbridged.
    """

    amplitude: float
    value: float | None
    x: np.ndarray
    y: np.ndarray
    ok: np.ndarray
    omega: float | None = None
    note: str = ""
    trajectory: Any = field(default=None, compare=False)

    def __repr__(self) -> str:
        return (f"Curve(amplitude={self.amplitude:g}, value={self.value}, omega={self.omega}, points={self.x.size}, "
                f"trusted={int(np.count_nonzero(self.ok))}{', ' + self.note if self.note else ''})")


@dataclass(repr=False)
class FigureData:
    """The numbers of a ``[figure]`` and how to draw them (``plot``)."""

    kind: str
    title: str
    parameter: str | None
    curves: list[Curve] = field(default_factory=list)
    input_name: str = "A"
    input_unit: str = ""
    simulations: int = 0

    def plot(self, ax=None) -> Any:
        """Draw the figure with :func:`dfloop.plot.study.plot_element_study`; ``ax`` is an axes (nyquist,
        collisions), two axes (loglog) or a 2-D array of axes (time_response: rows = frequencies, columns =
        parameter values). Returns a :class:`control.ControlPlot`."""
        from dfloop.plot.study import plot_element_study

        return plot_element_study(self, ax)

    def __repr__(self) -> str:
        body = "\n".join("  " + repr(c) for c in self.curves)
        sims = f", table samples computed={self.simulations}" if self.simulations else ""
        return f"FigureData(kind={self.kind!r}, title={self.title!r}, curves={len(self.curves)}{sims})\n{body}"


# -------------------------------------------------------------------------------------------- computing
def _elements(scene, spec) -> list[tuple[float | None, Any]]:
    """(value, element) per curve family: the scene's element, or one per value of the figure's parameter."""
    from .load import SceneLoop

    if spec.parameter is None:
        return [(None, scene.element)]
    try:
        loop_at = SceneLoop(scene.data, spec.parameter, scene.source)
    except SceneError as err:
        raise SceneError(scene.source, [Problem("figure.parameter", p.message, p.suggestion, p.expected)
                                        for p in err.problems]) from None
    return [(float(v), loop_at(v)[1]) for v in spec.values]


_IMPACT_SYSTEM = ("m1", "m2", "h", "restitution", "effects")  # what the impact kinds simulate with


def _impact_element(scene, spec, element) -> Any:
    """The element, when it describes the two-mass impact system (it carries masses m1, m2 in kg, clearance h
    in m, restitution and effects: the dynamic backlash); no switch on its type, so any element that carries
    these parameters can be studied."""
    missing = [name for name in _IMPACT_SYSTEM if not hasattr(element, name)]
    if missing:
        raise SceneError(scene.source, Problem("figure.kind", f"kind = {spec.kind!r} simulates the "
                                               f"two-mass impact system: the element must carry its parameters "
                                               f"({', '.join(_IMPACT_SYSTEM)}; e.g. DynamicBacklash), "
                                               f"{type(element).__name__} has no {', '.join(missing)}"))
    return element


def _lower_limit_note(element, F: float, w: float) -> str:
    from dfloop.impact.limits import lower_limit_frequency

    wc = float(lower_limit_frequency(F, element.m2, element.h, element.restitution))
    return f"model not applicable (paper): w < w_c = {wc:.1f} rad/s" if w < wc else ""


def _loci(scene, spec, elements) -> list[Curve]:
    from dfloop.describing.base import negative_inverse

    w = np.geomspace(spec.omega[0], spec.omega[1], spec.points)
    curves = []
    for value, element in elements:
        for A in spec.amplitudes:
            own = getattr(element, "negative_inverse", None)
            z = own(A, w) if own is not None else negative_inverse(element, A, w)
            ok = np.asarray(element.validity(A, w), bool)
            keep = np.isfinite(z)
            # untrusted values far beyond every trusted one (dynamic backlash grazing just below w_L, where
            # N -> 0 and the motion has not settled) would set the axes alone: left out, and counted
            reach = 2.0 * np.abs(z[keep & ok]).max(initial=0.0)
            far = keep & ~ok & (np.abs(z) > reach) if reach > 0 else np.zeros_like(keep)
            keep &= ~far
            note = f"{int(far.sum())} untrusted points beyond twice the trusted range left out" if far.any() else ""
            curves.append(Curve(A, value, w[keep], z[keep], ok[keep], note=note))
    return curves


def _time_responses(scene, spec, elements) -> list[Curve]:
    from dfloop.impact.extract import describing_function_from_trajectory
    from dfloop.impact.kernel import simulate

    curves = []
    for w in spec.frequencies:
        for value, element in elements:
            el = _impact_element(scene, spec, element)
            for F in spec.amplitudes:
                tp = 2.0 * math.pi / w
                t_a, t_b = spec.transient_periods * tp, (spec.transient_periods + spec.periods) * tp
                traj = simulate(el.m1, el.m2, el.h, el.restitution, F, w, t_b, effects=el.effects)
                t = np.linspace(t_a, t_b, SAMPLES_PER_PERIOD * spec.periods + 1)
                df = describing_function_from_trajectory(traj, spec.transient_periods, spec.periods)
                motion = (f"period {df.period}" if df.regular else "irregular") + f", {df.n_impacts} impacts"
                if spec.transient_periods == 0:
                    motion = "from rest, " + motion
                limit = _lower_limit_note(el, F, w) if spec.mark_lower_limit else ""
                curves.append(Curve(F, value, t, traj.evaluate(t)["v1"], np.full(t.size, df.regular), w,
                                    "; ".join(s for s in (motion, limit) if s), traj))
    return curves


def _collisions(scene, spec, elements) -> list[Curve]:
    from dfloop.impact.extract import impact_describing_function_batch

    w = np.geomspace(spec.omega[0], spec.omega[1], spec.points)
    curves = []
    for value, element in elements:
        el = _impact_element(scene, spec, element)
        for F in spec.amplitudes:
            batch = impact_describing_function_batch(el.m1, el.m2, el.h, el.restitution, F, w, effects=el.effects,
                                                     transient_periods=spec.transient_periods,
                                                     periods=spec.periods)
            curves.append(Curve(F, value, w, batch.max_run_A.astype(float), batch.regular))
    return curves


def figure_spec(scene) -> Any:
    """The scene's validated ``[figure]`` section (:class:`dfloop.scene.schema.Figure`), or None."""
    from .schema import validate_scene

    model, problems = validate_scene(scene.data)
    if problems:
        raise SceneError(scene.source, problems)
    return model.figure


def figure_data(scene) -> FigureData:
    """Compute the numbers of a scene's ``[figure]`` (the scene must have one).

    Raises
    ------
    SceneError
        The figure's parameter is not a number of the scene, or a kind that simulates the impact system is
        asked of another element.
    """
    spec = figure_spec(scene)
    if spec is None:
        raise ValueError(f"scene {scene.name!r} has no [figure] section")
    elements = _elements(scene, spec)
    compute = {"nyquist": _loci, "loglog": _loci, "time_response": _time_responses, "collisions": _collisions}
    curves = compute[spec.kind](scene, spec, elements)
    simulations = sum(getattr(el, "n_simulations", 0) for _, el in elements)  # tables built for this figure
    return FigureData(spec.kind, scene.title, spec.parameter, curves, getattr(scene.element, "input_name", "A"),
                      getattr(scene.element, "input_unit", ""), simulations)
