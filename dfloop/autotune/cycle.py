"""The exact relay oscillation of a process model with dead time (symmetric or biased relay, with hysteresis).

The relay acts on x = -c (c the process output, setpoint 0 in deviation variables): it switches to ``high`` when c
falls through -a and to ``low`` when c rises through +a (a the hysteresis). The process input, delayed by L, is then
``high`` for h1 seconds and ``low`` for h2 seconds. Between its switches the model's state follows the closed form
of :meth:`ProcessModel.propagate`, so the periodic state s0 at the input's rise solves the linear equation
s0 = Phi(h2) (Phi(h1) s0 + g_high(h1)) + g_low(h2), and (h1, h2) solve the two switching conditions
c((h1 - L) mod P) = +a, c((P - L) mod P) = -a (P = h1 + h2). For a symmetric relay (high = -low) the orbit is
odd-symmetric (h1 = h2 = h, s(h) = -s(0)) and h is bracketed on a grid and found by Brent's method (with a dead time
the loop also has faster periodic solutions, h < L, which a relay experiment does not settle on: the slowest
orbit is taken); a bias is then
reached by continuation from the symmetric orbit (Newton-type ``scipy.optimize.root``). Every orbit is checked
for a spurious earlier switch on a grid of each segment (the relay must hold its level until its switching time).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .models import ProcessModel

__all__ = ["RelayCycle", "relay_cycle", "fopdt_relay_cycle", "fopdt_biased_relay_cycle"]

_CHECK_POINTS = 400        # grid points per segment of the earlier-switch check
_SCAN = 400                # grid of the half-period scan (log spaced)
_CONTINUATION = 8          # bias continuation steps


@dataclass(frozen=True, repr=False)
class RelayCycle:
    """The exact relay oscillation of a :class:`ProcessModel`.

    Time origin: the relay's switch to ``high`` (what a recording shows as the rise of u). The process input
    follows L seconds later.

    Attributes
    ----------
    model : ProcessModel
    high, low : float
        Relay output levels (process input unit), high > low.
    hysteresis : float
        a >= 0 (process output unit): switch to high at c = -a (falling), to low at c = +a (rising).
    h1, h2 : float
        Time (s) the relay output stays high, low; the period is h1 + h2.
    state : ndarray
        Model state when the process input rises to ``high``.
    """

    model: ProcessModel
    high: float
    low: float
    hysteresis: float
    h1: float
    h2: float
    state: np.ndarray

    @property
    def period(self) -> float:
        return self.h1 + self.h2

    def output(self, t) -> np.ndarray:
        """Process output c at times t (s) after a relay switch to ``high`` (any t: the orbit is periodic)."""
        P, L = self.period, self.model.L
        tau = np.mod(np.asarray(t, float) - L, P)      # time since the process input rose
        first = tau < self.h1
        z1 = self.model.propagate(self.state, self.high, self.h1)
        out = np.where(first, self.model.propagate(self.state, self.high, np.where(first, tau, 0.0))[..., -1],
                       self.model.propagate(z1, self.low, np.where(first, 0.0, tau - self.h1))[..., -1])
        return out

    def relay_output(self, t) -> np.ndarray:
        """Relay output u at times t after its switch to ``high``."""
        return np.where(np.mod(np.asarray(t, float), self.period) < self.h1, self.high, self.low)

    def extremes(self) -> tuple[float, float]:
        """(max c, min c) over the orbit (grid of 4096 points per period, each extreme refined by a bounded
        scalar search to 1e-13 s, and the output at the input's switches, where c has its kinks)."""
        from scipy.optimize import minimize_scalar

        P = self.period
        t = np.linspace(0.0, P, 4097)
        c = self.output(t)
        dt = t[1] - t[0]
        corners = self.output(np.array([self.model.L, self.model.L + self.h1]))   # the input's switches (kinks)
        out = []
        for sign in (1.0, -1.0):
            i = int(np.argmax(sign * c))
            r = minimize_scalar(lambda s: -sign * float(self.output(s)), bounds=(t[i] - dt, t[i] + dt),
                                method="bounded", options={"xatol": 1e-13})
            out.append(max(sign * c[i], -r.fun, *(sign * corners)) * sign)
        return out[0], out[1]

    @property
    def amplitude(self) -> float:
        """Half the peak-to-peak process output (max c - min c) / 2: the relay input's amplitude a an experimenter
        reads."""
        hi, lo = self.extremes()
        return 0.5 * (hi - lo)

    @property
    def mean_output(self) -> float:
        """Mean of c over the period (equals K times the mean relay output, the static gain's identity): 64-point
        Gauss-Legendre on each segment of constant process input, where c is smooth (exact to rounding)."""
        x, w = np.polynomial.legendre.leggauss(64)
        L, total = self.model.L, 0.0
        for a, b in ((L, L + self.h1), (L + self.h1, L + self.period)):
            total += 0.5 * (b - a) * float(w @ self.output(0.5 * (b - a) * x + 0.5 * (a + b)))
        return total / self.period

    @property
    def mean_input(self) -> float:
        return (self.high * self.h1 + self.low * self.h2) / self.period

    def ultimate_estimate(self) -> tuple[float, float]:
        """The relay experiment's reading (Ku, Tu) = (4 d / (pi a), period), d = (high - low) / 2."""
        return 2.0 * (self.high - self.low) / (math.pi * self.amplitude), self.period

    def __repr__(self) -> str:
        return (f"RelayCycle({self.model!r}, relay {self.high:g}/{self.low:g} hysteresis {self.hysteresis:g}: "
                f"period {self.period:.6g} s (high {self.h1:.6g} s, low {self.h2:.6g} s), amplitude "
                f"{self.amplitude:.6g})")

    def to_dict(self) -> dict:
        hi, lo = self.extremes()
        return {"model": self.model.to_dict(), "high": self.high, "low": self.low, "hysteresis": self.hysteresis,
                "h1": self.h1, "h2": self.h2, "period": self.period, "max": hi, "min": lo,
                "amplitude": 0.5 * (hi - lo)}


def _periodic_state(model, high, low, h1, h2):
    P1, g1 = model.transition(high, h1)
    P2, g2 = model.transition(low, h2)
    n = model.order
    return np.linalg.solve(np.eye(n) - P2 @ P1, P2 @ g1 + g2)


def _c_at(model, high, low, s0, h1, tau):
    """c at process-input time tau in [0, h1 + h2)."""
    if tau < h1:
        return float(model.propagate(s0, high, tau)[-1])
    z1 = model.propagate(s0, high, h1)
    return float(model.propagate(z1, low, tau - h1)[-1])


def _residuals(model, high, low, a, h1, h2):
    s0 = _periodic_state(model, high, low, h1, h2)
    P, L = h1 + h2, model.L
    return np.array([_c_at(model, high, low, s0, h1, (h1 - L) % P) - a,
                     _c_at(model, high, low, s0, h1, (P - L) % P) + a]), s0


def _symmetric_half_periods(model, M, a):
    """Half periods h where the odd-symmetric orbit meets its switching condition c((h - L) mod 2h) = a, slowest
    first (a generator: the caller stops at the first valid orbit)."""
    from scipy.optimize import brentq

    L = model.L

    def f(h):
        return _residuals(model, M, -M, a, h, h)[0][0]

    scale = L + sum(model.T)
    grid = np.geomspace(1e-4 * scale, 50.0 * scale, _SCAN)
    vals = _symmetric_scan(model, M, a, grid)
    for i in np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[::-1]:
        h = brentq(f, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15, maxiter=200)
        if abs(f(h)) <= 1e-9 * (abs(model.K * M) + a):
            yield h


def _symmetric_scan(model, M, a, h):
    """c((h - L) mod 2h) - a of the odd-symmetric orbit for an array of half periods h (vectorised)."""
    n = model.order
    zero = [np.zeros_like(h)] * n
    gamma = model.propagate(zero, M, h)                                   # (nh, n)
    Phi = np.stack([model.propagate([np.full_like(h, float(i == j)) for i in range(n)], 0.0, h)
                    for j in range(n)], axis=-1)                          # (nh, n, n)
    s0 = np.linalg.solve(np.eye(n) + Phi, -gamma[..., None])[..., 0]      # s(h) = -s(0)
    tau = np.mod(h - model.L, 2.0 * h)
    first = tau < h
    z0 = [s0[:, i] for i in range(n)]
    c1 = model.propagate(z0, M, np.where(first, tau, 0.0))[:, -1]
    z1 = model.propagate(z0, M, h)
    c2 = model.propagate([z1[:, i] for i in range(n)], -M, np.where(first, 0.0, tau - h))[:, -1]
    return np.where(first, c1, c2) - a


def _valid(model, high, low, a, h1, h2, s0) -> bool:
    """The relay holds each level until its switching time: c < a while high (relay time 0..h1), c > -a while
    low (h1..P), on a grid of each segment (ends excluded)."""
    cyc = RelayCycle(model, high, low, a, h1, h2, s0)
    tol = 1e-9 * (abs(model.K) * (high - low) + a)
    t_hi = np.linspace(0.0, h1, _CHECK_POINTS + 2)[1:-1]
    t_lo = np.linspace(h1, h1 + h2, _CHECK_POINTS + 2)[1:-1]
    return bool(np.all(cyc.output(t_hi) < a + tol) and np.all(cyc.output(t_lo) > -a - tol))


def relay_cycle(model: ProcessModel, high: float = 1.0, low: float | None = None, hysteresis: float = 0.0, *,
                guess: tuple[float, float] | None = None, tol: float = 1e-13) -> RelayCycle:
    """The exact relay oscillation of ``model`` with relay levels high/low and hysteresis a.

    Parameters
    ----------
    model : ProcessModel
        FOPDT or SOPDT (K > 0).
    high, low : float
        Relay output levels (process input unit); ``low`` defaults to -high. A bias (high + low != 0) makes the
        orbit asymmetric; both K high > a and K low < -a are needed for the output to reach both thresholds.
    hysteresis : float
        a >= 0, in process output units.
    guess : (h1, h2), optional
        Start of the solve (s), e.g. a neighbouring model's orbit; default: the symmetric orbit, then continuation
        in the bias.
    tol : float
        Tolerance of the switching conditions, relative to K (high - low).

    Returns
    -------
    RelayCycle

    Raises
    ------
    ValueError
        Bad levels or hysteresis; no orbit with one switch per level (the message says what was tried).
    """
    from scipy.optimize import root

    if not isinstance(model, ProcessModel):
        raise ValueError(f"model must be a ProcessModel, got {type(model).__name__}")
    high = float(high)
    low = -high if low is None else float(low)
    a = float(hysteresis)
    if not (math.isfinite(high) and math.isfinite(low) and high > low):
        raise ValueError(f"the relay levels must be finite with high > low; got high={high!r}, low={low!r}")
    if not (math.isfinite(a) and a >= 0):
        raise ValueError(f"hysteresis must be finite and >= 0; got {hysteresis!r}")
    if not (model.K * high > a and model.K * low < -a):
        raise ValueError(f"the output never reaches both switching levels +-{a:g}: K high = {model.K * high:g}, K low "
                         f"= {model.K * low:g}; the relay needs K high > a and K low < -a")
    scale = model.K * (high - low) + a
    M, b = 0.5 * (high - low), 0.5 * (high + low)

    def solve(hi, lo, start):
        sol = root(lambda h: _residuals(model, hi, lo, a, h[0], h[1])[0] / scale, start, method="hybr",
                   options={"xtol": 1e-14})
        h = sol.x
        if not (np.all(np.isfinite(h)) and np.all(h > 0)):
            return None
        r, s0 = _residuals(model, hi, lo, a, h[0], h[1])
        if np.max(np.abs(r)) > tol * scale * 1e3 or not _valid(model, hi, lo, a, h[0], h[1], s0):
            return None
        return h, s0

    if guess is not None:
        got = solve(high, low, np.asarray(guess, float))
        if got is not None:
            return RelayCycle(model, high, low, a, float(got[0][0]), float(got[0][1]), got[1])
    # the slowest orbit: faster ones (h < L) exist with a delay, and the relay does not settle on them
    slowest = next((h for h in _symmetric_half_periods(model, M, a)
                    if _valid(model, M, -M, a, h, h, _residuals(model, M, -M, a, h, h)[1])), None)
    if slowest is None:
        raise ValueError(f"no symmetric relay orbit of {model!r} with level {M:g} and hysteresis {a:g} (half periods "
                         f"scanned {1e-4:g}..50 times L + sum T)")
    h = np.array([slowest, slowest])
    if b == 0:
        _, s0 = _residuals(model, high, low, a, h[0], h[1])
        return RelayCycle(model, high, low, a, float(h[0]), float(h[1]), s0)
    for k in range(1, _CONTINUATION + 1):
        got = solve(b * k / _CONTINUATION + M, b * k / _CONTINUATION - M, h)
        if got is None:
            raise ValueError(f"the relay orbit of {model!r} was lost in the continuation from the symmetric relay to "
                             f"bias {b:g} (step {k} of {_CONTINUATION})")
        h, s0 = got
    return RelayCycle(model, high, low, a, float(h[0]), float(h[1]), s0)


def fopdt_relay_cycle(K: float, T: float, L: float, M: float, a: float = 0.0) -> tuple[float, float]:
    """Exact relay oscillation of K e^{-Ls} / (T s + 1) with a relay of level M and hysteresis a (switches at
    x = +-a, x = -c): (peak |x|, period).

    Let the relay switch to +M at t = 0 (c falls through -a); the plant input follows at t = L, when c is at its
    extreme -c1; then c = K M - (K M + c1) e^{-(t - L)/T}. Symmetry gives c(L + h) = c1 (h the half period) and
    the next switch c(h) = a. With q = e^{-h/T}: c1 = K M (1 - q) / (1 + q) and
    q = (1 - a / (K M)) / (2 e^{L/T} - 1 + a / (K M)), so h = -T ln q, peak c1 = K M tanh(h / 2T), period 2h.
    Valid when h > L (always for a = 0) and a < K M.
    """
    if not (K > 0 and T > 0 and L >= 0 and M > 0 and 0 <= a < K * M):
        raise ValueError(f"fopdt_relay_cycle needs K, T, M > 0, L >= 0 and 0 <= a < K M; got K={K}, T={T}, L={L}, "
                         f"M={M}, a={a}")
    r = a / (K * M)
    q = (1.0 - r) / (2.0 * math.exp(L / T) - 1.0 + r)
    h = -T * math.log(q)
    if h <= L:
        raise ValueError(f"no symmetric relay oscillation of this form: half period {h:g} s <= delay {L:g} s")
    return K * M * math.tanh(h / (2.0 * T)), 2.0 * h


def fopdt_biased_relay_cycle(K: float, T: float, L: float, high: float, low: float,
                             a: float = 0.0) -> tuple[float, float, float, float]:
    """Exact oscillation of K e^{-Ls} / (T s + 1) under a biased relay (levels high > 0 > low, hysteresis a):
    (max c, min c, h1, h2) with h1, h2 the times at high and low.

    The process input rises to ``high`` when c is at its minimum c_lo (L after c fell through -a), so
    c_lo = K low + (-a - K low) e^{-L/T}, and likewise c_hi = K high + (a - K high) e^{-L/T}. Rising from c_lo towards
    K high, c reaches +a after h1 - L: e^{-(h1 - L)/T} = (K high - a) / (K high - c_lo); falling from c_hi towards
    K low it reaches -a after h2 - L: e^{-(h2 - L)/T} = (-a - K low) / (c_hi - K low).
    """
    if not (K > 0 and T > 0 and L >= 0 and high > 0 > low and K * high > a and K * low < -a and a >= 0):
        raise ValueError(f"fopdt_biased_relay_cycle needs K, T > 0, L >= 0, high > 0 > low, a >= 0 and K high > a, "
                         f"K low < -a; got K={K}, T={T}, L={L}, high={high}, low={low}, a={a}")
    e = math.exp(-L / T)
    c_lo = K * low + (-a - K * low) * e
    c_hi = K * high + (a - K * high) * e
    h1 = L + T * math.log((K * high - c_lo) / (K * high - a))
    h2 = L + T * math.log((c_hi - K * low) / (-a - K * low))
    return c_hi, c_lo, h1, h2
