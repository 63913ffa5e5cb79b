"""Scene files: a loop study described in TOML, run with only the stages it asks for.

A scene names a plant, a nonlinear element (with, for dynamic backlash, the physical effects it needs), the
windows to search, and the optional stages: closed-loop verification and plots. Every ``type`` key is resolved
by one mechanism, :func:`build`, so any DF object or effect exported by dfloop can appear in a scene::

    [plant]                      # loop transfer function seen by the element: controller * plant
    type = "tf"                  # "tf" (num, den), "zpk" (zeros, poles, gain), "ss" (A, B, C, D)
    num = [5.0]
    den = [1.0, 1.0, 0.0]
    delay = 0.0                  # optional pure delay in seconds (makes G a callable G(jw))

    [element]
    type = "Backlash"            # any DescribingFunction class exported by dfloop
    h = 1.0

    [analysis]
    omega = [0.1, 10.0]          # optional windows; chosen automatically when absent
    verify = true                # closed-loop time simulation of each predicted cycle
    verify_perturbation = 0.3    # relative offset of the starts inside and outside each cycle
    plots = ["nyquist"]
"""
from __future__ import annotations

import inspect
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ._checks import in_closed_interval

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["Scene", "load_scene", "run_scene", "build", "SceneReport"]

_PLANT_KINDS = ("tf", "zpk", "ss")
_STAGES = ("nyquist", "residual")


def _registry() -> dict[str, Any]:
    """Names a scene may use as ``type``: dfloop's DF classes and impact effects."""
    import dfloop
    from dfloop.describing.base import DescribingFunction

    names: dict[str, Any] = {}
    for name in dir(dfloop):
        obj = getattr(dfloop, name)
        if isinstance(obj, type) and issubclass(obj, DescribingFunction) and not inspect.isabstract(obj):
            names[name] = obj
    try:
        from dfloop.impact import effects as effects_module
    except ImportError:  # pragma: no cover - the impact package is optional at import time
        effects_module = None
    if effects_module is not None:
        for name in getattr(effects_module, "__all__", []):
            obj = getattr(effects_module, name)
            if isinstance(obj, type) and hasattr(obj, "keeps_similarity"):
                names[name] = obj
    return names


def _plant(spec: dict[str, Any]):
    """A python-control LTI (or a callable G(jw) when a delay is given) from a plant table."""
    import control as ct

    kind = spec.get("type", "tf")
    if kind not in _PLANT_KINDS:
        raise ValueError(f"plant.type must be one of {_PLANT_KINDS}, got {kind!r}")
    try:
        if kind == "tf":
            sys_ = ct.tf(spec["num"], spec["den"])
        elif kind == "zpk":
            sys_ = ct.zpk(spec.get("zeros", []), spec.get("poles", []), spec["gain"])
        else:
            sys_ = ct.ss(spec["A"], spec["B"], spec["C"], spec["D"])
    except KeyError as err:
        raise ValueError(f"plant of type {kind!r} needs the key {err.args[0]!r}") from None
    delay = float(spec.get("delay", 0.0))
    if not np.isfinite(delay) or delay < 0:
        raise ValueError(f"plant.delay must be a finite number >= 0, got {delay}")
    if delay == 0.0:
        return sys_

    def delayed(omega, _sys=sys_, _T=delay):
        w = np.asarray(omega, dtype=float)
        return np.asarray(_sys(1j * w), dtype=complex) * np.exp(-1j * w * _T)

    delayed.__name__ = f"{kind}_with_delay_{delay:g}s"
    return delayed


def build(spec: Any, registry: dict[str, Any] | None = None) -> Any:
    """Build an object from a scene table: ``{"type": Name, **params}``, recursively.

    Nested tables with a ``type`` become objects, nested tables with ``num``/``den`` (or ``zeros``/``poles``,
    or ``A``/``B``/``C``/``D``) become python-control systems, lists are built element by element.
    """
    registry = _registry() if registry is None else registry
    if isinstance(spec, list):
        return [build(item, registry) for item in spec]
    if not isinstance(spec, dict):
        return spec
    if "type" in spec and spec["type"] in _PLANT_KINDS or "type" not in spec and ("num" in spec or "A" in spec):
        return _plant(spec)
    if "type" not in spec:
        return {key: build(value, registry) for key, value in spec.items()}
    name = spec["type"]
    if name not in registry:
        raise ValueError(f"unknown type {name!r}; known: {', '.join(sorted(registry))}")
    params = {key: build(value, registry) for key, value in spec.items() if key != "type"}
    if "effects" in params:
        params["effects"] = tuple(params["effects"])
    try:
        return registry[name](**params)
    except TypeError as err:
        raise ValueError(f"bad parameters for {name}: {err}") from None


@dataclass(frozen=True)
class Scene:
    """A loop study: plant, element, windows and the stages to run."""

    name: str
    title: str
    plant: Any
    element: Any
    omega: tuple[float, float] | None = None
    amplitude: tuple[float, float] | None = None
    verify: bool = False
    verify_perturbation: float = 0.3
    plots: tuple[str, ...] = ("nyquist",)
    source: Path | None = None


def _window(analysis: dict[str, Any], key: str) -> tuple[float, float] | None:
    if key not in analysis:
        return None
    value = analysis[key]
    if not (isinstance(value, list) and len(value) == 2):
        raise ValueError(f"analysis.{key} must be a [lo, hi] pair, got {value!r}")
    return float(value[0]), float(value[1])


