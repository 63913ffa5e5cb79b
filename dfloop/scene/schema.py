"""The scene-file schema: pydantic models of every section, and their errors translated into scene terms.

Why pydantic: it is already a dependency, its v2 core validates strictly (``verify = "false"`` is a type error,
not a truthy string), forbids unknown keys, and reports every error with its location, which is exactly what a
scene needs; the field descriptions below double as the reference page (:mod:`dfloop.scene.reference`).

The ``[element]`` table is checked here only for being a table: its keys depend on its ``type`` and are checked
against the element's constructor in :mod:`dfloop.scene.elements`.
"""
from __future__ import annotations

import types
import typing
from functools import lru_cache
from typing import Annotated, Any, Literal, Union

from pydantic import (AfterValidator, BaseModel, ConfigDict, Discriminator, Field, Tag, TypeAdapter, ValidationError,
                      model_validator)

from .errors import Problem, closest, dotted, validator_message

__all__ = ["SceneFile", "SceneMeta", "TfPlant", "ZpkPlant", "SsPlant", "Analysis", "Sweep", "SweepRange", "Chart", "ChartAxis",
           "Figure", "Loop", "Forced",
           "Autotune", "validate_scene", "validate_plant", "type_name", "PLANT_TYPES", "FIGURE_KINDS"]

MAX_SWEEP_VALUES = 100_000
MAX_FIGURE_POINTS = 5_000
FIGURE_KINDS = ("nyquist", "loglog", "time_response", "collisions")


class _Table(BaseModel):
    # defer_build: the validators are compiled on first use, not when dfloop.scene is imported
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False, defer_build=True)


class _WindowName(str):
    """Marks the window type for :func:`type_name`."""


def _ordered(window: list[float]) -> list[float]:
    if not 0 < window[0] < window[1]:
        raise ValueError(f"must be [lo, hi] with 0 < lo < hi, got {window}")
    return window


Window = Annotated[list[float], Field(min_length=2, max_length=2), AfterValidator(_ordered),
                   _WindowName("[lo, hi] with 0 < lo < hi")]


class SceneMeta(_Table):
    """Names of the study."""

    name: str | None = Field(None, description="Short name, used for output files (default: the file name).")
    title: str | None = Field(None, description="Title of the plots and the report, and the line `dfloop list` "
                                                "shows (default: the name).")


class _Plant(_Table):
    delay: float = Field(0.0, ge=0.0, description="Pure delay in seconds: the plant becomes `delayed(G, delay)`, exact in "
                                                    "prediction, exact cycles and verification; in a digital loop "
                                                    "(`dt`, or a controller with `dt`) the exact sampled map of "
                                                    "G e^{-s delay} behind the hold.")
    dt: float | None = Field(None, gt=0.0, description="Sampling period in seconds of a digital loop: the system "
                             "is sampled behind a zero-order hold (control.sample_system), or, with `discrete = "
                             "true`, its coefficients are already in powers of z. The loop then uses G(e^{jw dt}).")
    discrete: bool = Field(False, description="The coefficients (or matrices) are those of a discrete-time system in "
                           "z with sampling period `dt` (a digital controller); requires `dt`.")


class TfPlant(_Plant):
    """Transfer function num(s)/den(s), coefficients in descending powers of s."""

    type: Literal["tf"] = Field("tf", description="Transfer function (the default when `type` is absent).")
    num: list[float] = Field(min_length=1, description="Numerator coefficients, highest power first.")
    den: list[float] = Field(min_length=1, description="Denominator coefficients, highest power first.")


class ZpkPlant(_Plant):
    """Real zeros, real poles and a gain."""

    type: Literal["zpk"] = Field(description="Zeros, poles and gain.")
    zeros: list[float] = Field([], description="Zeros (real).")
    poles: list[float] = Field([], description="Poles (real).")
    gain: float = Field(description="Gain k of k prod(s - z) / prod(s - p).")


