"""The compiled event loop of the exact linear-mode engine (:mod:`dfloop.impact._engine`).

State z = [x1, v1, d, u, extra..., 1] with d = gap - wall (the gap measured from the wall of the last impact,
``ref``: 0 = side A at gap 0, 1 = side B at gap h) and u = v2 - v1, so that a gap near a wall is carried with
full relative precision (chatter of nanometre bounces is resolved, not drowned in the rounding of x2 - x1).
The extra states are the forcing oscillator [cos wt, sin wt] (open loop) or the plant's states (closed loop).

In one mode (contact FREE / STUCK_A / STUCK_B x ground mode of a friction mass) the motion is z' = A z.
:func:`run_engine` advances z by the precomputed step exponential E = exp(A dt) until a constraint row r
(r.z >= 0 in the mode) is violated inside a step, refines the crossing on the Taylor series of exp(A s) z over
the step, applies the event (impact law, plastic settle of a converged chatter, separation, stick-slip), selects
the next admissible mode and records the segment in preallocated buffers; it returns when the buffers are full
(the caller grows them and resumes), when ``t_end`` is reached or when ``max_events`` is exceeded.

Plain float arrays only, so everything also runs (slowly) with NUMBA_DISABLE_JIT=1 and gives the same numbers:
the hot products are explicit loops and the others ``np.dot`` (the BLAS calls NumPy makes), so results do not
depend on the JIT. This matters in chaotic regimes, where rounding-level differences in the event times grow
over the transient.

Speed without changing a bit: :func:`run_engine` allocates its work arrays once per call (the ``_into``
variants; the public functions allocate and call them), products with a mode matrix skip its zero entries,
Horner sums stop at the Taylor terms kept, and bisection takes a sign from the leading terms only when a
rounding bound proves it equals the full evaluation's (:func:`_certain_sign`). ``tests/test_effects_core.py``
checks each shortcut against the plain evaluation, byte for byte.
"""
from __future__ import annotations

import numpy as np
from numba import njit

TAYLOR_TERMS = 30
NO_ROOT = -1.0       # first_violation: no violation inside the step
SUB_PIECES = 8       # pieces of an examined step (one turning point assumed per piece)
REFINE_ITERATIONS = 200
NEWTON_STEPS = 12    # refine: Newton steps before pure bisection

# state slots
X1, V1, D, U = 0, 1, 2, 3
# contact modes and ground modes (ground code stored in records: 0 grounded / no friction, +1, -1 slipping)
FREE, STUCK_A, STUCK_B = 0, 1, 2
N_SLOTS = 9          # slot = 3 * contact + ground index (0: none or grounded, 1: slipping +, 2: slipping -)
# constraint kinds
HIT_A, HIT_B, SEPARATE, STOP, SLIP = 0, 1, 2, 3, 4
# segment causes
START, IMPACT_A, IMPACT_B, SEPARATION, GROUND_EVENT = 0, 1, 2, 3, 4
# run status
DONE, BUFFER_FULL, EVENT_LIMIT, NO_MODE, DIVERGED = 0, 1, 2, 3, 4
BEYOND_LIMIT = -2    # scan_steps: a state component passed the divergence limit
# float parameters: m1, m2, eps, h, v_stick, dt, divergence limit; int parameters: has friction, friction mass
P_M1, P_M2, P_EPS, P_H, P_VSTICK, P_DT, P_LIMIT = range(7)
I_FRICTION, I_FMASS = range(2)
# float run state: t, t_end, record_from; int run state: slot, ref, events, max_events, records
S_T, S_TEND, S_RECORD_FROM = range(3)
J_SLOT, J_REF, J_EVENTS, J_MAX_EVENTS, J_RECORDS = range(5)


@njit(cache=True, nogil=True)
def _matvec(M, x, out):
    """out = M x with explicit loops (no allocation; the same rounding with or without the JIT)."""
    for i in range(M.shape[0]):
        acc = 0.0
        for k in range(M.shape[1]):
            acc += M[i, k] * x[k]
        out[i] = acc


@njit(cache=True, nogil=True)
def _sparse_into(M, ptr, col, val, mag):
    """Nonzero entries of M in row order: row i holds val[ptr[i]:ptr[i + 1]] at columns col[...]; mag = |val|.

    :func:`_spmv` over them gives M x bit for bit like :func:`_matvec`: a skipped product 0 * x (x finite) is
    +-0, and adding +-0 to a partial sum never changes it (a partial sum that starts at +0 is never -0).
    """
    p = 0
    for i in range(M.shape[0]):
        ptr[i] = p
        for k in range(M.shape[1]):
            if M[i, k] != 0.0:
                col[p] = k
                val[p] = M[i, k]
                mag[p] = abs(M[i, k])
                p += 1
    ptr[M.shape[0]] = p


