"""Loading scenes: find the file (a path, or the name of a shipped scene), parse, validate, build the loop."""
from __future__ import annotations

import copy
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .elements import build, check_parameter_path, element_problems, table_defaults
from .errors import Problem, SceneError, closest
from .plant import make_plant, series
from .schema import Sweep, SweepRange, validate_scene

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["Scene", "SceneLoop", "ChartLoop", "load_scene", "find_scene", "shipped_scenes", "read_toml", "TableProgress"]


# ------------------------------------------------------------------------------------------- finding files
def _models_dir() -> Path | None:
    """The shipped scenes: ``dfloop/models`` in an installed package, ``models/`` beside it in a checkout."""
    package = Path(__file__).resolve().parents[1]
    for candidate in (package / "models", package.parent / "models"):
        if candidate.is_dir():
            return candidate
    return None


def shipped_scenes() -> dict[str, Path]:
    """The scenes shipped with dfloop, by name (file stem), sorted."""
    folder = _models_dir()
    return {} if folder is None else {p.stem: p for p in sorted(folder.glob("*.toml"))}


def find_scene(name: str | Path) -> Path:
    """The scene file ``name`` names: an existing path, else a shipped scene (``backlash_servo`` or
    ``backlash_servo.toml``).

    Raises
    ------
    SceneError
        Neither exists; the message lists the shipped scenes and the closest name.
    """
    path = Path(name)
    if path.is_file():
        return path
    shipped = shipped_scenes()
    stem = path.name[:-5] if path.name.endswith(".toml") else path.name
    if path.parent == Path(".") and stem in shipped:
        return shipped[stem]
    raise SceneError(path, Problem("", "scene file not found, and no shipped scene has this name",
                                   closest(stem, shipped), "a .toml path or one of " + ", ".join(shipped)))


def read_toml(path: Path) -> dict:
    """Parse a TOML file; a syntax error becomes a :class:`SceneError` naming the file and the line."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise SceneError(path, Problem("", f"invalid TOML: {err}")) from None
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(path, Problem("", f"cannot read the file: {err}")) from None


# ----------------------------------------------------------------------------------------- building loops
class TableProgress:
    """A table build's progress callback ``(n_samples, stage)`` shown through :func:`dfloop.progress.progress_bar`
    (tqdm on a terminal, plain lines otherwise); one bar per build or extension, closed at stage ``"done"``."""

    def __init__(self, label: str):
        self.label = label
        self._bar = None
        self._n = 0

    def __call__(self, n: int, stage: str) -> None:
        from dfloop.progress import progress_bar

        if self._bar is None:
            self._bar = progress_bar(self.label, None, enabled=True).__enter__()
        self._bar.update(max(int(n) - self._n, 0), stage=stage)
        self._n = int(n)
        if stage == "done":
            self._bar.close()
            self._bar = None


def _loop(data: dict, element_extra: dict | None = None) -> tuple[Any, Any]:
    """(G, N) of validated scene data: controller * plant, and the element."""
    model, problems = validate_scene(data)
    if problems:
        raise SceneError(None, problems)
    plant = make_plant(model.plant, ("plant",))
    if model.controller is not None:
        plant = series(make_plant(model.controller, ("controller",)), plant)
    return plant, build(data["element"], ("element",), element_extra)


def _set_path(data: dict, path: str, value: float) -> dict:
    """A deep copy of ``data`` with the number at the dotted ``path`` replaced by ``value``."""
    data = copy.deepcopy(data)
    *parents, last = path.split(".")
    node: Any = data
    for part in parents:
        node = node[int(part)] if isinstance(node, list) else node[part]
    key: Any = int(last) if isinstance(node, list) else last
    old = node[key] if isinstance(node, list) or key in node else table_defaults(node)[key]
    value = float(value)
    node[key] = int(value) if isinstance(old, int) and not isinstance(old, bool) and value.is_integer() else value
    return data


class SceneLoop:
    """``loop_at(value) -> (G, N)``: a scene's loop rebuilt with one parameter replaced.

    The parameter is a dotted path into the scene (``"element.h"``, ``"plant.num.0"``,
    ``"element.effects.0.c"``). Holds only the scene's data, so it pickles (executors send it to workers).
    """

    def __init__(self, data: dict, parameter: str, source: Path | None = None):
        problems = check_parameter_path(data, parameter)
        if problems:
            raise SceneError(source, problems)
        self.data, self.parameter, self.source = data, parameter, source

    def __call__(self, value: float) -> tuple[Any, Any]:
        try:
            return _loop(_set_path(self.data, self.parameter, value))
        except SceneError as err:
            raise SceneError(self.source, [Problem("sweep.values", f"at {self.parameter} = {value:g}: {p}")
                                           for p in err.problems]) from None

    def __repr__(self) -> str:
        return f"SceneLoop(parameter={self.parameter!r}, source={str(self.source)!r})"


class ChartLoop:
    """``loop_at(x, y) -> (G, N)``: a scene's loop rebuilt with two parameters replaced (a ``[chart]``).
    Holds only the scene's data, so it pickles."""

    def __init__(self, data: dict, x: str, y: str, source: Path | None = None):
        self.data, self.x, self.y, self.source = data, x, y, source

    def __call__(self, x: float, y: float) -> tuple[Any, Any]:
        return SceneLoop(_set_path(self.data, self.x, x), self.y, self.source)(y)

    def __repr__(self) -> str:
        return f"ChartLoop(x={self.x!r}, y={self.y!r}, source={str(self.source)!r})"