class SsPlant(_Plant):
    """State space x' = A x + B u, y = C x + D u (SISO)."""

    type: Literal["ss"] = Field(description="State space.")
    A: list[list[float]] = Field(description="State matrix, one list per row.")
    B: list[list[float]] = Field(description="Input matrix (n x 1).")
    C: list[list[float]] = Field(description="Output matrix (1 x n).")
    D: list[list[float]] = Field([[0.0]], description="Feedthrough (1 x 1).")


def _plant_tag(value: Any) -> str | None:
    if isinstance(value, dict):
        return value.get("type", "tf")
    return getattr(value, "type", None)


Plant = Annotated[Union[Annotated[TfPlant, Tag("tf")], Annotated[ZpkPlant, Tag("zpk")],
                        Annotated[SsPlant, Tag("ss")]], Discriminator(_plant_tag)]
PLANT_TYPES = {"tf": TfPlant, "zpk": ZpkPlant, "ss": SsPlant}


class Analysis(_Table):
    """Windows and the optional stages."""

    omega: Window | None = Field(None, description="Frequency window [lo, hi] in rad/s (default: automatic).")
    amplitude: Window | None = Field(None, description="Amplitude window [lo, hi] of the element's input "
                                                       "(default: automatic).")
    verify: bool = Field(False, description="Closed-loop time simulation of each predicted cycle.")
    verify_perturbation: float = Field(0.3, ge=1e-3, le=0.95, description="Relative offset of the simulation's "
                                                                         "starts inside and outside each cycle.")
    plots: list[Literal["nyquist", "residual"]] = Field(["nyquist"], description="Plots to draw.")
    exact: bool = Field(False, description="Attach the exact periodic orbit (`dfloop.exact_cycle`: shooting on "
                                           "the exact flow, Floquet multipliers) to each predicted cycle.")
    predict: bool = Field(True, description="Predict the loop's limit cycles; false for a study of the element "
                                            "alone (a `[figure]`), which then skips prediction, verification "
                                            "and plots.")

    @model_validator(mode="after")
    def _stages_need_prediction(self) -> "Analysis":
        if not self.predict:
            asked = [k for k in ("verify", "exact", "plots") if k in self.model_fields_set and getattr(self, k)]
            if asked:
                raise ValueError(f"{', '.join(asked)} need predict = true (with predict = false there are no "
                                 f"cycles: use plots = [] and leave verify and exact out)")
        return self


class SweepRange(_Table):
    """Evenly spaced values, on a linear or a logarithmic scale (both ends included)."""

    start: float = Field(description="First value.")
    stop: float = Field(description="Last value.")
    num: int = Field(ge=2, le=MAX_SWEEP_VALUES, description="Number of values.")
    scale: Literal["linear", "log"] = Field("linear", description="Spacing.")

    @model_validator(mode="after")
    def _positive_log(self) -> "SweepRange":
        if self.scale == "log" and not (self.start > 0 and self.stop > 0):
            raise ValueError(f"a log scale needs start > 0 and stop > 0, got start={self.start}, stop={self.stop}")
        if self.start == self.stop:
            raise ValueError(f"start and stop must differ, got {self.start}")
        return self


def _values_tag(value: Any) -> str | None:
    return "list" if isinstance(value, list) else "range" if isinstance(value, (dict, SweepRange)) else None


class Sweep(_Table):
    """A parameter sweep that follows each cycle from value to value."""

    parameter: str = Field(description='Dotted path of a number in the scene, e.g. "element.h", '
                                       '"plant.num.0", "element.restitution", "element.effects.0.c".')
    values: Annotated[Union[Annotated[list[float], Tag("list"), Field(min_length=2, max_length=MAX_SWEEP_VALUES)],
                            Annotated[SweepRange, Tag("range")]], Discriminator(_values_tag)] = Field(
        description="The values: a list, or a table {start, stop, num, scale}.")
    csv: bool = Field(True, description="Write the branches to <name>_sweep.csv.")
    name: str | None = Field(None, description='Name of the parameter in the report, the CSV header and the axes, '
                                               'e.g. "gain K" (default: derived from the path: "gain K" for a '
                                               'one-coefficient numerator, "delay T" for a delay, "clearance h" '
                                               'for a backlash h, else the path).')
    unit: str | None = Field(None, description='Unit of the parameter, e.g. "m" (default: derived from the path: '
                                               '"s" for a delay, the element\'s input unit for its thresholds).')
    nominal: float | None = Field(None, description="The design value the limit-cycle margins are measured from "
                                                    "(default: the value in the scene at `parameter`).")


