"""Dual-input describing functions: the element's response to a biased sinusoid e = B + A sin(theta).

Convention (docs/bias_forced.md): over one period of theta,

    mean output     m(B, A)   = (1 / (2 pi)) int y d theta            (= B N_B(B, A)),
    bias gain       N_B(B, A) = m(B, A) / B,
    sinusoid gain   N_A(B, A) = (1 / (pi A)) int y (sin theta + j cos theta) d theta

(N_A is complex for elements with memory; N_A(0, A) is the symmetric DF N(A)). The mean output ``m`` is what the
bias equations use (it is finite at B = 0, where N_B of an asymmetric element is not).

How each element is evaluated:

- piecewise-affine static maps (:class:`~dfloop.Saturation`, :class:`~dfloop.DeadZone`, :class:`~dfloop.Relay`
  without hysteresis, :class:`~dfloop.PreloadedSpring`, :class:`~dfloop.CoulombViscousFriction`, or any map given
  by :meth:`DualInputDF.piecewise_affine`, e.g. a relay with unequal levels): closed form. With the map written as
  f(e) = c0 + c1 e + sum_i (dc0_i + dc1_i e) H(e - L_i), each step contributes through the exact integrals over
  {theta : e > L} = (alpha, pi - alpha), alpha = asin(clip((L - B) / A)):
  I0 = pi - 2 alpha, I1 = int sin = 2 cos alpha, I2 = int sin^2 = (pi - 2 alpha) / 2 + sin alpha cos alpha;
- relays with hysteresis: exact, from the switching phases (where e crosses the switching levels): in closed form
  without a dead zone, and with one from the output level held between them (the relay's switching rule run over
  three periods of the interval midpoints, vectorised);
- :class:`~dfloop.Backlash`: exact: the play operator's periodic orbit commutes with a shift of its input, so
  m = k B and N_A(B, A) = N(A);
- any other static function (a :class:`~dfloop.describing.static.StaticElement` or a callable f(x) with optional
  ``breakpoints``): Gauss-Legendre quadrature on the smooth pieces between the phases where e crosses a breakpoint
  (located exactly: theta = asin((L - B) / A)), as :class:`~dfloop.NumericDF` does; ``error_estimate`` compares
  two node counts.
"""
from __future__ import annotations

import math

import numpy as np

from .._checks import integer_at_least, real_array
from ..errors import DfloopError
from .base import DescribingFunction
from .time_model import PiecewiseAffine
from .static import (Backlash, CoulombViscousFriction, DeadZone, PreloadedSpring, Relay, Saturation,
                     StaticElement)

__all__ = ["DualInputDF"]

_MAX_NODES = 512


def _bias_amplitude(B, A) -> tuple[np.ndarray, np.ndarray]:
    """Validated, broadcast (B, A): B real and finite, A real, finite and > 0."""
    b = real_array(B, "B")
    a = real_array(A, "A")
    if not np.all(np.isfinite(b)):
        raise DfloopError(f"B (bias) must be finite, got {b[~np.isfinite(b)].ravel()[0]!r}")
    if not np.all(np.isfinite(a) & (a > 0)):
        raise DfloopError(f"A (amplitude) must be finite and > 0, got {a[~(np.isfinite(a) & (a > 0))].ravel()[0]!r}")
    try:
        return np.broadcast_arrays(b.astype(float), a.astype(float))
    except ValueError:
        raise DfloopError(f"B and A must broadcast together, got shapes {b.shape} and {a.shape}") from None


def _affine_map(L: np.ndarray, c0: np.ndarray, c1: np.ndarray):
    """The vectorised map f(e) = c0[i] + c1[i] e on the i-th piece (value at a level: the piece below it)."""

    def f(x):
        x = np.asarray(x, float)
        i = np.searchsorted(L, x, side="left")
        return c0[i] + c1[i] * x

    return f


