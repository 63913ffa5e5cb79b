"""The compiled integrator of :class:`~dfloop.hybrid.smooth.SmoothLoop` for the built-in smooth elements.

The loop s' = A s + B (f(x) + load), x = r0 - C s, with f a built-in smooth element encoded as the compiled
prediction pipeline encodes it (kind code of :mod:`dfloop.solve.compiled.kinds` and the parameter vector of the
element's ``compiled_form()``; the cubic stiffness: kind ``cubic``, parameters (k1, 3 k3 / 4)), integrated by
DOP853 in numba: the tableau, error estimate (the 5th- and 3rd-order estimates combined as Hairer's DOP853 and
scipy do), step control (safety 0.9, factors in [0.2, 10], the initial step of Hairer, Norsett & Wanner II.4) and
7th-order dense output of scipy's ``DOP853`` (the steps scipy takes on one node's equations, up to rounding), with
the variational equation P' = (A - B f'(x) C) P alongside for the monodromy (P = I at the start, its error
controlled with the state's).

Each node of a shooting is its own integration (own steps) within one call (:func:`flows`); every flow keeps its
dense output (three more stages of the state alone per step), so the period's flow is joined from the node flows
without integrating again, and the waveform and Fourier samples are polynomial evaluations (:func:`dense_values`).
Python elements keep scipy's ``solve_ivp`` (:mod:`dfloop.hybrid.smooth`).
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.integrate import DOP853

from ..solve.compiled.kinds import CUBIC

__all__ = ["SMOOTH_KINDS", "MAX_STEPS", "COMPILE_SECONDS", "TABLE", "flows", "dense_values", "failure", "announce"]

SMOOTH_KINDS = frozenset({CUBIC})
"""Kind codes (:mod:`dfloop.solve.compiled.kinds`) whose time function is compiled here."""
MAX_STEPS = 200_000
"""Bound on the accepted steps of one node's flow (a flow reaching it fails with a message naming it)."""
COMPILE_SECONDS = 4
"""About how long compiling :func:`flows` and :func:`dense_values` takes once per installation (s; measured by
``python benchmarks/bench_exact.py --compile``)."""

# the tableau of scipy's DOP853 class (Hairer's coefficients: 12 stages, the FSAL stage 12, 3 extra stages for the
# dense output) as one table of rows: stages 0-15 (A), solution weights (B), error weights (E5, E3), dense output (D)
_STAGES = 12
_B, _E5, _E3, _D = 16, 17, 18, 19
TABLE = np.zeros((23, 16))
TABLE[:_STAGES, :_STAGES] = DOP853.A
TABLE[_STAGES + 1:16] = DOP853.A_EXTRA
TABLE[_B, :_STAGES] = DOP853.B
TABLE[_E5, :_STAGES + 1] = DOP853.E5
TABLE[_E3, :_STAGES + 1] = DOP853.E3
TABLE[_D:] = DOP853.D
_SAFETY, _MIN_FACTOR, _MAX_FACTOR, _EXPONENT = 0.9, 0.2, 10.0, -1.0 / 8.0
OK, TOO_SMALL, TOO_MANY, NOT_FINITE = 0, 1, 2, 3   # status of a node's flow


@njit(cache=True, nogil=True)
def _coefficients(kind, params):
    """Time-domain coefficients of the element from its compiled form: cubic (k1, 3 k3 / 4) -> (k1, k3)."""
    q = np.zeros(2)
    if kind == CUBIC:
        q[0] = params[0]
        q[1] = params[1] / 0.75
    return q


@njit(cache=True, nogil=True)
def _element(kind, q, x):
    """(f(x), f'(x)); cubic: x (k1 + k3 x^2) (the Horner form of CubicStiffness.output), k1 + 3 k3 x^2."""
    xx = x * x
    return x * (q[0] + q[1] * xx), q[0] + 3.0 * q[1] * xx


@njit(cache=True, nogil=True)
def _field(A, B, C, r0, load, kind, q, y, n, out):
    """out[:n] = A s + B (f(x) + load), x = r0 - C s, for the state s = y[:n]; returns f'(x).

    The helpers take only run-time values and array rows (no literal arguments), so each compiles once: a literal
    argument (a constant index, a constant flag) would compile a specialisation of its own."""
    x = r0
    for k in range(n):
        x -= C[k] * y[k]
    f, slope = _element(kind, q, x)
    u = f + load
    for i in range(n):
        acc = B[i] * u
        for k in range(n):
            acc += A[i, k] * y[k]
        out[i] = acc
    return slope


@njit(cache=True, nogil=True)
def _variational(A, B, C, y, n, slope, out):
    """out[n:] = (A - B f'(x) C) P for P = y[n:] (row-major), slope = f'(x)."""
    for j in range(n):
        cp = 0.0
        for k in range(n):
            cp += C[k] * y[n + k * n + j]
        g = slope * cp
        for i in range(n):
            acc = -B[i] * g
            for k in range(n):
                acc += A[i, k] * y[n + k * n + j]
            out[n + i * n + j] = acc