class ChartAxis(_Table):
    """One axis of a design chart: a parameter of the scene, its range, name and unit."""

    parameter: str = Field(description='Dotted path of a number in the scene, e.g. "plant.num.0", "plant.delay".')
    start: float = Field(description="First value.")
    stop: float = Field(description="Last value (!= start).")
    scale: Literal["linear", "log"] = Field("linear", description="Spacing of the chart's samples and plot axis.")
    name: str | None = Field(None, description="Name in the report, the CSV and the axes (default: derived "
                                               "from the path, as for `[sweep]`).")
    unit: str | None = Field(None, description="Unit (default: derived from the path).")
    nominal: float | None = Field(None, description="Design value (default: the value in the scene).")

    @model_validator(mode="after")
    def _range(self) -> "ChartAxis":
        if self.start == self.stop:
            raise ValueError(f"start and stop must differ, got {self.start}")
        if self.scale == "log" and not (self.start > 0 and self.stop > 0):
            raise ValueError(f"a log scale needs start > 0 and stop > 0, got start={self.start}, stop={self.stop}")
        return self


class Chart(_Table):
    """A two-parameter design chart: where the loop has no cycle, a stable cycle, only unstable cycles or
    several, with the boundaries traced as curves (births, folds, stability changes)."""

    x_axis: ChartAxis = Field(description="Horizontal axis: `{parameter, start, stop, scale, name, unit, "
                                          "nominal}`.")
    y_axis: ChartAxis = Field(description="Vertical axis: the same keys.")
    samples: int = Field(13, ge=3, le=200, description="Region samples per axis (predict_limit_cycles at each); "
                                                       "the boundaries are traced, not sampled.")
    resolution: int = Field(100, ge=10, le=2000, description="Equivalent resolution per axis: the boundary "
                                                             "curves' steps and the filled plot's grid.")
    csv: bool = Field(True, description="Write the boundary curves to <name>_chart.csv and the region samples "
                                        "to <name>_chart_regions.csv.")
    exact: bool = Field(False, description="Also look for the exact periodic orbits (`dfloop.exact_cycle`) at "
                                           "every sample and mark where they put it in another region than the "
                                           "DF (python-control plants without delay).")