@njit(cache=True, nogil=True)
def _sparse(M):
    """(ptr, col, val, mag) of :func:`_sparse_into`, allocated."""
    n = M.shape[0]
    ptr = np.empty(n + 1, dtype=np.int64)
    col = np.empty(n * M.shape[1], dtype=np.int64)
    val = np.empty(n * M.shape[1])
    mag = np.empty(n * M.shape[1])
    _sparse_into(M, ptr, col, val, mag)
    return ptr, col, val, mag


@njit(cache=True, nogil=True)
def _spmv(ptr, col, val, x, out):
    """out = M x over the nonzero entries of M (:func:`_sparse_into`)."""
    for i in range(ptr.shape[0] - 1):
        acc = 0.0
        for p in range(ptr[i], ptr[i + 1]):
            acc += val[p] * x[col[p]]
        out[i] = acc


@njit(cache=True, nogil=True)
def _taylor_into(ptr, col, val, z, terms, span):
    """terms[k] = A^k z / k! (A given by its nonzero entries), in place; returns the count m of terms kept.

    With ``span`` > 0 (the longest s used), terms from m on are set to 0 once two consecutive terms are below
    1e-30 of max|z| over the span (their contribution is far below rounding); with ``span`` = 0, m =
    TAYLOR_TERMS. Sums over the first m terms equal the sums over all of them bit for bit (the rest are +0).
    """
    terms[0] = z
    n = z.shape[0]
    size = 0.0
    for i in range(n):
        size = max(size, abs(z[i]))
    small = 0
    power = 1.0
    for k in range(1, TAYLOR_TERMS):
        if small >= 2:
            terms[k:] = 0.0
            return k
        big = 0.0
        for i in range(n):            # (A terms[k - 1])_i / k; a zero stays the same zero without the division
            acc = 0.0
            for q in range(ptr[i], ptr[i + 1]):
                acc += val[q] * terms[k - 1, col[q]]
            if acc != 0.0:
                acc /= k
                big = max(big, abs(acc))
            terms[k, i] = acc
        power *= span
        small = small + 1 if span > 0.0 and big * power <= 1e-30 * size else 0
    return TAYLOR_TERMS


@njit(cache=True, nogil=True)
def _poly_into(terms, m, s, out):
    """out = exp(A s) z (s >= 0) by Horner over the first m Taylor coefficients (the others are +0).

    Bit for bit the sum over all TAYLOR_TERMS rows: with m < TAYLOR_TERMS the zero tail leaves +0, which the
    start value 0 reproduces.
    """
    if m == terms.shape[0]:
        out[:] = terms[m - 1]
        top = m - 2
    else:
        out[:] = 0.0
        top = m - 1
    for k in range(top, -1, -1):
        for i in range(out.shape[0]):
            out[i] = out[i] * s + terms[k, i]


@njit(cache=True, nogil=True)
def _pval(c, m, s, derivative):
    """Scalar polynomial sum c_k s^k (or its derivative) by Horner over the first m coefficients (s >= 0).

    The coefficients from m on are +0 (a truncated Taylor series); the start value 0 reproduces the sum over
    all of them bit for bit.
    """
    n = c.shape[0]
    if derivative:
        if m == n:
            acc = (n - 1) * c[n - 1]
            top = n - 2
        else:
            acc = 0.0
            top = m - 1
        for k in range(top, 0, -1):
            acc = acc * s + k * c[k]
        return acc
    if m == n:
        acc = c[n - 1]
        top = n - 2
    else:
        acc = 0.0
        top = m - 1
    for k in range(top, -1, -1):
        acc = acc * s + c[k]
    return acc


@njit(cache=True, nogil=True)
def _pval2(c, m, s, derivative):
    """Value and slope at s of the polynomial c (derivative False) or of its derivative (True), first m terms."""
    n = c.shape[0]
    d = 0.0
    if derivative:   # p'(s) and p''(s)
        if m == n:
            f = (n - 1) * c[n - 1]
            top = n - 2
        else:
            f = 0.0
            top = m - 1
        for k in range(top, 0, -1):
            d = d * s + f
            f = f * s + k * c[k]
        return f, d
    if m == n:
        f = c[n - 1]
        top = n - 2
    else:
        f = 0.0
        top = m - 1
    for k in range(top, -1, -1):
        d = d * s + f
        f = f * s + c[k]
    return f, d


