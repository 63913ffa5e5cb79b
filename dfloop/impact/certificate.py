"""A tabulated describing function certified at the point of use.

A table (the dynamic backlash's N(F, w), :mod:`dfloop.tables`) carries an error estimate from its own
refinement, but the motion from rest can flip into another basin in a window narrower than any probing. The
cycle can check what the table cannot: :func:`table_certificate` re-simulates N at the cycle's own (A, w), says
whether the table value is confirmed, and when it is not, refines the root of 1 + G N = 0 on direct values.
:func:`dfloop.exact.exact_cycle` attaches it (``extra["table"]``) and :func:`dfloop.solve.confidence.cycle_confidence`
reads it (``Confidence.table``). The plant comes in as a function w -> G(jw) (rad/s), so this layer needs no
plant conversion.
"""
from __future__ import annotations

import math

import numpy as np

from typing import Callable

from ..describing.time_model import Impact
from .extract import impact_describing_function

__all__ = ["table_certificate", "impact_direct"]

_TABLE_AGREEMENT = 3.0      # a table value within this many of its error estimates of the direct value is confirmed
_REFINE_ITERATIONS = 8


def table_certificate(G_of: Callable[[float], complex], N, A: float, w: float) -> dict | None:
    """Certify a tabulated N at the point of use: the table's value, its error estimate and validity at (A, w),
    and N re-simulated directly there (elements whose time model is an
    :class:`~dfloop.describing.time_model.Impact`: :func:`dfloop.impact.extract.impact_describing_function`).

    Returns None for an element without a table (a closed form or a static element: ``error_estimate`` 0 or not
    finite). Otherwise a dict: ``table`` (complex N from the table), ``error`` (its error estimate, absolute),
    ``valid`` (the table's validity flag), ``direct`` (the re-simulated N, None without a direct evaluation),
    ``regular`` (the direct run found a periodic motion), ``difference`` |direct - table|, ``status``:
    ``"confirmed"`` (within 3 error estimates, or 1e-6 relative), ``"replaced"`` (the direct value differs: the
    motion from rest may flip into another basin in a window narrower than the table's probing) or ``"not
    re-simulated"``; when replaced, ``refined`` holds the root (A, w) of 1 + G(jw) N(A, w) = 0 found by Newton's
    method on direct values from (A, w), or None with ``refine_message`` saying why. ``G_of(w)`` is the plant's
    frequency response G(jw) at w rad/s (the pure delay included).
    """
    try:
        err = float(np.asarray(N.error_estimate(A, w) if N.frequency_dependent else N.error_estimate(A)))
    except (TypeError, ValueError, NotImplementedError):
        return None
    if not (math.isfinite(err) and err > 0.0):
        return None
    n_table = complex(N(A, w) if N.frequency_dependent else N(A))
    valid = bool(np.all(N.validity(A, w) if N.frequency_dependent else N.validity(A)))
    out = {"table": n_table, "error": err, "valid": valid, "direct": None, "regular": None, "difference": None,
           "status": "not re-simulated"}
    tm = N.time_model(A)
    if not isinstance(tm, Impact):
        return out
    direct = impact_direct(tm)
    d, regular = direct(A, w)
    diff = abs(d - n_table)
    out.update(direct=d, regular=regular, difference=diff,
               status="confirmed" if diff <= max(_TABLE_AGREEMENT * err, 1e-6 * abs(n_table)) else "replaced")
    if out["status"] == "replaced":
        out["refined"], out["refine_message"] = _refine_root(G_of, direct, A, w)
    return out


def impact_direct(tm):
    """N(F, w) of the impact element re-simulated at one point: a function (F, w) -> (complex N, regular motion)."""
    def direct(F, w):
        r = impact_describing_function(tm.m1, tm.m2, tm.h, tm.restitution, F, w, effects=tm.effects,
                                       chatter_tol=tm.chatter_tol)
        return complex(r.N), bool(r.regular)

    return direct


def _refine_root(G_of, direct, A: float, w: float):
    """Newton on 1 + G(jw) N(A, w) = 0 in (ln A, ln w) with N re-simulated (forward differences, relative step
    1e-5): ((A, w), message), or (None, why)."""
    def R(u, v):
        F, om = math.exp(u), math.exp(v)
        g = complex(G_of(om))
        return 1.0 + g * direct(F, om)[0]

    u, v = math.log(A), math.log(w)
    r = R(u, v)
    for it in range(1, _REFINE_ITERATIONS + 1):
        if abs(r) < 1e-10:
            return (math.exp(u), math.exp(v)), f"converged in {it - 1} Newton iteration(s), |1 + G N| {abs(r):.1e}"
        d = 1e-5
        ru, rv = (R(u + d, v) - r) / d, (R(u, v + d) - r) / d
        J = np.array([[ru.real, rv.real], [ru.imag, rv.imag]])
        try:
            du, dv = np.linalg.solve(J, [-r.real, -r.imag])
        except np.linalg.LinAlgError:
            return None, "singular Jacobian of 1 + G N on the direct values"
        u, v = u + du, v + dv
        r = R(u, v)
    if abs(r) < 1e-8:
        return (math.exp(u), math.exp(v)), f"|1 + G N| {abs(r):.1e} after {_REFINE_ITERATIONS} iterations"
    return None, (f"no root of 1 + G N on the direct values within {_REFINE_ITERATIONS} Newton iterations "
                  f"(|1 + G N| {abs(r):.1e}; a jump of N there)")