class DualInputDF:
    """Dual-input describing function of an element: mean output and sinusoid gain for e = B + A sin(theta).

    Parameters
    ----------
    element : DescribingFunction or callable
        A dfloop element (closed forms for saturation, dead zone, relays, preloaded spring, Coulomb friction,
        backlash; quadrature for any other :class:`~dfloop.describing.static.StaticElement`), or a vectorised
        static function ``y = f(x)`` (symmetric or not).
    breakpoints : array_like, optional
        For a callable ``f``: the input levels where f or its slope jumps, signed (used as given: an asymmetric map
        has asymmetric breakpoints). Without them the quadrature resolves jumps only through ``nodes`` and is not
        accurate to rounding for a discontinuous f.
    nodes : int
        Gauss-Legendre nodes per smooth piece (quadrature path only), in [4, 512].

    Attributes
    ----------
    method : str
        ``"closed form"``, ``"switching phases"`` (relays with hysteresis), ``"shift invariance"`` (backlash) or
        ``"quadrature"``.
    memory : bool
        Whether N_A can be complex (the element has memory).
    function : callable or None
        The static map y = f(x) (vectorised) when the element is memoryless, None for relays with hysteresis and
        backlash; with ``breakpoints`` (signed input levels where f or f' jumps) it is what the exact engine needs.

    Notes
    -----
    All methods take ``B`` (bias, element input units, real, finite) and ``A`` (amplitude, > 0, finite) with numpy
    broadcasting. A relay with hysteresis whose input does not cross both of its switching levels holds one output
    level forever (which one depends on the history): it is taken as the level on the side of B (the upper one for
    B >= 0); so is a backlash with A <= h/2 (the play centred on B).
    """

    def __init__(self, element, *, breakpoints=None, nodes: int = 48):
        nodes = integer_at_least("nodes", nodes, 4)
        if nodes > _MAX_NODES:
            raise DfloopError(f"nodes must be <= {_MAX_NODES} (Gauss-Legendre nodes per piece), got {nodes!r}")
        self.nodes = nodes
        self.element = element
        self.memory = False
        self._affine = None
        self._relay = None
        self._f = None
        self._time_model = None
        self.function, levels = None, np.empty(0)
        if isinstance(element, StaticElement):
            self.function = element.output
            try:
                bp = np.asarray(element.breakpoints(None) if breakpoints is None else breakpoints, float).ravel()
            except DfloopError as err:
                raise DfloopError(f"{err}; pass breakpoints=element.breakpoints(A_max) with A_max the largest |B| + A "
                                  "of interest") from None
            levels = np.unique(np.concatenate([bp, -bp]))  # an element's breakpoints are levels >= 0, mirrored
        elif callable(element) and not isinstance(element, DescribingFunction):
            self.function = element
            if breakpoints is not None:  # a callable's breakpoints are signed: used as given
                levels = np.unique(np.asarray(breakpoints, float).ravel())
        if not np.all(np.isfinite(levels)):
            raise DfloopError(f"breakpoints must be finite, got {breakpoints!r}")
        self.breakpoints = self._levels = levels
        if isinstance(element, Saturation):
            L, k = element.limit, element.k
            self._affine = (np.array([-L, L]), np.array([-k * L, 0.0, k * L]), np.array([0.0, k, 0.0]))
        elif isinstance(element, DeadZone):
            d, k = element.delta, element.k
            self._affine = (np.array([-d, d]), np.array([k * d, 0.0, -k * d]), np.array([k, 0.0, k]))
        elif isinstance(element, Relay) and element.hysteresis == 0.0:
            M, d = element.M, element.dead_zone
            if d == 0.0:
                self._affine = (np.array([0.0]), np.array([-M, M]), np.zeros(2))
            else:
                self._affine = (np.array([-d, d]), np.array([-M, 0.0, M]), np.zeros(3))
        elif isinstance(element, PreloadedSpring):
            F, k = element.preload, element.k
            self._affine = (np.array([0.0]), np.array([-F, F]), np.array([k, k]))
        elif isinstance(element, CoulombViscousFriction):
            F, c = element.Fc, element.c
            self._affine = (np.array([0.0]), np.array([-F, F]), np.array([c, c]))
        elif isinstance(element, Relay):
            self.memory = True
            self._relay = element
        elif isinstance(element, Backlash):
            self.memory = True
        elif isinstance(element, StaticElement):
            self._f = element.output
        elif isinstance(element, DescribingFunction):
            self._time_model = _time_model_of(element)
            self.memory = True
        elif callable(element):
            self._f = element
        else:
            raise DfloopError(f"element must be a dfloop element or a callable f(x), got {element!r}")
        if self._affine is not None and self.function is None:  # a relay without hysteresis: static after all
            self.function, self.breakpoints = _affine_map(*self._affine), self._affine[0]
        self.method = ("closed form" if self._affine is not None else "switching phases" if self._relay is not None
                       else "shift invariance" if isinstance(element, Backlash) else "quadrature")
        if self._time_model is not None:
            self.method = ("switching phases of the time model" if isinstance(self._time_model, PiecewiseAffine)
                           else f"sampled operator ({_SAMPLED} samples per period)")

    @classmethod
    def piecewise_affine(cls, levels, offsets, slopes) -> "DualInputDF":
        """The closed-form dual-input DF of a piecewise-affine static map.

        Parameters
        ----------
        levels : array_like
            Increasing input levels L_1 < ... < L_m where the map changes piece.
        offsets, slopes : array_like
            m + 1 pieces: f(e) = offsets[i] + slopes[i] e on (L_i, L_{i+1}) (L_0 = -inf, L_{m+1} = inf).

        Examples
        --------
        A relay with unequal levels (+2 for e > 0, -1 for e < 0):
        ``DualInputDF.piecewise_affine([0.0], [-1.0, 2.0], [0.0, 0.0])``.
        """
        L = np.asarray(levels, float).ravel()
        c0, c1 = np.asarray(offsets, float).ravel(), np.asarray(slopes, float).ravel()
        if L.size == 0 or not np.all(np.isfinite(L)) or np.any(np.diff(L) <= 0):
            raise DfloopError(f"levels must be finite and strictly increasing (at least one), got {levels!r}")
        if c0.shape != (L.size + 1,) or c1.shape != (L.size + 1,):
            raise DfloopError(f"offsets and slopes need {L.size + 1} entries (one per piece), got {offsets!r} "
                              f"and {slopes!r}")
        if not (np.all(np.isfinite(c0)) and np.all(np.isfinite(c1))):
            raise DfloopError(f"offsets and slopes must be finite, got {offsets!r} and {slopes!r}")

        new = cls(_affine_map(L, c0, c1), breakpoints=L)
        new._affine = (L, c0, c1)
        new.method = "closed form"
        new.element = f"piecewise affine (levels={L.tolist()}, offsets={c0.tolist()}, slopes={c1.tolist()})"
        return new

    @property
    def describing_function(self) -> DescribingFunction:
        """The element as a :class:`~dfloop.DescribingFunction` with a time model, for :func:`dfloop.exact_cycle`
        and :func:`dfloop.verify_cycle`: the element itself, or the static map as a
        :class:`~dfloop.NumericDF` with its breakpoints (each level used as +-level)."""
        if isinstance(self.element, DescribingFunction):
            return self.element
        from .numeric import NumericDF

        levels = np.unique(np.abs(self.breakpoints))
        return NumericDF(self.function, breakpoints=levels if levels.size else None)

    # ------------------------------------------------------------------------------------------------ values

    def mean(self, B, A) -> np.ndarray:
        """Mean output m(B, A) = B N_B(B, A) (element output units), real."""
        return self._moments(*_bias_amplitude(B, A))[0]

    def N_A(self, B, A) -> np.ndarray:
        """Sinusoid gain N_A(B, A) (complex; real for memoryless elements); N_A(0, A) = N(A)."""
        return self._moments(*_bias_amplitude(B, A))[1]

    def N_B(self, B, A) -> np.ndarray:
        """Bias gain N_B(B, A) = m / B; at B = 0 the slope dm/dB (by a central difference of relative step 1e-6
        of A: about 1e-10 relative), infinite when m(0, A) != 0 (an asymmetric element)."""
        b, a = _bias_amplitude(B, A)
        m = self._moments(b, a)[0]
        out = np.empty(b.shape)
        nz = b != 0
        out[nz] = m[nz] / b[nz]
        if np.any(~nz):
            a0 = a[~nz]
            h = 1e-6 * a0
            m0 = m[~nz]
            slope = (self._moments(h, a0)[0] - self._moments(-h, a0)[0]) / (2 * h)
            out[~nz] = np.where(np.abs(m0) > 1e-12 * np.abs(slope * a0) + np.finfo(float).tiny,
                                np.copysign(np.inf, m0), slope)
        return out

    def error_estimate(self, B, A) -> np.ndarray:
        """Estimated |error| of (m, N_A) (the larger of the two): 0 for the exact paths; for the quadrature the
        difference between ``nodes`` and ``nodes // 2`` nodes per piece; for a sampled operator the difference
        between its sampled period and one of half as many samples."""
        b, a = _bias_amplitude(B, A)
        if self._time_model is not None:
            if isinstance(self._time_model, PiecewiseAffine):
                return np.zeros(b.shape)
            m1, n1 = _sampled_moments(self._time_model, b, a, _SAMPLED)
            m2, n2 = _sampled_moments(self._time_model, b, a, _SAMPLED // 2)
            return np.maximum(np.abs(m1 - m2), np.abs(n1 - n2))
        if self._f is None or self._affine is not None:
            return np.zeros(b.shape)
        m1, n1 = self._quadrature(b, a, self.nodes)
        m2, n2 = self._quadrature(b, a, max(self.nodes // 2, 2))
        return np.maximum(np.abs(m1 - m2), np.abs(n1 - n2))

    def _moments(self, b: np.ndarray, a: np.ndarray):
        if self._time_model is not None:
            if isinstance(self._time_model, PiecewiseAffine):
                return _modes_moments(self._time_model, b, a)
            return _sampled_moments(self._time_model, b, a, _SAMPLED)
        if self._affine is not None:
            return self._closed(b, a)
        if self._relay is not None:
            if self._relay.dead_zone == 0.0:
                return self._two_state(b, a)
            return self._switching(b, a)
        if self._f is None:  # backlash: shift invariance of the play operator
            el = self.element
            return el.k * b, np.asarray(el(a), complex)
        return self._quadrature(b, a, self.nodes)

    def _closed(self, b, a):
        L, c0, c1 = self._affine
        d0, d1 = np.diff(c0), np.diff(c1)
        s = np.clip((L[:, None] - b.ravel()[None, :]) / a.ravel()[None, :], -1.0, 1.0)
        alpha = np.arcsin(s)
        cos_a = np.sqrt((1.0 - s) * (1.0 + s))
        I0 = np.pi - 2 * alpha
        I1 = 2 * cos_a
        I2 = 0.5 * I0 + s * cos_a
        bb, aa = b.ravel()[None, :], a.ravel()[None, :]
        total = 2 * np.pi * (c0[0] + c1[0] * b.ravel()) + np.sum(d0[:, None] * I0 + d1[:, None] * (bb * I0 + aa * I1),
                                                                 axis=0)
        fund = c1[0] * np.pi * a.ravel() + np.sum(d0[:, None] * I1 + d1[:, None] * (bb * I1 + aa * I2), axis=0)
        return (total / (2 * np.pi)).reshape(b.shape), (fund / (np.pi * a.ravel())).reshape(b.shape).astype(complex)

    def _quadrature(self, b, a, nodes):
        x, w = np.polynomial.legendre.leggauss(nodes)
        bf, af = b.ravel(), a.ravel()
        n = bf.size
        lo, hi = -0.5 * np.pi, 1.5 * np.pi
        if self._levels.size:
            s = (self._levels[None, :] - bf[:, None]) / af[:, None]
            inside = np.abs(s) < 1
            t1 = np.where(inside, np.arcsin(np.clip(s, -1, 1)), lo)
            t2 = np.where(inside, np.pi - t1, lo)
            cuts = np.concatenate([t1, t2], axis=1)
        else:
            cuts = np.empty((n, 0))
        bounds = np.sort(np.concatenate([np.full((n, 1), lo), cuts, np.full((n, 1), hi)], axis=1), axis=1)
        left, right = bounds[:, :-1], bounds[:, 1:]
        half = 0.5 * (right - left)
        theta = (left + half)[..., None] + half[..., None] * x  # (n, pieces, nodes)
        y = np.asarray(self._f(bf[:, None, None] + af[:, None, None] * np.sin(theta)), float)
        y = np.broadcast_to(y, theta.shape)
        if not np.all(np.isfinite(y)):
            raise DfloopError("the element's output is not finite along B + A sin(theta)")
        wt = half[..., None] * w
        total = np.sum(wt * y, axis=(1, 2))
        fs = np.sum(wt * y * np.sin(theta), axis=(1, 2))
        fc = np.sum(wt * y * np.cos(theta), axis=(1, 2))
        return (total / (2 * np.pi)).reshape(b.shape), ((fs + 1j * fc) / (np.pi * af)).reshape(b.shape)

    def _two_state(self, b, a):
        """Relay with hysteresis a and no dead zone (output +-M): +M from the rising crossing of +a,
        theta_on = asin((a - B) / A), to the falling crossing of -a, theta_off = pi - asin((-a - B) / A)."""
        M, h = self._relay.M, self._relay.hysteresis
        with np.errstate(invalid="ignore"):
            t_on = np.arcsin(np.clip((h - b) / a, -1.0, 1.0))
            t_off = np.pi - np.arcsin(np.clip((-h - b) / a, -1.0, 1.0))
        width = t_off - t_on
        m = M * (width - np.pi) / np.pi
        n = 2 * M * ((np.cos(t_on) - np.cos(t_off)) + 1j * (np.sin(t_off) - np.sin(t_on))) / (np.pi * a)
        held = np.where(b >= 0, b - a >= -h, b + a <= h)  # never switches: holds the level on B's side
        return np.where(held, np.where(b >= 0, M, -M), m), np.where(held, 0.0, n)

    def _switching(self, b, a):
        """Relays with hysteresis and dead zone, in closed form: over the rising half of e = B + A sin(theta)
        (theta from -pi/2 to pi/2) the relay can only release -M at e = -off and switch on at e = +on, over the
        falling half only release +M at e = +off and switch to -M at e = -on (the switching rule of
        :class:`~dfloop.describing.static.RelayOperator`); each crossing phase is exact (asin), the state held at
        the input's minimum is the fixed point of the period's state map (reached from the level on B's side in
        at most three periods), and the output, constant between the phases, is integrated exactly."""
        relay = self._relay
        M, on, off = relay.M, relay.on_level, relay.off_level
        bf, af = b.ravel(), a.ravel()
        x_min, x_max = bf - af, bf + af

        def phase(level, falling):
            t = np.arcsin(np.clip((level - bf) / af, -1.0, 1.0))
            return np.pi - t if falling else t

        # rising: release of -M (at -off) then switch-on (at +on); falling: release of +M (at off), switch to -M
        rel_up, on_up = (x_min < -off) & (x_max > -off), x_max > on
        rel_dn, on_dn = (x_max > off) & (x_min < off), x_min < -on
        t_rel_up, t_on_up, t_rel_dn, t_on_dn = phase(-off, False), phase(on, False), phase(off, True), phase(-on, True)

        def half(s, release, switch):
            """State after a half period from state s: (state after the release, state at the end)."""
            mid = np.where((s == release[0]) & release[1], 0.0, s)
            return mid, np.where((mid == 0) & switch[1], switch[0], mid)

        s = np.where(bf >= 0, np.where(x_max > on, 1.0, np.where(x_min < -on, -1.0, 0.0)),
                     np.where(x_min < -on, -1.0, np.where(x_max > on, 1.0, 0.0)))
        s = np.where((bf >= 0) & (x_min >= off), 1.0, np.where((bf < 0) & (x_max <= -off), -1.0, s))
        for _ in range(4):
            previous = s
            _, s1 = half(s, (-1.0, rel_up), (1.0, on_up))
            _, s = half(s1, (1.0, rel_dn), (-1.0, on_dn))
        if not np.array_equal(s, previous):
            row = int(np.argmax(s != previous))
            raise DfloopError(f"the relay's output is not periodic at B = {bf[row]!r}, A = {af[row]!r}")
        s0 = s
        u1, s1 = half(s0, (-1.0, rel_up), (1.0, on_up))
        u2, s2 = half(s1, (1.0, rel_dn), (-1.0, on_dn))
        lo, hi = -0.5 * np.pi, 0.5 * np.pi
        # pieces (start, end, level): the release and switch phases only where they happen
        ta = np.where((s0 == -1) & rel_up, t_rel_up, lo)
        tb = np.where((u1 == 0) & on_up, t_on_up, hi)
        tc = np.where((s1 == 1) & rel_dn, t_rel_dn, hi)
        td = np.where((u2 == 0) & on_dn, t_on_dn, 1.5 * np.pi)
        pieces = ((lo, ta, s0), (ta, tb, u1), (tb, hi, s1), (hi, tc, s1), (tc, td, u2), (td, 1.5 * np.pi, s2))
        m = sum(level * (t1 - t0) for t0, t1, level in pieces) * (M / (2 * np.pi))
        fs = M * sum(level * (np.cos(t0) - np.cos(t1)) for t0, t1, level in pieces)
        fc = M * sum(level * (np.sin(t1) - np.sin(t0)) for t0, t1, level in pieces)
        return m.reshape(b.shape), ((fs + 1j * fc) / (np.pi * af)).reshape(b.shape)

    def __repr__(self) -> str:
        name = self.element if isinstance(self.element, str) else repr(self.element)
        return f"DualInputDF({name}, method={self.method!r})"


# ------------------------------------------------------------------------- any element with a time model

_SAMPLED = 8192          # samples per period of an operator-only element
_PERIODS = 8             # bound on the periods run to reach the periodic regime of a piecewise-affine element
_EVENTS = 1000           # bound on the switches of one period


def _time_model_of(element):
    """The element's time model for its dual-input DF (PiecewiseAffine or Sampled), or ValueError."""
    from .time_model import Sampled

    try:
        tm = element.time_model(1.0)
    except NotImplementedError:
        tm = None
    if not isinstance(tm, (PiecewiseAffine, Sampled)):
        raise DfloopError(f"element {element!r} has no dual-input DF in dfloop: it needs a piecewise-affine or "
                          "sampled time model (time_model()), or pass its static function f(x) with breakpoints")
    return tm


def _modes_moments(tm, b: np.ndarray, a: np.ndarray):
    """Mean and N_A of any piecewise-affine element (its modes and guards, :mod:`dfloop.describing.time_model`)
    driven by e = B + A sin(theta): within a mode the output is a + b sin(theta) and every guard
    alpha + beta sin(theta) + gamma cos(theta) (x' taken as dx/dtheta: rate-independent guards), so each switching
    phase is exact (an arcsine) and the output's moments are integrated exactly. The element starts in the mode its
    own ``initial`` gives after a sampled period of the input and runs until two consecutive periods end in the same
    state (at most ``_PERIODS``); the last period is integrated."""
    bf, af = b.ravel(), a.ravel()
    m_out, n_out = np.empty(bf.size), np.empty(bf.size, complex)
    for i, (B, A) in enumerate(zip(bf, af)):
        m_out[i], n_out[i] = _modes_one(tm, float(B), float(A))
    return m_out.reshape(b.shape), n_out.reshape(b.shape)


def _modes_one(tm, B: float, A: float):
    theta0 = -0.5 * math.pi
    history = B + A * np.sin(theta0 + 2 * np.pi * (np.arange(16) / 16 - 1.0))   # coarse: the periods below settle it
    mode, e = tm.initial(np.append(history, B - A), 0.0)
    previous = None
    for _ in range(_PERIODS):
        pieces, (mode, e) = _one_period(tm, B, A, theta0, int(mode), float(e))
        state = (mode, e)
        if previous is not None and previous[0] == state[0] and abs(previous[1] - state[1]) <= 1e-12 * (
                abs(B) + A + abs(e)):
            break
        previous = state
    else:
        raise DfloopError(f"the element's output does not become periodic within {_PERIODS} periods at B = {B!r}, "
                          f"A = {A!r}")
    total = fs = fc = 0.0
    for t0, t1, c0, c1 in pieces:
        s0, s1, k0, k1 = math.sin(t0), math.sin(t1), math.cos(t0), math.cos(t1)
        total += c0 * (t1 - t0) + c1 * (k0 - k1)
        fs += c0 * (k0 - k1) + c1 * (0.5 * (t1 - t0) - 0.25 * (math.sin(2 * t1) - math.sin(2 * t0)))
        fc += c0 * (s1 - s0) + c1 * 0.5 * (s1 * s1 - s0 * s0)
    return total / (2 * math.pi), (fs + 1j * fc) / (math.pi * A)


def _one_period(tm, B: float, A: float, theta0: float, mode: int, e: float):
    """Pieces (theta0, theta1, c0, c1) with y = c0 + c1 sin(theta) over one period from theta0, and the end state."""
    end = theta0 + 2 * math.pi
    t = theta0
    pieces = []

    for _ in range(_EVENTS):
        md = tm.modes[mode]
        x0 = B + A * math.sin(t)
        c0 = md.gx * B + md.ge * (e + md.de * (B - x0)) + md.g1
        c1 = (md.gx + md.ge * md.de) * A
        best, which = end, None
        for j, g in enumerate(md.guards):
            alpha = (g.cx + g.ce * md.de) * B + g.c1 + g.ce * (e - md.de * x0)
            beta, gamma = (g.cx + g.ce * md.de) * A, g.cxd * A
            hit = _down_crossing(alpha, beta, gamma, t, end)
            if hit is not None and hit < best:
                best, which = hit, j
        pieces.append((t, best, c0, c1))
        e = e + md.de * (B + A * math.sin(best) - x0)
        if which is None:
            return pieces, (mode, e)
        g = md.guards[which]
        if g.target < 0:
            raise DfloopError(f"the input B + A sin(theta) (B = {B!r}, A = {A!r}) leaves the range the element's "
                              "model covers")
        x = B + A * math.sin(best)
        if g.reset is not None:
            e = g.reset[0] * x + g.reset[1]
        mode, t = g.target, best
    raise DfloopError(f"more than {_EVENTS} switches in one period at B = {B!r}, A = {A!r} (a chattering element?)")


def _down_crossing(alpha: float, beta: float, gamma: float, t0: float, t1: float):
    """First phase in (t0, t1] where alpha + beta sin(theta) + gamma cos(theta) falls through 0 (or is already
    below 0 and falling at t0: then t0), None if none."""
    rho = math.hypot(beta, gamma)
    scale = abs(alpha) + rho
    if scale == 0.0:
        return None
    g0 = alpha + beta * math.sin(t0) + gamma * math.cos(t0)
    d0 = beta * math.cos(t0) - gamma * math.sin(t0)
    if g0 < -1e-12 * scale or (abs(g0) <= 1e-12 * scale and d0 < -1e-12 * scale):
        return t0          # outside the mode already (entered at a switch whose guard here fails): leave now
    if rho <= abs(alpha):
        return None        # never reaches 0 (or touches it only)
    phi = math.atan2(gamma, beta)   # g = alpha + rho sin(theta + phi)
    psi = math.pi - math.asin(min(max(-alpha / rho, -1.0), 1.0)) - phi   # falling zero
    k = math.ceil((t0 - psi) / (2 * math.pi))
    hit = psi + 2 * math.pi * k
    if hit <= t0 + 1e-13 * (1.0 + abs(t0)):
        hit += 2 * math.pi
    return float(hit) if hit <= t1 else None


def _sampled_moments(tm, b: np.ndarray, a: np.ndarray, samples: int):
    """Mean and N_A of an operator-only element from its periodic response to ``samples`` samples of a period."""
    theta = 2 * np.pi * np.arange(samples) / samples
    bf, af = b.ravel(), a.ravel()
    m_out, n_out = np.empty(bf.size), np.empty(bf.size, complex)
    for i, (B, A) in enumerate(zip(bf, af)):
        y = np.asarray(tm.response(B + A * np.sin(theta)), float)
        m_out[i] = float(np.mean(y))
        n_out[i] = 2j * np.mean(y * np.exp(-1j * theta)) / A
    return m_out.reshape(b.shape), n_out.reshape(b.shape)