@njit(cache=True, nogil=True)
def _cheap_terms(c, m, derivative, hi, work):
    """(K, tail): the polynomial's first K terms (of m) carry all but ``tail`` of sum |term| on [0, hi].

    ``tail`` bounds sum_{k >= K} |c_k| s^k (or the derivative's sum_{k >= K} k |c_k| s^(k-1)) for 0 <= s <= hi,
    rounding and underflow included; K is the fewest terms with tail <= 1e-16 of the whole sum at hi (K = m when
    that saves nothing). ``work``: scratch of m floats. Powers of hi are formed upwards only while they stay
    above 1e-200; the terms beyond are bounded together by hi^k times their Horner sum (no underflow).
    """
    first = 1 if derivative else 0
    total = 0.0
    power = 1.0
    stop = m
    for k in range(first, m):
        work[k] = abs(k * c[k] if derivative else c[k]) * power
        total += work[k]
        power *= hi
        if power < 1e-200:
            stop = k + 1
            break
    rest = 0.0
    if stop < m:
        for k in range(m - 1, stop - 1, -1):
            rest = rest * hi + abs(k * c[k] if derivative else c[k])
        rest = rest * power * 1.01 + 1e-300
        total += rest
    tail = rest
    K = stop
    for k in range(stop - 1, first, -1):
        if not tail + work[k] <= 1e-16 * total:
            break
        tail += work[k]
        K = k
    if K == stop and stop < m and not tail <= 1e-16 * total:
        K = m                          # the lumped rest is not negligible: use every term
    return K, tail


@njit(cache=True, nogil=True)
def _certain_sign(c, s, derivative, K, tail):
    """+1 or -1 when the sign of :func:`_pval` (all m terms, s >= 0) is certain from its first K terms, else 0.

    Horner over n terms errs by at most ~ 3 n 2^-53 sum |c_k| s^k (here <= 1e-14 of it for n <= TAYLOR_TERMS), the
    dropped terms by at most ``tail``: a value beyond 1e-13 of the kept |terms| plus the tail has the sign of the
    full evaluation, which then is not 0.
    """
    if derivative:
        acc = (K - 1) * c[K - 1]
        size = abs(acc)
        for k in range(K - 2, 0, -1):
            acc = acc * s + k * c[k]
            size = size * s + abs(k * c[k])
    else:
        acc = c[K - 1]
        size = abs(acc)
        for k in range(K - 2, -1, -1):
            acc = acc * s + c[k]
            size = size * s + abs(c[k])
    bound = 1e-13 * size + 1.01 * tail + 1e-290
    if acc > bound:
        return 1.0
    if acc < -bound:
        return -1.0
    return 0.0


@njit(cache=True, nogil=True)
def refine(c, m, derivative, lo, hi, flo):
    """Root of the polynomial c (first m coefficients; or of its derivative) with a sign change on [lo, hi].

    Newton steps kept inside the bracket (bisection when a step leaves it, and only bisection after
    NEWTON_STEPS steps without convergence); once a Newton step is at rounding level the bracket is closed
    with one probe to either side. Returns the end on the far side of the root from ``lo`` (the violated
    side), at relative distance <= 4e-16 from the root.

    Bisection needs only the sign of the polynomial: it is taken from the few terms that matter on the bracket
    when they decide it for certain (:func:`_certain_sign`), else from the full evaluation, so the brackets, and
    the root, are those of full evaluations bit for bit (a chatter flight's root at 1e-9 of the step takes ~80
    bisections, most of them decided by 3-5 terms).
    """
    s = 0.5 * (lo + hi)
    hi_terms = -1.0                    # bracket top at which (K, tail) were taken
    K, tail = m, 0.0
    work = np.empty(0)
    for it in range(REFINE_ITERATIONS):
        if hi - lo <= 4e-16 * max(hi, 1e-300):
            break
        newton = it < NEWTON_STEPS
        if newton:
            fs, ds = _pval2(c, m, s, derivative)
        else:
            if hi_terms < 0.0 or hi <= hi_terms / 16.0:
                if hi_terms < 0.0:
                    work = np.empty(m)
                K, tail = _cheap_terms(c, m, derivative, hi, work)
                hi_terms = hi
            fs = _certain_sign(c, s, derivative, K, tail) if K < m else 0.0
            if fs == 0.0:
                fs = _pval(c, m, s, derivative)
            ds = 0.0
        if fs == 0.0:
            return s
        if (fs > 0) == (flo > 0):
            lo, flo = s, fs
        else:
            hi = s
        if newton and ds != 0.0:
            s_new = s - fs / ds
            if abs(s_new - s) <= 2e-16 * max(abs(s), 1e-300):
                step = 4e-16 * max(abs(s_new), 1e-300)   # converged: close the bracket around s_new
                for probe in (s_new - step, s_new + step):
                    if lo < probe < hi:
                        fp = _pval(c, m, probe, derivative)
                        if fp == 0.0:
                            return probe
                        if (fp > 0) == (flo > 0):
                            lo, flo = probe, fp
                        else:
                            hi = probe
                s_new = 0.5 * (lo + hi)
            elif not (lo < s_new < hi):
                s_new = 0.5 * (lo + hi)
        else:
            s_new = 0.5 * (lo + hi)
        s = s_new
    return hi


@njit(cache=True, nogil=True)
def _surely_positive(c, m, dt):
    """True when c0 + c1 s + c2 s^2 + ... > 0 on [0, dt] for sure: the quadratic's minimum exceeds a bound on
    the remaining terms (a cheap proof that a dip inside the step stays clear of the constraint). Terms from m
    on are +0 (they would add exactly 0 to the bound)."""
    rest = 0.0
    p = dt * dt
    for k in range(3, m):
        p *= dt
        rest += abs(c[k]) * p
    lo = min(c[0], c[0] + c[1] * dt + c[2] * dt * dt)
    if c[2] > 0.0:
        s = -c[1] / (2.0 * c[2])
        if 0.0 < s < dt:
            lo = min(lo, c[0] + c[1] * s + c[2] * s * s)
    return lo > 2.0 * rest


