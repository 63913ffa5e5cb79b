"""Analytic describing functions of rate-independent elements (closed forms, vectorised).

Convention (docs/design.md section 1): input x(t) = A sin(w t), N(A) = (Y1 / A) exp(j phi1) where Y1 sin(w t + phi1)
is the output's fundamental. Every ``N`` here is amplitude-only, evaluated with numpy broadcasting, equal to
0 exactly (never NaN) where the output has no fundamental (inside dead bands, below switching levels); NaN
entries of ``A`` give NaN in those entries only; negative, complex or non-numeric ``A`` raises ``ValueError``
(:class:`dfloop.errors.DfloopError`). At ``A = 0`` and ``A = inf`` every element returns the limit of N, stated
under "Limits" in its docstring (possibly infinite, never NaN).

Each element also provides :meth:`operator`, a fresh stateful callable ``op(x) -> y`` for time-domain
simulation, and static (memoryless) elements provide a vectorised :meth:`StaticElement.output` ``y = f(x)``
and their :meth:`StaticElement.breakpoints` (where f or f' jumps), which :class:`dfloop.NumericDF` can use.
"""
from __future__ import annotations

import math
from abc import abstractmethod

import numpy as np

from .._checks import finite, frequency_array, in_closed_interval, nonnegative, positive, real_array
from ..errors import DfloopError
from .base import DescribingFunction
from .time_model import Smooth, play_model, relay_model, static_model

__all__ = [
    "StaticElement",
    "Backlash",
    "PlayOperator",
    "Saturation",
    "DeadZone",
    "Relay",
    "RelayOperator",
    "CubicStiffness",
    "Quantizer",
    "PreloadedSpring",
    "CoulombViscousFriction",
]

_QUANTIZER_MAX_LEVELS = 10**7
_SERIES_COEFFS = np.array([math.comb(2 * n, n) / 4.0**n * 2.0 / (2 * n + 3) for n in range(16)])


def _asin_minus(t: np.ndarray, c: np.ndarray) -> np.ndarray:
    """phi(t) = asin(t) - t sqrt(1 - t^2) on [0, 1] to full relative precision, given c = sqrt(1 - t^2).

    asin(t) is taken as atan2(t, c), well conditioned up to t = 1 when c is computed without
    cancellation by the caller; phi grows like (2/3) t^3, so for t < 0.25 the Taylor series
    phi(t) = 2 sum_n C(2n, n) 4^-n t^(2n+3) / (2n + 3) is summed instead (16 terms: error < 1e-19 phi).
    """
    tc = np.clip(t, 0.0, 1.0)
    out = np.array(np.arctan2(tc, c) - tc * c, dtype=float)
    small = tc < 0.25
    if small.any():  # the series only where it is used
        t2 = tc[small] * tc[small]
        out[small] = np.polynomial.polynomial.polyval(t2, _SERIES_COEFFS) * t2 * tc[small]
    out[np.isnan(t)] = np.nan
    return out


def _f(u: np.ndarray) -> np.ndarray:
    """f(u) = (2/pi)(asin u + u sqrt(1 - u^2)) for u in [0, 1] (the saturation gain), well conditioned."""
    c = np.sqrt((1.0 - u) * (1.0 + u))
    return (2.0 / np.pi) * (np.arctan2(u, c) + u * c)


def _ratio(level: float, A: np.ndarray) -> np.ndarray:
    """level / A with level / 0 = inf (no warning, also when it overflows) and level / inf = 0; NaN stays NaN."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return level / A


def _one_minus_ratio(level: float, A: np.ndarray) -> np.ndarray:
    """1 - level / A computed as (A - level) / A (exact near A = level), 1 at A = inf, -inf at A = 0."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return np.where(np.isinf(A), 1.0, (A - level) / A)


