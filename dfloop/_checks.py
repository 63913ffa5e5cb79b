"""Validation of user input: every failure is a :class:`dfloop.errors.DfloopError` (a ``ValueError``) that
names the parameter and the value."""
from __future__ import annotations

import math
import numbers
import os

import numpy as np

from .errors import DfloopError

__all__ = ["positive", "nonnegative", "finite", "in_closed_interval", "amplitude_array", "frequency_array",
           "real_array", "integer_at_least", "window", "show", "flag", "text",
           "scale", "SCALE_RANGE",
           "memory_limit", "MEMORY_LIMIT_GIB", "environ"]


def _real(name: str, value, nan: bool = False) -> float:
    if isinstance(value, (complex, np.complexfloating)):
        raise DfloopError(f"{name} must be a real number, got the complex value {show(value)}")
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise DfloopError(f"{name} must be a real number, got {show(value)} ({type(value).__name__})")
    try:
        x = float(value)
    except OverflowError:  # a Python integer beyond the float range
        raise DfloopError(f"{name} must be representable as a float, got {show(value)}") from None
    except (TypeError, ValueError):
        raise DfloopError(f"{name} must be a real number, got {show(value)}") from None
    if math.isnan(x) and not nan:
        raise DfloopError(f"{name} must not be NaN, got {show(value)}")
    return x


def finite(name: str, value) -> float:
    """Return ``value`` as a float, raising if it is NaN or infinite."""
    x = _real(name, value)
    if not math.isfinite(x):
        raise DfloopError(f"{name} must be finite, got {x}")
    return x


def positive(name: str, value) -> float:
    """Return ``value`` as a finite float > 0."""
    x = finite(name, value)
    if x <= 0:
        raise DfloopError(f"{name} must be > 0, got {x}")
    return x


def nonnegative(name: str, value) -> float:
    """Return ``value`` as a finite float >= 0."""
    x = finite(name, value)
    if x < 0:
        raise DfloopError(f"{name} must be >= 0, got {x}")
    return x


def in_closed_interval(name: str, value, lo: float, hi: float) -> float:
    """Return ``value`` as a float in [lo, hi]."""
    x = finite(name, value)
    if not lo <= x <= hi:
        raise DfloopError(f"{name} must lie in [{lo}, {hi}], got {x}")
    return x


