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
    """

    amplitude: float
    value: float | None
    x: np.ndarray
    y: np.ndarray
    ok: np.ndarray
    omega: float | None = None
    note: str = ""

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

    @property
    def z_unit(self) -> str:
        """Unit of -1/N: the input's unit per metre for backlash with masses (N/m), else empty."""
        return " (N/m)" if self.input_unit == "N" else ""

    def label(self, curve: Curve) -> str:
        """Legend entry of a curve: the parameter's value and the amplitude with its name and unit."""
        parts = [] if self.parameter is None else [f"{self.parameter.rsplit('.', 1)[-1]}={curve.value:g}"]
        parts.append(f"{self.input_name}={curve.amplitude:g}{' ' + self.input_unit if self.input_unit else ''}")
        return ", ".join(parts)

    def plot(self, ax=None) -> Any:
        """Draw the figure; ``ax`` is an axes (nyquist, collisions), two axes (loglog) or a 2-D array of axes
        (time_response: rows = frequencies, columns = parameter values). Returns the axes drawn."""
        import matplotlib.pyplot as plt

        return {"nyquist": _plot_nyquist, "loglog": _plot_loglog, "time_response": _plot_time,
                "collisions": _plot_collisions}[self.kind](self, ax, plt)

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


def _impact_element(scene, spec, element) -> Any:
    from dfloop.impact.dynamic_backlash import DynamicBacklash

    if not isinstance(element, DynamicBacklash):
        raise SceneError(scene.source, Problem("figure.kind", f"kind = {spec.kind!r} simulates the "
                                               f"two-mass impact system: the element must be DynamicBacklash, "
                                               f"got {type(element).__name__}"))
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
                                    "; ".join(s for s in (motion, limit) if s)))
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


# --------------------------------------------------------------------------------------------- drawing
def _colors(plt, n: int):
    return plt.cm.viridis(np.linspace(0.0, 0.9, max(n, 1)))


def _plot_nyquist(data: FigureData, ax, plt):
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 6))
    for curve, color in zip(data.curves, _colors(plt, len(data.curves))):
        z = curve.y
        ax.plot(np.where(curve.ok, z.real, np.nan), np.where(curve.ok, z.imag, np.nan), color=color, lw=1.0,
                label=data.label(curve))
        ax.plot(z.real[~curve.ok], z.imag[~curve.ok], ".", color=color, ms=1.5, alpha=0.35)
    ax.set_xlabel("Re{-1/N}" + data.z_unit)
    ax.set_ylabel("Im{-1/N}" + data.z_unit)
    ax.set_title(data.title + "\n(dots: irregular motion, N is an average)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6, ncol=2 if len(data.curves) > 8 else 1)
    return ax


def _plot_loglog(data: FigureData, ax, plt):
    if ax is None:
        _, ax = plt.subplots(1, 2, figsize=(12, 5))
    for curve, color in zip(data.curves, _colors(plt, len(data.curves))):
        for a, part in zip(ax, (curve.y.real, curve.y.imag)):
            a.loglog(curve.x, np.where(curve.ok, np.abs(part), np.nan), color=color, lw=1.0,
                     label=data.label(curve))
            a.loglog(curve.x[~curve.ok], np.abs(part[~curve.ok]), ".", color=color, ms=1.5, alpha=0.35)
    for a, name in zip(ax, ("|Re{-1/N}|", "|Im{-1/N}|")):
        a.set_xlabel("omega (rad/s)")
        a.set_ylabel(name + data.z_unit)
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=6)
    ax[0].figure.suptitle(data.title, fontsize=10)
    return ax


def _plot_time(data: FigureData, ax, plt):
    frequencies = list(dict.fromkeys(c.omega for c in data.curves))
    values = list(dict.fromkeys(c.value for c in data.curves))
    if ax is None:
        _, ax = plt.subplots(len(frequencies), len(values), squeeze=False, sharex="row",
                             figsize=(4.2 * len(values), 2.6 * len(frequencies) + 0.6))
    for curve in data.curves:
        a = ax[frequencies.index(curve.omega), values.index(curve.value)]
        a.plot(curve.x, curve.y, lw=0.8, label=data.label(curve))
        head = f"w={curve.omega:g} rad/s" + ("" if data.parameter is None else
                                             f", {data.parameter.rsplit('.', 1)[-1]}={curve.value:g}")
        a.set_title(head + "\n" + curve.note, fontsize=7, color="firebrick" if "not applicable" in curve.note
                    else "black")
        a.set_xlabel("t (s)", fontsize=8)
        a.set_ylabel("dx1/dt (m/s)", fontsize=8)
        a.tick_params(labelsize=7)
        a.grid(True, alpha=0.3)
    ax.flat[0].figure.suptitle(data.title, fontsize=10)
    ax.flat[0].figure.tight_layout()
    return ax


def _plot_collisions(data: FigureData, ax, plt):
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 5))
    for curve, color in zip(data.curves, _colors(plt, len(data.curves))):
        ax.semilogx(curve.x, curve.y, "-", color=color, lw=0.8, label=data.label(curve))
        ax.semilogx(curve.x[~curve.ok], curve.y[~curve.ok], "x", color=color, ms=3)
    ax.set_xlabel("omega (rad/s)")
    ax.set_ylabel("n_A: longest run of consecutive impacts on side A")
    ax.set_title(data.title + "\n(x: irregular motion)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    return ax
