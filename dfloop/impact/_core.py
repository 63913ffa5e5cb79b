"""The event-driven loop of the paper's model (clearance + restitution impacts + sticking), JIT-compiled.

Units are SI throughout; the state is (t, phase, x1, v1, g, u) with g = x2 - x1 the gap and u = v2 - v1 the
relative velocity, so that the gap near a wall is carried with full relative precision. Runs identically as
plain Python under NUMBA_DISABLE_JIT=1.
"""
from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit

from ._flight import TWO_PI, dshape, shape, wrap_phase

# segment modes
FREE, STUCK_A, STUCK_B = 0, 1, 2
# causes of a segment start
START, IMPACT_A, IMPACT_B, SEPARATION = 0, 1, 2, 3
# columns of the float segment table
T0, PHI0, X1, V1, GAP, U, V1_PRE, U_PRE, V1_POST, U_POST = range(10)
N_FLOAT_COLUMNS = 10
# kernel status
DONE, BUFFER_FULL = 0, 1

# Bisection at least halves the bracket every step; reaching a relative width of 4e-16 from any bracket whose
# root exceeds 1e-20 of its length takes < 130 halvings, so the bound is never the limiting factor.
_MAX_ROOT_ITERATIONS = 200
_ZERO = np.int64(0)  # a typed zero for calls inside compiled code (a literal 0 adds a Literal[int] signature)


@njit(cache=True, nogil=True)
def _gap(g0, u, c0, s0, B, w, s):
    return g0 + u * s + B * shape(c0, s0, w * s)


@njit(cache=True, nogil=True)
def _gap_rate(u, c0, s0, B, w, s):
    return u + B * w * dshape(c0, s0, w * s)


@njit(cache=True, nogil=True)
def _refine(g0, u, c0, s0, B, w, wall, lo, hi):
    """Root of gap(s) = wall in [lo, hi] where the gap is monotone and changes side (Newton + bisection)."""
    f_lo = _gap(g0, u, c0, s0, B, w, lo) - wall
    if f_lo == 0.0:
        return lo
    s = 0.5 * (lo + hi)
    for _ in range(_MAX_ROOT_ITERATIONS):
        f = _gap(g0, u, c0, s0, B, w, s) - wall
        if f == 0.0:
            return s
        if (f > 0.0) == (f_lo > 0.0):
            lo = s
        else:
            hi = s
        if hi - lo <= 4e-16 * hi:
            return hi
        d = _gap_rate(u, c0, s0, B, w, s)
        s_new = s - f / d if d != 0.0 else lo - 1.0
        if not (lo < s_new < hi):
            s_new = 0.5 * (lo + hi)
        s = s_new
    return hi


@njit(cache=True, nogil=True)
def _crossing(g0, u, c0, s0, B, w, h, a, b, gb, skip_wall):
    """Wall hit in the monotone piece [a, b] (gap gb at b): (s, wall) or (-1, -1)."""
    if gb < 0.0 and skip_wall != 0:
        return _refine(g0, u, c0, s0, B, w, 0.0, a, b), 0
    if gb > h and skip_wall != 1:
        return _refine(g0, u, c0, s0, B, w, h, a, b), 1
    return -1.0, -1


@njit(cache=True, nogil=True)
def next_impact(g0, u, phi0, B, w, h, smax, start_wall):
    """First s in (0, smax] where a free flight hits a wall, from the gap's closed-form turning points.

    The relative acceleration is (F/M2) cos(phi0 + w s), so g'(s) = 0 where sin(phi0 + w s) = q with
    q = sin(phi0) - u / (B w): between consecutive such instants the gap is monotone. The first piece leaves
    ``start_wall`` (0: side A, 1: side B, -1: none) and is not tested against it.
    Returns (s, wall) with wall 0 / 1, or (smax, -1) when no wall is reached by smax.
    """
    c0 = math.cos(phi0)
    s0 = math.sin(phi0)
    q = s0 - u / (B * w)
    skip = start_wall
    a = 0.0
    if abs(q) >= 1.0:
        # monotone for ever: the linear part (u - B w s0) s outruns the bounded part (|.| <= 3 B)
        slope = abs(u - B * w * s0)
        b = min((h + 6.0 * B) / slope, smax)
        gb = _gap(g0, u, c0, s0, B, w, b)
        s, wall = _crossing(g0, u, c0, s0, B, w, h, a, b, gb, skip)
        if wall >= 0:
            return s, wall
        return smax, -1
    alpha = math.asin(q)
    th1 = wrap_phase(alpha - phi0)
    th2 = wrap_phase(math.pi - alpha - phi0)
    lo_th = min(th1, th2)
    hi_th = max(th1, th2)
    k = 0
    while True:  # bounded: each pass advances b by >= pi / w until smax
        for th in (lo_th, hi_th):
            b = (th + TWO_PI * k) / w
            if b <= a:
                continue
            last = b >= smax
            if last:
                b = smax
            gb = _gap(g0, u, c0, s0, B, w, b)
            s, wall = _crossing(g0, u, c0, s0, B, w, h, a, b, gb, skip)
            if wall >= 0:
                return s, wall
            if last:
                return smax, -1
            a = b
            skip = -1
        k += 1