@njit(cache=True, nogil=True)
def _piece_violation(c, m, tol, lo, hi, fa, da):
    """First s in [lo, hi] with c(s) < -tol given the values at lo, assuming at most one turning point."""
    fb = _pval(c, m, hi, False)
    db = _pval(c, m, hi, True)
    turns = (da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0)
    if fb >= -tol and not (turns and da < 0.0):
        return NO_ROOT
    turn = refine(c, m, True, lo, hi, da) if turns else lo
    if fb < -tol:
        if turns and da > 0.0:  # rises to a maximum, then falls through zero
            ft = _pval(c, m, turn, False)
            return refine(c, m, False, turn, hi, ft) if ft > 0.0 else turn
        return refine(c, m, False, lo, hi, fa) if fa > 0.0 else lo
    ft = _pval(c, m, turn, False)  # dips to a minimum inside the piece
    if ft < -tol:
        return refine(c, m, False, lo, turn, fa) if fa > 0.0 else lo
    return NO_ROOT


@njit(cache=True, nogil=True)
def _first_violation(terms, m, r, leaving, dt, c):
    """First s in [0, dt] where r.z(s) < 0 given r.z >= 0 before (NO_ROOT if none in the step).

    ``leaving``: the step starts on r.z = 0 and moves away; values within rounding of 0 are then not events.
    When the curvature keeps its sign over the step the slope is monotone (one turning point at most);
    otherwise the step is examined in SUB_PIECES pieces, each with at most one turning point assumed (the scan
    examines a step whenever the row's value, rate or curvature changes sign in it). A bound on the Taylor
    series that proves the row positive over the whole step ends the search first.

    ``terms``: the Taylor rows of which the first m are kept (the rest +0); ``c``: work array of TAYLOR_TERMS
    (the row's coefficients r.A^k z / k!, set for k < m).
    """
    for k in range(m):
        acc = 0.0
        for i in range(r.shape[0]):
            acc += terms[k, i] * r[i]
        c[k] = acc
    tol = 0.0
    if leaving:
        for i in range(r.shape[0]):
            tol += abs(r[i]) * abs(terms[0, i])
        tol *= 1e-12
    elif _surely_positive(c, m, dt):
        return NO_ROOT
    # the slope is monotone (one turning point at most) when the curvature keeps its sign over the step
    _, curvature_b = _pval2(c, m, dt, True)
    pieces = 1 if c[2] * curvature_b > 0.0 else SUB_PIECES
    lo, fa, da = 0.0, c[0], c[1]
    for k in range(1, pieces + 1):
        hi = dt * k / pieces if k < pieces else dt
        s = _piece_violation(c, m, tol, lo, hi, fa, da)
        if s != NO_ROOT:
            return s
        lo, fa, da = hi, _pval(c, m, hi, False), _pval(c, m, hi, True)
    return NO_ROOT


@njit(cache=True, nogil=True)
def scan_steps(A, E, dt, rows, rows_a, rows_aa, leaving, z, t, t_end, limit=np.inf):
    """Advance z (in place) by steps exp(A dt) = E from time t until the first event or ``t_end``.

    ``rows_a`` = rows @ A and ``rows_aa`` = rows @ A @ A (the rows' rates and curvatures). The last step,
    shorter than ``dt``, is taken on the Taylor series. ``leaving[j]``: row j starts on 0 and moves away (applies
    to the first step only). A row is examined closely (Taylor series, root refinement) only when it is negative
    at the step end or its rate or curvature changes sign in the step (two turning points need the latter).
    A state component beyond ``limit`` in magnitude stops the scan (a diverging closed loop).

    Returns
    -------
    t : float
        Time reached (s): the event time, or ``t_end``.
    hit : int
        Index of the violated row, -1 when no event occurred, BEYOND_LIMIT past ``limit``.
    """
    a_ptr, a_col, a_val, _ = _sparse(A)
    n_rows = rows.shape[0]
    work = np.empty((6, n_rows))
    return _scan_into(a_ptr, a_col, a_val, E, dt, rows, rows_a, rows_aa, leaving, z, t, t_end,
                      limit, np.empty_like(z), work, np.empty((TAYLOR_TERMS, z.shape[0])), np.empty(TAYLOR_TERMS))


