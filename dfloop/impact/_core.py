"""The event-driven loop of the paper's model (clearance + restitution impacts + sticking), JIT-compiled.

Units are SI throughout; the state is (t, phase, x1, v1, g, u) with g = x2 - x1 the gap and u = v2 - v1 the
relative velocity, so that the gap near a wall is carried with full relative precision. Runs identically as
plain Python under NUMBA_DISABLE_JIT=1.
"""
from __future__ import annotations

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