@njit(cache=True, nogil=True)
def run_kernel(params, state, t_end, seg, seg_mode, seg_cause, n0):
    """Advance the motion from ``state`` until ``t_end`` or until the segment buffers are full.

    params = (m1, m2, h, F, w, eps, v_stick); state = [t, phase, x1, v1, g, u, mode, start_wall] (updated
    in place). Segment rows are written from index n0. Returns (number of rows written in total, status).
    """
    m1, m2, h, F, w, eps, v_stick = params[0], params[1], params[2], params[3], params[4], params[5], params[6]
    M = m1 + m2
    B = F / (m2 * w * w)  # relative (gap) forcing length
    Bc = F / (M * w * w)  # common-body forcing length
    t, phi, x1, v1, g, u = state[0], state[1], state[2], state[3], state[4], state[5]
    mode = int(state[6])
    start_wall = int(state[7])
    n = n0
    cap = seg.shape[0]
    status = DONE
    while True:
        if n >= cap:
            status = BUFFER_FULL
            break
        smax = t_end - t
        if smax <= 0.0:
            break
        if mode == FREE:
            s, wall = next_impact(g, u, phi, B, w, h, smax, start_wall)
            if wall < 0:
                break
            c0 = math.cos(phi)
            s0 = math.sin(phi)
            u_pre = _gap_rate(u, c0, s0, B, w, s)
            x1 = x1 + v1 * s
            t = t + s
            phi = wrap_phase(phi + w * s)
            g = 0.0 if wall == 0 else h
            v1_pre = v1
            v1_post = v1 + (1.0 + eps) * m2 * u_pre / M
            u_post = -eps * u_pre
            v1 = v1_post
            u = u_post
            cause = IMPACT_A if wall == 0 else IMPACT_B
            start_wall = wall
            if abs(u) <= v_stick:
                cphi = math.cos(phi)
                pushes = cphi < 0.0 or (cphi == 0.0 and math.sin(phi) > 0.0)
                if wall == 1:
                    pushes = cphi > 0.0 or (cphi == 0.0 and math.sin(phi) < 0.0)
                if pushes:  # chattering has converged: a plastic settle (momentum kept), then stuck
                    v1 = v1 + m2 * u / M
                    u = 0.0
                    mode = STUCK_A if wall == 0 else STUCK_B
        else:
            # stuck: contact force on M1 is -M1 F cos(phase)/M (side A) and must stay compressive;
            # separation where cos(phase) changes sign: phase 3 pi/2 (side A) or pi/2 (side B)
            target = 1.5 * math.pi if mode == STUCK_A else 0.5 * math.pi
            s = wrap_phase(target - phi) / w
            if s >= smax:
                break
            c0 = math.cos(phi)
            s0 = math.sin(phi)
            x1 = x1 + v1 * s + Bc * shape(c0, s0, w * s)
            v1 = v1 + Bc * w * dshape(c0, s0, w * s)
            t = t + s
            phi = target
            u = 0.0
            u_pre = 0.0
            v1_pre = v1
            v1_post = v1
            u_post = 0.0
            start_wall = 0 if mode == STUCK_A else 1
            mode = FREE
            cause = SEPARATION
        seg[n, T0] = t
        seg[n, PHI0] = phi
        seg[n, X1] = x1
        seg[n, V1] = v1
        seg[n, GAP] = g
        seg[n, U] = u
        seg[n, V1_PRE] = v1_pre
        seg[n, U_PRE] = u_pre
        seg[n, V1_POST] = v1_post
        seg[n, U_POST] = u_post
        seg_mode[n] = mode
        seg_cause[n] = cause
        n += 1
    state[0] = t
    state[1] = phi
    state[2] = x1
    state[3] = v1
    state[4] = g
    state[5] = u
    state[6] = mode
    state[7] = start_wall
    return n, status


def empty_buffers(capacity: int):
    """Segment buffers (float table, mode, cause) for ``run_kernel``."""
    return (np.empty((capacity, N_FLOAT_COLUMNS)), np.empty(capacity, np.int8), np.empty(capacity, np.int8))


# ---------------------------------------------------------------------------------------------------------
# Period-by-period driver: the kernel run one forcing period at a time, with everything the describing
# function and the period detection need accumulated on the fly (no trajectory is stored).