@njit(cache=True, nogil=True)
def _scan_into(a_ptr, a_col, a_val, E, dt, rows, rows_a, rows_aa, leaving, z, t, t_end, limit,
               z_next, work, terms, c):
    """:func:`scan_steps` with A given by its nonzero entries (:func:`_sparse_into`) and work arrays
    z_next (n,), work (6, >= n_rows) (row values, rates and curvatures at both step ends), terms
    (TAYLOR_TERMS, n) and c (TAYLOR_TERMS,): no allocation, the same numbers."""
    n_rows = rows.shape[0]
    fa, fb, da, db, ca, cb = work[0], work[1], work[2], work[3], work[4], work[5]
    first = True
    _matvec(rows, z, fb)
    _matvec(rows_a, z, db)
    _matvec(rows_aa, z, cb)
    while t < t_end:
        step = dt if t_end - t >= dt else t_end - t
        m = 0                         # Taylor terms kept (0: not computed for this step yet)
        if step == dt:
            _matvec(E, z, z_next)
        else:
            m = _taylor_into(a_ptr, a_col, a_val, z, terms, step)
            _poly_into(terms, m, step, z_next)
        for j in range(n_rows):       # r.A z at the step start = r.A z_next of the previous step
            da[j] = db[j]
            ca[j] = cb[j]
            fa[j] = fb[j]
        _matvec(rows, z_next, fb)
        _matvec(rows_a, z_next, db)
        _matvec(rows_aa, z_next, cb)
        best_s = NO_ROOT
        hit = -1
        for j in range(n_rows):
            # a row leaving its boundary with a positive, increasing slope all through the step (curvature of
            # one sign) cannot come back within it
            lv = first and leaving[j] and not (fb[j] > 0.0 and da[j] > 0.0 and db[j] > 0.0 and ca[j] * cb[j] > 0.0)
            if lv or fb[j] < 0.0 or ((da[j] * db[j] < 0.0 or ca[j] * cb[j] < 0.0)
                                     and min(fa[j], fb[j]) <= 0.5 * step * step * max(abs(ca[j]), abs(cb[j]))):
                # (a dip between two positive ends is at most (max curvature) step^2 / 8 deep: with the
                # curvature allowed to double inside the step, ends above 0.5 step^2 |curvature| are clear)
                if m == 0:
                    m = _taylor_into(a_ptr, a_col, a_val, z, terms, step)
                s = _first_violation(terms, m, rows[j], lv, step, c)
                if s != NO_ROOT and (hit < 0 or s < best_s):
                    best_s, hit = s, j
        first = False
        if hit >= 0:
            _poly_into(terms, m, best_s, z)
            return t + best_s, hit
        z[:] = z_next
        t = t + step if step == dt else t_end
        for i in range(z.shape[0]):
            if not abs(z[i]) <= limit:
                return t, BEYOND_LIMIT
    return t, -1


@njit(cache=True, nogil=True)
def _magnitudes_into(z, out):
    """out = |z| with a floor of 1e-4 max|z|: the rounding scale of a row's value. A component near 0 at an
    event (cos wt at a zero of the force) was computed from values of the state's size, not from its own."""
    big = 0.0
    for i in range(z.shape[0]):
        out[i] = abs(z[i])
        big = max(big, out[i])
    floor = 1e-4 * big
    for i in range(z.shape[0]):
        out[i] += floor


@njit(cache=True, nogil=True)
def rows_on_zero(rows, z):
    """Rows r with r.z = 0 to rounding (|r.z| <= 1e-12 |r|.|z|, |z| floored): constraints on their boundary."""
    out = np.empty(rows.shape[0], dtype=np.bool_)
    _rows_on_zero_into(rows, z, np.empty_like(z), out)
    return out


@njit(cache=True, nogil=True)
def _rows_on_zero_into(rows, z, abs_z, out):
    """:func:`rows_on_zero` into ``out`` (abs_z: work array of z's size)."""
    _magnitudes_into(z, abs_z)
    for j in range(rows.shape[0]):
        val = 0.0
        size = 1e-300
        for i in range(z.shape[0]):
            val += rows[j, i] * z[i]
            size += abs(rows[j, i]) * abs_z[i]
        out[j] = abs(val) <= 1e-12 * size


@njit(cache=True, nogil=True)
def admissible(A, rows, z):
    """All rows hold at z (r.z >= 0), ties broken by the first non-negligible derivative r.A^k z, k <= 3."""
    ptr, col, val, mag = _sparse(A)
    return _admissible_into(ptr, col, val, mag, rows, z, np.empty((4, z.shape[0])), np.empty((4, z.shape[0])))


