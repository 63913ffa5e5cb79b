"""Validation of user input: every failure is a ``ValueError`` that names the parameter."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["positive", "nonnegative", "finite", "in_closed_interval", "amplitude_array", "frequency_array"]


def _real(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if math.isnan(x):
        raise ValueError(f"{name} must not be NaN")
    return x


def finite(name: str, value) -> float:
    """Return ``value`` as a float, raising if it is NaN or infinite."""
    x = _real(name, value)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x}")
    return x


def positive(name: str, value) -> float:
    """Return ``value`` as a finite float > 0."""
    x = finite(name, value)
    if x <= 0:
        raise ValueError(f"{name} must be > 0, got {x}")
    return x


def nonnegative(name: str, value) -> float:
    """Return ``value`` as a finite float >= 0."""
    x = finite(name, value)
    if x < 0:
        raise ValueError(f"{name} must be >= 0, got {x}")
    return x


def in_closed_interval(name: str, value, lo: float, hi: float) -> float:
    """Return ``value`` as a float in [lo, hi]."""
    x = finite(name, value)
    if not lo <= x <= hi:
        raise ValueError(f"{name} must lie in [{lo}, {hi}], got {x}")
    return x


def amplitude_array(A, name: str = "A") -> np.ndarray:
    """Amplitudes as a float array; negative entries raise, NaN entries pass through (and give NaN)."""
    a = np.asarray(A, dtype=float)
    with np.errstate(invalid="ignore"):
        if np.any(a < 0):
            raise ValueError(f"{name} (amplitude) must be >= 0; got a negative entry")
    return a


def frequency_array(omega, name: str = "omega") -> np.ndarray:
    """Frequencies in rad/s as a float array; non-positive entries raise, NaN entries pass through."""
    w = np.asarray(omega, dtype=float)
    with np.errstate(invalid="ignore"):
        if np.any(w <= 0):
            raise ValueError(f"{name} (frequency, rad/s) must be > 0; got a non-positive entry")
    return w


def window(name: str, value) -> tuple[float, float]:
    """A window (lo, hi) of positive finite floats with lo < hi (frequencies in rad/s, amplitudes)."""
    try:
        lo, hi = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} window must be a pair (lo, hi); got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"{name} window must satisfy 0 < lo < hi, both finite; got ({lo}, {hi})")
    return lo, hi
