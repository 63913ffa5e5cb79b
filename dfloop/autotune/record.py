"""A recorded relay experiment: the CSV format, and what a recording says by itself (no model).

Format (``docs/autotune.md``): UTF-8 text, ``#`` comment lines first, each ``# key = value``; the keys
``relay_high``, ``relay_low`` (relay output levels, process input unit) and ``hysteresis`` (process output unit)
describe the relay, other keys (``description``, ``units``, ...) are kept in ``meta``. Then a header line ``t,u,y``
and one row per sample: time t (s, increasing), the relay output u (= the process input before its dead time) and
the process output y, both as deviations from the operating point (so the relay levels lie on either side of 0,
high > 0 > low, and the relay's input is x = -y).

:meth:`RelayRecord.features` reads the settled oscillation: the relay's switching instants (the sample interval in
which u changes level; the midpoint, uncertain by +-dt/2), the period and the time at the high level by a
straight-line fit of the switching instants against the cycle index (standard errors from the fit's residuals,
which hold the +-dt/2 quantisation), and from y folded on that period and averaged per phase bin: the amplitude
(half peak-to-peak of the average) with a bootstrap standard error over whole cycles, the mean of y over whole
fitted periods (trapezoid) and, with a biased relay, the static gain mean y / mean u (mean u from the switching
fits: the sampled u would quantise it), the noise level, and the DF's ultimate-point estimate Ku = 4 d / (pi a),
Tu = period (d = (high - low) / 2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["RelayRecord", "RecordFeatures", "load_relay_record", "write_relay_record"]

_BOOTSTRAP = 200        # bootstrap resamples of whole cycles for the amplitude's standard error
_MAX_SAMPLES = 10_000_000


@dataclass(frozen=True, repr=False)
class RecordFeatures:
    """What a relay recording says without a model (values with their standard errors, ``*_se``).

    Attributes
    ----------
    period, period_se : float
        Oscillation period (s).
    high_time, high_time_se : float
        Time per period the relay output is high (s).
    t0 : float
        A switching instant of the relay to high (s), from the line fit (the phase origin of the cycles).
    rises, falls : ndarray
        Estimated switching instants (s) of the relay to high and to low, after the skipped cycles.
    n_cycles : int
        Whole cycles used.
    amplitude, amplitude_se : float
        Half the peak-to-peak y of the period-folded average (y unit).
    mean_y, mean_y_se, mean_u : float
        Means over the whole cycles used.
    static_gain, static_gain_se : float or None
        mean y / mean u when the relay is biased (|mean u| > 1 % of d), else None.
    noise_sd : float
        Standard deviation of the noise on y (y unit), from the second differences (1.4826 MAD / sqrt 6).
    Ku, Ku_se, Tu, Tu_se : float
        The DF's estimate of the ultimate point: 4 d / (pi a) and the period.
    t_start, t_end : float
        Time span of the whole cycles used (s).
    """

    period: float
    period_se: float
    high_time: float
    high_time_se: float
    t0: float
    rises: np.ndarray
    falls: np.ndarray
    n_cycles: int
    amplitude: float
    amplitude_se: float
    mean_y: float
    mean_y_se: float
    mean_u: float
    static_gain: float | None
    static_gain_se: float | None
    noise_sd: float
    Ku: float
    Ku_se: float
    Tu: float
    Tu_se: float
    t_start: float
    t_end: float

    def __repr__(self) -> str:
        gain = ("" if self.static_gain is None else
                f", static gain {self.static_gain:.5g} +- {self.static_gain_se:.2g}")
        return (f"RecordFeatures({self.n_cycles} cycles: period {self.period:.6g} +- {self.period_se:.2g} s, amplitude "
                f"{self.amplitude:.5g} +- {self.amplitude_se:.2g}, noise sd {self.noise_sd:.3g}; DF Ku = "
                f"{self.Ku:.5g} +- {self.Ku_se:.2g}, Tu = {self.Tu:.5g} +- {self.Tu_se:.2g} s{gain})")

    def to_dict(self) -> dict:
        skip = {"rises", "falls"}
        return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in self.__dict__.items()
                if k not in skip}


@dataclass(frozen=True, repr=False)
class RelayRecord:
    """A recorded relay experiment (see the module notes for the file format).

    Attributes
    ----------
    t, u, y : ndarray
        Time (s), relay output (process input unit), process output (deviation from the setpoint).
    high, low : float
        Relay output levels.
    hysteresis : float
        Relay hysteresis a (y unit): to high when y falls through -a, to low when y rises through +a.
    meta : dict
        The file's other ``# key = value`` lines.
    """

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    high: float
    low: float
    hysteresis: float
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("t", "u", "y"):
            v = np.asarray(getattr(self, name), float)
            if v.ndim != 1 or v.size < 10 or not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be a 1-D array of at least 10 finite samples; got shape "
                                 f"{np.shape(getattr(self, name))}")
            object.__setattr__(self, name, v)
        if not (self.t.size == self.u.size == self.y.size):
            raise ValueError(f"t, u, y must have the same length; got {self.t.size}, {self.u.size}, {self.y.size}")
        if np.any(np.diff(self.t) <= 0):
            raise ValueError("t must be strictly increasing")
        if not (math.isfinite(self.high) and math.isfinite(self.low) and self.high > self.low):
            raise ValueError(f"relay levels must satisfy high > low; got high={self.high!r}, low={self.low!r}")
        if not (math.isfinite(self.hysteresis) and self.hysteresis >= 0):
            raise ValueError(f"hysteresis must be >= 0; got {self.hysteresis!r}")
        tol = 1e-6 * (self.high - self.low)
        off = ~((np.abs(self.u - self.high) <= tol) | (np.abs(self.u - self.low) <= tol))
        if np.any(off):
            i = int(np.flatnonzero(off)[0])
            raise ValueError(f"u must take only the relay levels {self.high:g} and {self.low:g}; u[{i}] = "
                             f"{self.u[i]!r} at t = {self.t[i]:g} s")

    def __repr__(self) -> str:
        return (f"RelayRecord({self.t.size} samples over {self.t[-1] - self.t[0]:.6g} s, relay {self.high:g}/"
                f"{self.low:g}, hysteresis {self.hysteresis:g})")

    def to_dict(self) -> dict:
        return {"samples": int(self.t.size), "duration": float(self.t[-1] - self.t[0]), "high": self.high,
                "low": self.low, "hysteresis": self.hysteresis, "meta": dict(self.meta)}

    def switches(self) -> tuple[np.ndarray, np.ndarray]:
        """(rises, falls): estimated instants (s) of the relay's switches to high and to low (midpoints of the
        sample intervals where u changes)."""
        hi = self.u > 0.5 * (self.high + self.low)
        i = np.flatnonzero(hi[1:] != hi[:-1]) + 1
        mid = 0.5 * (self.t[i - 1] + self.t[i])
        return mid[hi[i]], mid[~hi[i]]

    def features(self, skip_cycles: int = 1, *, seed: int = 0) -> RecordFeatures:
        """Period, time high, amplitude, mean and noise of the settled oscillation (see the module notes).

        Parameters
        ----------
        skip_cycles : int
            Whole cycles dropped at the start (the settling of the experiment), >= 0.
        seed : int
            Seed of the bootstrap (reproducible standard errors).
        """
        from .._checks import integer_at_least

        skip = integer_at_least("skip_cycles", skip_cycles, 0)
        rises, falls = self.switches()
        rises = rises[skip:]
        if rises.size < 3:
            raise ValueError(f"the record holds {rises.size} relay switches to high after skip_cycles={skip}; at least "
                             "3 (two whole cycles) are needed: record longer or skip fewer cycles")
        falls = falls[(falls > rises[0]) & (falls < rises[-1])]
        n = rises.size - 1
        if falls.size != n:
            raise ValueError(f"the relay switched {falls.size} times to low between {n + 1} switches to high: not one "
                             "oscillation (chattering? give the relay more hysteresis)")
        k = np.arange(n + 1, dtype=float)
        P, t0, P_se, _ = _line(k, rises)
        h_all = falls - rises[:-1]
        h1 = float(np.mean(h_all))
        h1_se = float(np.std(h_all, ddof=1) / math.sqrt(n)) if n > 1 else P_se
        h1_se = max(h1_se, (self.t[1] - self.t[0]) / math.sqrt(12 * n))
        use = (self.t >= rises[0]) & (self.t < rises[-1])
        t, y, u = self.t[use], self.y[use], self.u[use]
        per_period = t.size / n
        bins = int(max(8, min(256, per_period // 4)))
        phase = np.mod(t - t0, P) / P
        b = np.minimum((phase * bins).astype(int), bins - 1)
        cyc = np.minimum(np.floor((t - rises[0]) / P).astype(int), n - 1)
        sums = np.zeros((n, bins))
        counts = np.zeros((n, bins))
        np.add.at(sums, (cyc, b), y)
        np.add.at(counts, (cyc, b), 1.0)

        def amplitude(rows):
            s, c = sums[rows].sum(axis=0), counts[rows].sum(axis=0)
            avg = s[c > 0] / c[c > 0]
            return 0.5 * float(avg.max() - avg.min())

        a = amplitude(np.arange(n))
        rng = np.random.default_rng(seed)
        boots = [amplitude(rng.integers(0, n, n)) for _ in range(_BOOTSTRAP)]
        a_se = float(np.std(boots, ddof=1))
        d2 = y[2:] - 2.0 * y[1:-1] + y[:-2]          # white noise of sd s has second differences of sd s sqrt(6)
        noise = float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))
        a0, a1 = t0 + P * round((rises[0] - t0) / P), t0 + P * round((rises[-1] - t0) / P)
        means = np.array([_mean(self.t, self.y, a0 + j * P, a0 + (j + 1) * P) for j in range(n)])
        mean_y = _mean(self.t, self.y, a0, a1)
        mean_y_se = float(np.std(means, ddof=1) / math.sqrt(n)) if n > 1 else noise / math.sqrt(y.size)
        # mean u from the switching line fits (the sampled u would quantise it by dt / period)
        mean_u = (self.high * h1 + self.low * (P - h1)) / P
        d = 0.5 * (self.high - self.low)
        gain, gain_se = None, None
        if abs(mean_u) > 0.01 * d:
            gain = mean_y / mean_u
            mean_u_se = (self.high - self.low) * h1_se / P
            gain_se = abs(gain) * math.hypot(mean_y_se / mean_y if mean_y else 0.0, mean_u_se / mean_u)
        Ku = 4.0 * d / (math.pi * a)
        return RecordFeatures(P, P_se, h1, h1_se, t0, rises, falls, n, a, a_se, mean_y, mean_y_se, mean_u, gain, gain_se,
                              noise, Ku, Ku * a_se / a, P, P_se, float(rises[0]), float(rises[-1]))


def _mean(t, y, a, b):
    """Mean of the piecewise-linear interpolant of (t, y) over [a, b] (trapezoid with interpolated ends)."""
    inside = (t > a) & (t < b)
    tt = np.concatenate([[a], t[inside], [b]])
    yy = np.concatenate([[np.interp(a, t, y)], y[inside], [np.interp(b, t, y)]])
    return float(np.sum(0.5 * (yy[1:] + yy[:-1]) * np.diff(tt)) / (b - a))


def _line(k, t):
    """Least-squares t = t0 + P k: (P, t0, se(P), se(t0))."""
    A = np.column_stack([k, np.ones_like(k)])
    coef, *_ = np.linalg.lstsq(A, t, rcond=None)
    r = t - A @ coef
    dof = max(k.size - 2, 1)
    s2 = float(r @ r) / dof
    cov = s2 * np.linalg.inv(A.T @ A)
    return float(coef[0]), float(coef[1]), float(math.sqrt(cov[0, 0])), float(math.sqrt(cov[1, 1]))


def load_relay_record(path, *, high: float | None = None, low: float | None = None,
                      hysteresis: float | None = None) -> RelayRecord:
    """Read a relay recording (CSV with ``# key = value`` header lines; see the module notes).

    Parameters
    ----------
    path : str or Path
    high, low, hysteresis : float, optional
        The relay's settings when the file does not give them (``relay_high``, ``relay_low``, ``hysteresis``);
        levels default to the largest and smallest u, hysteresis to 0.

    Raises
    ------
    ValueError
        A malformed file (the message names the line), or data the record refuses (see :class:`RelayRecord`).
    """
    path = Path(path)
    meta, header, rows = {}, None, []
    with path.open(encoding="utf-8") as fh:
        for number, line in enumerate(fh, 1):
            line = line.strip()
            if not line:
                continue
            if line.startswith("#"):
                if "=" in line and header is None:
                    key, value = line[1:].split("=", 1)
                    meta[key.strip()] = value.strip()
                continue
            if header is None:
                header = [c.strip() for c in line.split(",")]
                if header != ["t", "u", "y"]:
                    raise ValueError(f"{path}:{number}: the header must be 't,u,y'; got {line!r}")
                continue
            parts = line.split(",")
            try:
                rows.append([float(p) for p in parts])
            except ValueError:
                raise ValueError(f"{path}:{number}: a row must be three numbers t,u,y; got {line!r}") from None
            if len(parts) != 3:
                raise ValueError(f"{path}:{number}: a row must be three numbers t,u,y; got {line!r}")
            if len(rows) > _MAX_SAMPLES:
                raise ValueError(f"{path}: more than {_MAX_SAMPLES} samples; decimate the recording")
    if header is None or not rows:
        raise ValueError(f"{path}: no 't,u,y' header and data rows")
    data = np.array(rows)

    def setting(key, given, default):
        if given is not None:
            return float(given)
        if key in meta:
            try:
                return float(meta.pop(key))
            except ValueError:
                raise ValueError(f"{path}: '# {key} = ...' must be a number") from None
        return default

    hi = setting("relay_high", high, float(data[:, 1].max()))
    lo = setting("relay_low", low, float(data[:, 1].min()))
    a = setting("hysteresis", hysteresis, 0.0)
    return RelayRecord(data[:, 0], data[:, 1], data[:, 2], hi, lo, a, meta)


def write_relay_record(path, record: RelayRecord, *, digits: int = 9) -> Path:
    """Write ``record`` in the format :func:`load_relay_record` reads (its ``meta`` first, then the relay)."""
    path = Path(path)
    lines = [f"# {k} = {v}" for k, v in record.meta.items()]
    lines += [f"# relay_high = {record.high!r}", f"# relay_low = {record.low!r}",
              f"# hysteresis = {record.hysteresis!r}", "t,u,y"]
    lines += [f"{t:.{digits}g},{u:.{digits}g},{y:.{digits}g}" for t, u, y in zip(record.t, record.u, record.y)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
