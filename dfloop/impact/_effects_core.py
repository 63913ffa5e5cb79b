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

Plain float arrays only, so everything also runs (slowly) with NUMBA_DISABLE_JIT=1. Products are taken with
``np.dot`` (the BLAS gemv/dot calls NumPy makes), so results do not depend on the JIT: this matters in chaotic
regimes, where rounding-level differences in the event times grow over the transient.
"""
from __future__ import annotations

import numpy as np
from numba import njit

TAYLOR_TERMS = 30
NO_ROOT = -1.0       # first_violation: no violation inside the step
REFINE_ITERATIONS = 200

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
DONE, BUFFER_FULL, EVENT_LIMIT, NO_MODE = 0, 1, 2, 3
# float parameters: m1, m2, eps, h, v_stick, dt, friction force; int parameters: has friction, friction mass
P_M1, P_M2, P_EPS, P_H, P_VSTICK, P_DT = range(6)
I_FRICTION, I_FMASS = range(2)
# float run state: t, t_end, record_from; int run state: slot, ref, events, max_events, records
S_T, S_TEND, S_RECORD_FROM = range(3)
J_SLOT, J_REF, J_EVENTS, J_MAX_EVENTS, J_RECORDS = range(5)


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
    """Advance z (in place) by steps exp(A dt) = E from time t until the first event or ``t_end``.

    The last step, shorter than ``dt``, is taken on the Taylor series. ``leaving[j]``: row j starts on 0 and
    moves away (applies to the first step only).

    Returns
    -------
    t : float
        Time reached (s): the event time, or ``t_end``.
    hit : int
        Index of the violated row, or -1 when no event occurred.
    """
    n_rows = rows.shape[0]
    first = True
    db = np.dot(rows, np.dot(A, z))
    while t < t_end:
        step = dt if t_end - t >= dt else t_end - t
        have_terms = False
        terms = np.empty((0, 0))
        if step == dt:
            z_next = np.dot(E, z)
        else:
            terms = taylor(A, z)
            have_terms = True
            z_next = poly(terms, step)
        fb = np.dot(rows, z_next)
        da = db                       # r.A z at the step start = r.A z_next of the previous step
        db = np.dot(rows, np.dot(A, z_next))
        best_s = NO_ROOT
        hit = -1
        for j in range(n_rows):
            r = rows[j]
            lv = first and leaving[j]
            if fb[j] < 0.0 or da[j] * db[j] < 0.0 or lv:
                if not have_terms:
                    terms = taylor(A, z)
                    have_terms = True
                s = first_violation(terms, A, r, lv, step)
                if s != NO_ROOT and (hit < 0 or s < best_s):
                    best_s, hit = s, j
        first = False
        if hit >= 0:
            z[:] = poly(terms, best_s)
            return t + best_s, hit
        z[:] = z_next
        t = t + step if step == dt else t_end
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


@njit(cache=True)
def friction_velocity(z, fmass):
    """Velocity of the friction mass: v1 (fmass 0) or v2 = v1 + u (fmass 1)."""
    return z[V1] if fmass == 0 else z[V1] + z[U]


@njit(cache=True)
def choose_mode(mats, rows, nrows, valid, ipar, fpar, z, ref):
    """The first admissible mode slot at z (stuck preferred over free, grounded over slipping), or -1.

    Contact is a candidate when the gap sits on the reference wall with no relative velocity; a friction mass
    at rest may stay on the ground or slip either way.
    """
    h = fpar[P_H]
    n_contacts = 1
    contacts = np.zeros(2, dtype=np.int64)
    if abs(z[U]) <= fpar[P_VSTICK] and abs(z[D]) <= 1e-12 * h:
        contacts[0] = STUCK_A if ref == 0 else STUCK_B
        contacts[1] = FREE
        n_contacts = 2
    grounds = np.zeros(3, dtype=np.int64)
    n_grounds = 1
    if ipar[I_FRICTION]:
        v = friction_velocity(z, ipar[I_FMASS])
        if v == 0.0:
            grounds[1], grounds[2] = 1, 2
            n_grounds = 3
        else:
            grounds[0] = 1 if v > 0.0 else 2
    for ci in range(n_contacts):
        for gi in range(n_grounds):
            slot = 3 * contacts[ci] + grounds[gi]
            if valid[slot] and admissible(mats[slot], rows[slot, ref, :nrows[slot]], z):
                return slot
    return -1


@njit(cache=True)
def ground_code(slot):
    """Ground mode of a slot as recorded: 0 (grounded or no friction), +1 or -1 (slipping)."""
    g = slot % 3
    return 0 if g == 0 else (1 if g == 1 else -1)


@njit(cache=True, nogil=True)
def run_engine(mats, exps, rows, kinds, nrows, valid, fpar, ipar, z, fst, ist,
               rec_t, rec_z, rec_slot, rec_ref, rec_cause, rec_vel):
    """Run the event loop from the state (z, fst, ist) until done, the buffers are full or the event bound.

    Parameters
    ----------
    mats, exps : (N_SLOTS, n, n)
        Mode matrices A and step exponentials exp(A dt) (dt = ``fpar[P_DT]``).
    rows : (N_SLOTS, 2, n_rows_max, n); kinds : (N_SLOTS, n_rows_max); nrows, valid : (N_SLOTS,)
        Constraint rows per slot and reference wall, their kinds (HIT_A, ...), counts, and which slots exist.
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
    leaving = rows_on_zero(rows[slot, ref, :nrows[slot]], z)
    status = DONE
    while t < t_end:
        if n_rec >= capacity:
            status = BUFFER_FULL
            break
        t, j = scan_steps(mats[slot], exps[slot], dt, rows[slot, ref, :nrows[slot]], leaving, z, t, t_end)
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
            z[D] = 0.0
            u = z[U]
            z[V1] = z[V1] + (1.0 + eps) * m2 * u / M
            z[U] = -eps * u
            if abs(z[U]) <= v_stick:  # converged chatter: plastic settle (momentum kept)
                z[V1] = z[V1] + m2 * z[U] / M
                z[U] = 0.0
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
        slot = choose_mode(mats, rows, nrows, valid, ipar, fpar, z, ref)
        if slot < 0:
            status = NO_MODE
            break
        leaving = rows_on_zero(rows[slot, ref, :nrows[slot]], z)
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
