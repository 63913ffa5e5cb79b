"""JIT step loop and event search of the linear-mode effects engine (:mod:`dfloop.impact.effects`).

State z = [x1, v1, x2, v2, cos wt, sin wt, 1] evolves by z' = A z in one mode. :func:`scan_steps` advances z by
the precomputed step exponential E = exp(A dt) until a constraint row r (r.z >= 0 in the mode) is violated inside
a step; the crossing is then refined on the Taylor series of exp(A s) z over that step. Plain float arrays only,
so the functions also run (slowly) with NUMBA_DISABLE_JIT=1. Products are taken with ``np.dot`` (the same BLAS
gemv/dot calls NumPy makes), so results do not depend on the JIT: this matters in chaotic regimes, where
rounding-level differences in the event times grow over the transient.
"""
from __future__ import annotations

import numpy as np
from numba import njit

TAYLOR_TERMS = 30
NO_ROOT = -1.0       # first_violation: no violation inside the step
REFINE_ITERATIONS = 200


@njit(cache=True)
def taylor(A, z):
    """Rows A^k z / k! for k < TAYLOR_TERMS (Taylor coefficients of exp(A s) z)."""
    terms = np.empty((TAYLOR_TERMS, z.shape[0]))
    terms[0] = z
    for k in range(1, TAYLOR_TERMS):
        terms[k] = np.dot(A, terms[k - 1]) / k
    return terms


@njit(cache=True)
def poly(terms, s):
    """exp(A s) z from Taylor coefficients (Horner)."""
    out = terms[-1].copy()
    for k in range(terms.shape[0] - 2, -1, -1):
        for i in range(out.shape[0]):
            out[i] = out[i] * s + terms[k, i]
    return out


@njit(cache=True)
def _value(terms, A, r, s, derivative):
    """r.z(s) (derivative False) or r.A z(s) (derivative True)."""
    z = poly(terms, s)
    if derivative:
        return np.dot(r, np.dot(A, z))
    return np.dot(r, z)