@njit(cache=True, nogil=True)
def _admissible_into(ptr, col, val, mag, rows, z, derivs, sizes):
    """:func:`admissible` with A given by its nonzero entries and |entries| (:func:`_sparse_into`); derivs and
    sizes (4, n) are work arrays (sizes bound the terms summed in each derivative: the rounding scale)."""
    n = z.shape[0]
    derivs[0] = z
    _magnitudes_into(z, sizes[0])
    done = 0                           # derivatives computed so far (only when a tie needs them)
    for j in range(rows.shape[0]):
        for k in range(4):
            if k > done:
                _spmv(ptr, col, val, derivs[k - 1], derivs[k])
                _spmv(ptr, col, mag, sizes[k - 1], sizes[k])
                done = k
            v = 0.0
            tol = 0.0
            for i in range(n):
                v += rows[j, i] * derivs[k, i]
                tol += abs(rows[j, i]) * sizes[k, i]
            tol *= 1e-12
            if v > tol:
                break
            if v < -tol:
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
    ptr, col, val, _ = _sparse(A)
    terms = np.empty((TAYLOR_TERMS, z0.shape[0]))
    out = np.empty((s.shape[0], z0.shape[0]))
    for i in range(s.shape[0]):
        _taylor_into(ptr, col, val, starts[chunks[i]], terms, 0.0)
        _poly_into(terms, TAYLOR_TERMS, s[i] - chunks[i] * step, out[i])
    return out


@njit(cache=True, nogil=True)
def friction_velocity(z, fmass):
    """Velocity of the friction mass: v1 (fmass 0) or v2 = v1 + u (fmass 1)."""
    return z[V1] if fmass == 0 else z[V1] + z[U]


@njit(cache=True, nogil=True)
def choose_mode(mats, rows, nrows, valid, ipar, fpar, z, ref):
    """The first admissible mode slot at z (stuck preferred over free, grounded over slipping), or -1.

    Contact is a candidate when the gap sits on the reference wall with no relative velocity; a friction mass
    at rest may stay on the ground or slip either way.
    """
    n, n_slots = z.shape[0], mats.shape[0]
    ptr = np.empty((n_slots, n + 1), dtype=np.int64)
    col = np.empty((n_slots, n * n), dtype=np.int64)
    val = np.empty((n_slots, n * n))
    mag = np.empty((n_slots, n * n))
    for slot in range(n_slots):
        _sparse_into(mats[slot], ptr[slot], col[slot], val[slot], mag[slot])
    return _choose_mode_into(ptr, col, val, mag, rows, nrows, valid, ipar, fpar, z, ref,
                             np.empty((4, n)), np.empty((4, n)))


@njit(cache=True, nogil=True)
def _choose_mode_into(ptr, col, val, mag, rows, nrows, valid, ipar, fpar, z, ref, derivs, sizes):
    """:func:`choose_mode` with the slots' matrices given by their nonzero entries (per slot, leading axis)."""
    h = fpar[P_H]
    n_contacts = 1
    contact0, contact1 = FREE, FREE
    if abs(z[U]) <= fpar[P_VSTICK] and abs(z[D]) <= 1e-12 * h:
        contact0 = STUCK_A if ref == 0 else STUCK_B
        n_contacts = 2
    n_grounds = 1
    ground0 = 0
    if ipar[I_FRICTION]:
        v = friction_velocity(z, ipar[I_FMASS])
        if v == 0.0:
            n_grounds = 3
        else:
            ground0 = 1 if v > 0.0 else 2
    for ci in range(n_contacts):
        contact = contact0 if ci == 0 else contact1
        for gi in range(n_grounds):
            slot = 3 * contact + (ground0 if gi == 0 else gi)
            if valid[slot] and _admissible_into(ptr[slot], col[slot], val[slot], mag[slot],
                                                rows[slot, ref, :nrows[slot]], z, derivs, sizes):
                return slot
    return -1


@njit(cache=True)
def ground_code(slot):
    """Ground mode of a slot as recorded: 0 (grounded or no friction), +1 or -1 (slipping)."""
    g = slot % 3
    return 0 if g == 0 else (1 if g == 1 else -1)


@njit(cache=True, nogil=True)
def _impact(z, side, eps, mu2, v_stick):
    """Impact law (8a/8b) on wall ``side`` (d -> 0): v1 += (1 + eps) M2/M u, u -> -eps u; below v_stick the
    converged chatter settles plastically (momentum kept, u = 0). A pair found on the wall while already moving
    away from it (a micro-flight whose apex lies below the rounding of the gap) settles plastically too."""
    z[D] = 0.0
    u = z[U]
    if (side == 0 and u > 0.0) or (side == 1 and u < 0.0):
        z[V1] = z[V1] + mu2 * u
        z[U] = 0.0
        return
    z[V1] = z[V1] + (1.0 + eps) * mu2 * u
    z[U] = -eps * u
    if abs(z[U]) <= v_stick:
        z[V1] = z[V1] + mu2 * z[U]
        z[U] = 0.0