def load_scene(path: str | Path) -> Scene:
    """Read a scene file (TOML) and build its plant and element."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"scene file not found: {path}")
    with path.open("rb") as handle:
        data = tomllib.load(handle)
    for table in ("plant", "element"):
        if table not in data:
            raise ValueError(f"scene {path} has no [{table}] table")
    meta = data.get("scene", {})
    analysis = data.get("analysis", {})
    plots = tuple(analysis.get("plots", ["nyquist"]))
    unknown = set(plots) - set(_STAGES)
    if unknown:
        raise ValueError(f"analysis.plots: unknown plot(s) {sorted(unknown)}; known: {list(_STAGES)}")
    plant = _plant(data["plant"])
    if "controller" in data:
        controller = _plant(data["controller"])
        if callable(plant) and not hasattr(plant, "dt"):
            raise ValueError("a [controller] cannot be combined with a delayed plant; put the delay last")
        plant = controller * plant
    element = build(data["element"])
    verify = bool(analysis.get("verify", False))
    if verify and not hasattr(element, "simulate_loop"):
        try:
            element.operator()
        except NotImplementedError:
            raise ValueError(f"analysis.verify: {type(element).__name__} has no time-domain operator, so the "
                             "closed-loop verification cannot run") from None
    return Scene(
        name=meta.get("name", path.stem),
        title=meta.get("title", path.stem),
        plant=plant,
        element=element,
        omega=_window(analysis, "omega"),
        amplitude=_window(analysis, "amplitude"),
        verify=verify,
        verify_perturbation=in_closed_interval("analysis.verify_perturbation",
                                               analysis.get("verify_perturbation", 0.3), 1e-3, 0.95),
        plots=plots,
        source=path,
    )


@dataclass
class SceneReport:
    """What a scene run produced: cycles, verifications, files, and the stages that ran with their times."""

    scene: Scene
    cycles: Any = None
    verifications: list[Any] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    stages: list[tuple[str, float]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def to_markdown(self) -> str:
        lines = [f"# {self.scene.title}", "", f"Scene `{self.scene.source}`; element `{self.scene.element!r}`.", ""]
        lines += ["## Predicted limit cycles", "", "```", repr(self.cycles), "```", ""]
        if self.verifications:
            lines += ["## Closed-loop verification", "", "```"]
            lines += [repr(v) for v in self.verifications]
            lines += ["```", ""]
        lines += ["## Stages run", "", "| stage | time (s) |", "|---|---|"]
        lines += [f"| {name} | {seconds:.3f} |" for name, seconds in self.stages]
        lines += [""] + [f"- {note}" for note in self.notes] if self.notes else []
        if self.files:
            lines += ["", "## Files", ""] + [f"- `{p.name}`" for p in self.files]
        return "\n".join(lines) + "\n"


def run_scene(scene: Scene, out_dir: str | Path = "out", log: Callable[[str], None] = print) -> SceneReport:
    """Run a scene's stages: predict cycles, verify them if asked, draw the plots asked for, write a report."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dfloop.solve import predict_limit_cycles

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    report = SceneReport(scene)

    def stage(name: str, fn: Callable[[], Any]) -> Any:
        log(f"[{scene.name}] {name} ...")
        t0 = time.perf_counter()
        result = fn()
        report.stages.append((name, time.perf_counter() - t0))
        log(f"[{scene.name}] {name} done in {report.stages[-1][1]:.2f} s")
        return result

    report.cycles = stage(
        "predict limit cycles",
        lambda: predict_limit_cycles(scene.plant, scene.element, omega=scene.omega, amplitude=scene.amplitude),
    )
    log(repr(report.cycles))
    simulations = getattr(scene.element, "n_simulations", None)
    if simulations is not None:  # tabulated elements: how much of the table this run had to simulate
        report.notes.append(f"{type(scene.element).__name__}: {simulations} motions simulated in this run "
                            f"({'table served from the cache' if simulations == 0 else 'table built and cached'})")
        log(f"[{scene.name}] {report.notes[-1]}")
    if scene.verify:
        from dfloop.verify import verify_cycle

        for cycle in report.cycles:
            report.verifications.append(
                stage(
                    f"verify cycle at w = {cycle.frequency:.4g} rad/s",
                    lambda c=cycle: verify_cycle(scene.plant, scene.element, c,
                                                 perturbation=scene.verify_perturbation),
                )
            )
            log(repr(report.verifications[-1]))
    if "nyquist" in scene.plots:
        from dfloop.plot.nyquist import plot_nyquist

        def nyquist() -> Path:
            fig, ax = plt.subplots(figsize=(6.5, 5.5))
            plot_nyquist(scene.plant, scene.element, cycles=report.cycles, ax=ax)
            ax.set_title(scene.title)
            path = out / f"{scene.name}_nyquist.png"
            fig.savefig(path, dpi=120, bbox_inches="tight")
            plt.close(fig)
            return path

        report.files.append(stage("plot nyquist", nyquist))
    if "residual" in scene.plots:
        from dfloop.plot.nyquist import plot_residual_map

        def residual() -> Path:
            fig, ax = plt.subplots(figsize=(6.5, 5.0))
            plot_residual_map(scene.plant, scene.element, cycles=report.cycles, ax=ax)
            path = out / f"{scene.name}_residual.png"
            fig.savefig(path, dpi=120, bbox_inches="tight")
            plt.close(fig)
            return path

        report.files.append(stage("plot residual map", residual))
    path = out / f"{scene.name}_report.md"
    path.write_text(report.to_markdown())
    report.files.append(path)
    log(f"[{scene.name}] report written to {path}")
    return report
