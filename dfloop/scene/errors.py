"""Scene errors: every problem names the file, the key (a dotted path), the closest valid name and the type.

A :class:`SceneError` is a ``ValueError`` holding one or more :class:`Problem` records, so a scene with
several mistakes reports all of them at once.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from ..errors import DfloopError

__all__ = ["SceneError", "Problem", "closest", "dotted", "validator_message"]


def closest(name: str, valid: Iterable[str]) -> str | None:
    """The valid name closest to ``name``: a known synonym (``slope`` -> ``k``, see
    :data:`dfloop.describing.base.PARAMETER_SYNONYMS`) when it is valid, else by spelling (difflib ratio >= 0.6),
    or None."""
    from ..describing.base import PARAMETER_SYNONYMS

    valid = [str(v) for v in valid]
    synonym = PARAMETER_SYNONYMS.get(str(name).lower())
    if synonym in valid:
        return synonym
    matches = difflib.get_close_matches(str(name), valid, n=1, cutoff=0.6)
    return matches[0] if matches else None


def _items(n: int) -> str:
    return f"{n} value{'s' if n != 1 else ''}"


def validator_message(kind: str, ctx: dict | None, value) -> str:
    """A schema validator's complaint in the project's words (never the validator library's phrasing).

    ``kind`` is the validator's error type (``too_short``, ``greater_than_equal``, ...), ``ctx`` its limits,
    ``value`` the offending input. Kinds without a wording of their own become ``invalid value ...``.
    """
    ctx = ctx or {}
    size = len(value) if isinstance(value, (list, tuple, str)) else None
    if kind == "too_short" and size is not None:
        return f"needs at least {_items(ctx.get('min_length', 0))}, got {_items(size)}: {value!r}"
    if kind == "too_long" and size is not None:
        return f"takes at most {_items(ctx.get('max_length', 0))}, got {_items(size)}: {value!r}"
    bounds = {"greater_than": (">", "gt"), "greater_than_equal": (">=", "ge"), "less_than": ("<", "lt"),
              "less_than_equal": ("<=", "le"), "multiple_of": ("a multiple of", "multiple_of")}
    if kind in bounds:
        words, key = bounds[kind]
        return f"must be {words} {ctx.get(key)!r}, got {value!r}"
    if kind == "finite_number":
        return f"must be a finite number, got {value!r}"
    if kind in ("string_too_short", "string_too_long"):
        limit = ctx.get("min_length", ctx.get("max_length"))
        return f"must have {'at least' if kind == 'string_too_short' else 'at most'} {limit} character(s), got {value!r}"
    return f"invalid value {value!r}"


def dotted(loc: Iterable) -> str:
    """``("element", "effects", 0, "c")`` -> ``"element.effects.0.c"``."""
    return ".".join(str(part) for part in loc)


@dataclass(frozen=True)
class Problem:
    """One mistake in a scene.

    Attributes
    ----------
    key : str
        Dotted path of the offending key (``"analysis.verify"``, ``"element.effects.0.c"``); ``""`` for the
        whole file.
    message : str
        What is wrong.
    suggestion : str or None
        The closest valid name, when the key or value looks like a misspelling.
    expected : str or None
        The type (or values) the key accepts.
    """

    key: str
    message: str
    suggestion: str | None = None
    expected: str | None = None

    def __str__(self) -> str:
        text = f"{self.key}: {self.message}" if self.key else self.message
        hints = []
        if self.suggestion is not None:
            hints.append(f"did you mean {self.suggestion!r}?")
        if self.expected is not None:
            hints.append(f"expected {self.expected}")
        return text + (f" ({'; '.join(hints)})" if hints else "")


class SceneError(DfloopError):
    """A scene file that cannot be used: one or more :class:`Problem` records, each naming its key.

    Attributes
    ----------
    file : pathlib.Path or None
        The scene file.
    problems : list of Problem
    """

    def __init__(self, file: str | Path | None, problems: Problem | list[Problem]):
        self.file = None if file is None else Path(file)
        self.problems = [problems] if isinstance(problems, Problem) else list(problems)
        prefix = f"{self.file}: " if self.file is not None else ""
        if len(self.problems) == 1:
            text = prefix + str(self.problems[0])
        else:
            text = prefix + f"{len(self.problems)} problems\n" + "\n".join(f"  {p}" for p in self.problems)
        super().__init__(text)

    def in_file(self, file: str | Path) -> "SceneError":
        """The same problems attributed to ``file``."""
        return SceneError(file, self.problems)