@njit(cache=True)
def refine(terms, A, r, derivative, lo, hi, flo):
    """Root of r.z(s) (or of r.A z(s)) with a sign change on [lo, hi] (bisection with secant steps)."""
    fhi = _value(terms, A, r, hi, derivative)
    for _ in range(REFINE_ITERATIONS):
        if hi - lo <= 4e-16 * max(hi, 1e-300):
            break
        s = hi - fhi * (hi - lo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        if not (lo < s < hi) or (hi - lo) < 1e-3 * abs(s - 0.5 * (lo + hi)):
            s = 0.5 * (lo + hi)
        fs = _value(terms, A, r, s, derivative)
        if fs == 0.0:
            return s
        if (fs > 0) == (flo > 0):
            lo, flo = s, fs
        else:
            hi, fhi = s, fs
        # force a bisection every other step to guarantee progress
        m = 0.5 * (lo + hi)
        fm = _value(terms, A, r, m, derivative)
        if fm == 0.0:
            return m
        if (fm > 0) == (flo > 0):
            lo, flo = m, fm
        else:
            hi, fhi = m, fm
    return hi


@njit(cache=True)
def first_violation(terms, A, r, leaving, dt):
    """First s in [0, dt] where r.z(s) < 0 given r.z >= 0 before (NO_ROOT if none in the step).

    ``leaving``: the step starts on r.z = 0 and moves away; values within rounding of 0 are then not events.
    One turning point per step is resolved (the step is 1/32 of the fastest time scale).
    """
    tol = 1e-12 * np.dot(np.abs(r), np.abs(terms[0])) if leaving else 0.0
    fa = _value(terms, A, r, 0.0, False)
    fb = _value(terms, A, r, dt, False)
    da = _value(terms, A, r, 0.0, True)
    db = _value(terms, A, r, dt, True)
    turns = (da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0)
    turn = refine(terms, A, r, True, 0.0, dt, da) if turns else 0.0
    if fb < -tol:
        if turns and da > 0.0:  # rises to a maximum, then falls through zero
            ft = _value(terms, A, r, turn, False)
            return refine(terms, A, r, False, turn, dt, ft) if ft > 0.0 else turn
        return refine(terms, A, r, False, 0.0, dt, fa) if fa > 0.0 else 0.0
    if turns and da < 0.0:      # dips to a minimum inside the step
        ft = _value(terms, A, r, turn, False)
        if ft < -tol:
            return refine(terms, A, r, False, 0.0, turn, fa) if fa > 0.0 else 0.0
    return NO_ROOT


@njit(cache=True, nogil=True)
def scan_steps(A, E, dt, rows, leaving, z, t, t_end):
    """Advance z (in place) by steps exp(A dt) = E from time t until the first event or the end.

    Stops before a step shorter than ``dt`` (the last one before ``t_end``), which the caller takes with its own
    exponential. ``leaving[j]``: row j starts on 0 and moves away (applies to the first step only).

    Returns
    -------
    t : float
        Time reached (s): the event time, or the time at which stepping stopped.
    hit : int
        Index of the violated row, or -1 when no event occurred.
    """
    n_rows = rows.shape[0]
    first = True
    db = np.dot(rows, np.dot(A, z))
    while t < t_end and min(dt, t_end - t) == dt:
        z_next = np.dot(E, z)
        fb = np.dot(rows, z_next)
        da = db                       # r.A z at the step start = r.A z_next of the previous step
        db = np.dot(rows, np.dot(A, z_next))
        best_s = NO_ROOT
        hit = -1
        have_terms = False
        terms = np.empty((0, 0))
        for j in range(n_rows):
            r = rows[j]
            lv = first and leaving[j]
            if fb[j] < 0.0 or da[j] * db[j] < 0.0 or lv:
                if not have_terms:
                    terms = taylor(A, z)
                    have_terms = True
                s = first_violation(terms, A, r, lv, dt)
                if s != NO_ROOT and (hit < 0 or s < best_s):
                    best_s, hit = s, j
        first = False
        if hit >= 0:
            z[:] = poly(terms, best_s)
            return t + best_s, hit
        z[:] = z_next
        t += dt
    return t, -1


@njit(cache=True)
def rows_on_zero(rows, z):
    """Rows r with r.z = 0 to rounding (|r.z| <= 1e-12 |r|.|z|): constraints that start on their boundary."""
    out = np.empty(rows.shape[0], dtype=np.bool_)
    abs_z = np.abs(z)
    for j in range(rows.shape[0]):
        r = rows[j]
        out[j] = abs(np.dot(r, z)) <= 1e-12 * (np.dot(np.abs(r), abs_z) + 1e-300)
    return out


@njit(cache=True)
def admissible(A, rows, z):
    """All rows hold at z (r.z >= 0), ties broken by the first non-negligible derivative r.A^k z, k <= 3."""
    derivs = np.empty((4, z.shape[0]))
    sizes = np.empty((4, z.shape[0]))   # sizes bound the terms summed in each derivative (rounding scale)
    derivs[0] = z
    sizes[0] = np.abs(z)
    abs_a = np.abs(A)
    for k in range(1, 4):
        derivs[k] = np.dot(A, derivs[k - 1])
        sizes[k] = np.dot(abs_a, sizes[k - 1])
    for j in range(rows.shape[0]):
        r = rows[j]
        abs_r = np.abs(r)
        for k in range(4):
            val = np.dot(r, derivs[k])
            tol = 1e-12 * np.dot(abs_r, sizes[k])
            if val > tol:
                break
            if val < -tol:
                return False
    return True


@njit(cache=True, nogil=True)
def propagate(A, E, z0, s, step):
    """exp(A s) z0 for an array of s >= 0: exact steps E = exp(A step) to the chunk starts, Taylor inside."""
    chunks = np.floor(s / step).astype(np.int64)
    starts = np.empty((chunks.max() + 1 if chunks.size else 1, z0.shape[0]))
    starts[0] = z0
    for c in range(1, starts.shape[0]):
        starts[c] = np.dot(E, starts[c - 1])
    out = np.empty((s.shape[0], z0.shape[0]))
    for i in range(s.shape[0]):
        out[i] = poly(taylor(A, starts[chunks[i]]), s[i] - chunks[i] * step)
    return out