# driver status
CONVERGED, IRREGULAR, SETTLED, EVENT_LIMIT, SIDES_FULL, NOT_CONVERGED = 0, 1, 2, 3, 4, 5
# columns of the per-boundary stroboscopic record: x1, gap / h, u / v_scale, mode
SX1, SGAP, SU, SMODE = range(4)
# control vector of run_periods (floats)
C_TOL, C_FLOOR, C_VSCALE, C_WINDOW, C_KMAX, C_CHAOS, C_MAXEV, C_MATCH_TOL = range(8)
# ... and its in/out part, kept between calls: first boundary usable by the detection, restarts, matches
C_KFIRST, C_RESTARTS, C_MATCHES, C_FAILS = range(8, 12)
C_CHECKED = 12               # out: the periods over which a converged period was verified
C_DIST = 13                  # in/out: distance to the known attractor when the current run of matches began
N_CONTROL = 14
MAX_PERIOD = 12               # longest period looked for (forcing periods)
_SETTLE_CHECKS = 3            # consecutive boundaries within tolerance of a known orbit (the last closer)
_MAX_CONTRACTION = 0.9995     # clear contraction: slope of log mismatch below log of this per period
_EXTRAPOLATE_BELOW = 1e-2     # ... with the mismatch already below this
_MAX_JUMP = 1e-2              # largest extrapolation step (normalised state) the driver takes
_MAX_RESTARTS = 16            # extrapolated restarts per run
_SLOW = 0.5                   # contraction per period slower than this is worth extrapolating


@njit(cache=True, nogil=True)
def fourier_piece(p0, p1, q, phi0, w, sa, sb):
    """Integral over local time s in [sa, sb] of (p0 + p1 s + q cos(phi0 + w s)) e^{-j(phi0 + w s)}."""
    ea = cmath.exp(-1j * w * sa) if sa != 0.0 else 1.0 + 0j
    eb = cmath.exp(-1j * w * sb)
    # antiderivatives (without the common factor e^{-j phi0}) of e^{-j w s} and s e^{-j w s}
    a0 = (ea - eb) / (1j * w)
    a1 = 1j * (sb * eb - sa * ea) / w - (ea - eb) / (w * w)
    total = p0 * a0 + p1 * a1
    if q != 0.0:
        # cos(phi0 + w s) e^{-j w s} = (e^{j phi0} + e^{-j phi0} e^{-2j w s}) / 2
        e0 = cmath.exp(1j * phi0)
        total += q * (e0 * 0.5 * (sb - sa) + (ea * ea - eb * eb) / (4j * w * e0))
    return cmath.exp(-1j * phi0) * total


@njit(cache=True, nogil=True)
def fourier_pieces(p0, p1, q, phi0, w, sa, sb):
    """:func:`fourier_piece` over arrays of pieces."""
    out = np.empty(p0.size, dtype=np.complex128)
    for i in range(p0.size):
        out[i] = fourier_piece(p0[i], p1[i], q[i], phi0[i], w, sa[i], sb[i])
    return out


@njit(cache=True, nogil=True)
def _segment_piece(params, t0, phi0, x1, v1, mode, ta, tb):
    """Fourier integral of x1 over [ta, tb] inside the segment that starts at t0 (state x1, v1, mode)."""
    m1, m2, F, w = params[0], params[1], params[3], params[4]
    q = -F / ((m1 + m2) * w * w) if mode != FREE else 0.0
    p0 = x1 - q * math.cos(phi0)
    p1 = v1 + q * w * math.sin(phi0)
    return fourier_piece(p0, p1, q, phi0, w, ta - t0, tb - t0)


@njit(cache=True, nogil=True)
def _mismatch(strobe, i, j):
    """Max-norm distance of the stroboscopic states at boundaries i and j (a change of mode counts 1)."""
    if strobe[i, SMODE] != strobe[j, SMODE]:
        return 1.0
    return max(abs(strobe[i, SGAP] - strobe[j, SGAP]), abs(strobe[i, SU] - strobe[j, SU]))