@njit(cache=True, nogil=True)
def _combine(coef, K, width, out):
    """out[:width] = sum_r coef[r] K[r, :width] over a row of TABLE (its zero coefficients skipped)."""
    for c in range(width):
        out[c] = 0.0
    for r in range(coef.size):
        a = coef[r]
        if a != 0.0:
            for c in range(width):
                out[c] += a * K[r, c]


@njit(cache=True, nogil=True)
def _initial_step(A, B, C, r0, load, kind, q, y, K, n, variational, width, span, h_max, rtol, atol, tmp):
    """The initial step of scipy's ``select_initial_step`` (Hairer, Norsett & Wanner II.4), order 7 estimator;
    f(y) in K[0], K[1] used as work space."""
    d0 = 0.0
    d1 = 0.0
    for c in range(width):
        sc = atol + abs(y[c]) * rtol
        u = y[c] / sc
        v = K[0, c] / sc
        d0 += u * u
        d1 += v * v
    d0 = np.sqrt(d0 / width)
    d1 = np.sqrt(d1 / width)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, span)
    for c in range(width):
        tmp[c] = y[c] + h0 * K[0, c]
    slope = _field(A, B, C, r0, load, kind, q, tmp, n, K[1])
    if variational:
        _variational(A, B, C, tmp, n, slope, K[1])
    d2 = 0.0
    for c in range(width):
        sc = atol + abs(y[c]) * rtol
        u = (K[1, c] - K[0, c]) / sc
        d2 += u * u
    d2 = np.sqrt(d2 / width) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, span, h_max)


