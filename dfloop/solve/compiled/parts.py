"""The arguments of the compiled driver (:mod:`.driver`) for a loop, read from G and N without numba: the
coefficients of a rational G and the compiled form of the element with the constants of its bounds. None
wherever the driver does not mirror the Python path (it then runs instead)."""
from __future__ import annotations

import math
import sys

import numpy as np

from ...describing.base import DescribingFunction
from ...describing.static import CubicStiffness, StaticElement
from ..delay import DelayedSystem
from ..plant import MAX_ORDER
from .kinds import KINDS

__all__ = ["plant_part", "element_part"]


_CACHE_SIZE = 256  # plants and elements remembered by their contents (repeated calls skip the conversion)
_PLANTS: dict = {}
_ELEMENTS: dict = {}


def _remember(cache: dict, key, value):
    if len(cache) >= _CACHE_SIZE:
        cache.clear()
    cache[key] = value
    return value


def _roots(p: np.ndarray) -> np.ndarray:
    """np.roots(p) for p without leading zeros (what :class:`~dfloop.solve.plant.Plant` holds), with the degree-0
    and degree-1 cases taken without numpy's call overhead: np.roots gives there no root, or the eigenvalue of the
    1 x 1 companion matrix [-p1 / p0], exactly, followed by the roots at 0 of trailing zeros."""
    c = p.tolist()
    core = len(c) - _first_nonzero(c[::-1])  # up to the last non-zero coefficient
    if core > 2:
        return np.roots(p)
    return np.array(([-c[1] / c[0]] if core == 2 else []) + [0.0] * (len(c) - core))


def plant_part(G):
    """(num, den, zeros, poles, delay) of G for the driver: a continuous SISO python-control tf, optionally inside
    a :class:`~dfloop.solve.delay.DelayedSystem`; None for anything else or anything the Python path would reject
    (it then says why). Remembered by the coefficients and the delay (the result depends on nothing else)."""
    ct = sys.modules.get("control")
    delay = 0.0
    if isinstance(G, DelayedSystem):
        G, delay = G.system, float(G.delay)
    if ct is None or not isinstance(G, ct.TransferFunction):
        return None
    if getattr(G, "ninputs", 1) != 1 or getattr(G, "noutputs", 1) != 1 or getattr(G, "dt", 0) not in (0, None):
        return None
    arrays = getattr(G, "num_array", None)  # python-control >= 0.10: the coefficient arrays, without num's lists
    num, den = (arrays[0, 0], G.den_array[0, 0]) if arrays is not None else (G.num[0][0], G.den[0][0])
    key = None
    if type(num) is np.ndarray and type(den) is np.ndarray and num.ndim == 1 and den.ndim == 1:
        key = (num.dtype, num.tobytes(), den.dtype, den.tobytes(), delay)  # as given: no conversion
        hit = _PLANTS.get(key)
        if hit is not None:
            return hit
    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    if num.ndim != 1 or den.ndim != 1:
        return None
    if max(den.size, num.size) - 1 > MAX_ORDER:
        return None
    nl, dl = num.tolist(), den.tolist()  # a few coefficients: scalar Python is faster than numpy's calls
    if not all(map(math.isfinite, nl)) or not all(map(math.isfinite, dl)):
        return None
    num, den = num[_first_nonzero(nl):], den[_first_nonzero(dl):]  # leading zeros trimmed, as Plant does
    if num.size == 0 or den.size == 0 or num.size > den.size:
        return None
    zeros, poles = (np.ascontiguousarray(_roots(x), complex) for x in (num, den))  # as Plant has them
    out = (np.ascontiguousarray(num), np.ascontiguousarray(den), zeros, poles, delay)
    return out if key is None else _remember(_PLANTS, key, out)


def _first_nonzero(c: list) -> int:
    """The index of the first non-zero coefficient (the length when all are zero: nothing is left)."""
    for i, x in enumerate(c):
        if x != 0:
            return i
    return len(c)


_NOTHING = object()
_UNIT = np.ones(1)  # the amplitude at which the element's bound constants are read (read-only: ~1 us per np.ones)
_UNIT.flags.writeable = False


def element_part(N, form_of):
    """The element's arguments for the driver (kind, parameters, continuity, domain and its logs, tail and head
    bound constants, breakpoint), or None where the driver does not mirror the element's methods or
    ``form_of(N)`` (:func:`.residual.element_form`) gives it no compiled form. Remembered by the class and the
    attributes (a built-in element is a function of them; an element whose attributes cannot be hashed is
    converted every time)."""
    cls = type(N)
    try:
        key = (cls, tuple(vars(N).items()))
        hash(key)
    except TypeError:
        key = None
    if key is not None:
        hit = _ELEMENTS.get(key, _NOTHING)
        if hit is not _NOTHING:
            return hit
    form = form_of(N)
    out = None if form is None else _element_part(N, form, cls)
    return out if key is None else _remember(_ELEMENTS, key, out)


_MIRRORED: dict = {}  # element class -> whether the driver mirrors its methods (a fact of the class)


def _mirrored(cls) -> bool:
    """Whether the driver mirrors the methods of element class ``cls``: the protocol's default validity and
    error estimate, and the bounds, domain and breakpoints of the class that defines its compiled form."""
    hit = _MIRRORED.get(cls)
    if hit is None:
        owner = next(c for c in cls.__mro__ if "compiled_form" in c.__dict__)
        hit = _MIRRORED[cls] = (
            cls.validity is DescribingFunction.validity and cls.error_estimate is DescribingFunction.error_estimate
            and all(getattr(cls, m) is getattr(owner, m) for m in ("tail_bound", "head_bound", "amplitude_domain"))
            and (not issubclass(cls, StaticElement) or cls.breakpoints is owner.breakpoints))
    return hit


def _element_part(N, form, cls):
    if not _mirrored(cls):
        return None
    kind = KINDS[form[0]]
    lo, hi = (float(x) for x in N.amplitude_domain())  # the class's own: 0-d arrays
    ln_lo, ln_hi = (float(np.log(x)) if x > 0 else -math.inf for x in (lo, hi))  # np.log(0) = -inf
    tail = N.tail_bound(_UNIT)
    tail_c = np.nan if tail is None else float(tail[0])
    head_c = head_d = np.nan
    if N.head_bound(_UNIT) is not None:
        if not isinstance(N, CubicStiffness):
            return None
        head_c, head_d = 0.75 * (1 + 1e-12) * abs(N.k3), float(4 * np.spacing(N.k1))
    bp = np.nan
    if isinstance(N, StaticElement):
        if getattr(N, "step", None) is not None:
            return None
        pts = np.asarray(N.breakpoints(np.inf), float)
        if pts.size > 1:
            return None
        bp = float(pts[0]) if pts.size else np.nan
    return (kind, np.ascontiguousarray(form[1], float), bool(getattr(N, "continuous", False)), ln_lo, ln_hi, lo, hi,
            tail_c, head_c, head_d, bp)
