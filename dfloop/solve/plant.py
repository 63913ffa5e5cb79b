"""Plant adapter: a SISO python-control LTI (tf, ss, frd) or a callable, as a vectorised G(jw).

Frequencies are in rad/s. The adapter also proposes a default frequency window and the frequencies
where the response has features (lightly damped poles and zeros), so the solver's grid resolves them.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import DfloopError
from .delay import DelayedSystem
from .sampled import discrete_parts

__all__ = ["Plant", "as_plant", "MAX_ORDER"]

_DECADES_BEYOND_FEATURES = 2.0  # default window: two decades beyond the slowest / fastest pole or zero
_LIGHT_DAMPING = 0.2  # poles/zeros with damping ratio below this get a dense cluster of grid frequencies
_CHUNK_VALUES = 2**18  # entries of one chunk of log_variation's work arrays (intervals x roots)
MAX_ORDER = 1000
"""Largest plant order accepted: beyond it the poles (O(n^3) work: an ss conversion takes ~3 s at n = 500, ~25 s at n = 1000) and
the polynomial form (which overflows at |s| ~ 10^(308 / n)) are useless; reduce the model first."""


@dataclass
class Plant:
    """A SISO frequency response G(jw), vectorised over omega (rad/s).

    Attributes
    ----------
    response : callable
        ``response(omega) -> complex ndarray``, same shape as ``omega``.
    default_window : (float, float) or None
        Frequency window (rad/s) proposed from the plant (poles, zeros, frd grid); None for callables.
    feature_frequencies : ndarray
        Frequencies (rad/s) the solver's grid must resolve (clustered around lightly damped poles/zeros;
        an frd's own grid).
    domain : (float, float)
        Frequencies where G can be evaluated at all (an frd's grid range; (0, inf) otherwise).
    lti : object or None
        The python-control system, when one was given without a delay (used by time-domain verification).
    roots : (zeros, poles) or None
        Of a rational G (tf, ss): its exact variation is then known (:meth:`log_variation`).
    delay : float
        Pure delay T (s) of a :class:`~dfloop.solve.delay.DelayedSystem`: ``response`` includes e^{-jwT}, and
        ``log_slope`` / ``log_variation`` carry its exact phase turn; ``lti`` is then None (the delay-free part
        is ``delay_free``), so no engine can drop the delay unnoticed.
    delay_free : object or None
        The python-control system without its delay (delayed plants only).
    frequency_map, map_slope, dt : callable, callable, float or None
        Discrete-time G (:mod:`dfloop.solve.sampled`): ``roots`` belong to H with G(e^{jw dt}) = H(j nu(w)),
        ``frequency_map`` is nu(w), ``map_slope`` d ln nu / d ln w, ``dt`` the sampling period (s).
    """

    response: Callable[[np.ndarray], np.ndarray]
    default_window: tuple[float, float] | None
    feature_frequencies: np.ndarray = field(default_factory=lambda: np.empty(0))
    domain: tuple[float, float] = (0.0, np.inf)
    lti: object = None
    roots: tuple[np.ndarray, np.ndarray] | None = None
    delay: float = 0.0
    delay_free: object = None
    frequency_map: Callable | None = None
    map_slope: Callable | None = None
    dt: float | None = None

    def __call__(self, omega) -> np.ndarray:
        """G(j omega) as a complex array; raises ValueError if G is NaN or infinite anywhere, or if a
        callable returns an array of the wrong shape."""
        w = np.asarray(omega, dtype=float)
        try:
            g = np.asarray(self.response(w), dtype=complex)
        except (TypeError, ValueError) as exc:
            if isinstance(exc, DfloopError):  # dfloop's own message (frd range, overflow): unchanged
                raise
            raise ValueError(f"G(omega) must return complex numbers for an array omega; it raised {exc!r}") from None
        if g.shape != w.shape:
            if g.size != 1:
                raise ValueError(f"G(omega) must return an array of the same shape as omega; got shape {g.shape} "
                                 f"for omega of shape {w.shape}")
            g = np.broadcast_to(g, w.shape)
        bad = ~np.isfinite(g)
        if bad.any():
            w_bad = w[bad].flat[0]
            raise ValueError(f"G(jw) is not finite (NaN, overflow or a pole on the imaginary axis) at "
                             f"omega={w_bad:g} rad/s")
        return g

    @property
    def exact(self) -> bool:
        """True when G is rational with known poles and zeros (then its variation is known exactly)."""
        return self.roots is not None

    def log_slope(self, omega) -> np.ndarray:
        """d ln G / d ln w = sum_z jw / (jw - z) - sum_p jw / (jw - p) - jwT (exact; rational G, delay T)."""
        zeros, poles = self.roots
        w = np.asarray(omega, float)
        s = 1j * (w if self.frequency_map is None else self.frequency_map(w))[..., None]
        slope = (s / (s - zeros)).sum(axis=-1) - (s / (s - poles)).sum(axis=-1)
        if self.map_slope is not None:
            slope = slope * self.map_slope(w)
        return slope - 1j * w * self.delay

    def log_variation(self, w0, w1) -> np.ndarray:
        """Upper bound on |ln G(w) - ln G(w0)| for every w in [w0, w1] (rational G only).

        Each factor (jw - r), r = x + jy, moves along a vertical line as w grows: its argument turns
        monotonically, by exactly atan2(x (w1 - w0), x^2 + (w0 - y)(w1 - y)), and ln|jw - r| has one
        minimum (at w = y). So the change of arg G over the interval lies between the sums of the
        negative and of the positive turns (zeros count +, poles -), the change of ln|G| likewise between
        the sums of the decreases and increases; the bound is the hypotenuse of the two extremes.
        A pure delay T turns arg G by exactly -T (w1 - w0) and leaves |G| unchanged: it joins the negative
        turns, so the bound stays exact (no aliasing, however fast the delay turns the phase).
        Infinite when a zero lies on the interval of the imaginary axis. Evaluated in chunks of intervals, so
        the work arrays (intervals x poles and zeros) stay below ~``_CHUNK_VALUES`` entries.
        """
        if self.frequency_map is not None:   # along nu(w), monotone: the same bound for H(j nu)
            w0, w1 = self.frequency_map(w0), self.frequency_map(w1)
        w0, w1 = np.broadcast_arrays(np.asarray(w0, float), np.asarray(w1, float))
        n_roots = max(1, sum(r.size for r in self.roots))
        size = max(1, _CHUNK_VALUES // n_roots)
        if w0.ndim != 1 or w0.size <= size:
            return self._log_variation(w0, w1)
        return np.concatenate([self._log_variation(w0[i:i + size], w1[i:i + size])
                               for i in range(0, w0.size, size)])

    def _log_variation(self, w0, w1) -> np.ndarray:
        zeros, poles = self.roots
        r = np.concatenate([zeros, poles])
        sign = np.concatenate([np.ones(zeros.size), -np.ones(poles.size)])
        w0, w1 = np.asarray(w0, float)[..., None], np.asarray(w1, float)[..., None]
        x, y = -r.real, r.imag  # jw - r = x + j (w - y)
        turn = sign * np.arctan2(x * (w1 - w0), x * x + (w0 - y) * (w1 - y))
        with np.errstate(divide="ignore", invalid="ignore"):
            m0, m1 = 0.5 * np.log(x * x + (w0 - y) ** 2), 0.5 * np.log(x * x + (w1 - y) ** 2)
            inside = (w0 < y) & (y < w1)
            low = np.where(inside, np.log(np.abs(x)), np.minimum(m0, m1))
            up, down = m1 - low, m0 - low  # total rise and fall of ln|jw - r| on the interval
            rise = np.where(sign > 0, up, down).sum(axis=-1)
            fall = np.where(sign > 0, down, up).sum(axis=-1)
        delay_turn = self.delay * (w1[..., 0] - w0[..., 0])
        arg = np.maximum(np.where(turn > 0, turn, 0).sum(axis=-1),
                         -np.where(turn < 0, turn, 0).sum(axis=-1) + delay_turn)
        return np.hypot(arg, np.maximum(rise, fall))


def _check_siso(sys) -> None:
    nin, nout = getattr(sys, "ninputs", 1), getattr(sys, "noutputs", 1)
    if nin != 1 or nout != 1:
        raise ValueError(f"G must be SISO; got a system with {nin} inputs and {nout} outputs")


def _feature_grid(roots: np.ndarray) -> tuple[np.ndarray, tuple[float, float] | None]:
    """Frequencies clustered around each pole/zero's natural frequency, and the default window."""
    r = roots[np.isfinite(roots)]
    mag = np.abs(r)
    r, mag = r[mag > 0], mag[mag > 0]
    if r.size == 0:
        return np.empty(0), (1e-2, 1e2)
    lo = mag.min() * 10.0 ** -_DECADES_BEYOND_FEATURES
    hi = mag.max() * 10.0 ** _DECADES_BEYOND_FEATURES
    # lightly damped poles/zeros (|Re p| < 0.2 |p|): tan-spaced points within a few bandwidths |Re p|
    # around |p| resolve the resonance however narrow; a log grid resolves the others
    light = np.abs(r.real) < _LIGHT_DAMPING * mag
    offsets = np.tan(np.linspace(-1.45, 1.45, 41))
    width = np.maximum(np.abs(r.real[light]), 1e-12 * mag[light])
    pts = (mag[light, None] + width[:, None] * offsets[None, :]).ravel()
    return np.unique(pts[pts > 0]), (float(lo), float(hi))


def _show_matrix(m: np.ndarray) -> str:
    text = np.array2string(m, threshold=6, edgeitems=2)
    return " ".join(text.split())


_MARKOV_ZERO = 1e-12  # |C A^(k-1) B| below this times |C| |A|^(k-1) |B| (elementwise) is rounding: zero


def _ss_polynomials(ss) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator of a SISO state-space G, with its true numerator degree.

    By the matrix determinant lemma G(s) = [det(sI - A + BC) - det(sI - A)] / det(sI - A) + D. Where the
    numerator is exactly zero, its leading coefficients (the relative degree r), the difference of the two
    characteristic polynomials leaves rounding (``control.tf(ss)`` gives -2.2e-16 s + 5 for the ss form of
    5/(s(s+1))), and such leading coefficients are huge spurious zeros (4.5e16 rad/s) that would set the
    default window. The relative degree is found from the Markov parameters h_k = C A^(k-1) B, k = 1..n: the
    first one above ``_MARKOV_ZERO`` times the elementwise product |C| |A|^(k-1) |B| (its rounding scale;
    structurally zero below r in the companion forms ``control.ss`` / ``control.tf2ss`` make, and in modal or
    diagonally scaled forms a cancellation at that scale). The r leading numerator coefficients are set to zero,
    so the ss form gives the tf form's poles, zeros and default window. A dense, badly conditioned change of
    state basis determines G's coefficients only to its conditioning (no method recovers more).
    """
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    n = A.shape[0]
    p0 = np.real(np.poly(np.linalg.eigvals(A)))
    d = float(D.ravel()[0])
    num = np.real(np.poly(np.linalg.eigvals(A - np.outer(B[:, 0], C[0])))) - p0 + d * p0
    r = 0 if d != 0.0 else n + 1
    v, bound = B[:, 0], np.abs(B[:, 0])
    for k in range(1, n + 1):
        if r <= n:
            break
        if abs(float(C[0] @ v)) > _MARKOV_ZERO * float(np.abs(C[0]) @ bound):
            r = k
        v, bound = A @ v, np.abs(A) @ bound
    num[:min(r, num.size)] = 0.0   # coefficients of s^n .. s^(n-r+1)
    return num, p0


def _from_tf(sys) -> Plant:
    import control as ct

    order = sys.nstates if isinstance(sys, ct.StateSpace) else max(len(sys.den[0][0]) - 1, len(sys.num[0][0]) - 1)
    if order > MAX_ORDER:  # refused before the O(n^3) conversion and root finding (order 5000: 10 GB, minutes)
        raise DfloopError(f"G has order {order}, above the bound of {MAX_ORDER}: its poles cost O(n^3) and its "
                          f"polynomials overflow for |s| > about 10^{308 / order:.2g}; reduce the model first "
                          "(e.g. control.balred or control.minreal)")
    if isinstance(sys, ct.StateSpace):  # a NaN in A would surface as a LinAlgError of the conversion
        for name in ("A", "B", "C", "D"):
            m = np.asarray(getattr(sys, name))
            if not np.all(np.isfinite(m)):
                raise ValueError(f"G (ss) must have finite matrices; got {name} = {_show_matrix(m)}")
    if isinstance(sys, ct.TransferFunction):
        num, den = (np.asarray(x, dtype=float) for x in (sys.num[0][0], sys.den[0][0]))
    else:  # state space: the same polynomials as the tf form (rounding of the conversion removed)
        num, den = _ss_polynomials(sys)
    for name, coef in (("num", num), ("den", den)):  # np.roots would raise LinAlgError
        if not np.all(np.isfinite(coef)):
            raise ValueError(f"G (tf) must have finite coefficients; got {name} = {coef.tolist()!r}")
    num, den = (x[np.argmax(x != 0):] if np.any(x) else x[:0] for x in (num, den))  # leading zeros off
    if num.size == 0:
        raise ValueError("G is zero (its numerator is 0): no loop, no limit cycle")
    if num.size > den.size:
        raise ValueError(f"G must be proper (numerator degree <= denominator degree); got degrees "
                         f"{num.size - 1} > {den.size - 1}")

    def response(w):
        s = 1j * w
        with np.errstate(over="ignore", invalid="ignore"):
            top, bottom = np.polyval(num, s), np.polyval(den, s)
        over = ~(np.isfinite(top) & np.isfinite(bottom)) & np.isfinite(w)
        if np.any(over):  # the polynomials, not G, leave the float range: say so (not "NaN or pole")
            raise DfloopError(f"G(jw) overflows: at omega={float(w[over].flat[0]):g} rad/s the degree-"
                             f"{den.size - 1} polynomials of G exceed the float range (about 1.8e308); "
                             "narrow the omega window (or scale time so that the frequencies are near 1)")
        return top / bottom

    if getattr(sys, "dt", 0) not in (0, None):  # discrete time: G(e^{jw dt}) on (0, pi/dt] (solve/sampled.py)
        return Plant(feature_frequencies=np.empty(0), lti=sys, **discrete_parts(sys, num, den))
    zeros, poles = np.roots(num), np.roots(den)
    features, window = _feature_grid(np.concatenate([poles, zeros]))
    return Plant(response, window, features, lti=sys, roots=(zeros, poles))


def _from_frd(sys) -> Plant:
    from scipy.interpolate import CubicSpline

    w = np.asarray(sys.omega, dtype=float)
    g = np.asarray(sys.frdata if hasattr(sys, "frdata") else sys.fresp)[0, 0, :]
    if w.size < 2:
        raise ValueError("G (frd) needs at least two frequency points")
    if not np.all(np.isfinite(g)):
        raise ValueError("G (frd) contains NaN or infinite response values")
    lw = np.log(w)
    re, im = CubicSpline(lw, g.real), CubicSpline(lw, g.imag)
    lo, hi = float(w[0]), float(w[-1])

    def response(omega):
        if np.any(omega < lo * (1 - 1e-12)) or np.any(omega > hi * (1 + 1e-12)):
            raise DfloopError(f"omega outside the frd's frequency grid [{lo:g}, {hi:g}] rad/s")
        x = np.log(omega)
        return re(x) + 1j * im(x)

    return Plant(response, (lo, hi), w, domain=(lo, hi), lti=sys)


def _from_delayed(G) -> Plant:
    base = as_plant(G.system)
    T, inner = G.delay, base.response
    if T == 0.0:
        return base

    def response(w):
        return inner(w) * np.exp(-1j * np.asarray(w, float) * T)

    return Plant(response, base.default_window, base.feature_frequencies, base.domain, lti=None,
                 roots=base.roots, delay=T, delay_free=base.lti)


def as_plant(G) -> Plant:
    """Adapt ``G`` (python-control tf/ss/frd, a :class:`~dfloop.solve.delay.DelayedSystem`, a callable G(omega),
    or a :class:`Plant`) to a :class:`Plant`.

    A discrete-time tf/ss (``dt`` > 0) gives G(e^{jw dt}) on (0, pi/dt] (:mod:`dfloop.solve.sampled`).
    A callable receives an array of frequencies in rad/s and must return G(j omega) of the same shape. A plant
    with a pure delay T is best given as ``delayed(G, T)`` (:func:`dfloop.solve.delay.delayed`): its grid bound
    stays exact and the exact engines can run it; a callable such as ``lambda w: np.exp(-1j * w * T) /
    (1j * w + 1)`` is only sampled.
    """
    if isinstance(G, Plant):
        return G
    if isinstance(G, DelayedSystem):
        return _from_delayed(G)
    ct = sys.modules.get("control")  # an LTI exists only once python-control is imported
    if ct is not None and isinstance(G, ct.LTI):
        _check_siso(G)
        if isinstance(G, ct.FrequencyResponseData):
            return _from_frd(G)
        return _from_tf(G)
    if callable(G):
        return Plant(G, None)
    raise ValueError(f"G must be a python-control tf/ss/frd or a callable G(omega); got {type(G).__name__}")
