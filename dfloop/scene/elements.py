"""Elements and effects in scenes: ``{type = Name, **parameters}`` tables checked against the constructors.

Every describing-function class of :mod:`dfloop.describing` and :mod:`dfloop.impact`, and every physical effect
of :mod:`dfloop.impact.effects`, may appear as a ``type``. Its parameters are the constructor's: an unknown key
is reported with the closest valid parameter, a missing one by name, and a value of the wrong type (by the
constructor's annotation, strictly: ``true`` is not a number, ``"1.0"`` is not a float) with the expected type.
Nested tables are built recursively: ``{type = ...}`` becomes an element or effect, ``{num, den}`` (or
``zeros``/``poles``/``gain``, ``A``/``B``/``C``/``D``) a python-control system.
"""
from __future__ import annotations

import inspect
import re
import types
import typing
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Literal, Union

from pydantic import TypeAdapter, ValidationError

from .errors import Problem, SceneError, closest, dotted
from .plant import make_plant
from .schema import PLANT_TYPES, validate_plant

__all__ = ["registry", "Signature", "signature", "build", "element_problems", "table_defaults",
           "check_parameter_path"]

_SCALARS = {"float": float, "int": int, "str": str, "bool": bool, "None": type(None)}


@lru_cache(maxsize=1)
def registry() -> dict[str, type]:
    """Names a scene may use as ``type``: the concrete DF classes and the impact effects, by class name."""
    import dfloop.describing as describing
    import dfloop.impact as impact
    import dfloop.impact.effects as effects
    from dfloop.describing.base import DescribingFunction

    names: dict[str, type] = {}
    for module in (describing, impact):
        for name in module.__all__:
            obj = getattr(module, name)
            if isinstance(obj, type) and issubclass(obj, DescribingFunction) and not inspect.isabstract(obj):
                names[name] = obj
    for name in effects.__all__:
        obj = getattr(effects, name)
        if isinstance(obj, type) and hasattr(obj, "keeps_similarity"):
            names[name] = obj
    return dict(sorted(names.items()))


def _scalar_type(annotation: Any) -> Any | None:
    """The annotation as a type pydantic can check strictly, if it is made of scalars only (else None)."""
    if isinstance(annotation, str):
        parts = [part.strip() for part in annotation.split("|")]
        if all(part in _SCALARS for part in parts):
            types_ = tuple(_SCALARS[part] for part in parts)
            return types_[0] if len(types_) == 1 else Union[types_]
        return None
    if annotation in _SCALARS.values():
        return annotation
    origin = typing.get_origin(annotation)
    if origin is Literal:
        return annotation
    if origin in (Union, types.UnionType):
        return annotation if all(_scalar_type(a) is not None for a in typing.get_args(annotation)) else None
    return None


def _doc_parameters(cls: type) -> dict[str, str]:
    """Descriptions of the parameters from a numpydoc ``Parameters`` section (first paragraph of each)."""
    doc = inspect.getdoc(cls) or ""
    match = re.search(r"^Parameters\n-+\n(.*?)(?:\n\n[A-Z][a-z]+\n-+\n|\Z)", doc, re.S | re.M)
    found: dict[str, str] = {}
    names: list[str] = []
    for line in (match.group(1).splitlines() if match else []):
        if line and not line.startswith(" "):
            names = [n.strip() for n in line.split(":")[0].split(",")]
        elif not line.strip():
            names = []
        for name in names if line.startswith(" ") else []:
            found[name] = (found.get(name, "") + " " + line.strip()).strip()
    return found


@dataclass(frozen=True)
class Parameter:
    """A constructor parameter: name, annotation (as written), default (``inspect.Parameter.empty`` if none)."""

    name: str
    annotation: str
    default: Any
    description: str
    check: Any  # a pydantic TypeAdapter for scalar parameters, None for objects built from nested tables

    @property
    def required(self) -> bool:
        return self.default is inspect.Parameter.empty


@dataclass(frozen=True)
class Signature:
    """What a scene may write for one ``type``: its parameters, in constructor order."""

    name: str
    cls: type
    summary: str
    parameters: dict[str, Parameter]


