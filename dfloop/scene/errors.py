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

__all__ = ["SceneError", "Problem", "closest", "dotted"]


def closest(name: str, valid: Iterable[str]) -> str | None:
    """The valid name closest to ``name`` (difflib ratio >= 0.6), or None."""
    matches = difflib.get_close_matches(str(name), [str(v) for v in valid], n=1, cutoff=0.6)
    return matches[0] if matches else None


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