@njit(cache=True, nogil=True)
def run_engine(mats, exps, rows, rows_a, rows_aa, kinds, nrows, valid, fpar, ipar, z, fst, ist,
               rec_t, rec_z, rec_slot, rec_ref, rec_cause, rec_vel):
    """Run the event loop from the state (z, fst, ist) until done, the buffers are full or the event bound.

    Parameters
    ----------
    mats, exps : (N_SLOTS, n, n)
        Mode matrices A and step exponentials exp(A dt) (dt = ``fpar[P_DT]``).
    rows : (N_SLOTS, 2, n_rows_max, n); kinds : (N_SLOTS, n_rows_max); nrows, valid : (N_SLOTS,)
        Constraint rows per slot and reference wall, their kinds (HIT_A, ...), counts, and which slots exist;
        ``rows_a``, ``rows_aa``: the rows times the slot's A and A^2 (their rates and curvatures).
    fpar, ipar : parameter arrays (P_*, I_* slots).
    z : (n,) state, updated in place; fst, ist : run state (S_*, J_* slots), updated in place.
    rec_* : record buffers (segment start time, state, slot, reference wall, cause, [v1, v2 pre, v1, v2 post]).
        Segments starting at or before ``fst[S_RECORD_FROM]`` overwrite record 0 (bounded memory).

    Returns
    -------
    int
        DONE, BUFFER_FULL, EVENT_LIMIT or NO_MODE.
    """
    m1, m2, eps = fpar[P_M1], fpar[P_M2], fpar[P_EPS]
    M = m1 + m2
    v_stick = fpar[P_VSTICK]
    dt = fpar[P_DT]
    fmass = ipar[I_FMASS]
    t, t_end, record_from = fst[S_T], fst[S_TEND], fst[S_RECORD_FROM]
    slot, ref, n_rec = ist[J_SLOT], ist[J_REF], ist[J_RECORDS]
    capacity = rec_t.shape[0]
    # work arrays and the slots' sparse matrices, once per call (the loop allocates nothing)
    n, n_slots = z.shape[0], mats.shape[0]
    a_ptr = np.empty((n_slots, n + 1), dtype=np.int64)
    a_col = np.empty((n_slots, n * n), dtype=np.int64)
    a_val = np.empty((n_slots, n * n))
    a_mag = np.empty((n_slots, n * n))
    for k in range(n_slots):
        _sparse_into(mats[k], a_ptr[k], a_col[k], a_val[k], a_mag[k])
    z_next = np.empty(n)
    abs_z = np.empty(n)
    work = np.empty((6, rows.shape[2]))
    terms = np.empty((TAYLOR_TERMS, n))
    c = np.empty(TAYLOR_TERMS)
    derivs = np.empty((4, n))
    sizes = np.empty((4, n))
    leaving = np.empty(rows.shape[2], dtype=np.bool_)
    _rows_on_zero_into(rows[slot, ref, :nrows[slot]], z, abs_z, leaving)
    status = DONE
    while t < t_end:
        if n_rec >= capacity:
            status = BUFFER_FULL
            break
        nr = nrows[slot]
        t, j = _scan_into(a_ptr[slot], a_col[slot], a_val[slot], exps[slot], dt,
                          rows[slot, ref, :nr], rows_a[slot, ref, :nr], rows_aa[slot, ref, :nr], leaving, z, t,
                          t_end, fpar[P_LIMIT], z_next, work, terms, c)
        if j == BEYOND_LIMIT:
            status = DIVERGED
            break
        if j < 0:
            break
        ist[J_EVENTS] += 1
        if ist[J_EVENTS] > ist[J_MAX_EVENTS]:
            status = EVENT_LIMIT
            break
        kind = kinds[slot, j]
        contact = slot // 3
        v1_pre, v2_pre = z[V1], z[V1] + z[U]
        if kind == HIT_A or kind == HIT_B:
            ref = 0 if kind == HIT_A else 1
            _impact(z, ref, eps, m2 / M, v_stick)
            cause = IMPACT_A if kind == HIT_A else IMPACT_B
        elif kind == SEPARATE:
            cause = SEPARATION
        elif kind == STOP:
            cause = GROUND_EVENT
            if contact != FREE:
                z[V1] = 0.0
                z[U] = 0.0
            elif fmass == 0:
                z[U] = z[U] + z[V1]   # M1 stops, v2 kept
                z[V1] = 0.0
            else:
                z[U] = -z[V1]         # M2 stops
        else:
            cause = GROUND_EVENT
        if ipar[I_FRICTION] and slot % 3 == 0 and kind != HIT_A and kind != HIT_B:
            # the friction mass was grounded: its speed is 0 exactly (not the rounding of v1 + u)
            if fmass == 0:
                z[U] = z[U] + z[V1]
                z[V1] = 0.0
            else:
                z[U] = -z[V1]
        slot = _choose_mode_into(a_ptr, a_col, a_val, a_mag, rows, nrows, valid, ipar, fpar, z, ref, derivs, sizes)
        if slot < 0:
            # two events at one instant: the event left the pair on a wall moving into it (e.g. a friction stop
            # as the gap closes): the impact happens now
            gap = z[D] + ref * fpar[P_H]
            side = -1
            if abs(gap) <= 1e-12 * fpar[P_H] and z[U] < 0.0:
                side = 0
            elif abs(gap - fpar[P_H]) <= 1e-12 * fpar[P_H] and z[U] > 0.0:
                side = 1
            if side >= 0:
                v1_pre, v2_pre = z[V1], z[V1] + z[U]
                ref = side
                _impact(z, side, eps, m2 / M, v_stick)
                cause = IMPACT_A if side == 0 else IMPACT_B
                slot = _choose_mode_into(a_ptr, a_col, a_val, a_mag, rows, nrows, valid, ipar, fpar, z, ref,
                                         derivs, sizes)
        if slot < 0:
            status = NO_MODE
            break
        if slot // 3 != FREE and (z[U] != 0.0 or z[D] != 0.0):
            # stuck chosen with a relative speed below v_stick left by a non-impact event: settle exactly
            z[D] = 0.0
            if ipar[I_FRICTION] and slot % 3 == 0:
                z[V1] = 0.0           # the pair rests on the ground
            else:
                z[V1] = z[V1] + m2 * z[U] / M
            z[U] = 0.0
        _rows_on_zero_into(rows[slot, ref, :nrows[slot]], z, abs_z, leaving)
        k = 0 if t <= record_from else n_rec
        rec_t[k] = t
        rec_z[k] = z
        rec_slot[k] = slot
        rec_ref[k] = ref
        rec_cause[k] = cause
        rec_vel[k, 0], rec_vel[k, 1] = v1_pre, v2_pre
        rec_vel[k, 2], rec_vel[k, 3] = z[V1], z[V1] + z[U]
        n_rec = k + 1
    fst[S_T] = t
    ist[J_SLOT], ist[J_REF], ist[J_RECORDS] = slot, ref, n_rec
    return status