def _keep_nan(A: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` with NaN wherever ``A`` is NaN."""
    return np.where(np.isnan(A), np.nan, values)


def _scalar_input(x) -> float:
    """One input sample of an operator as a float; complex or non-numeric samples raise naming ``x``."""
    try:
        return float(x)
    except (TypeError, ValueError, OverflowError):
        raise DfloopError(f"x must be a real number, got {x!r}") from None


def _domain(lo: float, hi: float, omega) -> tuple[np.ndarray, np.ndarray]:
    if omega is None:  # 0-d arrays (np.array of a float: what np.full((), x) gives, at a tenth of its cost)
        return np.array(float(lo)), np.array(float(hi))
    shape = np.shape(frequency_array(omega))
    return np.full(shape, float(lo)), np.full(shape, float(hi))


class StaticElement(DescribingFunction):
    """A memoryless odd element y = f(x): real N, a vectorised :meth:`output` and a static operator.

    N is continuous in A > 0 (the average of a bounded f(A sin t) sin t moves continuously with A)."""

    continuous = True

    @abstractmethod
    def output(self, x) -> np.ndarray:
        """Output y = f(x), vectorised over ``x`` (same shape)."""

    def breakpoints(self, A_max: float | None = None) -> np.ndarray:
        """Sorted input levels >= 0 where f or its slope jumps, up to ``A_max`` (empty for smooth f)."""
        return np.empty(0)

    def operator(self):
        """A static time-domain operator ``op(x) -> float`` (no state; a fresh object each call)."""
        f = self.output

        def op(x: float) -> float:
            return float(f(_scalar_input(x)))

        return op

    def time_model(self, amplitude: float):
        """Piecewise affine when f is affine between its breakpoints, smooth otherwise
        (:func:`dfloop.describing.time_model.static_model`)."""
        return static_model(self.output, self.breakpoints, type(self).__name__, amplitude)


# ---------------------------------------------------------------------------------------------- backlash


class PlayOperator:
    """Friction-controlled backlash (the play operator), stateful: ``op(x) -> y``.

    The driven side sits at ``c``; it stays put while |x - c| <= h/2 and is dragged along otherwise
    (c = x -/+ h/2). Output y = k c. Starts at rest with the play centred (c = 0), as python-control's
    ``friction_backlash_nonlinearity`` (which is this operator with k = 1).
    """

    def __init__(self, h: float, k: float = 1.0):
        self.h = positive("h", h)
        self.k = positive("k", k)
        self.center = 0.0

    def __call__(self, x: float) -> float:
        x = _scalar_input(x)
        half = 0.5 * self.h
        if x - self.center > half:
            self.center = x - half
        elif x - self.center < -half:
            self.center = x + half
        return self.k * self.center

    def __deepcopy__(self, memo):
        new = object.__new__(PlayOperator)
        new.__dict__.update(self.__dict__)  # floats only: a shallow copy is a deep copy
        return new

    def time_model(self, amplitude: float = 1.0, name: str = "PlayOperator"):
        """The play operator's exact modes (free, engaged rising, engaged falling)."""
        h, k = self.h, self.k
        return play_model(h, k, name, lambda: PlayOperator(h, k))

    def __repr__(self) -> str:
        return f"PlayOperator(h={self.h!r}, k={self.k!r}, center={self.center!r})"


class Backlash(DescribingFunction):
    """Backlash (friction-controlled, geometric) of total clearance ``h`` and slope ``k``.

    Input x is the driving side's position (m), output y = k * (position of the driven side). Its DF
    (paper eq. (4), written as in docs/design.md section 1) with r = h / X:

        Im N = -(k / pi) r (2 - r)                      (= -(2 k h / (pi X^2)) (X - h/2)),
        Re N = k [1 - phi(t) / pi]   for X >= h,        Re N = (k / pi) phi(t)   for h/2 < X < h,

    with t = sqrt(r (2 - r)) and phi(t) = asin t - t sqrt(1 - t^2); this equals (k/2)[1 + f(1 - h/X)] with
    f(u) = (2/pi)(asin u + u sqrt(1 - u^2)), rewritten so that it keeps full relative precision near
    X = h/2 and for X >> h. N = 0 exactly for X <= h/2; N(h) = k/2 - j k/pi; N -> k as X -> inf.

    Limits: N(0) = 0, N(inf) = k. N is continuous (it rises from 0 at X = h/2).

    Parameters
    ----------
    h : float
        Total clearance (m), > 0.
    k : float
        Slope of the engaged characteristic, > 0.
    """

    continuous = True
    input_name = "X"
    input_unit = "m"

    def __init__(self, h: float, k: float = 1.0):
        self.h = positive("h", h)
        self.k = positive("k", k)

    def _evaluate(self, A, omega):
        r = _ratio(self.h, A)
        with np.errstate(invalid="ignore", divide="ignore"):
            rc = np.clip(r, 0.0, 2.0)
            u = _one_minus_ratio(self.h, A)  # 1 - h/X: (X - h) is exact near X = h (Sterbenz)
            s = np.clip(2.0 * _one_minus_ratio(0.5 * self.h, A), 0.0, 2.0)  # 2 - r, exact near X = h/2
            t = np.sqrt(rc * s)
            phi = _asin_minus(t, np.abs(np.clip(u, -1.0, 1.0)))
            re = np.where(rc <= 1.0, self.k * (1.0 - phi / np.pi), self.k * phi / np.pi)
            im = -(self.k / np.pi) * rc * s
            return np.where(r >= 2.0, 0.0, re + 1j * im)

    def compiled_form(self):
        """("backlash", (h, k, h / 2)): the kind and parameters of the compiled pipeline (dfloop.solve.compiled)."""
        return "backlash", (self.h, self.k, 0.5 * self.h)

    def amplitude_domain(self, omega=None):
        """(h/2, inf): N = 0 for X <= h/2 (the input never crosses the play)."""
        return _domain(0.5 * self.h, np.inf, omega)

    def tail_bound(self, A):
        """|N - k| <= k h / X (the supremum of |N - k| X / (k h) is 2/pi, reached as X -> inf)."""
        return self.k * self.h / np.asarray(A, float)

    def operator(self) -> PlayOperator:
        """A fresh :class:`PlayOperator` (play centred, output 0)."""
        return PlayOperator(self.h, self.k)

    def time_model(self, amplitude: float):
        """The play operator as three modes (free, engaged rising, engaged falling)."""
        return self.operator().time_model(amplitude, type(self).__name__)


# ------------------------------------------------------------------------------------ saturation, dead zone


class Saturation(StaticElement):
    """Saturation: y = k x for |x| <= limit, y = k limit sign(x) beyond.

    N = k for A <= limit, N = k f(limit / A) above, f(u) = (2/pi)(asin u + u sqrt(1 - u^2)).

    Limits: N(0) = k, N(inf) = 0.

    Parameters
    ----------
    limit : float
        Input level at which the element saturates (output saturates at +/- k limit), > 0.
    k : float
        Slope of the linear part, > 0.
    """

    def __init__(self, limit: float, k: float = 1.0):
        self.limit = positive("limit", limit)
        self.k = positive("k", k)

    def output(self, x):
        return self.k * np.clip(real_array(x, "x"), -self.limit, self.limit)

    def breakpoints(self, A_max=None):
        return np.array([self.limit])

    def _evaluate(self, A, omega):
        r = _ratio(self.limit, A)
        with np.errstate(invalid="ignore"):
            return _keep_nan(A, np.where(r >= 1.0, self.k, self.k * _f(np.clip(r, 0.0, 1.0))))

    def compiled_form(self):
        """("saturation", (limit, k)) for the compiled pipeline."""
        return "saturation", (self.limit, self.k)

    def amplitude_domain(self, omega=None):
        """(0, inf): N is non-zero for every amplitude (N(0) = k)."""
        return _domain(0.0, np.inf, omega)

    def tail_bound(self, A):
        """|N| <= (4/pi) k limit / A (f(u) <= 4 u / pi)."""
        return (4.0 / np.pi) * (1 + 1e-12) * self.k * self.limit / np.asarray(A, float)


class DeadZone(StaticElement):
    """Dead zone: y = 0 for |x| <= delta, y = k (x - delta sign x) beyond.

    N = k [1 - f(delta / A)] = (2 k / pi) phi(sqrt(1 - (delta/A)^2)) for A > delta, N = 0 exactly for
    A <= delta (phi(t) = asin t - t sqrt(1 - t^2); the second form is used near the edge, where the
    first cancels).

    Limits: N(0) = 0, N(inf) = k.

    Parameters
    ----------
    delta : float
        Half-width of the dead band, > 0.
    k : float
        Slope outside the dead band, > 0.
    """

    def __init__(self, delta: float, k: float = 1.0):
        self.delta = positive("delta", delta)
        self.k = positive("k", k)

    def output(self, x):
        x = real_array(x, "x")
        return self.k * (x - np.clip(x, -self.delta, self.delta))

    def breakpoints(self, A_max=None):
        return np.array([self.delta])

    def _evaluate(self, A, omega):
        r = _ratio(self.delta, A)
        with np.errstate(invalid="ignore"):
            rc = np.clip(r, 0.0, 1.0)
            gap = np.clip(_one_minus_ratio(self.delta, A), 0.0, 1.0)  # 1 - delta/A without cancellation
            near_edge = (2.0 / np.pi) * self.k * _asin_minus(np.sqrt(gap * (1.0 + rc)), rc)
            n = np.where(rc < 0.5, self.k * (1.0 - _f(rc)), near_edge)
            return np.where(r >= 1.0, 0.0, n)

    def compiled_form(self):
        """("dead_zone", (delta, k)) for the compiled pipeline."""
        return "dead_zone", (self.delta, self.k)

    def amplitude_domain(self, omega=None):
        """(delta, inf)."""
        return _domain(self.delta, np.inf, omega)

    def tail_bound(self, A):
        """|N - k| = k f(delta / A) <= (4/pi) k delta / A."""
        return (4.0 / np.pi) * (1 + 1e-12) * self.k * self.delta / np.asarray(A, float)


# -------------------------------------------------------------------------------------------------- relay


class RelayOperator:
    """Three-state relay with switching levels ``on`` >= |``off``|, output in {-M, 0, +M}: ``op(x) -> y``.

    Crossings are strict: from 0 it switches to +M when x > on and to -M when x < -on; from +M it
    leaves when x < off (to -M if also x < -on, else to 0); from -M symmetrically when x > -off.
    Starts at rest, output 0. With on = off = 0 (ideal relay) the output is M sign(x) for x != 0
    (x = 0 holds the last output).
    """

    def __init__(self, M: float, on: float, off: float):
        self.M = positive("M", M)
        self.on = nonnegative("on", on)
        self.off = in_closed_interval("off", off, -self.on, self.on)
        self.state = 0

    def __call__(self, x: float) -> float:
        x = _scalar_input(x)
        if self.state == 1 and x < self.off:
            self.state = -1 if x < -self.on else 0
        elif self.state == -1 and x > -self.off:
            self.state = 1 if x > self.on else 0
        elif self.state == 0:
            self.state = 1 if x > self.on else (-1 if x < -self.on else 0)
        return self.M * self.state

    def __deepcopy__(self, memo):
        new = object.__new__(RelayOperator)
        new.__dict__.update(self.__dict__)  # numbers only: a shallow copy is a deep copy
        return new

    def time_model(self, amplitude: float = 1.0, name: str = "RelayOperator"):
        """The relay's exact modes (-M, 0, +M) switched by its levels."""
        M, on, off = self.M, self.on, self.off
        return relay_model(M, on, off, name, lambda: RelayOperator(M, on, off))

    def __repr__(self) -> str:
        return f"RelayOperator(M={self.M!r}, on={self.on!r}, off={self.off!r}, state={self.state})"


class Relay(DescribingFunction):
    """Relay of output level ``M`` with optional ``hysteresis`` a and ``dead_zone`` d.

    Switching levels (both combine): the output switches on (to +M) when x rises through the on-level
    d + a, and off when x falls back through the off-level d - a (symmetrically for negative x). So a = 0
    gives the dead-zone relay (levels +/- d), d = 0 the hysteresis relay (up at x = +a, down at x = -a),
    and d > 0, a > 0 the classical three-level relay with hysteresis. For A >= d + a:

        N = (2M / (pi A)) [sqrt(1 - ((d + a)/A)^2) + sqrt(1 - ((d - a)/A)^2)] - j 4 M a / (pi A^2),

    which reduces to (4M / (pi A)) exp(-j asin(a / A)) for d = 0 and to 4M sqrt(1 - (d/A)^2) / (pi A) for
    a = 0. Switching needs x to pass a level strictly, so N = 0 exactly for A <= d + a (no switching, no
    fundamental), and N(0) = inf for the ideal relay (a = d = 0).

    Limits: N(0) = inf for the ideal relay (a = d = 0), 0 otherwise; N(inf) = 0. N is continuous for A > 0
    without hysteresis; with it, N jumps from 0 to a non-zero value at A = d + a.

    Parameters
    ----------
    M : float
        Output level, > 0.
    hysteresis : float
        Half-width a of each hysteresis band, >= 0.
    dead_zone : float
        Centre d of the switching band (the dead-zone half-width when a = 0), >= 0.
    """

    def __init__(self, M: float = 1.0, hysteresis: float = 0.0, dead_zone: float = 0.0):
        self.M = positive("M", M)
        self.hysteresis = nonnegative("hysteresis", hysteresis)
        self.dead_zone = nonnegative("dead_zone", dead_zone)

    @property
    def continuous(self) -> bool:
        """Whether N is continuous (no hysteresis)."""
        return self.hysteresis == 0.0

    @property
    def on_level(self) -> float:
        """Input level d + a at which the output switches on."""
        return self.dead_zone + self.hysteresis

    @property
    def off_level(self) -> float:
        """Input level d - a at which the output switches off (negative when a > d)."""
        return self.dead_zone - self.hysteresis

    def _evaluate(self, A, omega):
        on, off = self.on_level, self.off_level
        r_on, r_off = _ratio(on, A), _ratio(off, A)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            c_on = np.clip(r_on, -1.0, 1.0)
            c_off = np.clip(r_off, -1.0, 1.0)
            gap_on = np.clip(_one_minus_ratio(on, A), 0.0, 2.0)  # 1 - on/A without cancellation
            gap_off = np.clip(_one_minus_ratio(off, A), 0.0, 2.0)
            re = (2.0 / np.pi) * (self.M / A) * (  # scaled so that neither pi A nor 2 M overflows
                np.sqrt(gap_on * (1.0 + c_on)) + np.sqrt(gap_off * (1.0 + c_off))
            )
            im = 0.0 if self.hysteresis == 0.0 else -(4.0 / np.pi) * ((self.M / A) * (self.hysteresis / A))
            n = re + 1j * im
            if on == 0.0:
                return np.where(A == 0.0, complex(np.inf, 0.0), n)
            return np.where(A <= on, 0.0, n)

    def compiled_form(self):
        """("relay", (M, hysteresis, on level, off level)) for the compiled pipeline."""
        return "relay", (self.M, self.hysteresis, self.on_level, self.off_level)

    def amplitude_domain(self, omega=None):
        """(d + a, inf)."""
        return _domain(self.on_level, np.inf, omega)

    def tail_bound(self, A):
        """|N| <= 4 M / (pi A)."""
        return (4.0 / np.pi) * (1 + 1e-12) * self.M / np.asarray(A, float)

    def operator(self) -> RelayOperator:
        """A fresh :class:`RelayOperator` at rest (output 0 until |x| exceeds the on-level d + a)."""
        return RelayOperator(self.M, self.on_level, self.off_level)

    def time_model(self, amplitude: float):
        """The relay as three modes (-M, 0, +M) switched by its levels."""
        return self.operator().time_model(amplitude, type(self).__name__)


# ------------------------------------------------------------------------------------- further elements


class CubicStiffness(StaticElement):
    """Cubic (Duffing) spring: y = k1 x + k3 x^3, N = k1 + 3 k3 A^2 / 4.

    Limits: N(0) = k1, N(inf) = +inf (hardening, k3 > 0) or -inf (softening); beyond X ~ 1e154 m the
    value overflows to that infinity.

    Parameters
    ----------
    k1 : float
        Linear stiffness (N/m), > 0.
    k3 : float
        Cubic stiffness (N/m^3), finite and non-zero: > 0 hardening, < 0 softening.
    """

    input_name = "X"
    input_unit = "m"

    def __init__(self, k1: float, k3: float):
        self.k1 = positive("k1", k1)
        self.k3 = finite("k3", k3)
        if self.k3 == 0.0:
            raise DfloopError("k3 must be non-zero, got 0.0 (use a linear gain for k3 = 0)")

    def output(self, x):
        x = real_array(x, "x")
        with np.errstate(over="ignore"):  # Horner form: the limits at x = +/-inf, not inf - inf
            return x * (self.k1 + self.k3 * (x * x))

    def time_model(self, amplitude: float):
        """Smooth, with its exact slope k1 + 3 k3 x^2 for the variational equation, and its compiled form (the
        compiled integrator evaluates f itself) unless a subclass computes its own output."""
        k1, k3 = self.k1, self.k3
        own = type(self).output is CubicStiffness.output
        return Smooth(type(self).__name__, self.output, lambda x: k1 + 3.0 * k3 * (x * x),
                      form=self.compiled_form() if own else None)

    def _evaluate(self, A, omega):
        with np.errstate(over="ignore"):  # beyond ~1e154 m: +/-inf, the rounded value of the true N
            return self.k1 + 0.75 * self.k3 * A * A

    def compiled_form(self):
        """("cubic", (k1, 0.75 k3)) for the compiled pipeline."""
        return "cubic", (self.k1, 0.75 * self.k3)

    def amplitude_domain(self, omega=None):
        """(0, inf) when hardening; (0, sqrt(4 k1 / (3 |k3|))) when softening (N = 0 at the upper end)."""
        hi = np.inf if self.k3 > 0 else math.sqrt(4.0 * self.k1 / (3.0 * -self.k3))
        return _domain(0.0, hi, omega)

    def head_bound(self, A):
        """|N - k1| = (3/4) |k3| A^2 (plus the rounding of k1 + 3 k3 A^2 / 4, a few ulp of k1)."""
        return 0.75 * (1 + 1e-12) * abs(self.k3) * np.asarray(A, float) ** 2 + 4 * np.spacing(self.k1)


class Quantizer(StaticElement):
    """Mid-tread quantizer: y = step * round(x / step) (half-way points rounded away from zero).

    It is a sum of dead-zone relays of level ``step`` at thresholds c_i = (i - 1/2) step, so

        N = (4 step / (pi A)) sum_{i : c_i < A} sqrt(1 - (c_i / A)^2),

    N = 0 exactly for A <= step/2, N -> 1 as A -> inf. The sum has A/step + 1/2 terms; more than 1e7
    levels raise ``ValueError`` (the quantizer is then a unit gain to about 1e-7).

    Limits: N(0) = 0, N(inf) = 1.

    Parameters
    ----------
    step : float
        Quantization step, > 0.
    """

    def __init__(self, step: float):
        self.step = positive("step", step)

    def output(self, x):
        x = real_array(x, "x")
        with np.errstate(over="ignore", invalid="ignore"):
            q = self.step * np.sign(x) * np.floor(np.abs(x) / self.step + 0.5)
        return np.where(np.abs(x) > self.step * 2.0**52, x, q)  # beyond: x is a multiple of step to rounding

    def time_model(self, amplitude: float):
        """One mode per level, levels modelled up to 64 ``amplitude`` (a motion leaving them stops the flow)."""
        return static_model(self.output, self.breakpoints, type(self).__name__, amplitude, unbounded_levels=True)

    def breakpoints(self, A_max: float | None = None) -> np.ndarray:
        """Thresholds (i - 1/2) step below ``A_max`` (required: there are infinitely many)."""
        if A_max is None:
            raise DfloopError("A_max is required: a quantizer has infinitely many breakpoints, got A_max=None")
        n = self._levels(np.asarray(A_max, dtype=float))
        return (np.arange(1, int(n) + 1) - 0.5) * self.step

    def _levels(self, A: np.ndarray) -> np.ndarray:
        with np.errstate(over="ignore"):
            n = np.ceil(np.nan_to_num(A, nan=0.0, posinf=0.0) / self.step - 0.5)
        n = np.maximum(n, 0.0)
        if n.size and n.max() > _QUANTIZER_MAX_LEVELS:
            worst = float(np.nan_to_num(A, nan=0.0, posinf=0.0).max())
            raise DfloopError(
                f"{self.input_name} / step = {worst / self.step:.6g} exceeds the bound of {_QUANTIZER_MAX_LEVELS} "
                f"quantization levels ({self.input_name} = {worst!r}, step = {self.step!r}): the quantizer is a "
                "unit gain there to about 1e-7; use a unit gain, or a larger step"
            )
        return n

    def _evaluate(self, A, omega):
        n = self._levels(A)
        total = np.zeros(A.shape)
        chunk = 4096
        n_max = int(n.max()) if n.size else 0
        with np.errstate(invalid="ignore", divide="ignore"):
            for start in range(0, n_max, chunk):  # bounded: n_max / chunk <= 2442 passes
                i = np.arange(start + 1, min(start + chunk, n_max) + 1)
                c = (i - 0.5) * self.step
                r = c / A[..., None]
                rc = np.clip(r, 0.0, 1.0)
                terms = np.where(i <= n[..., None], np.sqrt((1.0 - rc) * (1.0 + rc)), 0.0)
                total += terms.sum(axis=-1)
            n_out = (4.0 / np.pi) * (self.step * (total / A))  # step total / A <= 1 + step / A: no overflow
        return _keep_nan(A, np.where(A <= 0.5 * self.step, 0.0, np.where(np.isinf(A), 1.0, n_out)))

    def amplitude_domain(self, omega=None):
        """(step/2, step 1e7): N = 0 up to step/2; beyond 1e7 levels the element refuses (its level bound)."""
        return _domain(0.5 * self.step, self.step * _QUANTIZER_MAX_LEVELS, omega)

    def tail_bound(self, A):
        """|N - 1| <= step / (2 A) (checked on a dense scan with every threshold; the largest ratio, 1/2, is
        at A = step/2 where N = 0)."""
        return 0.5 * (1 + 1e-9) * self.step / np.asarray(A, float)


class PreloadedSpring(StaticElement):
    """Preloaded spring: y = k x + F0 sign(x), N = k + 4 F0 / (pi A) (N(0) = inf).

    Limits: N(0) = inf, N(inf) = k.

    Parameters
    ----------
    preload : float
        Preload force F0 (N), > 0.
    k : float
        Spring stiffness (N/m), >= 0.
    """

    input_name = "X"
    input_unit = "m"

    def __init__(self, preload: float, k: float = 1.0):
        self.preload = positive("preload", preload)
        self.k = nonnegative("k", k)

    def output(self, x):
        x = real_array(x, "x")
        return self.k * x + self.preload * np.sign(x)

    def breakpoints(self, A_max=None):
        return np.array([0.0])

    def _evaluate(self, A, omega):
        with np.errstate(divide="ignore", over="ignore"):
            return self.k + (4.0 / np.pi) * (self.preload / A)

    def compiled_form(self):
        """("preload", (k, preload)) for the compiled pipeline."""
        return "preload", (self.k, self.preload)

    def amplitude_domain(self, omega=None):
        """(0, inf)."""
        return _domain(0.0, np.inf, omega)

    def tail_bound(self, A):
        """|N - k| = 4 F0 / (pi A)."""
        return (4.0 / np.pi) * (1 + 1e-12) * self.preload / np.asarray(A, float)


class CoulombViscousFriction(StaticElement):
    """Coulomb plus viscous friction as a static function of the sliding velocity v (the input).

    y = Fc sign(v) + c v (N), input amplitude V in m/s: N = c + 4 Fc / (pi V) (N(0) = inf). Static in the
    input because the input is the velocity: the element sits in a loop whose plant outputs velocity
    (e.g. 1 / (m s + ...)); a position-driven loop must include the differentiation in the plant.

    Limits: N(0) = inf, N(inf) = c.

    Parameters
    ----------
    Fc : float
        Coulomb friction force (N), > 0.
    c : float
        Viscous coefficient (N s/m), >= 0.
    """

    input_name = "V"
    input_unit = "m/s"

    def __init__(self, Fc: float, c: float = 0.0):
        self.Fc = positive("Fc", Fc)
        self.c = nonnegative("c", c)

    def output(self, x):
        x = real_array(x, "x")
        return self.c * x + self.Fc * np.sign(x)

    def breakpoints(self, A_max=None):
        return np.array([0.0])

    def _evaluate(self, A, omega):
        with np.errstate(divide="ignore", over="ignore"):
            return self.c + (4.0 / np.pi) * (self.Fc / A)

    def compiled_form(self):
        """("friction", (c, Fc)) for the compiled pipeline."""
        return "friction", (self.c, self.Fc)

    def amplitude_domain(self, omega=None):
        """(0, inf)."""
        return _domain(0.0, np.inf, omega)

    def tail_bound(self, A):
        """|N - c| = 4 Fc / (pi V)."""
        return (4.0 / np.pi) * (1 + 1e-12) * self.Fc / np.asarray(A, float)