@lru_cache(maxsize=None)
def signature(name: str) -> Signature:
    """The parameters of the registered type ``name`` (from its constructor and docstring)."""
    cls = registry()[name]
    docs = _doc_parameters(cls)
    params: dict[str, Parameter] = {}
    for p in inspect.signature(cls).parameters.values():
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        annotation = p.annotation
        scalar = None if annotation is p.empty else _scalar_type(annotation)
        written = "" if annotation is p.empty else (annotation if isinstance(annotation, str)
                                                     else getattr(annotation, "__name__", str(annotation)))
        params[p.name] = Parameter(p.name, written, p.default, docs.get(p.name, ""),
                                   None if scalar is None else TypeAdapter(scalar))
    summary = (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")
    return Signature(name, cls, summary, params)


def _plant_table(spec: dict) -> bool:
    return "type" not in spec and any(k in spec for k in ("num", "A", "zeros", "poles", "gain")) or \
        spec.get("type") in ("tf", "zpk", "ss")


def _check(spec: dict, loc: tuple) -> list[Problem]:
    """Problems of one ``{type = ...}`` table (not of its nested tables)."""
    if "type" not in spec:
        return [Problem(dotted(loc + ("type",)), "missing required key", None,
                        "the name of a describing function or effect")]
    name = spec["type"]
    known = registry()
    if not isinstance(name, str) or name not in known:
        return [Problem(dotted(loc + ("type",)), f"unknown type {name!r}", closest(name, known),
                        "one of " + ", ".join(known))]
    sig = signature(name)
    problems = []
    for param, value in spec.items():
        if param == "type":
            continue
        if param not in sig.parameters:
            guess = closest(param, sig.parameters)
            expected = (sig.parameters[guess].annotation or None) if guess else \
                "one of " + ", ".join(sig.parameters)
            problems.append(Problem(dotted(loc + (param,)), f"unknown parameter of {name}", guess, expected))
            continue
        check = sig.parameters[param].check
        if check is not None:
            try:
                check.validate_python(value, strict=True)
            except ValidationError:
                problems.append(Problem(dotted(loc + (param,)),
                                        f"wrong type for {name}: got {type(value).__name__} {value!r}", None,
                                        sig.parameters[param].annotation))
    for param in sig.parameters.values():
        if param.required and param.name not in spec:
            problems.append(Problem(dotted(loc + (param.name,)), f"missing required parameter of {name}", None,
                                    param.annotation or None))
    return problems


def element_problems(spec: Any, loc: tuple) -> list[Problem]:
    """Problems of a table and everything nested in it."""
    if isinstance(spec, list):
        return [p for i, item in enumerate(spec) for p in element_problems(item, loc + (i,))]
    if not isinstance(spec, dict):
        return []
    if _plant_table(spec):
        return validate_plant(spec, loc)[1]
    problems = _check(spec, loc)
    for param, value in spec.items():
        if param != "type":
            problems += element_problems(value, loc + (param,))
    return problems


def _make(spec: Any, loc: tuple, extra: dict | None = None) -> Any:
    """Build a checked table (see :func:`build`); ``extra`` adds keyword arguments to the outermost type."""
    if isinstance(spec, list):
        return [_make(item, loc + (i,)) for i, item in enumerate(spec)]
    if not isinstance(spec, dict):
        return spec
    if _plant_table(spec):
        return make_plant(validate_plant(spec, loc)[0], loc)
    name = spec["type"]
    params = {key: _make(value, loc + (key,)) for key, value in spec.items() if key != "type"}
    params.update({key: value for key, value in (extra or {}).items()
                   if key in signature(name).parameters and key not in spec})
    if isinstance(params.get("effects"), list):
        params["effects"] = tuple(params["effects"])
    try:
        return registry()[name](**params)
    except (ValueError, TypeError) as err:  # the constructor's own checks (values out of range)
        first = str(err).split(" ", 1)[0]
        where = loc + (first,) if first in params else loc
        raise SceneError(None, Problem(dotted(where), f"{name}: {err}")) from None


def build(spec: Any, loc: tuple = ("element",), extra: dict | None = None) -> Any:
    """Build an element (or effect, or plant) from a scene table, checking every key first.

    Parameters
    ----------
    spec : dict or list
        ``{"type": Name, **parameters}``, recursively.
    loc : tuple
        Where the table sits in the scene (for messages), ``("element",)`` by default.
    extra : dict, optional
        Keyword arguments for the outermost type, used only if its constructor takes them and the table does
        not set them (the CLI passes a progress callback this way).

    Raises
    ------
    SceneError
        Listing every unknown or missing key and every wrong type, or the constructor's own ValueError.
    """
    problems = element_problems(spec, loc)
    if problems:
        raise SceneError(None, problems)
    return _make(spec, loc, extra)


def table_defaults(table: dict) -> dict[str, Any]:
    """The parameters a table may leave out, with their defaults: a ``{type = ...}`` table's optional constructor
    parameters, or a plant table's optional keys (e.g. ``delay``)."""
    if _plant_table(table):
        model = PLANT_TYPES.get(table.get("type", "tf"))
        fields = model.model_fields.items() if model is not None else ()
        return {name: f.get_default(call_default_factory=True) for name, f in fields if not f.is_required()}
    if isinstance(table.get("type"), str) and table["type"] in registry():
        return {p.name: p.default for p in signature(table["type"]).parameters.values() if not p.required}
    return {}


def check_parameter_path(data: dict, path: str) -> list[Problem]:
    """Problems of a sweep's ``parameter``: a dotted path to a number in the scene (or to a parameter its
    element may take, e.g. ``element.k`` when ``k`` is left at its default)."""
    key = "sweep.parameter"
    parts = path.split(".")
    roots = [r for r in ("plant", "controller", "element") if r in data]
    if parts[0] not in roots:
        return [Problem(key, f"{path!r} does not start with a section holding numbers", closest(parts[0], roots),
                        "a dotted path starting with one of " + ", ".join(roots))]
    node: Any = data[parts[0]]
    for depth, part in enumerate(parts[1:], start=1):
        where = ".".join(parts[:depth])
        if isinstance(node, list):
            if not (part.isdigit() and int(part) < len(node)):
                return [Problem(key, f"{path!r}: {where} is a list of {len(node)}, {part!r} is not an index",
                                None, f"an index 0..{len(node) - 1}")]
            node = node[int(part)]
        elif isinstance(node, dict):
            defaults = table_defaults(node)
            valid = list(node) + [p for p in defaults if p not in node]
            if part not in valid:
                return [Problem(key, f"{path!r}: {where} has no key {part!r}", closest(part, valid),
                                "one of " + ", ".join(v for v in valid if v != "type"))]
            node = node[part] if part in node else defaults[part]  # else: a parameter left at its default
        else:
            return [Problem(key, f"{path!r}: {where} is a number, it has no {part!r}")]
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        return [Problem(key, f"{path!r} is not a number (it is {type(node).__name__} {node!r})", None,
                        "a path to a number")]
    return []