def sweep_values(spec: Sweep) -> np.ndarray:
    """The values of a ``[sweep]``: the list as given, or ``num`` values from ``start`` to ``stop``."""
    values = spec.values
    if isinstance(values, SweepRange):
        space = np.geomspace if values.scale == "log" else np.linspace
        return space(values.start, values.stop, values.num)
    return np.asarray(values, dtype=float)


# ------------------------------------------------------------------------------------------------ scenes
@dataclass(frozen=True)
class Scene:
    """A loop study: plant, element, windows and the stages to run (see :mod:`dfloop.scene`)."""

    name: str
    title: str
    plant: Any
    element: Any
    omega: tuple[float, float] | None = None
    amplitude: tuple[float, float] | None = None
    verify: bool = False
    verify_perturbation: float = 0.3
    plots: tuple[str, ...] = ("nyquist",)
    exact: bool = False
    sweep: Sweep | None = None
    loop_at: SceneLoop | None = None
    chart: Any = None
    chart_loop: ChartLoop | None = None
    reference: float = 0.0
    load: float = 0.0
    forced: Any = None
    autotune: Any = None
    source: Path | None = None
    data: dict = field(default_factory=dict, repr=False)

    @property
    def biased(self) -> bool:
        """The loop has a constant input (``[loop] reference`` or ``load`` non-zero): its cycles are biased."""
        return self.reference != 0.0 or self.load != 0.0

    @property
    def sweep_values(self) -> np.ndarray | None:
        """The swept values, or None without a ``[sweep]``."""
        return None if self.sweep is None else sweep_values(self.sweep)


def load_scene(path: str | Path, *, progress: bool = False) -> Scene:
    """Read a scene (a TOML path, or the name of a shipped scene), validate every key and build its loop.

    Parameters
    ----------
    path : str or Path
        A file, or a shipped scene's name (``dfloop list`` shows them).
    progress : bool
        Show the progress of long element builds (tables of dynamic backlash) unless the scene sets
        ``progress`` itself.

    Raises
    ------
    SceneError
        (a ValueError) naming the file and every problem: unknown sections and keys with the closest valid
        name and the expected type, wrong types, unknown element types or parameters, bad TOML with its line.
    """
    path = find_scene(path)
    data = read_toml(path)
    model, problems = validate_scene(data)
    if isinstance(data.get("element"), dict):
        problems += element_problems(data["element"], ("element",))
    if model is not None and model.sweep is not None:
        problems += check_parameter_path(data, model.sweep.parameter)
    if model is not None and model.chart is not None:
        for axis in ("x_axis", "y_axis"):
            problems += [Problem(f"chart.{axis}.parameter", p.message, p.suggestion, p.expected)
                         for p in check_parameter_path(data, getattr(model.chart, axis).parameter)]
    if model is not None and model.loop is not None and (model.loop.reference or model.loop.load) \
            and model.analysis.amplitude is None and model.analysis.predict:
        problems.append(Problem("analysis.amplitude", "a constant input ([loop] reference / load) needs the amplitude "
                                "window of the biased solver", None, "[lo, hi]"))
    if problems:
        raise SceneError(path, problems)
    name = model.scene.name or path.stem
    # progress=False silences the element's own bar too (the CLI's --quiet, and quiet library use)
    extra = {"progress": TableProgress(f"{name}: {data['element']['type']} table") if progress else False}
    try:
        plant, element = _loop(data, extra)
        loop_at = None
        if model.sweep is not None:
            loop_at = SceneLoop(data, model.sweep.parameter, path)
            for value in sweep_values(model.sweep):  # every swept loop must build: bad values fail here, not later
                loop_at(value)
        chart_loop = None
        if model.chart is not None:
            cx, cy = model.chart.x_axis, model.chart.y_axis
            chart_loop = ChartLoop(data, cx.parameter, cy.parameter, path)
            for x in (cx.start, cx.stop):  # the corners must build
                for y in (cy.start, cy.stop):
                    chart_loop(x, y)
    except SceneError as err:
        raise err.in_file(path) from None
    if model.autotune is not None and type(element).__name__ != "Relay":
        raise SceneError(path, Problem("autotune", f"the relay experiment needs the element to be a Relay; got "
                                       f"{type(element).__name__}"))
    analysis = model.analysis
    if analysis.verify:
        try:
            element.time_model(1.0)
        except NotImplementedError:
            raise SceneError(path, Problem("analysis.verify", f"{type(element).__name__} has no time-domain "
                                           "operator, so the closed-loop verification cannot run")) from None
    return Scene(
        name=name,
        title=model.scene.title or name,
        plant=plant,
        element=element,
        omega=None if analysis.omega is None else tuple(analysis.omega),
        amplitude=None if analysis.amplitude is None else tuple(analysis.amplitude),
        verify=analysis.verify,
        verify_perturbation=analysis.verify_perturbation,
        plots=tuple(analysis.plots),
        exact=analysis.exact,
        sweep=model.sweep,
        loop_at=loop_at,
        chart=model.chart,
        chart_loop=chart_loop,
        reference=0.0 if model.loop is None else model.loop.reference,
        load=0.0 if model.loop is None else model.loop.load,
        forced=model.forced,
        autotune=model.autotune,
        source=path,
        data=data,
    )