@njit(cache=True, nogil=True)
def flows(A, B, C, r0, load, kind, params, S0, t_end, variational, rtol, atol, h_max, max_steps):
    """The flows of the loop from every row of S0 over [0, t_end[i]], each node its own DOP853 integration.

    Returns
    -------
    end : (m, width) array
        The end states (plant state, then the monodromy row-major when ``variational``).
    fields : (m, 2, n) array
        The vector field s' at each node's start and end state.
    status, steps : (m,) int arrays
        ``OK``, ``TOO_SMALL`` (step below 10 ulp of t), ``TOO_MANY`` (``max_steps`` accepted steps) or
        ``NOT_FINITE`` (the state left the floats); accepted steps.
    dense : (rows, 2 + 8 n) array
        Per accepted step: t_old, h, y_old (n), the 7 rows of the dense-output polynomial F (7 n), node after node.
    starts : (m + 1,) int array
        Node i's steps are rows starts[i]:starts[i + 1] of ``dense``.
    """
    m, n = S0.shape
    width = n + n * n if variational else n
    q = _coefficients(kind, params)
    end = np.zeros((m, width))
    fields = np.zeros((m, 2, n))
    status = np.zeros(m, np.int64)
    steps = np.zeros(m, np.int64)
    cols = 2 + 8 * n
    dense = np.empty((16 * m + 16, cols))
    rows = 0
    starts = np.zeros(m + 1, np.int64)
    K = np.empty((16, width))
    y = np.empty(width)
    y_new = np.empty(width)
    tmp = np.empty(width)
    acc = np.empty(width)
    acc3 = np.empty(width)
    for node in range(m):
        starts[node] = rows
        for c in range(width):          # element-wise copies throughout: a slice assignment compiles numba's
            y[c] = 0.0                  # shape-mismatch error path (seconds of compile time each)
        for c in range(n):
            y[c] = S0[node, c]
        if variational:
            for i in range(n):
                y[n + i * n + i] = 1.0
        span = t_end[node]
        t = 0.0
        slope = _field(A, B, C, r0, load, kind, q, y, n, K[0])
        if variational:
            _variational(A, B, C, y, n, slope, K[0])
        for c in range(n):
            fields[node, 0, c] = K[0, c]
        h_abs = _initial_step(A, B, C, r0, load, kind, q, y, K, n, variational, width, span, h_max, rtol, atol,
                              tmp) if span > 0.0 else 0.0
        while t < span:
            if steps[node] >= max_steps:
                status[node] = TOO_MANY
                break
            min_step = 10.0 * (np.nextafter(t, np.inf) - t)
            h_abs = min(h_abs, h_max)
            if h_abs < min_step:
                h_abs = min_step
            rejected = False
            while True:
                if h_abs < min_step:
                    status[node] = TOO_SMALL
                    break
                t_new = min(t + h_abs, span)
                h = t_new - t
                for s in range(1, _STAGES):
                    _combine(TABLE[s], K, width, acc)
                    for c in range(width):
                        tmp[c] = y[c] + h * acc[c]
                    slope = _field(A, B, C, r0, load, kind, q, tmp, n, K[s])
                    if variational:
                        _variational(A, B, C, tmp, n, slope, K[s])
                _combine(TABLE[_B], K, width, acc)
                for c in range(width):
                    y_new[c] = y[c] + h * acc[c]
                slope = _field(A, B, C, r0, load, kind, q, y_new, n, K[_STAGES])
                if variational:
                    _variational(A, B, C, y_new, n, slope, K[_STAGES])
                _combine(TABLE[_E5], K, width, acc)
                _combine(TABLE[_E3], K, width, acc3)
                e5 = 0.0
                e3 = 0.0
                for c in range(width):
                    sc = atol + max(abs(y[c]), abs(y_new[c])) * rtol
                    u = acc[c] / sc
                    v = acc3[c] / sc
                    e5 += u * u
                    e3 += v * v
                if e5 == 0.0 and e3 == 0.0:
                    err = 0.0
                else:
                    err = h * e5 / np.sqrt((e5 + 0.01 * e3) * width)
                if err < 1.0:
                    factor = _MAX_FACTOR if err == 0.0 else min(_MAX_FACTOR, _SAFETY * err ** _EXPONENT)
                    if rejected:
                        factor = min(1.0, factor)
                    h_abs *= factor
                    break
                factor = _SAFETY * err ** _EXPONENT
                h_abs *= factor if (np.isfinite(factor) and factor > _MIN_FACTOR) else _MIN_FACTOR
                rejected = True
            if status[node] != OK:
                break
            finite = True
            for c in range(width):
                finite = finite and np.isfinite(y_new[c])
            if not finite:
                status[node] = NOT_FINITE
                break
            # dense output of the state (scipy's Dop853DenseOutput): the three extra stages on the state alone
            for s in range(_STAGES + 1, 16):
                _combine(TABLE[s], K, n, acc)
                for c in range(n):
                    tmp[c] = y[c] + h * acc[c]
                _field(A, B, C, r0, load, kind, q, tmp, n, K[s])
            if rows == dense.shape[0]:
                grown = np.empty((2 * rows, cols))
                for r in range(rows):
                    for c in range(cols):
                        grown[r, c] = dense[r, c]
                dense = grown
            dense[rows, 0] = t
            dense[rows, 1] = h
            for c in range(n):
                dy = y_new[c] - y[c]
                dense[rows, 2 + c] = y[c]
                dense[rows, 2 + n + c] = dy
                dense[rows, 2 + 2 * n + c] = h * K[0, c] - dy
                dense[rows, 2 + 3 * n + c] = 2.0 * dy - h * (K[_STAGES, c] + K[0, c])
            for d in range(4):
                _combine(TABLE[_D + d], K, n, acc)
                for c in range(n):
                    dense[rows, 2 + (4 + d) * n + c] = h * acc[c]
            rows += 1
            steps[node] += 1
            t = t_new
            for c in range(width):
                y[c] = y_new[c]
                K[0, c] = K[_STAGES, c]
        for c in range(width):
            end[node, c] = y[c]
        for c in range(n):
            fields[node, 1, c] = K[0, c]
    starts[m] = rows
    return end, fields, status, steps, dense[:rows], starts


@njit(cache=True, nogil=True)
def dense_values(dense, n, t):
    """The state at times t from dense-output rows (sorted by t_old; a time outside them uses the nearest step's
    polynomial): (len(t), n)."""
    out = np.empty((t.size, n))
    rows = dense.shape[0]
    for i in range(t.size):
        lo, hi = 0, rows - 1          # the last step with t_old <= t[i] (the first step before them all)
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if dense[mid, 0] <= t[i]:
                lo = mid
            else:
                hi = mid - 1
        row = dense[lo]
        x = (t[i] - row[0]) / row[1]
        for c in range(n):
            v = 0.0
            for k in range(7):       # scipy's Horner scheme: F6..F0, alternately times x and (1 - x)
                v += row[2 + (7 - k) * n + c]
                v *= x if k % 2 == 0 else 1.0 - x
            out[i, c] = v + row[2 + c]
    return out


def failure(status: int) -> str:
    """What a node's flow status (not ``OK``) means."""
    return {TOO_SMALL: "the step size fell below 10 ulp of t (the motion escapes: a finite-time blow-up of the loop?)",
            TOO_MANY: f"MAX_STEPS = {MAX_STEPS} accepted steps in one node's flow (raise "
                      "dfloop.hybrid.smooth_compiled.MAX_STEPS to go further)",
            NOT_FINITE: "the state left the floating-point range"}[status]


def announce() -> None:
    """Say once, before the first compile on this installation, that the smooth-loop integrator compiles."""
    from ..progress import announce_compile

    announce_compile("the smooth-loop integrator", COMPILE_SECONDS, flows, dense_values)