@njit(cache=True, nogil=True)
def _window_of(period, window):
    """Periods checked for a candidate period: whole cycles, at least ``window`` periods and two cycles."""
    n = max(window, 2 * period)
    return period * ((n + period - 1) // period)


@njit(cache=True, nogil=True)
def _max_mismatch(strobe, lo, hi, p):
    """Largest mismatch |S_j - S_{j-p}| over boundaries lo <= j < hi."""
    out = 0.0
    for j in range(lo, hi):
        out = max(out, _mismatch(strobe, j, j - p))
    return out


@njit(cache=True, nogil=True)
def assess_period(strobe, k, k_first, tol, floor, window):
    """(period, periods checked, best) at boundary k: the smallest converged period (0 if none), the window of
    whole cycles over which it was verified, and the candidate whose recent mismatch is smallest (for the
    contraction test). Only boundaries from ``k_first`` on are used.

    A candidate p is converged when either

    - the mismatches m_j = |S_j - S_{j-p}| are at rounding level (below ``floor``) over the last
      ``_exact_window(p)`` boundaries (at least 3 checks and two cycles): the motion repeats exactly; or
    - over the last W(p) boundaries (``_window_of``: whole cycles, at least ``window`` periods) they are all
      below ``tol`` and so is the distance to the periodic orbit they imply: with the contraction rate r per
      period fitted from the maxima a, b of the two halves, that distance is about b r / (1 - r) (a slowly
      converging motion has a small mismatch per period but is still far from its orbit).
    """
    best, best_b = 0, math.inf
    for p in range(1, MAX_PERIOD + 1):
        ne = _exact_window(p)
        if k - ne - p < k_first:
            break
        if _mismatch(strobe, k, k - p) >= _EXTRAPOLATE_BELOW:
            continue            # far from periodic with this p: neither converged nor a candidate
        if _max_mismatch(strobe, k - ne + 1, k + 1, p) <= floor:
            return p, ne, p
        n = _window_of(p, window)
        if k - n - p < k_first:
            continue
        half = n // 2
        a = _max_mismatch(strobe, k - n + 1, k - half + 1, p)
        b = _max_mismatch(strobe, k - half + 1, k + 1, p)
        if max(a, b) < tol and 0.0 < b < a:
            rate = (b / a) ** (1.0 / half)
            if b * rate / (1.0 - rate) < tol:
                return p, n, p
        if b < best_b:
            best, best_b = p, b
    return 0, 0, best


@njit(cache=True, nogil=True)
def _exact_window(period):
    """Periods checked for a motion that repeats at rounding level: two cycles, at least three periods."""
    return period * ((max(3, 2 * period) + period - 1) // period)


@njit(cache=True, nogil=True)
def contracting(strobe, k, k_first, p, window):
    """Contraction rate per period of candidate p if its mismatch contracts clearly over its last W(p)
    boundaries (a least-squares line through log m_j with slope below log 0.9995 per period, residuals
    below 0.5, m_k < 1e-2); 1.0 if it does not; -1.0 if there are not enough boundaries since k_first."""
    if p <= 0:     # no candidate near periodic: not contracting, once there are boundaries enough to say so
        return -1.0 if k - _window_of(1, window) - 1 < k_first else 1.0
    n = _window_of(p, window)
    if k - n - p < k_first:
        return -1.0
    if _mismatch(strobe, k, k - p) >= _EXTRAPOLATE_BELOW:
        return 1.0
    ys = np.empty(n)
    sj = 0.0
    sy = 0.0
    sjj = 0.0
    sjy = 0.0
    for i in range(n):
        m = _mismatch(strobe, k - n + 1 + i, k - n + 1 + i - p)
        if m <= 0.0:
            return 1.0
        y = math.log(m)
        ys[i] = y
        sj += i
        sy += y
        sjj += i * i
        sjy += i * y
    slope = (n * sjy - sj * sy) / (n * sjj - sj * sj)
    icept = (sy - slope * sj) / n
    res = 0.0
    for i in range(n):
        res += (ys[i] - slope * i - icept) ** 2
    if slope < math.log(_MAX_CONTRACTION) and math.sqrt(res / n) <= 0.5:
        return math.exp(slope)
    return 1.0


@njit(cache=True, nogil=True)
def extrapolate(strobe, k, p):
    """Fixed point of the p-period stroboscopic map extrapolated from the boundaries k - 3p, ..., k.

    With the differences d_i of consecutive states (gap, u) p periods apart, a linear map A with
    d_{i+1} = A d_i is fitted on the last three (2 x 2, spiral convergence included; along the dominant
    direction, r = d2.d1 / d1.d1, when the two are nearly parallel), and the limit is
    S_k + (I - A)^-1 A d. Returns (ok, gap, u); ok is False when the four states are not all free flight
    or the fit is degenerate.
    """
    if k - 3 * p < 0:
        return False, 0.0, 0.0
    for i in range(4):
        if strobe[k - i * p, SMODE] != FREE:
            return False, 0.0, 0.0
    d = np.empty((3, 2))
    for i in range(3):
        j = k - (2 - i) * p
        d[i, 0] = strobe[j, SGAP] - strobe[j - p, SGAP]
        d[i, 1] = strobe[j, SU] - strobe[j - p, SU]
    det = d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0]
    n0 = math.hypot(d[0, 0], d[0, 1])
    n1 = math.hypot(d[1, 0], d[1, 1])
    if n0 == 0.0 or n1 == 0.0:
        return False, 0.0, 0.0
    if abs(det) > 1e-3 * n0 * n1:
        # A [d0 d1] = [d1 d2]
        i00, i01, i10, i11 = d[1, 1] / det, -d[1, 0] / det, -d[0, 1] / det, d[0, 0] / det
        a00 = d[1, 0] * i00 + d[2, 0] * i10
        a01 = d[1, 0] * i01 + d[2, 0] * i11
        a10 = d[1, 1] * i00 + d[2, 1] * i10
        a11 = d[1, 1] * i01 + d[2, 1] * i11
    else:
        r = (d[2, 0] * d[1, 0] + d[2, 1] * d[1, 1]) / (n1 * n1)
        a00, a01, a10, a11 = r, 0.0, 0.0, r
    # step = (I - A)^-1 A d2
    ad0 = a00 * d[2, 0] + a01 * d[2, 1]
    ad1 = a10 * d[2, 0] + a11 * d[2, 1]
    m00, m01, m10, m11 = 1.0 - a00, -a01, -a10, 1.0 - a11
    dm = m00 * m11 - m01 * m10
    if dm == 0.0:
        return False, 0.0, 0.0
    step0 = (m11 * ad0 - m01 * ad1) / dm
    step1 = (-m10 * ad0 + m00 * ad1) / dm
    if not (abs(step0) <= _MAX_JUMP and abs(step1) <= _MAX_JUMP):
        return False, 0.0, 0.0
    return True, strobe[k, SGAP] + step0, strobe[k, SU] + step1


@njit(cache=True, nogil=True)
def _orbit_distance(strobe, k, orbit):
    """Max-norm distance of boundary k to the nearest of the known orbit's points (rows gap / h,
    u / v_scale, mode; another mode counts as far)."""
    d = math.inf
    for i in range(orbit.shape[0]):
        if strobe[k, SMODE] == orbit[i, 2]:
            d = min(d, max(abs(strobe[k, SGAP] - orbit[i, 0]), abs(strobe[k, SU] - orbit[i, 1])))
    return d


@njit(cache=True, nogil=True)
def _relative_state(g, u, phi, mode, B, w, s):
    """Gap and relative velocity s seconds into the segment that starts with (g, u) at phase phi."""
    if mode != FREE:
        return g, 0.0
    c0 = math.cos(phi)
    s0 = math.sin(phi)
    return g + u * s + B * shape(c0, s0, w * s), u + B * w * dshape(c0, s0, w * s)


@njit(cache=True, nogil=True)
def run_periods(params, state, seg, seg_mode, seg_cause, ctl, k0, strobe, half, four, stuck, side_off, sides,
                n_events, orbit):
    """Run the motion from boundary k0 (t = k0 T, state = the kernel state there) period by period.

    Per forcing period k (from t = k T to (k + 1) T) it records the Fourier integral of x1 against e^{-j w t}
    (``four[k]``), the time stuck (``stuck[k]``), the sides of its impacts (``sides[side_off[k]:side_off[k+1]]``,
    0 = A, 1 = B) and, at the boundary k + 1, the stroboscopic state (``strobe[k + 1]``: x1, gap / h,
    u / v_scale, mode) and at mid-period (``half[k]``: gap / h, u / v_scale, mode). After every period it checks for a converged period (:func:`assess_period`); from
    ``ctl[C_CHAOS]`` periods on a motion without a clearly contracting candidate is irregular; a motion that
    comes within ``ctl[C_MATCH_TOL]`` of one of the points of ``orbit`` (rows gap / h, u / v_scale, mode;
    empty: none) at consecutive boundaries has settled on that known attractor.
    Returns (status, boundary reached, period, events so far). ``SIDES_FULL``: the side buffer is full at the
    start of the returned boundary (state and records stay consistent there; grow ``sides`` and call again).
    """
    tol, floor, vscale, window = ctl[C_TOL], ctl[C_FLOOR], ctl[C_VSCALE], int(ctl[C_WINDOW])
    k_max, chaos, max_events, match_tol = int(ctl[C_KMAX]), int(ctl[C_CHAOS]), int(ctl[C_MAXEV]), ctl[C_MATCH_TOL]
    h, B, Bc, w = params[2], params[3] / (params[1] * params[4] ** 2), \
        params[3] / ((params[0] + params[1]) * params[4] ** 2), params[4]
    tp = TWO_PI / w
    snap = np.empty(8)
    cap = seg.shape[0]
    n_sides_cap = sides.shape[0]
    k_first, restarts, matches = int(ctl[C_KFIRST]), int(ctl[C_RESTARTS]), int(ctl[C_MATCHES])
    fails = int(ctl[C_FAILS])     # consecutive chaos checkpoints without a clear contraction
    m1, m2 = params[0], params[1]
    for k in range(k0, k_max):
        snap[:] = state
        events0 = n_events
        ns = side_off[k]
        ta = k * tp
        tb = (k + 1) * tp
        tm = (k + 0.5) * tp
        mid = False
        # the segment running at ta: the kernel state (last event)
        c_t0, c_phi, c_x1, c_v1, c_g, c_u, c_mode = state[0], state[1], state[2], state[3], state[4], state[5], \
            int(state[6])
        acc = 0j
        st = 0.0
        overflow = False
        while True:
            room = min(cap, max_events - n_events)
            if room <= 0:
                ctl[C_KFIRST], ctl[C_RESTARTS], ctl[C_MATCHES], ctl[C_FAILS] = k_first, restarts, matches, fails
                return EVENT_LIMIT, k, 0, n_events
            # a typed zero: a literal 0 would compile run_kernel a second time (Literal[int] signature)
            n, status = run_kernel(params, state, tb, seg[:room], seg_mode[:room], seg_cause[:room], _ZERO)
            n_events += n
            for i in range(n):
                t_i = seg[i, T0]
                if not mid and t_i > tm:
                    half[k, 0], half[k, 1] = _relative_state(c_g, c_u, c_phi, c_mode, B, w, tm - c_t0)
                    half[k, 2] = c_mode
                    mid = True
                lo = max(c_t0, ta)
                acc += _segment_piece(params, c_t0, c_phi, c_x1, c_v1, c_mode, lo, t_i)
                if c_mode != FREE:
                    st += t_i - lo
                cause = seg_cause[i]
                if cause == IMPACT_A or cause == IMPACT_B:
                    if ns >= n_sides_cap:
                        overflow = True
                    else:
                        sides[ns] = 0 if cause == IMPACT_A else 1
                        ns += 1
                c_t0, c_phi, c_x1, c_v1 = t_i, seg[i, PHI0], seg[i, X1], seg[i, V1]
                c_g, c_u, c_mode = seg[i, GAP], seg[i, U], int(seg_mode[i])
            if status == DONE:
                break
            if n >= room and room < cap:
                ctl[C_KFIRST], ctl[C_RESTARTS], ctl[C_MATCHES], ctl[C_FAILS] = k_first, restarts, matches, fails
                return EVENT_LIMIT, k, 0, n_events
        if overflow:
            state[:] = snap
            ctl[C_KFIRST], ctl[C_RESTARTS], ctl[C_MATCHES], ctl[C_FAILS] = k_first, restarts, matches, fails
            return SIDES_FULL, k, 0, events0
        if not mid:
            half[k, 0], half[k, 1] = _relative_state(c_g, c_u, c_phi, c_mode, B, w, tm - c_t0)
            half[k, 2] = c_mode
        half[k, 0] /= h
        half[k, 1] /= vscale
        lo = max(c_t0, ta)
        acc += _segment_piece(params, c_t0, c_phi, c_x1, c_v1, c_mode, lo, tb)
        s = tb - c_t0
        g_b, u_b = _relative_state(c_g, c_u, c_phi, c_mode, B, w, s)
        x1_b = c_x1 + c_v1 * s
        if c_mode != FREE:
            st += tb - lo
            x1_b += Bc * shape(math.cos(c_phi), math.sin(c_phi), w * s)
        strobe[k + 1, SX1] = x1_b
        strobe[k + 1, SGAP] = g_b / h
        strobe[k + 1, SU] = u_b / vscale
        strobe[k + 1, SMODE] = c_mode
        four[k] = acc
        stuck[k] = st
        side_off[k + 1] = ns
        kb = k + 1
        if orbit.shape[0] > 0:
            # settled on the known attractor: within match_tol of it at consecutive checks, and closer at the
            # last than at the first (or at rounding level)
            d = _orbit_distance(strobe, kb, orbit)
            if d > match_tol:
                matches = 0
            else:
                if matches == 0:
                    ctl[C_DIST] = d
                matches += 1
                if matches >= _SETTLE_CHECKS and (d < ctl[C_DIST] or d <= floor):
                    ctl[C_KFIRST], ctl[C_RESTARTS], ctl[C_MATCHES], ctl[C_FAILS] = k_first, restarts, matches, fails
                    return SETTLED, kb, 0, n_events
        period, checked, best = assess_period(strobe, kb, k_first, tol, floor, window)
        if period > 0:
            ctl[C_CHECKED] = checked
            ctl[C_KFIRST], ctl[C_RESTARTS], ctl[C_MATCHES], ctl[C_FAILS] = k_first, restarts, matches, fails
            return CONVERGED, kb, period, n_events
        rate = contracting(strobe, kb, k_first, best, window)
        if kb >= chaos and (kb - chaos) % window == 0:
            # checkpoints every window from the chaos time on: irregular after two in a row without a clear
            # contraction towards any period (one can fall on a glitch of a slowly converging motion)
            fails = fails + 1 if rate == 1.0 else 0
            if fails >= 2:
                ctl[C_KFIRST], ctl[C_RESTARTS], ctl[C_MATCHES], ctl[C_FAILS] = k_first, restarts, matches, fails
                return IRREGULAR, kb, 0, n_events
        if _SLOW < rate < 1.0 and restarts < _MAX_RESTARTS:
            # slow but clear contraction: restart from the extrapolated fixed point; the period detection
            # then checks the motion from there (boundaries before the restart are not used again)
            ok, g_new, u_new = extrapolate(strobe, kb, best)
            if ok and 0.0 <= g_new <= 1.0 and int(state[6]) == FREE:
                p_total = (m1 + m2) * state[3] + m2 * strobe[kb, SU] * vscale     # momentum at the boundary
                state[0] = tb
                state[1] = 0.0
                state[4] = g_new * h
                state[5] = u_new * vscale
                state[3] = (p_total - m2 * state[5]) / (m1 + m2)
                state[2] = strobe[kb, SX1]
                state[7] = -1.0
                strobe[kb, SGAP] = g_new
                strobe[kb, SU] = u_new
                k_first = kb
                restarts += 1
                matches = 0
    ctl[C_KFIRST], ctl[C_RESTARTS], ctl[C_MATCHES], ctl[C_FAILS] = k_first, restarts, matches, fails
    return NOT_CONVERGED, k_max, 0, n_events


@njit(cache=True, nogil=True)
def window_summary(strobe, four, stuck, sides, side_off, k, n, period, w):
    """DF and diagnostics over the n periods before boundary k, in blocks of ``period`` (1 if 0) periods.

    The linear drift (x1_k - x1_{k-n}) / window is removed (exact for a periodic motion with drift).
    Returns (X1, spread over blocks, impacts, longest run on A, longest run on B, stuck time).
    """
    tp = TWO_PI / w
    block = max(period, 1)
    nb = n // block
    used = nb * block
    ka = k - used
    slope = (strobe[k, SX1] - strobe[ka, SX1]) / (used * tp)
    drift = slope * 1j * block * tp / w
    xs = np.empty(nb, dtype=np.complex128)
    total = 0j
    for b in range(nb):
        acc = 0j
        for j in range(ka + b * block, ka + (b + 1) * block):
            acc += four[j]
        xs[b] = 2.0 / (block * tp) * (acc - drift)
        total += xs[b]
    X1 = total / nb
    spread = 0.0
    if X1 != 0:
        for b in range(nb):
            spread = max(spread, abs(xs[b] - X1))
        spread /= abs(X1)
    run_a = 0
    run_b = 0
    cur = -1
    length = 0
    for i in range(side_off[ka], side_off[k]):
        if sides[i] == cur:
            length += 1
        else:
            cur = sides[i]
            length = 1
        if cur == 0:
            run_a = max(run_a, length)
        else:
            run_b = max(run_b, length)
    st = 0.0
    for j in range(ka, k):
        st += stuck[j]
    return X1, spread, side_off[k] - side_off[ka], run_a, run_b, st


@njit(cache=True, nogil=True)
def _grow_rows(a, n):
    out = np.empty((n,) + a.shape[1:], dtype=a.dtype)
    out[:a.shape[0]] = a
    return out


@njit(cache=True, nogil=True)
def adaptive_run(kparams, state, ctl, orbit, k_max, capacity):
    """:func:`run_periods` from t = 0 to the end (records grown as needed, ``capacity`` periods at first),
    then the DF over the window that was verified (:func:`window_summary`).

    ``state`` is the kernel state at t = 0 (free flight). Returns (status, boundary k reached, period,
    periods in the window, X1, spread, impacts, longest runs on A and B, stuck time, orbit, sides, side_off):
    ``orbit`` holds the converged orbit's stroboscopic rows (gap / h, u / v_scale, mode) followed by those
    of its mirror image (the motion half a period later reflected: x -> -x, gap -> h - gap, sides A <-> B,
    which is a motion too, with the same DF); ``sides[side_off[j]:side_off[j + 1]]`` are the sides of the
    impacts of period j.
    """
    h, vscale = kparams[2], ctl[C_VSCALE]
    window = int(ctl[C_WINDOW])
    seg = np.empty((256, N_FLOAT_COLUMNS))
    seg_mode = np.empty(256, np.int8)
    seg_cause = np.empty(256, np.int8)
    cap = min(k_max, capacity)
    strobe = np.empty((cap + 1, 4))
    half = np.empty((cap, 3))
    four = np.empty(cap, dtype=np.complex128)
    stuck = np.empty(cap)
    side_off = np.zeros(cap + 1, dtype=np.int64)
    sides = np.empty(64 * window, dtype=np.int8)
    strobe[0, SX1], strobe[0, SGAP], strobe[0, SU], strobe[0, SMODE] = state[2], state[4] / h, state[5] / vscale, FREE
    k = _ZERO          # typed zeros: literal ones would compile run_periods twice (Literal[int] signatures)
    events = _ZERO
    while True:
        ctl[C_KMAX] = cap
        status, k, period, events = run_periods(kparams, state, seg, seg_mode, seg_cause, ctl, k, strobe, half,
                                                four, stuck, side_off, sides, events, orbit)
        if status == SIDES_FULL:
            sides = _grow_rows(sides, 4 * sides.shape[0])
        elif status == NOT_CONVERGED and cap < k_max:
            cap = min(4 * cap, k_max)
            strobe = _grow_rows(strobe, cap + 1)
            side_off = _grow_rows(side_off, cap + 1)
            half = _grow_rows(half, cap)
            four = _grow_rows(four, cap)
            stuck = _grow_rows(stuck, cap)
        else:
            break
    out_orbit = np.zeros((0, 3))
    if status == EVENT_LIMIT or status == SETTLED:
        return status, k, period, 0, 0j, 0.0, 0, 0, 0, 0.0, out_orbit, sides, side_off
    n = int(ctl[C_CHECKED]) if status == CONVERGED else window
    X1, spread, n_imp, run_a, run_b, st = window_summary(strobe, four, stuck, sides, side_off, k, n, period,
                                                         kparams[4])
    used = n if period == 0 else period * (n // period)
    if n_imp == 0 and st == 0.0:
        # free flight throughout the window: x1 is exactly linear, its fundamental exactly 0
        X1, spread, period = 0j, 0.0, 1
    if period > 0:
        out_orbit = np.empty((2 * period, 3))
        for i in range(period):
            j = k - period + 1 + i
            out_orbit[i, 0], out_orbit[i, 1], out_orbit[i, 2] = strobe[j, SGAP], strobe[j, SU], strobe[j, SMODE]
            m = half[k - period + i, 2]
            out_orbit[period + i, 0] = 1.0 - half[k - period + i, 0]
            out_orbit[period + i, 1] = -half[k - period + i, 1]
            out_orbit[period + i, 2] = m if m == FREE else STUCK_A + STUCK_B - m
    return status, k, period, used, X1, spread, n_imp, run_a, run_b, st, out_orbit, sides, side_off


# columns of the per-point float results of adaptive_batch
R_X1_RE, R_X1_IM, R_SPREAD, R_STUCK = range(4)
# columns of the per-point integer results
R_STATUS, R_K, R_PERIOD, R_USED, R_IMPACTS, R_RUN_A, R_RUN_B, R_ORBIT = range(8)


@njit(cache=True, nogil=True)
def adaptive_batch(kparams, states, ctls, orbits, orbit_rows, k_max, capacity):
    """:func:`adaptive_run` for every row of ``kparams`` / ``states`` / ``ctls`` (one point each), in turn.

    ``orbits[i, :orbit_rows[i]]`` is the known attractor of point i (none when 0 rows). Returns float results
    (n, 4): X1 real and imaginary, spread, stuck time; integer results (n, 8): status, boundary reached,
    period, periods used, impacts, longest runs on A and B, orbit rows; and the orbits (n, 4 MAX_PERIOD, 3).
    """
    n = kparams.shape[0]
    fres = np.zeros((n, 4))
    ires = np.zeros((n, 8), dtype=np.int64)
    out_orbits = np.zeros((n, 2 * MAX_PERIOD, 3))
    for i in range(n):
        status, k, period, used, X1, spread, n_imp, run_a, run_b, st, orbit, _, _ = adaptive_run(
            kparams[i], states[i], ctls[i], orbits[i, :orbit_rows[i]], k_max, capacity)
        fres[i, R_X1_RE], fres[i, R_X1_IM], fres[i, R_SPREAD], fres[i, R_STUCK] = X1.real, X1.imag, spread, st
        ires[i, R_STATUS], ires[i, R_K], ires[i, R_PERIOD], ires[i, R_USED] = status, k, period, used
        ires[i, R_IMPACTS], ires[i, R_RUN_A], ires[i, R_RUN_B] = n_imp, run_a, run_b
        ires[i, R_ORBIT] = orbit.shape[0]
        out_orbits[i, :orbit.shape[0]] = orbit
    return fres, ires, out_orbits
