"""Plain-data forms of dfloop's results: ``to_dict()`` and CSV files.

Every result object (:class:`~dfloop.solve.result.LimitCycle`, :class:`~dfloop.solve.result.LimitCycles`,
:class:`~dfloop.exact.ExactCycle`, :class:`~dfloop.verify.Verification`, :class:`~dfloop.solve.confidence.Confidence`,
:class:`~dfloop.continuation.SweepResult`) has ``to_dict()`` (Python numbers, strings, lists and dicts, keyed by
the attribute names: the names its repr prints) and ``to_csv(path)``. The conventions, shared by all of them:

- a row is a flat dict of scalars; a complex scalar ``G`` becomes two columns ``G_real`` and ``G_imag``; an
  attached result (a cycle's ``confidence`` or ``exact``) becomes columns prefixed with its name;
- ``to_csv`` writes the result's table: one row per cycle (LimitCycles), per sample of the period (ExactCycle:
  ``t``, ``x``, ``y``), per branch point (SweepResult), or one row (a single cycle, Verification, Confidence);
- numbers are written with ``repr`` (they read back bit for bit with ``float``), None as an empty field,
  booleans as ``True``/``False``.

``pandas.DataFrame(cycles.to_dict()["cycles"])`` or ``pandas.read_csv(path)`` gives a data frame; pandas is not
needed by dfloop.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any, Iterable

import numpy as np

__all__ = ["plain", "flat", "write_csv", "read_csv"]


def plain(value: Any) -> Any:
    """``value`` as plain Python data: numpy scalars become int/float/complex/bool, arrays and tuples lists,
    dicts are converted entry by entry; strings and None are kept."""
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()] if value.dtype == object else value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    return value


def flat(fields: dict, prefix: str = "") -> dict:
    """One CSV row from scalar fields: complex ``z`` -> ``z_real``, ``z_imag``; nested dicts -> prefixed keys;
    lists and arrays are left out (they belong in a table of their own)."""
    row: dict = {}
    for key, value in fields.items():
        name = f"{prefix}{key}"
        value = plain(value)
        if isinstance(value, dict):
            row.update(flat(value, f"{name}_"))
        elif isinstance(value, complex):
            row[f"{name}_real"], row[f"{name}_imag"] = value.real, value.imag
        elif not isinstance(value, list):
            row[name] = value
    return row


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def write_csv(path: str | Path, rows: Iterable[dict]) -> Path:
    """Write ``rows`` (flat dicts; the columns are the union of their keys, in first-seen order) to ``path``.

    Raises
    ------
    ValueError
        When a row holds a value that is not a scalar (a list, a dict, a complex: flatten it first with
        :func:`flat`), naming the column.
    """
    rows = [dict(r) for r in rows]
    columns: list[str] = []
    for r in rows:
        for key, value in r.items():
            if isinstance(value, (list, tuple, dict, complex, np.ndarray)):
                raise ValueError(f"CSV column {key!r} must hold scalars, got {type(value).__name__}")
            if key not in columns:
                columns.append(key)
    path = Path(path)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow([_cell(plain(r.get(c))) for c in columns])
    return path


def _parse(text: str) -> Any:
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return text
    return value if not math.isnan(value) or text.lower() == "nan" else text


def read_csv(path: str | Path) -> list[dict]:
    """Read a file written by :func:`write_csv` back into rows (numbers, booleans and None restored)."""
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader, [])
        return [{k: _parse(v) for k, v in zip(header, line)} for line in reader]
