"""Plant adapter: a SISO python-control LTI (tf, ss, frd) or a callable, as a vectorised G(jw).

Frequencies are in rad/s. The adapter also proposes a default frequency window and the frequencies
where the response has features (lightly damped poles and zeros), so the solver's grid resolves them.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["Plant", "as_plant"]

_DECADES_BEYOND_FEATURES = 2.0  # default window: two decades beyond the slowest / fastest pole or zero
_LIGHT_DAMPING = 0.2  # poles/zeros with damping ratio below this get a dense cluster of grid frequencies


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
        The python-control system, when one was given (used by time-domain verification).
    """

    response: Callable[[np.ndarray], np.ndarray]
    default_window: tuple[float, float] | None
    feature_frequencies: np.ndarray = field(default_factory=lambda: np.empty(0))
    domain: tuple[float, float] = (0.0, np.inf)
    lti: object = None

    def __call__(self, omega) -> np.ndarray:
        """G(j omega) as a complex array; raises ValueError if G is NaN or infinite anywhere."""
        w = np.asarray(omega, dtype=float)
        g = np.asarray(self.response(w), dtype=complex)
        if g.shape != w.shape:
            g = np.broadcast_to(g, w.shape) if g.size == 1 else g.reshape(w.shape)
        bad = ~np.isfinite(g)
        if bad.any():
            w_bad = w[bad].flat[0]
            raise ValueError(f"G(jw) is not finite (NaN or pole on the imaginary axis) at omega={w_bad:g} rad/s")
        return g


def _check_siso(sys) -> None:
    nin, nout = getattr(sys, "ninputs", 1), getattr(sys, "noutputs", 1)
    if nin != 1 or nout != 1:
        raise ValueError(f"G must be SISO; got a system with {nin} inputs and {nout} outputs")
    dt = getattr(sys, "dt", 0)
    if dt not in (0, None):
        raise ValueError(f"G must be a continuous-time system; got dt={dt}")


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


def _from_tf(sys) -> Plant:
    import control as ct

    tf = sys if isinstance(sys, ct.TransferFunction) else ct.tf(sys)
    num = np.asarray(tf.num[0][0], dtype=float)
    den = np.asarray(tf.den[0][0], dtype=float)

    def response(w):
        s = 1j * w
        return np.polyval(num, s) / np.polyval(den, s)

    roots = np.concatenate([np.roots(den), np.roots(num)]) if num.size > 1 else np.roots(den)
    features, window = _feature_grid(roots)
    return Plant(response, window, features, lti=sys)


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
            raise ValueError(f"omega outside the frd's frequency grid [{lo:g}, {hi:g}] rad/s")
        x = np.log(omega)
        return re(x) + 1j * im(x)

    return Plant(response, (lo, hi), w, domain=(lo, hi), lti=sys)


def as_plant(G) -> Plant:
    """Adapt ``G`` (python-control tf/ss/frd, a callable G(omega), or a :class:`Plant`) to a :class:`Plant`.

    A callable receives an array of frequencies in rad/s and must return G(j omega) of the same shape,
    e.g. ``lambda w: np.exp(-1j * w * T) / (1j * w + 1)`` for a plant with a pure delay T.
    """
    if isinstance(G, Plant):
        return G
    ct = sys.modules.get("control")  # an LTI exists only once python-control is imported
    if ct is not None and isinstance(G, ct.LTI):
        _check_siso(G)
        if isinstance(G, ct.FrequencyResponseData):
            return _from_frd(G)
        return _from_tf(G)
    if callable(G):
        return Plant(G, None)
    raise ValueError(f"G must be a python-control tf/ss/frd or a callable G(omega); got {type(G).__name__}")