class Figure(_Table):
    """A figure of the element alone: its -1/N loci, or (dynamic backlash) the forced motion's time responses
    and collision runs, for several input amplitudes and values of one parameter."""

    kind: Literal["nyquist", "loglog", "time_response", "collisions"] = Field(
        description="nyquist: -1/N(A, w) in the complex plane; loglog: |Re{-1/N}| and |Im{-1/N}| vs w; "
                    "time_response: dx1/dt of the forced two-mass motion at each of `frequencies` "
                    "(DynamicBacklash only); collisions: longest run of consecutive impacts on side A (n_A) vs w "
                    "(DynamicBacklash only).")
    amplitudes: list[float] = Field(min_length=1, max_length=50, description="Input amplitudes A of the element "
                                                                            "(the force F in N for backlash "
                                                                            "with masses), each > 0.")
    parameter: str | None = Field(None, description='Optional dotted path of a number in the scene varied from '
                                                    'curve to curve, e.g. "element.restitution".')
    values: list[float] = Field([], max_length=50, description="The values of `parameter` (required with it).")
    omega: Window | None = Field(None, description="Frequency window [lo, hi] in rad/s of the nyquist, loglog "
                                                   "and collisions kinds (required for them).")
    points: int = Field(400, ge=10, le=MAX_FIGURE_POINTS, description="Frequencies, log-spaced over `omega`.")
    frequencies: list[float] = Field([], max_length=20, description="Forcing frequencies (rad/s) of "
                                                                    "time_response, one panel row each "
                                                                    "(required for it).")
    periods: int = Field(10, ge=1, le=1000, description="Forcing periods shown by time_response (the time axis "
                                                       "of a panel), and simulated after the transient by "
                                                       "collisions.")
    transient_periods: int = Field(0, ge=0, le=10_000, description="Forcing periods simulated before the window "
                                                                  "(time_response shows the motion from rest "
                                                                  "when 0).")
    mark_lower_limit: bool = Field(True, description="time_response: mark the panels where w is below the "
                                                     "paper's lower limit w_c of eq. (10), where it says the "
                                                     "model does not apply.")

    @model_validator(mode="after")
    def _consistent(self) -> "Figure":
        if any(a <= 0 for a in self.amplitudes):
            raise ValueError(f"amplitudes must all be > 0, got {self.amplitudes}")
        if (self.parameter is None) != (not self.values):
            raise ValueError("parameter and values go together: give both or neither")
        if self.kind == "time_response":
            if not self.frequencies or any(w <= 0 for w in self.frequencies):
                raise ValueError(f"kind = 'time_response' needs frequencies, all > 0, got {self.frequencies}")
        elif self.omega is None:
            raise ValueError(f"kind = {self.kind!r} needs omega = [lo, hi]")
        return self


class Loop(_Table):
    """The loop's constant input: a reference at the summing junction and a load at the element's output."""

    reference: float = Field(0.0, description="Constant r0 at the summing junction (element input units; e = r0 - "
                                              "y). Non-zero (or a load): the prediction stage predicts biased "
                                              "cycles e ~ B + A sin(w t) (`dfloop.biased.biased_cycles`, each with "
                                              "its exact orbit when `[analysis] exact = true`).")
    load: float = Field(0.0, description="Constant added to the element's output before the plant (element "
                                         "output units: a load torque, gravity).")


class Forced(_Table):
    """The loop's response to a sinusoidal reference r = R sin(w t): DF solutions, jumps, exact orbits."""

    forcing: float = Field(gt=0, description="Forcing amplitude R at the summing junction (element input units).")
    omega: Window = Field(description="Frequency range [lo, hi] in rad/s of the response.")
    num: int = Field(101, ge=2, le=MAX_FIGURE_POINTS, description="Frequencies, evenly spaced over `omega` (jumps "
                                                                 "are located between them to rounding).")
    amplitude: Window | None = Field(None, description="Amplitude window of the element's input (default: "
                                                       "`[analysis] amplitude`, else [1e-3 R, 100 R] with R = `forcing`).")
    exact: bool = Field(True, description="The exact orbit at the forcing period next to the DF solutions "
                                          "(`dfloop.hybrid.forced.exact_forced_response`): stability by "
                                          "multipliers, subharmonic / quasi-periodic responses marked.")
    every: int = Field(4, ge=1, description="Exact orbits at every `every`-th frequency.")
    region: list[Annotated[float, Field(gt=0)]] | None = Field(
        None, min_length=1, max_length=MAX_FIGURE_POINTS,
        description="Forcing amplitudes at which to locate the jumps: the jump-resonance region, plotted in the "
                    "(frequency, forcing amplitude) plane (`dfloop.solve.forced.jump_region`).")