@njit(cache=True, nogil=True)
def expm_taylor(M):
    """exp(M) by scaling and squaring of an 18-term Taylor series (||M/2^s||_1 <= 1/4: truncation < 1e-25).

    For the small mode matrices of the engine (real, or complex for the Van Loan blocks of the Fourier
    integrals); explicit loops, so it costs microseconds and gives the same numbers with or without the JIT.
    """
    n = M.shape[0]
    norm = 0.0
    for j in range(n):
        col = 0.0
        for i in range(n):
            col += abs(M[i, j])
        norm = max(norm, col)
    squarings = 0
    while norm > 0.25 and squarings < 1000:
        norm *= 0.5
        squarings += 1
    scale = 0.5 ** squarings
    X = M * scale
    out = np.zeros_like(M)
    term = np.zeros_like(M)
    prod = np.empty_like(M)
    for i in range(n):
        out[i, i] = 1.0
        term[i, i] = 1.0
    for k in range(1, 18):
        _matmul_into(term, X, prod)
        for i in range(n):
            for j in range(n):
                term[i, j] = prod[i, j] / k
                out[i, j] = out[i, j] + term[i, j]
    for _ in range(squarings):
        _matmul_into(out, out, prod)
        out[:] = prod
    return out


@njit(cache=True, nogil=True)
def _matmul_into(P, Q, out):
    """out = P Q with explicit loops (out distinct from P and Q)."""
    out[:] = 0.0
    for i in range(P.shape[0]):
        for k in range(P.shape[1]):
            a = P[i, k]
            if a != 0.0:
                for j in range(Q.shape[1]):
                    out[i, j] += a * Q[k, j]


@njit(cache=True, nogil=True)
def van_loan_pieces(exp_step, g, A, z0, lengths, dt, w, component):
    """Integral over [0, L] of component ``component`` of e^{-j w s} exp(A s) z0, per piece (rows of z0, L).

    Whole steps first: over step i the integral is e^{-j w i dt} g.z_i with z_{i+1} = exp(A dt) z_i (real) and
    g the row ``component`` of the Van Loan block int_0^dt e^{(A - j w) s} ds; over the remainder r (< dt) the
    Taylor series sum_k [(A - j w)^k z]_component r^(k+1) / (k+1)!.
    """
    m, n = z0.shape
    out = np.empty(m, dtype=np.complex128)
    z = np.empty(n)
    tmp = np.empty(n)
    v = np.empty(n, dtype=np.complex128)
    vtmp = np.empty(n, dtype=np.complex128)
    for p in range(m):
        z[:] = z0[p]
        chunks = int(np.floor(lengths[p] / dt))
        total = 0j
        for i in range(chunks):
            acc = 0j
            for k in range(n):
                acc += g[k] * z[k]
            total += np.exp(-1j * w * dt * i) * acc
            for a in range(n):
                r = 0.0
                for k in range(n):
                    r += exp_step[a, k] * z[k]
                tmp[a] = r
            z[:] = tmp
        rest = lengths[p] - chunks * dt
        phase = np.exp(-1j * w * dt * chunks)
        for i in range(n):
            v[i] = phase * z[i] * rest
        total += v[component]
        for k in range(1, TAYLOR_TERMS):
            for i in range(n):
                acc = -1j * w * v[i]
                for j in range(n):
                    acc += A[i, j] * v[j]
                vtmp[i] = acc * (rest / (k + 1))
            v[:] = vtmp
            total += v[component]
        out[p] = total
    return out