def show(value) -> str:
    """A short repr of a user value for error messages."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def real_array(value, name: str) -> np.ndarray:
    """``value`` as a float array; complex, non-numeric, None or ragged input raises naming ``name``.

    NaN and infinite entries pass (callers decide about them). Booleans count as 0 and 1 (numpy's rule).
    """
    try:
        a = np.asarray(value)
    except (ValueError, TypeError):  # ragged nested sequences
        raise DfloopError(f"{name} must be a real number or a rectangular array of them, got {show(value)}") from None
    if a.dtype.kind == "c":
        raise DfloopError(f"{name} must be real, got the complex value(s) {show(value)}")
    if a.dtype.kind == "O":
        flat = a.ravel()
        if not all(isinstance(v, numbers.Real) for v in flat):
            bad = next(v for v in flat if not isinstance(v, numbers.Real))
            where = "" if a.ndim == 0 else f" in {show(value)}"
            raise DfloopError(f"{name} must hold real numbers only, got {show(bad)}{where}")
    elif a.dtype.kind not in "biuf":
        raise DfloopError(f"{name} must be a real number or an array of them, got {show(value)}")
    try:
        return a.astype(float, copy=False)  # float input passes without a copy, as np.asarray(A, float) did
    except OverflowError:  # Python integers beyond the float range
        raise DfloopError(f"{name} must be representable as a float, got {show(value)}") from None


def amplitude_array(A, name: str = "A") -> np.ndarray:
    """Amplitudes as a float array, >= 0 (``inf`` allowed: elements return their limit there).

    Negative, complex or non-numeric entries raise naming ``name`` and the value; NaN entries pass through
    (and give NaN in those entries only).
    """
    a = real_array(A, name)
    with np.errstate(invalid="ignore"):
        neg = a < 0
    if np.any(neg):
        raise DfloopError(f"{name} (amplitude) must be >= 0; got {float(a[neg].ravel()[0])!r} "
                          f"({int(np.count_nonzero(neg))} negative entr{'y' if np.count_nonzero(neg) == 1 else 'ies'})")
    return a


def frequency_array(omega, name: str = "omega") -> np.ndarray:
    """Frequencies in rad/s as a float array, finite and > 0; NaN entries pass through.

    Non-positive, infinite, complex or non-numeric entries raise naming ``name`` and the value.
    """
    w = real_array(omega, name)
    with np.errstate(invalid="ignore"):
        bad = (w <= 0) | np.isinf(w)
    if np.any(bad):
        n_bad = int(np.count_nonzero(bad))
        raise DfloopError(f"{name} (frequency, rad/s) must be finite and > 0; got {float(w[bad].ravel()[0])!r} "
                          f"({n_bad} bad entr{'y' if n_bad == 1 else 'ies'})")
    return w


def integer_at_least(name: str, value, minimum: int) -> int:
    """``value`` as an int >= ``minimum`` (integral floats such as 4.0 pass; 2.5, NaN, inf, True do not)."""
    x = finite(name, value)
    if x != int(x) or x < minimum:
        raise DfloopError(f"{name} must be an integer >= {minimum}, got {show(value)}")
    return int(x)


_FLOAT_TYPES = (float, np.float64)  # window ends taken as they are (a subclass or any other type is converted)


def window(name: str, value) -> tuple[float, float]:
    """A window (lo, hi) of positive finite floats with lo < hi (frequencies in rad/s, amplitudes)."""
    if type(value) is tuple and len(value) == 2:  # the common case, two floats in order: no conversion
        lo, hi = value
        if type(lo) in _FLOAT_TYPES and type(hi) in _FLOAT_TYPES and 0 < lo < hi < math.inf:
            return float(lo), float(hi)
    try:
        pair = tuple(value)
    except TypeError:
        pair = ()
    if len(pair) != 2 or isinstance(value, (str, bytes)):
        raise DfloopError(f"{name} window must be a pair (lo, hi) of real numbers; got {show(value)}")
    lo, hi = (_real(f"{name} window", x, nan=True) for x in pair)  # booleans, strings, complex, huge integers
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise DfloopError(f"{name} window must be finite; got ({lo}, {hi})")
    if lo <= 0 or hi <= 0:
        raise DfloopError(f"{name} window must be positive; got ({lo}, {hi})")
    if lo >= hi:
        raise DfloopError(f"{name} window must satisfy lo < hi; got ({lo}, {hi})")
    return lo, hi


def flag(name: str, value, none: bool = False) -> bool | None:
    """``value`` as a bool: True/False (numpy's too), or None when ``none`` allows it; "yes", 1, NaN raise."""
    if value is None and none:
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise DfloopError(f"{name} must be True or False{' (or None)' if none else ''}, got {show(value)}")


def text(name: str, value) -> str:
    """``value`` as a str (names and units shown in reports and plots)."""
    if not isinstance(value, str):
        raise DfloopError(f"{name} must be a string, got {show(value)} ({type(value).__name__})")
    return value


SCALE_RANGE = (1e-300, 1e300)
"""Amplitudes and frequencies of a cycle handed to a simulation: beyond it, periods (2 pi / w) or ratios (1 / A)
overflow or lose all precision in subnormal numbers."""


def scale(name: str, value) -> float:
    """``value`` as a float in ``SCALE_RANGE`` (a cycle's amplitude or frequency, > 0)."""
    x = positive(name, value)
    lo, hi = SCALE_RANGE
    if not lo <= x <= hi:
        raise DfloopError(f"{name} must lie in [{lo:g}, {hi:g}], got {x!r}")
    return x


MEMORY_LIMIT_GIB = 2.0
"""Default bound (GiB) on the largest work arrays dfloop allocates (the solver's grid, an impact run's record);
the environment variable ``DFLOOP_MEMORY_LIMIT`` (GiB) overrides it."""


def environ(name: str) -> str | None:
    """``os.environ.get(name)``, read on every solver call (the environment may change between calls).

    For an unset variable ``os.environ.get`` raises and catches a KeyError inside (about 0.5 us, a few per cent of a
    small compiled solver call); this reads CPython's mapping of encoded names directly where it exists, and
    otherwise asks ``os.environ.get``."""
    data = getattr(os.environ, "_data", None)
    if type(data) is not dict:
        return os.environ.get(name)
    value = data.get(os.environ.encodekey(name))
    return None if value is None else os.environ.decodevalue(value)


def memory_limit() -> int:
    """The memory bound in bytes: ``DFLOOP_MEMORY_LIMIT`` (GiB, a positive number) or ``MEMORY_LIMIT_GIB``."""
    env = environ("DFLOOP_MEMORY_LIMIT")
    if env is None:
        return int(MEMORY_LIMIT_GIB * 1024 ** 3)
    try:
        gib = float(env)
    except ValueError:
        gib = math.nan
    if not (math.isfinite(gib) and gib > 0):
        raise DfloopError(f"DFLOOP_MEMORY_LIMIT must be a positive number of GiB, got {env!r}")
    return int(gib * 1024 ** 3)