class Autotune(_Table):
    """The relay experiment of relay-feedback auto-tuning on the scene's plant, with the scene's element (a
    `Relay`) as the relay: the DF and exact estimates of the ultimate point, PID tunings checked on the plant, and
    optionally the FOPDT/SOPDT fit of a recorded experiment (docs/autotune.md)."""

    rules: list[Literal["zn-p", "zn-pi", "zn-pid", "simc-pi", "simc-pid", "amigo-pi", "amigo-pid"]] = Field(
        ["zn-pid", "amigo-pid"], min_length=1, description="Tuning rules; `zn-*` use the ultimate point, the others "
                                                           "a process model (the fit, or the plant when it is one).")
    bias: float = Field(0.0, description="Relay output offset (levels bias +- M, |bias| < M): the experiment then "
                                         "also estimates the static gain (first- or second-order plants).")
    record: str | None = Field(None, description="A recorded relay experiment (CSV `t,u,y`, path relative to the "
                                                 "scene) to fit; its model then feeds the rules.")
    model: Literal["FOPDT", "SOPDT"] = Field("FOPDT", description="Model structure fitted to `record`.")
    t_end: float = Field(100.0, gt=0.0, description="Length (s) of the closed-loop step response of each check.")


class SceneFile(_Table):
    """A whole scene file."""

    scene: SceneMeta = Field(default_factory=SceneMeta, description="Names of the study.")
    plant: Plant = Field(description="The linear part G seen by the element (after the controller, if any).")
    controller: Plant | None = Field(None, description="Optional controller C: the loop is C * plant.")
    element: dict[str, Any] = Field(description="The nonlinear element: `type` names a describing-function "
                                                "class, the other keys are its parameters (see below).")
    analysis: Analysis = Field(default_factory=Analysis, description="Windows and the optional stages.")
    sweep: Sweep | None = Field(None, description="A parameter sweep (continuation of every cycle).")
    chart: Chart | None = Field(None, description="A two-parameter design chart (regions and traced boundaries).")
    figure: Figure | None = Field(None, description="A figure of the element alone: its -1/N loci, or (dynamic "
                                                    "backlash) the forced motion's time responses and collision "
                                                    "runs, for several input amplitudes and values of one "
                                                    "parameter.")
    loop: Loop | None = Field(None, description="The loop's constant input (reference, load).")
    forced: Forced | None = Field(None, description="The forced response to r = R sin(w t), its jumps and the "
                                                    "jump-resonance region.")
    autotune: Autotune | None = Field(None, description="The relay experiment and PID tuning (the element must be "
                                                        "a `Relay`).")


# ---------------------------------------------------------------------------------------------- type names
def _unwrap(annotation: Any) -> Any:
    """The type inside ``Annotated[...]`` layers."""
    while typing.get_origin(annotation) is Annotated:
        annotation = typing.get_args(annotation)[0]
    return annotation


def type_name(annotation: Any) -> str:
    """A short, readable name of a type annotation: ``float``, ``list of float``, ``'tf' | 'zpk'``, ``table``."""
    if typing.get_origin(annotation) is Annotated:
        names = [m for m in annotation.__metadata__ if isinstance(m, _WindowName)]
        if names:
            return str(names[0])
    annotation = _unwrap(annotation)
    origin = typing.get_origin(annotation)
    if annotation is Any:
        return "any"
    if origin is Literal:
        return " | ".join(repr(v) for v in typing.get_args(annotation))
    if origin in (Union, types.UnionType):
        parts = [type_name(a) for a in typing.get_args(annotation) if a is not type(None)]
        if not parts:
            return "none"
        return " or ".join(dict.fromkeys(parts))
    if origin in (list, tuple):
        args = typing.get_args(annotation)
        return f"list of {type_name(args[0])}" if args else "list"
    if origin is dict or annotation is dict:
        return "table"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "table"
    if isinstance(annotation, type):
        return {"float": "number (float)", "int": "integer", "str": "string", "bool": "bool (true/false)"}.get(
            annotation.__name__, annotation.__name__)
    return str(annotation)


# ---------------------------------------------------------------------------------- errors in scene terms
def _variants(annotation: Any) -> dict[str, Any]:
    """The variants of a tagged union, keyed by tag (empty for any other annotation)."""
    found: dict[str, Any] = {}
    for arg in typing.get_args(_unwrap(annotation)):
        if typing.get_origin(arg) is Annotated:
            tag = next((m.tag for m in arg.__metadata__ if isinstance(m, Tag)), None)
            if tag is not None:
                found[tag] = _unwrap(arg)
        found.update(_variants(arg))
    return found


