"""Fourier fundamental and periodicity measures of sampled signals.

Convention (docs/design.md section 1): a signal A sin(w t + phi) has the complex fundamental A exp(j phi),
i.e. x(t) ~ Im(c exp(j w t)).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import integer_at_least, positive, real_array
from .errors import DfloopError

__all__ = ["fundamental", "upward_crossings", "SteadyState", "steady_state"]


def fundamental(t: np.ndarray, x: np.ndarray, omega: float) -> complex:
    """Complex fundamental c of x at ``omega`` (rad/s) over the samples given (trapezoidal rule).

    The samples should span a whole number of periods 2 pi / omega; then x = A sin(w t + phi) gives
    c = A exp(j phi).
    """
    t, x = _samples(t, x)
    omega = positive("omega", omega)
    span = t[-1] - t[0]
    return complex(1j * 2.0 / span * np.trapezoid(x * np.exp(-1j * omega * t), t))


def _samples(t, x) -> tuple[np.ndarray, np.ndarray]:
    """Validated samples: t and x real, finite, one-dimensional, of one length >= 3, t increasing."""
    t, x = real_array(t, "t"), real_array(x, "x")
    if t.ndim != 1 or t.shape != x.shape:
        raise DfloopError(f"t and x must be one-dimensional of one length, got shapes {t.shape} and {x.shape}")
    if t.size < 3:
        raise DfloopError(f"t must hold at least 3 strictly increasing samples, got {t.size} samples")
    step = np.diff(t) <= 0
    if np.any(step):
        raise DfloopError(f"t must hold at least 3 strictly increasing samples, got {t.size} samples "
                          f"(first non-increasing step at index {int(np.argmax(step))})")
    for name, v in (("t", t), ("x", x)):
        if not np.all(np.isfinite(v)):
            raise DfloopError(f"{name} must be finite, got {float(v[~np.isfinite(v)][0])!r}")
    return t, x


def upward_crossings(t: np.ndarray, x: np.ndarray, level: float = 0.0) -> np.ndarray:
    """Times where x crosses ``level`` upwards (linear interpolation between samples)."""
    d = np.asarray(x, float) - level
    k = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0))
    return t[k] - d[k] * (t[k + 1] - t[k]) / (d[k + 1] - d[k])


def _span(t: np.ndarray, x: np.ndarray, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """Samples of x on [t0, t1], with the end values interpolated linearly at t0 and t1 exactly."""
    inner = (t > t0) & (t < t1)
    ts = np.concatenate([[t0], t[inner], [t1]])
    return ts, np.interp(ts, t, x)


@dataclass(frozen=True)
class SteadyState:
    """Amplitude and frequency of the fundamental over the last whole periods of a signal.

    Attributes
    ----------
    amplitude : float
        |fundamental| over the periods measured (0 when the signal no longer oscillates).
    frequency : float
        Mean angular frequency (rad/s) from upward zero crossings (0 when not oscillating).
    periodicity : float
        Relative spread (std / mean) of the per-period fundamental amplitudes: ~0 for a periodic signal.
    n_periods : int
        Number of periods used.
    oscillating : bool
        False when fewer than two crossings were found in the tail.
    """

    amplitude: float
    frequency: float
    periodicity: float
    n_periods: int
    oscillating: bool


def steady_state(t: np.ndarray, x: np.ndarray, periods: int = 10) -> SteadyState:
    """Measure the steady oscillation of x over its last ``periods`` periods (zero mean assumed)."""
    t, x = _samples(t, x)
    periods = integer_at_least("periods", periods, 1)
    crossings = upward_crossings(t, x)
    if crossings.size < 2:
        return SteadyState(float(np.max(np.abs(x[-max(t.size // 10, 1):]))), 0.0, 0.0, 0, False)
    use = crossings[-(periods + 1):]
    n = use.size - 1
    omega = 2 * np.pi * n / (use[-1] - use[0])
    amps = [abs(fundamental(*_span(t, x, t0, t1), 2 * np.pi / (t1 - t0))) for t0, t1 in zip(use[:-1], use[1:])]
    amplitude = abs(fundamental(*_span(t, x, use[0], use[-1]), omega))
    spread = float(np.std(amps) / np.mean(amps)) if amps and np.mean(amps) > 0 else 0.0
    return SteadyState(float(amplitude), float(omega), spread, n, True)