def model_of(annotation: Any) -> type[BaseModel] | None:
    """The one model an annotation holds (``M``, ``M | None``), or None."""
    annotation = _unwrap(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    models = [m for m in map(model_of, typing.get_args(annotation)) if m is not None]
    return models[0] if len(models) == 1 and not _variants(annotation) else None


def _resolve(loc: tuple) -> tuple[type[BaseModel] | None, Any, tuple]:
    """Walk a pydantic error location: (model reached, FieldInfo of the last key, the location without tags)."""
    model: type[BaseModel] | None = SceneFile
    field, variants, clean = None, {}, []
    for part in loc:
        if isinstance(part, str) and part in variants:  # a union tag, not a key
            model, variants = model_of(variants[part]), {}
            continue
        clean.append(part)
        if isinstance(part, int):  # a list index: still inside the same field
            continue
        if model is None or part not in model.model_fields:
            return model, None, tuple(clean)
        field = model.model_fields[part]
        variants = _variants(field.annotation)
        model = model_of(field.annotation)
    return model, field, tuple(clean)


def _problem(error: dict) -> Problem:
    loc = tuple(error["loc"])
    kind = error["type"]
    value = error.get("input")
    if kind == "extra_forbidden":
        parent, _, clean = _resolve(loc[:-1])
        key = dotted(clean + (loc[-1],))
        valid = list(parent.model_fields) if parent is not None else []
        guess = closest(loc[-1], valid)
        expected = type_name(parent.model_fields[guess].annotation) if guess else "one of " + ", ".join(valid)
        what = "unknown section" if len(clean) == 0 else "unknown key"
        return Problem(key, what, guess, expected)
    parent, field, clean = _resolve(loc)
    key = dotted(clean)
    expected = type_name(field.annotation) if field is not None else None
    if kind == "missing":
        return Problem(key, "missing required " + ("section" if len(clean) == 1 else "key"), None, expected)
    if kind == "union_tag_invalid":
        tags = list(_variants(field.annotation)) if field is not None else []
        tag = error.get("ctx", {}).get("tag", value)
        return Problem(key + ".type", f"unknown type {tag!r}", closest(tag, tags),
                       " | ".join(repr(t) for t in tags))
    if kind == "literal_error":
        options = [o.strip(" '") for o in error.get("ctx", {}).get("expected", "").replace(" or ", ",").split(",")]
        return Problem(key, f"unknown value {value!r}", closest(value, [o for o in options if o]),
                       error.get("ctx", {}).get("expected"))
    if kind.endswith("_type") or kind == "union_tag_not_found":
        return Problem(key, f"wrong type: got {type(value).__name__} {value!r}", None, expected)
    if kind == "value_error":
        return Problem(key, error["msg"].removeprefix("Value error, "), None, None)
    return Problem(key, validator_message(kind, error.get("ctx"), value), None, expected)


@lru_cache(maxsize=1)
def _plant_adapter() -> TypeAdapter:
    return TypeAdapter(Plant)


def validate_plant(data: dict, loc: tuple = ("plant",)) -> tuple[TfPlant | ZpkPlant | SsPlant | None, list[Problem]]:
    """Validate a plant table found at ``loc`` (e.g. nested in an element): the model, or every problem."""
    try:
        return _plant_adapter().validate_python(data), []
    except ValidationError as err:
        problems = []
        for e in err.errors():
            problem = _problem({**e, "loc": ("plant",) + tuple(e["loc"])})
            problems.append(Problem(dotted(loc) + problem.key[len("plant"):], problem.message,
                                    problem.suggestion, problem.expected))
        return None, problems


def validate_scene(data: dict) -> tuple[SceneFile | None, list[Problem]]:
    """Validate the parsed TOML of a scene: the model, or every problem found."""
    try:
        return SceneFile.model_validate(data), []
    except ValidationError as err:
        return None, [_problem(e) for e in err.errors()]
