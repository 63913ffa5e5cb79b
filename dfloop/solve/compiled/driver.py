"""The compiled driver: :func:`dfloop.predict_limit_cycles` end to end in one numba call, for the common case.

Where it applies: a rational continuous G (coefficients ``num``, ``den``, optionally a pure delay) and an
amplitude-only element with a compiled form (:mod:`.kinds`). It runs the Python driver's algorithm with the same
floating-point expressions in the same order (numpy's reduction order, complex division, ``linspace``):

1. the default frequency window two decades beyond the poles and zeros (numpy's, as the Plant has them);
2. G's grid, refined from the certified bound on its variation (``grid._interval_bound``, above
   :meth:`~dfloop.solve.plant.Plant.log_variation`);
3. the default amplitude window (``predict._default_amplitude_window`` with ``_limit_reach``), N's breakpoints as
   nodes and N's grid (``grid.resolve_sampled`` with ``monotone=True``);
4. the candidate cells (``_kernels.candidate_cells``), their windings with the edge bisection of
   ``roots.edge_phases``, the refinement of single-winding cells (``roots.refine``), the isolation
   (``roots._isolate``: quadrisection by windings) of the cells that wind more than once, of those whose
   refinement fails and of the neighbourhood of a tangent seed that refines to a root, the tangent seeds and their
   refinement (with the wider retry next to a jump), the continuum test, ``roots.merge``;
5. the residual-bound acceptance, the Loeb classification (``stability.label_roots``), the merge of marginal
   roots and the order of the result (``predict._build``).

Whenever the Python driver would take a branch this one does not carry (many cells winding more than once, a
root on a grid edge or an edge zero or a jump of N met in an isolation, a degenerate root that may sit on a
continuum, a work bound, a non-finite value, an input the Python path rejects), it stops with a non-zero
status and :func:`dfloop.predict_limit_cycles` runs the Python driver instead: a different route, never a
different answer. The elementary functions (exp, log, atan2, pow) come from the platform's libm here and
possibly from numpy's SIMD versions in the Python path, so results agree to rounding (tests/test_compiled.py
compares both on many loops to 1e-12).

:func:`solve_many` runs the same driver over a batch of loops, its row ranges shared among threads (the kernel
releases the GIL); each loop is independent and computed exactly as :func:`solve_one` computes it.
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import config as numba_config, njit

from ..._checks import memory_limit
from ..grid import (ANGLE_ROUNDING, BYTES_PER_POINT, SUM_ROUNDING, TAN_OK, TERM_ROUNDING, allpass_pairs,
                    chord_deviation, chord_gap)
from .kernels import accepted, cabs, cdiv, element, plant, refine, slopes_at

__all__ = ["solve_one", "solve_many", "solve_one_dispatcher", "solve_many_dispatcher", "kept_seeds",
           "kept_seeds_dispatcher", "apart_cells", "apart_cells_dispatcher", "FALLBACK", "MAX_ROOTS", "CONSTANTS",
           "STABLE", "UNSTABLE", "MARGINAL"]

# the constants of the Python driver this one mirrors (tests/test_compiled.py checks they are the same values)
CONSTANTS = dict(
    STEP=0.35, GOLDEN=0.3819660112501051, MONOTONE_WIDTH=1e-9, MAX_ROUNDS=64, MIN_WIDTH=1e-13,
    MAX_POINTS=2_000_000, SPLIT_PHASE=np.pi / 2, MAX_EDGE_DEPTH=50, MAX_SEGMENTS=4_000_000, JUMP_LENGTH=1e-9,
    JUMP_SIZE=1e-3, JUMP_KEEP=0.9, TANGENT_THRESHOLD=0.1, MAX_TANGENT_SEEDS=5000, MERGE_RADIUS=1e-12,
    JUMP_DOMINANCE=4.0, DEGENERATE_SIN=1e-4, DECADES=2.0, EDGE_TOL=1e-9, SEED_MARGIN=0.005, SEED_SPLITS=64,
    SEED_TESTS=4096, MAX_ISOLATE_DEPTH=40, MAX_LIVE_BOXES=4096, EARLY_CONTINUUM_CHECK=64)
_STEP = CONSTANTS["STEP"]
_GOLDEN = CONSTANTS["GOLDEN"]
_MONOTONE_WIDTH = CONSTANTS["MONOTONE_WIDTH"]
_MAX_ROUNDS = CONSTANTS["MAX_ROUNDS"]
_MIN_WIDTH = CONSTANTS["MIN_WIDTH"]
_MAX_POINTS = CONSTANTS["MAX_POINTS"]
_SPLIT = CONSTANTS["SPLIT_PHASE"]
_MAX_EDGE_DEPTH = CONSTANTS["MAX_EDGE_DEPTH"]
_MAX_SEGMENTS = CONSTANTS["MAX_SEGMENTS"]
_JUMP_LENGTH = CONSTANTS["JUMP_LENGTH"]
_JUMP_SIZE = CONSTANTS["JUMP_SIZE"]
_JUMP_KEEP = CONSTANTS["JUMP_KEEP"]
_TANGENT = CONSTANTS["TANGENT_THRESHOLD"]
_MAX_SEEDS = CONSTANTS["MAX_TANGENT_SEEDS"]
_MAX_ISOLATE_DEPTH = CONSTANTS["MAX_ISOLATE_DEPTH"]
_MAX_LIVE_BOXES = CONSTANTS["MAX_LIVE_BOXES"]
_EARLY_CONTINUUM_CHECK = CONSTANTS["EARLY_CONTINUUM_CHECK"]
_MERGE_RADIUS = CONSTANTS["MERGE_RADIUS"]
_DOMINANCE = CONSTANTS["JUMP_DOMINANCE"]
_DEGENERATE_SIN = CONSTANTS["DEGENERATE_SIN"]
_EDGE_TOL = CONSTANTS["EDGE_TOL"]
_SEED_MARGIN = CONSTANTS["SEED_MARGIN"]
_SEED_SPLITS = CONSTANTS["SEED_SPLITS"]
_SEED_TESTS = CONSTANTS["SEED_TESTS"]
_WIN_LO = 10.0 ** -CONSTANTS["DECADES"]
_WIN_HI = 10.0 ** CONSTANTS["DECADES"]
_TWO_PI = 2.0 * np.pi
_PI = np.pi
_TAN_OK = TAN_OK
_TAME = 1e100  # bound on |roots| and w below which the phase bound of an interval cannot be NaN
_MAX_PAIRWISE = 128  # roots of a plant beyond which the numpy reduction order is not mirrored (a fallback)

# the constant candidate amplitudes of predict._default_amplitude_window and the grid of predict._limit_reach
_CAND_ABOVE = np.logspace(-9, 8, 171)
_CAND_ALL = np.logspace(-30, 30, 601)
_CAND_BELOW = np.logspace(-9, -0.3, 88)
_REACH = np.logspace(-300, 300, 12001)

MAX_ROOTS = 64
"""Roots one loop of a batch may hold (more: that loop falls back to the Python driver)."""

FALLBACK = {1: "many cells wind more than once (a continuum?)",
            2: "a root's isolation met an edge zero, a jump of N or a work bound",
            3: "a root on a grid edge", 5: "a degenerate root (continuum?)",
            6: "a work bound", 7: "a non-finite value", 8: "an input the Python path rejects",
            9: "a marginal or on-edge case", 10: "too many roots for the batch", 11: "a plant of high order"}
"""Why the compiled driver left a loop to the Python driver (status codes)."""

_OPTS = dict(cache=True, nogil=True, error_model="numpy")

_CORNER_I = np.array([0, 1, 1, 0])
_CORNER_J = np.array([0, 0, 1, 1])

_BYTES_PER_POINT = float(BYTES_PER_POINT[False])  # the work arrays per grid point (amplitude-only N)
_allpass_pairs = njit(**_OPTS)(allpass_pairs)  # grid.allpass_pairs, the same source compiled
_chord_deviation = njit(**_OPTS)(chord_deviation)  # grid.chord_deviation, the same source compiled
_chord_gap = njit(**_OPTS)(chord_gap)  # grid.chord_gap, the same source compiled

# label codes
STABLE, UNSTABLE, MARGINAL = 0, 1, 2


# ------------------------------------------------------------------------------------------ numpy's arithmetic


@njit(**_OPTS)
def _npmax(x, y):
    """np.maximum of two floats (NaN propagates)."""
    if x != x:
        return x
    if y != y:
        return y
    return x if x >= y else y


@njit(**_OPTS)
def _npmin(x, y):
    if x != x:
        return x
    if y != y:
        return y
    return x if x <= y else y


@njit(**_OPTS)
def _pairwise(x, lo, n):
    """numpy's pairwise sum of x[lo:lo + n] (n <= 128: one block of eight accumulators; in order below 8 terms),
    as numpy sums the rows of a C-contiguous array along its last axis (numpy 2)."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += x[lo + i]
        return res
    r0, r1, r2, r3 = x[lo], x[lo + 1], x[lo + 2], x[lo + 3]
    r4, r5, r6, r7 = x[lo + 4], x[lo + 5], x[lo + 6], x[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += x[lo + i]
        r1 += x[lo + i + 1]
        r2 += x[lo + i + 2]
        r3 += x[lo + i + 3]
        r4 += x[lo + i + 4]
        r5 += x[lo + i + 5]
        r6 += x[lo + i + 6]
        r7 += x[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += x[lo + i]
        i += 1
    return res


@njit(**_OPTS)
def _linspace(start, stop, num):
    """np.linspace(start, stop, num) (endpoint included)."""
    y = np.empty(num)
    if num == 1:
        y[0] = start
        return y
    step = (stop - start) / (num - 1)
    for i in range(num):
        y[i] = i * step + start
    y[num - 1] = stop
    return y


@njit(**_OPTS)
def _geomspace(start, stop, num):
    """np.geomspace(start, stop, num) for 0 < start, stop."""
    y = _linspace(math.log10(start), math.log10(stop), num)
    for i in range(num):
        y[i] = 10.0 ** y[i]
    y[0] = start
    y[num - 1] = stop
    return y


@njit(**_OPTS)
def _angle(z):
    return math.atan2(z.imag, z.real)


@njit(**_OPTS)
def _clog(z):
    """grid.clog: ln|z| + j arg z."""
    return complex(math.log(cabs(z)), _angle(z))


@njit(**_OPTS)
def _hypot(x, y):
    """grid.hypot: sqrt(x^2 + y^2) where max(|x|, |y|) lies in (1e-150, 1e150), math.hypot elsewhere."""
    big = _npmax(abs(x), abs(y))
    if 1e-150 < big < 1e150:
        return math.sqrt(x * x + y * y)
    return math.hypot(x, y)


@njit(**_OPTS)
def _wrapped(d):
    """grid.wrap_phase: a phase difference wrapped into [-pi, pi] by one turn (exact where |d| <= 2 pi)."""
    if d > _PI and d <= _TWO_PI:
        return d - _TWO_PI
    if d < -_PI and d >= -_TWO_PI:
        return d + _TWO_PI
    if abs(d) <= _TWO_PI or d != d:
        return d
    return math.atan2(math.sin(d), math.cos(d))


@njit(**_OPTS)
def _dlog(l1, l0, wrapped):
    """grid._dlog, with the wrapped phase difference _wrapped(l1.imag - l0.imag) already computed."""
    dre = l1.real - l0.real
    if dre != dre:
        dre = 0.0
    return _hypot(dre, wrapped)


@njit(**_OPTS)
def _merge_sort(x):
    """(x sorted, the stable order that sorts it) of a 1-D array (NaN-free input): np.sort and
    np.argsort(kind="stable") at once, by a natural merge sort.

    The array is cut into its runs (non-decreasing, or strictly decreasing and then reversed: no ties inside, so
    no order among equal values changes), and adjacent runs are merged pairwise, the left one first on ties:
    the unique stable order, in O(n log(runs)). Sampled curves (|G| along the frequency grid) have few runs; input
    already in order (most grids) is the identity, after one pass. The values move with their indices, so the
    merge compares them directly."""
    n = x.size
    s = x.copy()
    idx = np.arange(n)
    bounds = np.empty(n + 1, np.int64)
    nb = 0
    i = 0
    while i < n:
        bounds[nb] = i
        nb += 1
        j = i + 1
        if j < n and s[j] < s[i]:  # a strictly decreasing run, reversed
            while j < n and s[j] < s[j - 1]:
                j += 1
            lo, hi = i, j - 1
            while lo < hi:
                s[lo], s[hi] = s[hi], s[lo]
                idx[lo], idx[hi] = idx[hi], idx[lo]
                lo += 1
                hi -= 1
        else:
            while j < n and s[j] >= s[j - 1]:
                j += 1
        i = j
    bounds[nb] = n
    if nb <= 1:
        return s, idx
    tmp, tmp_idx = np.empty(n, x.dtype), np.empty(n, np.int64)
    while nb > 1:
        k = 0
        for r in range(0, nb, 2):
            lo = bounds[r]
            if r + 1 < nb:
                mid, hi = bounds[r + 1], bounds[r + 2]
            else:
                mid = hi = bounds[r + 1]
            i, j, q = lo, mid, lo
            while i < mid and j < hi:
                if s[j] < s[i]:
                    tmp[q], tmp_idx[q] = s[j], idx[j]
                    j += 1
                else:
                    tmp[q], tmp_idx[q] = s[i], idx[i]
                    i += 1
                q += 1
            while i < mid:
                tmp[q], tmp_idx[q] = s[i], idx[i]
                i += 1
                q += 1
            while j < hi:
                tmp[q], tmp_idx[q] = s[j], idx[j]
                j += 1
                q += 1
            bounds[k] = lo
            k += 1
        bounds[k] = n
        nb = k
        s, tmp = tmp, s
        idx, tmp_idx = tmp_idx, idx
    return s, idx


@njit(**_OPTS)
def _order(x):
    """A stable argsort of a 1-D array (NaN-free input): np.argsort(kind="stable") (:func:`_merge_sort`)."""
    return _merge_sort(x)[1]


@njit(**_OPTS)
def _bisect(a, x, right):
    """np.searchsorted(a, x, side="right" if right else "left") on a sorted 1-D array."""
    lo, hi = 0, a.size
    while lo < hi:
        mid = (lo + hi) // 2
        if a[mid] < x or (right and a[mid] == x):
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(**_OPTS)
def _sorted(x):
    """x[_order(x)] (NaN-free input): np.sort with equal values in their stable order (-0.0 in its place)."""
    return _merge_sort(x)[0]


@njit(**_OPTS)
def _unique(x):
    """np.unique of a 1-D array (sorted, exact duplicates removed)."""
    s = _sorted(x)
    if s.size == 0:
        return s
    out = np.empty(s.size, s.dtype)
    out[0] = s[0]
    k = 1
    for i in range(1, s.size):
        if s[i] != s[i - 1]:
            out[k] = s[i]
            k += 1
    return out[:k]


@njit(**_OPTS)
def _merge_unique(x, y):
    """The distinct values of two ascending int arrays, ascending (what _unique gives for their concatenation)."""
    out = np.empty(x.size + y.size, np.int64)
    p = q = k = 0
    while p < x.size or q < y.size:
        if q == y.size or (p < x.size and x[p] <= y[q]):
            z = x[p]
            p += 1
        else:
            z = y[q]
            q += 1
        if k == 0 or out[k - 1] != z:
            out[k] = z
            k += 1
    return out[:k]


@njit(**_OPTS)
def _sign(x):
    if x != x:
        return x
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


# ------------------------------------------------------------------------------------------------ G's grid


@njit(**_OPTS)
def _resolve_plant(zeros, poles, delay, v):
    """grid.resolve_plant for a rational G: (nodes, e^nodes, eps per interval, status).

    The intervals of a round are the ones of the Python version, in its order, each bounded by
    grid._interval_bound's expressions. Every node (its w = e^x, and w - y and |jw - r| for each root r = -x + jy:
    grid.node_terms) is computed once, in a table the intervals index (a split adds its midpoint): the same
    expression at the same w gives the same value. The loops are written out here, with no call that takes an
    array (numba does not inline such calls across functions, and each one pays reference counting)."""
    rr = np.concatenate((zeros, poles))
    nz = zeros.size
    nr = rr.size
    xr, yr = np.empty(nr), np.empty(nr)
    for k in range(nr):
        xr[k], yr[k] = -rr[k].real, rr[k].imag  # jw - r = x + j (w - y)
    b1, b2, b3, b4 = np.empty(nr), np.empty(nr), np.empty(nr), np.empty(nr)
    # roots and delay within _TAME: no product below overflows, so no phase bound is NaN (see the split shortcut)
    tame = math.isfinite(delay)
    for k in range(nr):
        tame &= abs(xr[k]) <= _TAME and abs(yr[k]) <= _TAME
    scale, margin = 1.0 + SUM_ROUNDING * (nr + 1) + TERM_ROUNDING, ANGLE_ROUNDING * nr  # rounding margins
    paired, slack = _allpass_pairs(zeros, poles)  # all-pass pairs: magnitudes by their joint bound
    cap = 2 * v.size + 16
    # the node table: x, e^x, w - y, |jw - r| (unused, and not computed, for an all-pass pair's roots)
    tx, tw, tp, td = np.empty(cap), np.empty(cap), np.empty((cap, nr)), np.empty((cap, nr))
    n_nodes = v.size
    for i in range(n_nodes):
        w = math.exp(v[i])
        tx[i], tw[i] = v[i], w
        for k in range(nr):  # grid.node_terms
            pk = w - yr[k]
            tp[i, k] = pk
            if not paired[k]:
                td[i, k] = _hypot(xr[k], pk)
    out_n = np.empty(2 * v.size + 16, np.int64)  # the finished nodes (table indices) and intervals
    out_e = np.empty(2 * v.size + 16)
    out_n[0] = 0
    n_out = 1
    i0, i1 = np.arange(v.size - 1), np.arange(1, v.size)  # node indices of the live intervals' ends
    settled = False
    for _ in range(_MAX_ROUNDS):
        m = i0.size
        if m == 0:
            settled = True
            break
        eps = np.empty(m)
        split = np.empty(m, np.bool_)
        n_split = 0
        for i in range(m):
            p, q = i0[i], i1[i]
            w0, w1 = tw[p], tw[q]
            h = w1 - w0
            wide = tx[q] - tx[p] > _MIN_WIDTH * (1 + abs(tx[p]))
            for k in range(nr):  # grid._interval_bound, one root at a time (zeros +, poles -): magnitudes ...
                if paired[k]:
                    up = down = 0.0
                else:
                    p0, p1 = tp[p, k], tp[q, k]
                    d0, d1 = td[p, k], td[q, k]
                    if p0 < 0 and p1 > 0:  # the interval straddles y: down to |x| and up again
                        ax = abs(xr[k])
                        up, down = 0.5 * (p1 / ax) * (p1 / d1), 0.5 * (p0 / ax) * (p0 / d0)
                    else:
                        mono = 0.5 * (h / d0) * (abs(p1 + p0) / d1)
                        if p0 >= 0:
                            up, down = mono, 0.0
                        else:
                            up, down = 0.0, mono
                b1[k] = up if k < nz else down
                b2[k] = down if k < nz else up
            if nr < 8:  # numpy's sum along the last axis (pairwise: in order below 8 terms)
                rise = fall = -0.0
                for k in range(nr):
                    rise += b1[k]
                    fall += b2[k]
            else:
                rise, fall = _pairwise(b1, 0, nr), _pairwise(b2, 0, nr)
            rise, fall = rise * scale + slack, fall * scale + slack
            mag = _npmax(rise, fall)
            if wide and tame and w1 <= _TAME and mag > _STEP:
                # e = _hypot(arg, mag) >= mag > _STEP (arg is not NaN here): split whatever the phase bound
                # (a split interval's eps is not kept)
                split[i] = True
                n_split += 1
                continue
            for k in range(nr):  # ... then phases: the tangent of the turn, or the turn itself by atan2
                x = xr[k]
                pp = tp[p, k] * tp[q, k]
                xx = x * x
                den = xx + pp
                if den > _TAN_OK * (xx + abs(pp)):
                    turn = x * h / den
                else:
                    turn = math.atan2(x * h, den)
                if k >= nz:
                    turn = -turn
                b3[k] = turn if turn > 0 else 0.0
                b4[k] = turn if turn < 0 else 0.0
            if nr < 8:
                pos = neg = -0.0
                for k in range(nr):
                    pos += b3[k]
                    neg += b4[k]
            else:
                pos, neg = _pairwise(b3, 0, nr), _pairwise(b4, 0, nr)
            arg = _npmax(pos, -neg + delay * h) * scale + margin
            e = _hypot(arg, mag)
            eps[i] = e
            split[i] = (e > _STEP) and wide
            n_split += split[i]
        if n_out + m > out_n.size:
            grow = max(2 * out_n.size, n_out + m)
            on, oe = np.empty(grow, np.int64), np.empty(grow)
            on[:n_out], oe[:n_out] = out_n[:n_out], out_e[:n_out]
            out_n, out_e = on, oe
        if n_nodes + n_split > tx.size:
            grow = max(2 * tx.size, n_nodes + n_split)
            gx, gw, gp, gd = np.empty(grow), np.empty(grow), np.empty((grow, nr)), np.empty((grow, nr))
            gx[:n_nodes], gw[:n_nodes] = tx[:n_nodes], tw[:n_nodes]
            gp[:n_nodes], gd[:n_nodes] = tp[:n_nodes], td[:n_nodes]
            tx, tw, tp, td = gx, gw, gp, gd
        n0, n1 = np.empty(2 * n_split, np.int64), np.empty(2 * n_split, np.int64)
        k = 0
        for i in range(m):
            p, q = i0[i], i1[i]
            if split[i]:
                xm = 0.5 * (tx[p] + tx[q])
                w = math.exp(xm)
                tx[n_nodes], tw[n_nodes] = xm, w
                for r in range(nr):
                    pk = w - yr[r]
                    tp[n_nodes, r] = pk
                    if not paired[r]:
                        td[n_nodes, r] = _hypot(xr[r], pk)
                n0[k], n1[k] = p, n_nodes
                n0[n_split + k], n1[n_split + k] = n_nodes, q
                n_nodes += 1
                k += 1
            else:
                out_n[n_out] = q
                out_e[n_out - 1] = eps[i]
                n_out += 1
        i0, i1 = n0, n1
        if n_out + i0.size > _MAX_POINTS:
            return tx[:1], tw[:1], out_e[:0], 6
    if not settled:
        return tx[:1], tw[:1], out_e[:0], 6
    xs = np.empty(n_out - 1)
    for i in range(n_out - 1):
        xs[i] = tx[out_n[i + 1]]
    order = _order(xs)
    nodes, ws = np.empty(n_out), np.empty(n_out)
    eps = np.empty(n_out - 1)
    nodes[0], ws[0] = tx[0], tw[0]
    for i in range(n_out - 1):
        q = out_n[order[i] + 1]
        nodes[i + 1], ws[i + 1] = tx[q], tw[q]
        eps[i] = out_e[order[i]]
    return nodes, ws, eps, 0


# ------------------------------------------------------------------------------------------------ N's grid


@njit(**_OPTS)
def _turns(l0, lg, lm, l1, w_g0, w_1m):
    """grid._non_monotone of one interval sampled at l0, lg, lm, l1 (complex logs); w_g0, w_1m: the wrapped phase
    differences lg - l0 and l1 - lm (computed for the interval's bound already; the third, lm - lg, only when
    ln|N| alone does not turn)."""
    up = down = False
    for d in (lg.real - l0.real, lm.real - lg.real, l1.real - lm.real):
        up |= d > 1e-10
        down |= d < -1e-10
    if up and down:
        return True
    up = down = False
    for d in (w_g0, _wrapped(lm.imag - lg.imag), w_1m):
        up |= d > 1e-10
        down |= d < -1e-10
    return up and down


@njit(**_OPTS)
def _resolve_element(kind, p, x):
    """grid.resolve_sampled(N, x, monotone=True) for an amplitude-only N: (nodes, N at nodes, eps, n_eval, status).

    The rounds are the Python version's, in its order; the live intervals of a round and of the next are kept in
    two sets of work arrays that swap roles (grown by doubling when a round outgrows them), so a round allocates
    nothing."""
    m = x.size
    fx = np.empty(m, np.complex128)
    for i in range(m):
        fx[i] = element(kind, p, math.exp(x[i]))
        if fx[i] != fx[i]:
            return x[:1], fx[:1], x[:0], m, 7
    cap = 2 * m + 16
    out_x, out_f, out_e = np.empty(cap), np.empty(cap, np.complex128), np.empty(cap)
    out_x[0], out_f[0] = x[0], fx[0]
    n_out = 1
    # live intervals (x0, x1, ln N at both ends, N at the right end), this round's and the next's, and this
    # round's midpoints, their N and ln N, the intervals' eps and split flags: rows of two work arrays
    fb, cb = np.empty((6, cap)), np.empty((8, cap), np.complex128)
    x0, x1, nx0, nx1, xm, eps = fb[0], fb[1], fb[2], fb[3], fb[4], fb[5]
    l0, l1, nl0, nl1, f1, nf1, fm, lm = cb[0], cb[1], cb[2], cb[3], cb[4], cb[5], cb[6], cb[7]
    split = np.empty(cap, np.bool_)
    for i in range(m - 1):
        x0[i], x1[i] = x[i], x[i + 1]
        l0[i], l1[i] = _clog(fx[i]), _clog(fx[i + 1])
        f1[i] = fx[i + 1]
    k = m - 1
    n_eval = m
    settled = False
    for _ in range(_MAX_ROUNDS):
        if k == 0:
            settled = True
            break
        n_eval += 2 * k
        if k > xm.size:
            xm, fm, lm = np.empty(2 * k), np.empty(2 * k, np.complex128), np.empty(2 * k, np.complex128)
            eps, split = np.empty(2 * k), np.empty(2 * k, np.bool_)
        n_split = 0
        for i in range(k):
            dx = x1[i] - x0[i]
            xm[i] = x0[i] + 0.5 * dx
            xg = x0[i] + _GOLDEN * dx
            fm[i] = element(kind, p, math.exp(xm[i]))
            fg = element(kind, p, math.exp(xg))
            if fm[i] != fm[i] or fg != fg:
                return out_x[:1], out_f[:1], out_e[:0], n_eval, 7
            lm[i] = _clog(fm[i])
            lg = _clog(fg)
            w_g0, w_1m = _wrapped(lg.imag - l0[i].imag), _wrapped(l1[i].imag - lm[i].imag)
            e = _npmax(_dlog(lm[i], l0[i], _wrapped(lm[i].imag - l0[i].imag)) + _dlog(l1[i], lm[i], w_1m),
                       _dlog(lg, l0[i], w_g0) + _dlog(l1[i], lg, _wrapped(l1[i].imag - lg.imag)))
            eps[i] = e
            fin = math.isfinite(e)
            s = fin and (e > _STEP) and (dx > _MIN_WIDTH * (1 + abs(x0[i])))
            if not s and fin and dx > _MONOTONE_WIDTH * (1 + abs(x0[i])):
                s = _turns(l0[i], lg, lm[i], l1[i], w_g0, w_1m)
            split[i] = s
            n_split += s
        if n_out + k > out_x.size:
            grow = max(2 * out_x.size, n_out + k)
            ox, of, oe = np.empty(grow), np.empty(grow, np.complex128), np.empty(grow)
            ox[:n_out], of[:n_out], oe[:n_out] = out_x[:n_out], out_f[:n_out], out_e[:n_out]
            out_x, out_f, out_e = ox, of, oe
        if 2 * n_split > nx0.size:
            grow = 4 * n_split
            nx0, nx1 = np.empty(grow), np.empty(grow)
            nl0, nl1, nf1 = np.empty(grow, np.complex128), np.empty(grow, np.complex128), np.empty(grow, np.complex128)
        j = 0
        for i in range(k):
            if split[i]:
                nx0[j], nx1[j], nl0[j], nl1[j], nf1[j] = x0[i], xm[i], l0[i], lm[i], fm[i]
                q = n_split + j
                nx0[q], nx1[q], nl0[q], nl1[q], nf1[q] = xm[i], x1[i], lm[i], l1[i], f1[i]
                j += 1
            else:
                out_x[n_out], out_f[n_out] = x1[i], f1[i]
                out_e[n_out - 1] = eps[i]
                n_out += 1
        x0, x1, l0, l1, f1, nx0, nx1, nl0, nl1, nf1 = nx0, nx1, nl0, nl1, nf1, x0, x1, l0, l1, f1
        k = 2 * n_split
        if n_out + k > _MAX_POINTS:
            return out_x[:1], out_f[:1], out_e[:0], n_eval, 6
    if not settled:
        return out_x[:1], out_f[:1], out_e[:0], n_eval, 6
    order = _order(out_x[1:n_out])
    nodes, vals, eps = np.empty(n_out), np.empty(n_out, np.complex128), np.empty(n_out - 1)
    nodes[0], vals[0] = out_x[0], out_f[0]
    for i in range(n_out - 1):
        nodes[i + 1], vals[i + 1] = out_x[order[i] + 1], out_f[order[i] + 1]
        eps[i] = out_e[order[i]]
    return nodes, vals, eps, n_eval, 0


# ------------------------------------------------------------------------------------------ default windows


@njit(**_OPTS)
def _reach_index(c, d, half, to_inf):
    """The index predict._limit_reach reads on its amplitude grid for the bound c / A (to_inf) or c A^2 + d, and
    the threshold t with: every r with 0.5 r > t (and r <= 2 half) gives the same index; -1: no index (None).

    Found by bisection: with c, d >= 0 (the elements' bounds) the bound is monotone along the grid in floating
    point too (correctly rounded products, sums and quotients are monotone), so the first grid point where the
    test changes is the one a scan of every point finds."""
    n = _REACH.size
    lo, hi = 0, n  # the first index where the test holds (to_inf: below half; head: no longer below half)
    while lo < hi:
        mid = (lo + hi) // 2
        A = _REACH[mid]
        hit = c / A < half if to_inf else not (c * (A * A) + d < half)
        if hit:
            hi = mid
        else:
            lo = mid + 1
    if to_inf:
        return (lo, c / _REACH[lo]) if lo < n else (-1, np.inf)
    if lo == 0:
        return -1, np.inf
    B = _REACH[lo - 1]
    return (lo - 1 if lo < n else -1), c * (B * B) + d


@njit(**_OPTS)
def _room(g, n0, slack):
    """(room / (|G| (1 + slack)), ok) at one refined frequency of predict._limit_reach, G known there: ok False where
    that function gives up (G N_lim not finite, or no room)."""
    P = g * n0
    if not (math.isfinite(P.real) and math.isfinite(P.imag)):
        return np.nan, False
    room = cabs(1 + P) - cabs(P) * slack
    if not room > 0:
        return np.nan, False
    return room / (cabs(g) * (1 + slack)), True


@njit(**_OPTS)
def _limit_reach(num, den, zeros, poles, delay, kind, p, v, g, eps_v, to_inf, c, d):
    """predict._limit_reach: the amplitude beyond (to_inf) or below which no root lies, or NaN (None there).

    The element's bound is c / A (tail, to_inf) or c A^2 + d (head); c NaN: the element states none. The
    minimum r over the refined frequencies is needed only as far as it moves the index read on the amplitude
    grid: it is taken on the nodes first (G there is known: ``g`` is G at e^v, the same expression), then the
    refined frequencies of an interval are evaluated only where the interval's certified variation bound eps
    (|ln G(w) - ln G(w_k)| <= eps) cannot keep them above the threshold that would change the index, and there by
    halving blocks of them with a bound of each block (:func:`_variation_bound`); the result is the one of the full
    evaluation (a skipped value is above the threshold, and has room), whichever upper bound is used."""
    if c != c:
        return np.nan
    n0 = element(kind, p, np.inf if to_inf else 0.0)
    if not (math.isfinite(n0.real) and math.isfinite(n0.imag)) or n0 == 0:
        return np.nan
    nv = v.size
    k = min(max(200_000 // max(nv, 1), 1), 64)
    step_t = 1.0 / k
    slack_eps = -np.inf
    for i in range(eps_v.size):
        if math.isfinite(eps_v[i]) and eps_v[i] > slack_eps:
            slack_eps = eps_v[i]
    slack = math.expm1((slack_eps if slack_eps > -np.inf else _STEP) / k)
    r = np.inf
    for i in range(nv):  # the nodes (t = 0 of every interval, and the last node): G is known there (g[i] is
        val, ok = _room(g[i], n0, slack)  # plant(num, den, delay, math.exp(v[i])), the value evaluated here)
        if not ok:
            return np.nan
        r = _npmin(r, val)
    idx, thr = _reach_index(c, d, 0.5 * r, to_inf)
    if idx < 0 and to_inf:
        return np.nan  # no amplitude of the grid is reached: none for any smaller r either
    an0 = cabs(n0)
    bq0, bq1 = np.empty(2 * k + 2, np.int64), np.empty(2 * k + 2, np.int64)  # a stack of blocks
    for i in range(nv - 1):
        # value(w) = (|1/G(w) + N_lim| - |N_lim| slack) / (1 + slack), and |1/G(w) - 1/G_i| <= |1/G_i| (e^eps - 1)
        e = math.exp(eps_v[i]) * (1 + 1e-12)
        h = cdiv(1.0 + 0j, g[i])
        lb = (cabs(h + n0) - cabs(h) * (e - 1) - an0 * slack) / (1 + slack) * (1 - 1e-9) - 1e-300
        if math.isfinite(e) and math.isfinite(lb) and lb > 0 and thr < 0.5 * lb:
            continue  # no refined frequency of this interval can change the index (nor has no room)
        # the refined frequencies q = 1..k-1 in blocks [q0, q1]: G at q0 evaluated, the rest of the block skipped
        # when the exact variation of G over it keeps every value above the threshold (as for whole intervals)
        bq0[0], bq1[0] = 1, k - 1
        nb = 1
        while nb > 0:
            nb -= 1
            q0, q1 = bq0[nb], bq1[nb]
            x0 = v[i] + (v[i + 1] - v[i]) * (q0 * step_t)
            g0 = plant(num, den, delay, math.exp(x0))
            val, ok = _room(g0, n0, slack)
            if not ok:
                return np.nan
            r = _npmin(r, val)
            if q1 == q0:
                continue
            x1 = v[i] + (v[i + 1] - v[i]) * (q1 * step_t)
            e = math.exp(_variation_bound(zeros, poles, delay, math.exp(x0), math.exp(x1))) * (1 + 1e-12)
            h = cdiv(1.0 + 0j, g0)
            lb = (cabs(h + n0) - cabs(h) * (e - 1) - an0 * slack) / (1 + slack) * (1 - 1e-9) - 1e-300
            if math.isfinite(e) and math.isfinite(lb) and lb > 0 and thr < 0.5 * lb:
                continue
            mid = (q0 + 1 + q1) // 2  # [q0 + 1, mid - 1] and [mid, q1]
            bq0[nb], bq1[nb] = mid, q1
            nb += 1
            if mid - 1 >= q0 + 1:
                bq0[nb], bq1[nb] = q0 + 1, mid - 1
                nb += 1
    idx, thr = _reach_index(c, d, 0.5 * r, to_inf)
    if idx < 0:
        return np.nan
    return _REACH[idx]


@njit(**_OPTS)
def _amplitude_window(num, den, zeros, poles, delay, kind, p, v, g, g_abs, eps_v, lo, hi, tail_c, head_c, head_d):
    """predict._default_amplitude_window for an amplitude-only N: (A_lo, A_hi, case, top, bottom, status);
    case 0: |G N| can reach 1 there, 1: N's amplitude domain (never reaches 1)."""
    top = _limit_reach(num, den, zeros, poles, delay, kind, p, v, g, eps_v, True, tail_c, 0.0)
    bottom = _limit_reach(num, den, zeros, poles, delay, kind, p, v, g, eps_v, False, head_c, head_d)
    if lo > 0:
        cand = lo * (1 + _CAND_ABOVE)
        if top == top:
            cand = np.concatenate((cand, _geomspace(lo, _npmax(top, lo * 2), 200)))
    else:
        cand = _CAND_ALL.copy()
    if math.isfinite(hi):
        cand = np.concatenate((cand, hi * (1 - _CAND_BELOW)))
    if top == top:
        keep = cand[cand < top]
        cand = np.concatenate((keep, np.array([top])))
    if bottom == bottom:
        keep = cand[cand > bottom]
        cand = np.concatenate((np.array([bottom]), keep))
    cand = _unique(cand[(cand > lo) & (cand < hi)])
    nc = cand.size
    if nc < 2:
        return 0.0, 0.0, 2, top, bottom, 9  # a token window: left to the Python driver
    g_lo, g_hi = np.inf, -np.inf
    for i in range(g_abs.size):
        g_lo, g_hi = _npmin(g_lo, g_abs[i]), _npmax(g_hi, g_abs[i])
    # the rows where |G N| can reach 1: only the first and the last are needed, so the intervals between
    # candidates are examined from each end inward, N evaluated only where they reach (the same rows)
    n = np.empty(nc, np.complex128)
    known = np.zeros(nc, np.bool_)
    i0, i1 = -1, -1
    for i in range(nc - 1):
        for k in (i, i + 1):  # N at the candidates not evaluated yet
            if not known[k]:
                n[k] = element(kind, p, cand[k])
                known[k] = True
        lo_row, hi_row = _amplitude_rows(n[i], n[i + 1], g_lo, g_hi)
        if lo_row or hi_row:
            i0 = i if lo_row else i + 1
            break
    if i0 < 0:  # no row: every N was evaluated
        any_n = False
        for i in range(nc):
            any_n |= n[i] != 0
        if not any_n:
            return 0.0, 0.0, 2, top, bottom, 8
        return cand[0], cand[nc - 1], 1, top, bottom, 0
    for i in range(nc - 2, -1, -1):
        for k in (i, i + 1):  # N at the candidates not evaluated yet
            if not known[k]:
                n[k] = element(kind, p, cand[k])
                known[k] = True
        lo_row, hi_row = _amplitude_rows(n[i], n[i + 1], g_lo, g_hi)
        if lo_row or hi_row:
            i1 = i + 1 if hi_row else i
            break
    return cand[max(i0 - 2, 0)], cand[min(i1 + 2, nc - 1)], 0, top, bottom, 0


@njit(**_OPTS)
def _amplitude_rows(n0, n1, g_lo, g_hi):
    """Whether the interval between two candidates, with N = n0 and n1 there, marks its lower and its upper
    candidate as rows where |G N| can reach 1 (predict._default_amplitude_window: N there in the band 1/2..2 of
    |G|'s range, or crossing 1, and varying). Scalars only: a call per interval pays no reference counting."""
    m0, m1 = cabs(n0), cabs(n1)
    cross = (_npmin(m1, m0) * g_lo <= 1.0) and (_npmax(m1, m0) * g_hi >= 1.0)
    varying = cabs(n1 - n0) > 1e-9 * m0
    band0 = (m0 * g_lo <= 2.0) and (m0 * g_hi >= 0.5)
    band1 = (m1 * g_lo <= 2.0) and (m1 * g_hi >= 0.5)
    return (band0 or cross) and varying, (band1 or cross) and varying


# ------------------------------------------------------------------------------------------ cells and windings


@njit(**_OPTS)
def _candidate_cells(ln_n, eps_a, rg, g, eps_v):
    """_kernels.candidate_cells: sorted flat indices i * n_nodes_v + j of the cells that may hold a root, and
    arg G at the nodes where it was needed (NaN elsewhere).

    rg: ln|G| at the frequency nodes (the real part of grid.clog(G)); arg G, its imaginary part, is computed only
    at the nodes of cells whose real parts pass, once each. ln|G| is sorted once (a natural merge sort: one pass
    where |G| is monotone), and each row reads the nodes within its reach by bisection."""
    na, nv = ln_n.size - 1, rg.size - 1
    if na < 1 or nv < 1:
        return np.empty(0, np.int64), np.full(nv + 1, np.nan)
    emax = -np.inf
    for j in range(nv):
        emax = _npmax(emax, eps_v[j])
    order = _order(rg[:nv])  # ln|G| sorted, with eps_v in the same order: the search reads both in sequence
    srt = np.empty(nv)
    srt_e = np.empty(nv)
    for q in range(nv):
        srt[q], srt_e[q] = rg[order[q]], eps_v[order[q]]
    arg_g = np.full(nv + 1, np.nan)
    out = np.empty(64, np.int64)
    n_out = 0
    for i in range(na):
        row_start = n_out
        rn = ln_n[i].real
        reach = eps_a[i] + emax
        slack = 1e-9 * (abs(rn) + reach)
        lo, hi = -rn - reach - slack, -rn + reach + slack
        if lo != lo:
            lo = -np.inf
        if hi != hi:
            hi = np.inf
        for q in range(_bisect(srt, lo, False), _bisect(srt, hi, True)):
            re = rn + srt[q]
            e = eps_a[i] + srt_e[q]
            if abs(re) > e:
                continue
            j = order[q]
            if arg_g[j] != arg_g[j]:
                arg_g[j] = _angle(g[j])
            im = ln_n[i].imag + arg_g[j] - _PI
            if im > _PI:
                im -= _TWO_PI
            elif im < -_PI:
                im += _TWO_PI
            if re * re + im * im <= e * e:
                if n_out == out.size:
                    grow = np.empty(2 * out.size, np.int64)
                    grow[:n_out] = out[:n_out]
                    out = grow
                out[n_out] = i * (nv + 1) + j  # flat index in the node grid
                n_out += 1
        if n_out - row_start > 1:  # this row's cells came in the order of ln|G|: sorted here, so all are (the
            if n_out - row_start > 32:  # rows ascend); a long row by the merge sort
                seg = out[row_start:n_out].copy()
                out[row_start:n_out] = seg[_order(seg)]
            else:
                for q in range(row_start + 1, n_out):
                    x, k = out[q], q
                    while k > row_start and out[k - 1] > x:
                        out[k] = out[k - 1]
                        k -= 1
                    out[k] = x
    return out[:n_out], arg_g


@njit(**_OPTS)
def _edge_phases(num, den, delay, kind, p, continuous, a0, v0, a1, v1, R0, R1):
    """roots.edge_phases: (phase changes, suspects, discontinuities met, points evaluated, status).

    The depths are the Python version's, in its order; the segments of a depth and of the next are kept in two
    sets of work arrays that swap roles (grown when a depth outgrows them), so a depth allocates nothing."""
    m = a0.size
    total = np.zeros(m)
    level = np.empty(m)
    cap = 2 * m + 16
    # this depth's segments and the next's (rows of three work arrays), the phase steps and split flags
    fb, cb, ib = np.empty((9, cap)), np.empty((4, cap), np.complex128), np.empty((2, cap), np.int64)
    ca0, cv0, ca1, cv1, na0, nv0, na1, nv1, d = fb[0], fb[1], fb[2], fb[3], fb[4], fb[5], fb[6], fb[7], fb[8]
    cR0, cR1, nR0, nR1 = cb[0], cb[1], cb[2], cb[3]
    cseg, nseg = ib[0], ib[1]
    split = np.empty(cap, np.bool_)
    for i in range(m):
        ca0[i], cv0[i], ca1[i], cv1[i], cR0[i], cR1[i], cseg[i] = a0[i], v0[i], a1[i], v1[i], R0[i], R1[i], i
    k = m
    n_sus = n_jump = n_terms = 0
    for depth in range(_MAX_EDGE_DEPTH + 1):
        if k > d.size:
            d, split = np.empty(2 * k), np.empty(2 * k, np.bool_)
        n_split = 0
        for i in range(k):
            if cR0[i] == 0 or cR1[i] == 0:
                d[i] = 0.0
                n_sus += 1
            else:
                d[i] = _angle(cdiv(cR1[i], cR0[i]))
            s = abs(d[i]) > _SPLIT
            if s and not continuous and max(abs(ca1[i] - ca0[i]), abs(cv1[i] - cv0[i])) < _JUMP_LENGTH \
                    and cabs(cR1[i] - cR0[i]) > _JUMP_SIZE * (1 + _npmax(cabs(cR0[i] - 1), cabs(cR1[i] - 1))):
                am, vm = (ca0[i] + ca1[i]) / 2, (cv0[i] + cv1[i]) / 2
                Rh = 1.0 + plant(num, den, delay, math.exp(vm)) * element(kind, p, math.exp(am))
                n_terms += 1
                if _npmax(cabs(Rh - cR0[i]), cabs(cR1[i] - Rh)) >= _JUMP_KEEP * cabs(cR1[i] - cR0[i]):
                    n_jump += 1
                    s = False
            split[i] = s
            n_split += s
        if depth == _MAX_EDGE_DEPTH and n_split:
            n_sus += n_split
            split[:k] = False
            n_split = 0
        level[:] = 0.0
        for i in range(k):
            if not split[i]:
                level[cseg[i]] += d[i]
        for i in range(m):
            total[i] += level[i]
        if n_split == 0:
            break
        if 2 * n_split > _MAX_SEGMENTS:
            return total, n_sus, n_jump, n_terms, 6
        if 2 * n_split > na0.size:
            grow = 4 * n_split
            na0, nv0, na1, nv1 = np.empty(grow), np.empty(grow), np.empty(grow), np.empty(grow)
            nR0, nR1, nseg = np.empty(grow, np.complex128), np.empty(grow, np.complex128), np.empty(grow, np.int64)
        j = 0
        for i in range(k):
            if split[i]:
                am, vm = (ca0[i] + ca1[i]) / 2, (cv0[i] + cv1[i]) / 2
                Rm = 1.0 + plant(num, den, delay, math.exp(vm)) * element(kind, p, math.exp(am))
                n_terms += 1
                q = n_split + j
                na0[j], nv0[j], nR0[j], na1[j], nv1[j], nR1[j] = ca0[i], cv0[i], cR0[i], am, vm, Rm
                na0[q], nv0[q], nR0[q], na1[q], nv1[q], nR1[q] = am, vm, Rm, ca1[i], cv1[i], cR1[i]
                nseg[j] = nseg[q] = cseg[i]
                j += 1
        ca0, cv0, ca1, cv1, cR0, cR1, cseg, na0, nv0, na1, nv1, nR0, nR1, nseg = \
            na0, nv0, na1, nv1, nR0, nR1, nseg, ca0, cv0, ca1, cv1, cR0, cR1, cseg
        k = 2 * n_split
    return total, n_sus, n_jump, n_terms, 0


@njit(**_OPTS)
def _dominant_steps(x, k0, k1):
    """Whether roots.dominant_steps finds a step of the samples x[k0:k1] larger than ``_DOMINANCE`` times both
    neighbouring steps (the first and the last step compared with their one neighbour)."""
    m = k1 - k0 - 1
    if m < 2:
        return False
    d = np.empty(m)
    for k in range(m):
        d[k] = cabs(x[k0 + k + 1] - x[k0 + k])
    for k in range(m):
        before = d[1] if k == 0 else d[k - 1]
        after = d[k + 1] if k < m - 1 else d[m - 2]
        if d[k] > _DOMINANCE * _npmax(before, after):
            return True
    return False


@njit(**_OPTS)
def _near_jump(n, g, r0, r1, c0, c1):
    """roots._near_jump on the patch P[r0:r1, c0:c1] of P = n g (outer product): whether a step of P along either
    axis dominates its neighbours. Along the amplitudes every column's steps are |G_c| times N's steps, so one
    column's test is N's own (and a column where G is 0 has no step); along the frequencies likewise with G."""
    any_g = any_n = False
    for c in range(c0, c1):
        any_g |= g[c] != 0
    for r in range(r0, r1):
        any_n |= n[r] != 0
    return (any_g and _dominant_steps(n, r0, r1)) or (any_n and _dominant_steps(g, c0, c1))


@njit(**_OPTS)
def _m(P):
    """_kernels._m: |1 + P|^2 / (1 + |P|^2)."""
    pr, pi = P.real, P.imag
    q = pr * pr + pi * pi
    return (q + 2.0 * pr + 1.0) / (1.0 + q)


@njit(**_OPTS)
def _greedy_unique(a, v, radius):
    """roots.greedy_unique for points sorted by v: mask of the points kept."""
    n = a.size
    keep = np.ones(n, np.bool_)
    rmax = -np.inf
    for i in range(n):
        rmax = _npmax(rmax, radius[i])
    for k in range(n):
        reach = (radius[k] + rmax) * (1 + 1e-9)
        for m in range(k):
            if keep[m] and abs(v[k] - v[m]) <= reach:
                if max(abs(a[k] - a[m]), abs(v[k] - v[m])) <= radius[k] + radius[m]:
                    keep[k] = False
                    break
    return keep


@njit(**_OPTS)
def _columns(x, idx):
    out = np.empty((x.shape[0], idx.size), x.dtype)
    for k in range(idx.size):
        out[:, k] = x[:, idx[k]]
    return out


@njit(**_OPTS)
def _loeb_from(a, v, ra, rv):
    det_log = ra.real * rv.imag - rv.real * ra.imag
    scale = cabs(ra) * cabs(rv)
    cond = det_log / scale if scale > 0 else 0.0
    return det_log / (math.exp(a) * math.exp(v)), cond


@njit(**_OPTS)
def _s_min(ra, rv):
    jaa, jvv = cabs(ra) ** 2, cabs(rv) ** 2
    jav = ra.real * rv.real + ra.imag * rv.imag
    half_tr, dj = (jaa + jvv) / 2, jaa * jvv - jav ** 2
    return math.sqrt(_npmax(half_tr - math.sqrt(_npmax(half_tr ** 2 - dj, 0.0)), 0.0)), jaa, jvv, jav


# ------------------------------------------------------------------------------------------------ the driver


@njit(**_OPTS)
def _cells_apart(zeros, poles, delay, a, v, ln_n, eps_a, g, rg, arg_g, eps_v, ci, cj):
    """Which cells a[i]..a[i+1] x v[j]..v[j+1] (i, j from ci, cj) provably hold no point where |1 + G N| is
    within 0.125 % of 1 + |G N| (bool mask): the cell's N piece (monotone, bounded: the preconditions of
    :func:`_no_root_in`) lies ``_SEED_MARGIN`` beyond both discs of G's piece or beyond its thickened chord.
    arg_g: arg G at the nodes, NaN where not yet computed (filled here). All the cells in one call: a call per
    cell would pay the reference counting of its eleven arrays, more than the test itself costs."""
    apart = np.zeros(ci.size, np.bool_)
    for c in range(ci.size):
        i, j = ci[c], cj[c]
        if not (eps_a[i] <= _STEP and a[i + 1] - a[i] > _MONOTONE_WIDTH * (1 + abs(a[i]))):
            continue
        if not (math.isfinite(ln_n[i].real) and math.isfinite(ln_n[i + 1].real) and math.isfinite(eps_v[j])
                and math.isfinite(rg[j]) and math.isfinite(rg[j + 1])):
            continue
        for q in (j, j + 1):
            if arg_g[q] != arg_g[q]:
                arg_g[q] = _angle(g[q])
        t0, t1 = complex(-rg[j], _PI - arg_g[j]), complex(-rg[j + 1], _PI - arg_g[j + 1])
        if _npmax(_gap(ln_n[i], ln_n[i + 1], t0, eps_v[j]), _gap(ln_n[i], ln_n[i + 1], t1, eps_v[j])) \
                >= _SEED_MARGIN:
            apart[c] = True
            continue
        h = _chord_deviation(zeros, poles, delay, v[j], v[j + 1])
        apart[c] = _chord_gap(ln_n[i], ln_n[i + 1], t0, t1, eps_v[j], h) >= _SEED_MARGIN
    return apart


@njit(**_OPTS)
def _windings(num, den, zeros, poles, delay, kind, p, continuous, a, v, n, g, cells, ln_n, eps_a, rg, arg_g, eps_v):
    """roots.grid_windings on the candidate cells (flat indices): (cells of non-zero winding, their windings,
    status, points evaluated); status 3 for a root on an edge.

    A cell whose four edge steps all turn R by less than pi/2 (with a margin: Re(R1 conj R0) > 1e-6 |Im(..)|)
    winds 0 and splits no edge (its four principal steps sum to exactly 0 of the 2 pi k they must add up to):
    it is passed over without its atan2s, as the full computation would pass it. So is a cell that provably
    holds no point where |1 + G N| is within 0.125 % of 1 + |G N| (:func:`_cells_apart`, the seed exclusion's
    test of one pair of pieces): R has no zero in it, so it winds 0, and its edges (where |R| stays that far
    from 0) are resolved without a suspect; only the count of points evaluated changes."""
    nv = v.size
    n_points = 0
    if cells.size == 0:  # no candidate cell: no winding (and none of the work arrays below)
        return np.empty(0, np.int64), np.empty(0, np.int64), 0, n_points
    hard_c, hard_i = np.empty(cells.size, np.int64), np.empty(cells.size, np.int64)
    hard_j = np.empty(cells.size, np.int64)
    n_hard = 0
    for c in range(cells.size):
        i, j = cells[c] // nv, cells[c] % nv
        r0 = 1.0 + n[i] * g[j]
        r_first = r0
        easy = True
        for q in range(1, 5):
            r1 = r_first if q == 4 else 1.0 + n[i + _CORNER_I[q]] * g[j + _CORNER_J[q]]
            x = r1.real * r0.real + r1.imag * r0.imag
            y = r1.imag * r0.real - r1.real * r0.imag
            if not x > 1e-6 * abs(y):
                easy = False
                break
            r0 = r1
        if not easy:
            hard_c[n_hard], hard_i[n_hard], hard_j[n_hard] = cells[c], i, j
            n_hard += 1
    apart = _cells_apart(zeros, poles, delay, a, v, ln_n, eps_a, g, rg, arg_g, eps_v, hard_i[:n_hard], hard_j[:n_hard])
    keep = np.empty(n_hard, np.int64)
    nc = 0
    for c in range(n_hard):
        if not apart[c]:
            keep[nc] = hard_c[c]
            nc += 1
    cells = keep[:nc]
    # windings of the candidate cells, corners counter-clockwise: (i, j) (i+1, j) (i+1, j+1) (i, j+1)
    ca, cv = np.empty(4 * nc), np.empty(4 * nc)
    Pc = np.empty(4 * nc, np.complex128)
    for c in range(nc):
        i, j = cells[c] // nv, cells[c] % nv
        for q in range(4):
            di, dj = _CORNER_I[q], _CORNER_J[q]
            ca[q * nc + c], cv[q * nc + c] = a[i + di], v[j + dj]
            Pc[q * nc + c] = n[i + di] * g[j + dj]
    d = np.empty(4 * nc)
    hard = np.zeros(4 * nc, np.bool_)
    n_hard = 0
    for e in range(4 * nc):
        f = e + nc if e < 3 * nc else e - 3 * nc
        R0, R1 = 1.0 + Pc[e], 1.0 + Pc[f]
        d[e] = _angle(cdiv(R1, R0))
        hard[e] = abs(d[e]) > _SPLIT or R0 == 0 or R1 == 0
        n_hard += hard[e]
    if n_hard:
        ha0, hv0, ha1, hv1 = np.empty(n_hard), np.empty(n_hard), np.empty(n_hard), np.empty(n_hard)
        hR0, hR1 = np.empty(n_hard, np.complex128), np.empty(n_hard, np.complex128)
        k = 0
        for e in range(4 * nc):
            if hard[e]:
                f = e + nc if e < 3 * nc else e - 3 * nc
                ha0[k], hv0[k], ha1[k], hv1[k] = ca[e], cv[e], ca[f], cv[f]
                hR0[k], hR1[k] = 1.0 + Pc[e], 1.0 + Pc[f]
                k += 1
        tot, n_sus, _, n_terms, status = _edge_phases(num, den, delay, kind, p, continuous, ha0, hv0, ha1, hv1,
                                                      hR0, hR1)
        n_points += n_terms
        if status:
            return np.empty(0, np.int64), np.empty(0, np.int64), status, n_points
        if n_sus:
            return np.empty(0, np.int64), np.empty(0, np.int64), 3, n_points
        k = 0
        for e in range(4 * nc):
            if hard[e]:
                d[e] = tot[k]
                k += 1
    wind_cells = np.empty(nc, np.int64)
    windings = np.empty(nc, np.int64)
    n_wind = 0
    for c in range(nc):
        w = np.rint((((d[c] + d[nc + c]) + d[2 * nc + c]) + d[3 * nc + c]) / _TWO_PI)
        if w != 0:
            wind_cells[n_wind] = cells[c]
            windings[n_wind] = int(w)
            n_wind += 1
    return wind_cells[:n_wind], windings[:n_wind], 0, n_points




@njit(**_OPTS)
def _box_windings(num, den, delay, kind, p, continuous, ka0, ka1, kv0, kv1):
    """roots.box_windings: (windings, status, points evaluated); status 2 where an edge holds a zero of R or meets
    a discontinuity of N (the Python driver records suspects and jump crossings there)."""
    k = ka0.size
    ca = np.concatenate((ka0, ka1, ka1, ka0))
    cv = np.concatenate((kv0, kv0, kv1, kv1))
    R = np.empty(4 * k, np.complex128)
    for e in range(4 * k):
        R[e] = 1.0 + plant(num, den, delay, math.exp(cv[e])) * element(kind, p, math.exp(ca[e]))
    nxt = np.concatenate((np.arange(k, 4 * k), np.arange(k)))
    tot, n_sus, n_jump, n_terms, status = _edge_phases(num, den, delay, kind, p, continuous, ca, cv, ca[nxt],
                                                       cv[nxt], R, R[nxt])
    wind = np.empty(k, np.int64)
    if status == 0 and (n_sus or n_jump):
        status = 2
    for c in range(k):
        wind[c] = int(np.rint((((tot[c] + tot[k + c]) + tot[2 * k + c]) + tot[3 * k + c]) / _TWO_PI))
    return wind, status, 4 * k + n_terms


@njit(**_OPTS)
def _isolate(num, den, zeros, poles, delay, kind, p, continuous, ln_lo, ln_hi, a0, a1, v0, v1, window, tol,
             hinted, hint_a, hint_v):
    """roots._isolate of the box [a0, a1] x [v0, v1] on its common path: quadrisected until its roots sit in boxes
    of winding +-1, those refined (certified) from their centres in the box grown by half, a failed one quadrisected
    further; with a hint (``hinted``: a root refined at (hint_a, hint_v)), the boxes of winding 0 holding it are
    followed too, to the depth bound, where what is left is refined in boxes grown by their size. Returns (status,
    roots a, roots v, their values (5, k), points evaluated), the roots in the order the Python driver finds them.
    Status 2 wherever that driver takes another branch: an edge zero or a discontinuity of N met (suspects, jump
    crossings), more live boxes than its bound, a box of winding +-1 left at the depth bound without a root (its
    chase, or a box it records as unresolved)."""
    win_a0, win_a1, win_v0, win_v1 = window[0], window[1], window[2], window[3]
    qa0, qa1, qv0, qv1 = np.array([a0]), np.array([a1]), np.array([v0]), np.array([v1])
    q_wind = np.zeros(1, np.int64)
    fa, fv = np.empty(0), np.empty(0)
    fvals = np.empty((5, 0), np.complex128)
    n_points = 0
    for _ in range(_MAX_ISOLATE_DEPTH):
        if qa0.size == 0:
            break
        am, vm = (qa0 + qa1) / 2, (qv0 + qv1) / 2
        ka0, ka1 = np.concatenate((qa0, am, qa0, am)), np.concatenate((am, qa1, am, qa1))
        kv0, kv1 = np.concatenate((qv0, qv0, vm, vm)), np.concatenate((vm, vm, qv1, qv1))
        wind, status, n_box = _box_windings(num, den, delay, kind, p, continuous, ka0, ka1, kv0, kv1)
        n_points += n_box
        if status:
            return status, fa, fv, fvals, n_points
        k = ka0.size
        single = np.abs(wind) == 1
        ns = int(single.sum())
        if ns:
            idx = np.nonzero(single)[0]
            sa, sv = np.empty(ns), np.empty(ns)
            lo_a, hi_a, lo_v, hi_v = np.empty(ns), np.empty(ns), np.empty(ns), np.empty(ns)
            for q in range(ns):
                c = idx[q]
                sa[q], sv[q] = (ka0[c] + ka1[c]) / 2, (kv0[c] + kv1[c]) / 2
                ga, gv = (ka1[c] - ka0[c]) * 0.5, (kv1[c] - kv0[c]) * 0.5
                lo_a[q], hi_a[q] = _npmax(ka0[c] - ga, win_a0), _npmin(ka1[c] + ga, win_a1)
                lo_v[q], hi_v[q] = _npmax(kv0[c] - gv, win_v0), _npmin(kv1[c] + gv, win_v1)
            ra, rv, ok, vals, evaluated = refine(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, sa, sv, lo_a,
                                                 hi_a, lo_v, hi_v, tol, True)
            n_points += evaluated
            good = np.zeros(ns, np.bool_)
            for q in range(ns):
                c = idx[q]
                ga, gv = (ka1[c] - ka0[c]) * 1e-9, (kv1[c] - kv0[c]) * 1e-9
                good[q] = ok[q] and (_npmax(ka0[c] - ga, win_a0) <= ra[q] <= _npmin(ka1[c] + ga, win_a1)
                                     and _npmax(kv0[c] - gv, win_v0) <= rv[q] <= _npmin(kv1[c] + gv, win_v1))
                single[c] = good[q]  # failed refinements are subdivided further
            sel = np.nonzero(good)[0]
            fa, fv = np.concatenate((fa, ra[sel])), np.concatenate((fv, rv[sel]))
            fvals = np.concatenate((fvals, _columns(vals, sel)), axis=1)
        live = ~single & (wind != 0)
        if hinted:
            for c in range(k):
                live[c] |= wind[c] == 0 and ka0[c] <= hint_a <= ka1[c] and kv0[c] <= hint_v <= kv1[c]
        keep = np.nonzero(live)[0]
        if keep.size > _MAX_LIVE_BOXES:
            return 2, fa, fv, fvals, n_points
        qa0, qa1, qv0, qv1, q_wind = ka0[keep], ka1[keep], kv0[keep], kv1[keep], wind[keep]
    nq = qa0.size
    if nq:  # the depth bound: what is left is a multiple root smaller than the boxes, refined in them grown
        lo_a, hi_a, lo_v, hi_v = np.empty(nq), np.empty(nq), np.empty(nq), np.empty(nq)
        for q in range(nq):
            ga, gv = qa1[q] - qa0[q], qv1[q] - qv0[q]
            lo_a[q], hi_a[q] = _npmax(qa0[q] - ga, win_a0), _npmin(qa1[q] + ga, win_a1)
            lo_v[q], hi_v[q] = _npmax(qv0[q] - gv, win_v0), _npmin(qv1[q] + gv, win_v1)
        ra, rv, ok, vals, evaluated = refine(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, (qa0 + qa1) / 2,
                                             (qv0 + qv1) / 2, lo_a, hi_a, lo_v, hi_v, tol, False)
        n_points += evaluated
        for q in range(nq):
            if not ok[q] and q_wind[q] != 0:
                return 2, fa, fv, fvals, n_points
        sel = np.nonzero(ok)[0]
        fa, fv = np.concatenate((fa, ra[sel])), np.concatenate((fv, rv[sel]))
        fvals = np.concatenate((fvals, _columns(vals, sel)), axis=1)
    return 0, fa, fv, fvals, n_points


@njit(**_OPTS)
def _variation_bound(zeros, poles, delay, w0, w1):
    """An upper bound on :func:`_variation` in rational arithmetic (grid._interval_bound's terms for one interval,
    every root's magnitude counted by itself, rounding margins added): at most a few % above it on the short
    intervals where it is used, and without its logarithms and arctangents."""
    nr = zeros.size + poles.size
    h = w1 - w0
    rise = fall = pos = neg = 0.0
    for k in range(nr):
        r = zeros[k] if k < zeros.size else poles[k - zeros.size]
        x, y = -r.real, r.imag
        p0, p1 = w0 - y, w1 - y
        d0, d1 = _hypot(x, p0), _hypot(x, p1)
        if p0 < 0 and p1 > 0:  # falls to |x| and rises again
            ax = abs(x)
            up, down = 0.5 * (p1 / ax) * (p1 / d1), 0.5 * (p0 / ax) * (p0 / d0)
        else:
            mono = 0.5 * (h / d0) * (abs(p1 + p0) / d1)
            up, down = (mono, 0.0) if p0 >= 0 else (0.0, mono)
        pp, xx = p0 * p1, x * x
        D = xx + pp
        turn = x * h / D if D > _TAN_OK * (xx + abs(pp)) else math.atan2(x * h, D)
        if k < zeros.size:
            rise, fall = rise + up, fall + down
        else:
            rise, fall, turn = rise + down, fall + up, -turn
        pos += turn if turn > 0 else 0.0
        neg += turn if turn < 0 else 0.0
    scale = 1.0 + SUM_ROUNDING * (nr + 1) + TERM_ROUNDING
    arg = _npmax(pos, -neg + delay * h) * scale + ANGLE_ROUNDING * nr
    return _hypot(arg, _npmax(rise, fall) * scale)


@njit(**_OPTS)
def _variation(zeros, poles, delay, w0, w1):
    """Plant.log_variation on one interval [w0, w1]: the exact bound on |ln G(w) - ln G(w0)| there."""
    rise = fall = pos = neg = 0.0
    for k in range(zeros.size + poles.size):
        r = zeros[k] if k < zeros.size else poles[k - zeros.size]
        sg = 1.0 if k < zeros.size else -1.0
        x, y = -r.real, r.imag
        turn = sg * math.atan2(x * (w1 - w0), x * x + (w0 - y) * (w1 - y))
        m0 = 0.5 * math.log(x * x + (w0 - y) * (w0 - y))
        m1 = 0.5 * math.log(x * x + (w1 - y) * (w1 - y))
        low = math.log(abs(x)) if (w0 < y and y < w1) else _npmin(m0, m1)
        rise += (m1 - low) if sg > 0 else (m0 - low)
        fall += (m0 - low) if sg > 0 else (m1 - low)
        pos += turn if turn > 0 else 0.0
        neg += turn if turn < 0 else 0.0
    return math.hypot(_npmax(pos, -neg + delay * (w1 - w0)), _npmax(rise, fall))


@njit(**_OPTS)
def _wrap(d):
    """d wrapped to [-pi, pi) (d within (-5 pi, 5 pi): sums and differences of two args and pi)."""
    for _ in range(2):
        if d >= _PI:
            d -= _TWO_PI
        elif d < -_PI:
            d += _TWO_PI
    return d


@njit(**_OPTS)
def _gap(l0, l1, t, e):
    """How far (log units, arg taken modulo 2 pi) the rectangle spanned by l0, l1 (ln N at the ends of a piece on
    which ln|N| and arg N are monotone and arg N turns by less than pi) lies from the disc of radius e around t
    (j pi - ln G at the left end of a piece of G, e the exact bound of ln G's change on it)."""
    x0, x1 = _npmin(l0.real, l1.real), _npmax(l0.real, l1.real)
    dy = _wrap(l1.imag - l0.imag)
    yc, hy = l0.imag + 0.5 * dy, 0.5 * abs(dy)
    dx = _npmax(_npmax(x0 - t.real, t.real - x1), 0.0)
    dd = _npmax(abs(_wrap(t.imag - yc)) - hy, 0.0)
    return math.sqrt(dx * dx + dd * dd) - e


@njit(**_OPTS)
def _close_ends(l0, l1, t0, t1):
    """Whether an end of the N piece (l0, l1) lies within ``_SEED_MARGIN`` of an end of the G piece (t0, t1), arg
    modulo 2 pi: a point of the box where the curves are that close, so no halving can prove the box (every pair
    of pieces holding both points fails both tests), and :func:`_no_root_in` would fail at its budget anyway."""
    for l in (l0, l1):
        for t in (t0, t1):
            if math.hypot(l.real - t.real, _wrap(l.imag - t.imag)) < _SEED_MARGIN:
                return True
    return False


@njit(**_OPTS)
def _grown(pn, pg, top):
    """The stack (pn, pg) of size top with twice the room (called only when a push finds it full: a call per push
    would pay its arrays' reference counting every time)."""
    gn, gg = np.empty(2 * pn.size + 2, np.int64), np.empty(2 * pn.size + 2, np.int64)
    gn[:top], gg[:top] = pn[:top], pg[:top]
    return gn, gg


@njit(**_OPTS)
def _no_root_in(zeros, poles, num, den, delay, kind, p, a, v, ln_n, eps_a, g, rg, arg_g, eps_v, i0, i1, j0, j1):
    """roots.seed_excluded: whether the box a[i0]..a[i1] x v[j0]..v[j1] provably holds no point where
    |1 + G N| is within 0.125 % of 1 + |G N| (nothing the refinement could accept): a pair of pieces is apart
    beyond the two discs of G's variation bound or beyond G's thickened chord (grid.chord_gap, its deviation
    computed only where the discs do not already separate). The pieces of N and of G are binary trees (a piece
    halved once, its halves shared by every pair that reads them); arg_g: arg G at the nodes, NaN where not yet
    computed (filled here)."""
    for j in range(j0, j1 + 1):
        if not math.isfinite(rg[j]):
            return False
        if arg_g[j] != arg_g[j]:
            arg_g[j] = _angle(g[j])
    for i in range(i0, i1):
        if not (eps_a[i] <= _STEP) or not (a[i + 1] - a[i] > _MONOTONE_WIDTH * (1 + abs(a[i]))):
            return False
        if not (math.isfinite(ln_n[i].real) and math.isfinite(ln_n[i + 1].real)):
            return False
    for j in range(j0, j1):
        if not math.isfinite(eps_v[j]):
            return False
    apart = True  # the grid's own pieces first: most boxes need no halving (and no work arrays)
    for j in range(j0, j1):
        t0, t1 = complex(-rg[j], _PI - arg_g[j]), complex(-rg[j + 1], _PI - arg_g[j + 1])
        h = np.inf
        for i in range(i0, i1):
            if _npmax(_gap(ln_n[i], ln_n[i + 1], t0, eps_v[j]), _gap(ln_n[i], ln_n[i + 1], t1, eps_v[j])) \
                    >= _SEED_MARGIN:
                continue
            if h == np.inf:
                h = _chord_deviation(zeros, poles, delay, v[j], v[j + 1])
            if _chord_gap(ln_n[i], ln_n[i + 1], t0, t1, eps_v[j], h) < _SEED_MARGIN:
                apart = False
                break
        if not apart:
            break
    if apart:
        return True
    n_n, n_g = i1 - i0, j1 - j0
    cn, cg = n_n + 2 * _SEED_SPLITS, n_g + 2 * _SEED_SPLITS
    pa0, pa1, pc = np.empty(cn), np.empty(cn), np.full(cn, -1, np.int64)
    pl0, pl1 = np.empty(cn, np.complex128), np.empty(cn, np.complex128)
    for i in range(i0, i1):  # N pieces: the grid's intervals, then halves
        if not (eps_a[i] <= _STEP) or not (a[i + 1] - a[i] > _MONOTONE_WIDTH * (1 + abs(a[i]))):
            return False
        if not (math.isfinite(ln_n[i].real) and math.isfinite(ln_n[i + 1].real)):
            return False
        pa0[i - i0], pa1[i - i0], pl0[i - i0], pl1[i - i0] = a[i], a[i + 1], ln_n[i], ln_n[i + 1]
    qv0, qv1, qe, qc = np.empty(cg), np.empty(cg), np.empty(cg), np.full(cg, -1, np.int64)
    qt0, qt1 = np.empty(cg, np.complex128), np.empty(cg, np.complex128)
    qh = np.full(cg, np.nan)  # the G pieces' chord deviations, computed where the discs do not separate a pair
    for j in range(j0, j1):  # G pieces: the grid's intervals (j pi - ln G at their ends), then halves
        if not math.isfinite(eps_v[j]):
            return False
        qv0[j - j0], qv1[j - j0], qe[j - j0] = v[j], v[j + 1], eps_v[j]
        qt0[j - j0] = complex(-rg[j], _PI - arg_g[j])
        qt1[j - j0] = complex(-rg[j + 1], _PI - arg_g[j + 1])
    pn, pg = np.empty(2 * n_n * n_g + 16, np.int64), np.empty(2 * n_n * n_g + 16, np.int64)
    top = 0
    for x in range(n_n):
        for y in range(n_g):
            pn[top], pg[top] = x, y
            top += 1
    splits = tests = 0
    while top > 0:
        top -= 1
        x, y = pn[top], pg[top]
        l0, l1, e = pl0[x], pl1[x], qe[y]
        tests += 1
        lens = _npmax(_gap(l0, l1, qt0[y], e), _gap(l0, l1, qt1[y], e))
        if lens >= _SEED_MARGIN:
            continue
        if qh[y] != qh[y]:
            qh[y] = _chord_deviation(zeros, poles, delay, qv0[y], qv1[y])
        chord = _chord_gap(l0, l1, qt0[y], qt1[y], e, qh[y])
        if chord >= _SEED_MARGIN:
            continue
        if tests > _SEED_TESTS or _close_ends(l0, l1, qt0[y], qt1[y]):
            return False
        # the piece whose uncertainty binds the better test: G's is h against its chord, e against the discs
        if math.hypot(l1.real - l0.real, _wrap(l1.imag - l0.imag)) >= (qh[y] if chord >= lens else e):
            if pc[x] < 0:
                splits += 1
                if splits > _SEED_SPLITS:
                    return False
                xm = 0.5 * (pa0[x] + pa1[x])
                nm = element(kind, p, math.exp(xm))
                if not (math.isfinite(nm.real) and math.isfinite(nm.imag)) or nm == 0:
                    return False
                lm = _clog(nm)
                c = pc[x] = n_n
                n_n += 2
                pa0[c], pa1[c], pl0[c], pl1[c] = pa0[x], xm, l0, lm
                pa0[c + 1], pa1[c + 1], pl0[c + 1], pl1[c + 1] = xm, pa1[x], lm, l1
            if top + 2 > pn.size:
                pn, pg = _grown(pn, pg, top)
            pn[top], pg[top], pn[top + 1], pg[top + 1] = pc[x], y, pc[x] + 1, y
            top += 2
        else:  # the G piece's halves
            if qc[y] < 0:
                splits += 1
                if splits > _SEED_SPLITS:
                    return False
                xm = 0.5 * (qv0[y] + qv1[y])
                w0, wm, w1 = math.exp(qv0[y]), math.exp(xm), math.exp(qv1[y])
                gm = plant(num, den, delay, wm)
                if not (math.isfinite(gm.real) and math.isfinite(gm.imag)) or gm == 0:
                    return False
                lgm = _clog(gm)
                tm = complex(-lgm.real, _PI - lgm.imag)
                e0, e1 = _variation(zeros, poles, delay, w0, wm), _variation(zeros, poles, delay, wm, w1)
                if not (math.isfinite(e0) and math.isfinite(e1)):
                    return False
                c = qc[y] = n_g
                n_g += 2
                qv0[c], qv1[c], qt0[c], qt1[c], qe[c] = qv0[y], xm, qt0[y], tm, e0
                qv0[c + 1], qv1[c + 1], qt0[c + 1], qt1[c + 1], qe[c + 1] = xm, qv1[y], tm, qt1[y], e1
            if top + 2 > pn.size:
                pn, pg = _grown(pn, pg, top)
            pn[top], pg[top], pn[top + 1], pg[top + 1] = x, qc[y], x, qc[y] + 1
            top += 2
    return True


@njit(**_OPTS)
def _tangent_seeds(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, a, v, n, g, cells, wind_cells, tol, ln_n,
                   eps_a, rg, arg_g, eps_v):
    """The tangent seeds of roots.find_roots and their refinement (with the wider retry next to a jump): (status,
    points evaluated, the seeds that refined to a root: their (a, v), values (5, k) and boxes (a0, a1, v0, v1)).
    Seeds whose boxes provably hold nothing a refinement could accept (:func:`_no_root_in`) are not refined."""
    nc, nv, nA, n_wind = cells.size, v.size, a.size, wind_cells.size
    n_points = 0
    none = np.empty(0)
    if nc == 0:  # no candidate cell: no corner, so no seed
        return 0, n_points, none, none, np.empty((5, 0), np.complex128), none, none, none, none
    # tangent seeds: local minima of m below the threshold among the corners of the candidate cells
    # a cell's flat index is its lower-left corner's (i nv + j), and the cells ascend: the corners are the union
    # of four ascending runs, merged in two steps
    lower = _merge_unique(cells, cells + 1)
    nodes = _merge_unique(lower, lower + nv)
    excl = np.empty(16 * n_wind, np.int64)
    n_ex = 0
    for c in range(n_wind):
        i, j = wind_cells[c] // nv, wind_cells[c] % nv
        for di in range(-1, 3):
            for dj in range(-1, 3):
                x, y = i + di, j + dj
                if 0 <= x < nA and 0 <= y < nv:
                    excl[n_ex] = x * nv + y
                    n_ex += 1
    excl = excl[:n_ex]
    excl = excl[_order(excl)]
    seeds = np.empty(nodes.size, np.int64)
    n_seed = 0
    i, row_start = 0, 0  # the nodes ascend: their row follows without a division
    for node in nodes:
        q = _bisect(excl, node, False)
        if q < n_ex and excl[q] == node:
            continue
        while node >= row_start + nv:
            i += 1
            row_start += nv
        j = node - row_start
        x = _m(n[i] * g[j])
        if x >= _TANGENT:
            continue
        low = True
        for di in range(-1, 2):
            for dj in range(-1, 2):
                if (di or dj) and 0 <= i + di < nA and 0 <= j + dj < nv:
                    if _m(n[i + di] * g[j + dj]) < x:
                        low = False
                        break
            if not low:
                break
        if low:
            seeds[n_seed] = node
            n_seed += 1
    if n_seed > _MAX_SEEDS:
        return 6, n_points, none, none, np.empty((5, 0), np.complex128), none, none, none, none
    n_kept = 0
    for s in range(n_seed):  # roots.seed_excluded: no refinement of the seed could succeed
        i, j = seeds[s] // nv, seeds[s] % nv
        if _no_root_in(zeros, poles, num, den, delay, kind, p, a, v, ln_n, eps_a, g, rg, arg_g, eps_v,
                       max(i - 2, 0), min(i + 2, nA - 1), max(j - 2, 0), min(j + 2, nv - 1)):
            r0, r1, c0, c1 = max(i - 4, 0), min(i + 5, nA), max(j - 4, 0), min(j + 5, nv)
            if not _near_jump(n, g, r0, r1, c0, c1):
                continue  # no wider retry either
            if _no_root_in(zeros, poles, num, den, delay, kind, p, a, v, ln_n, eps_a, g, rg, arg_g, eps_v,
                           max(i - 3, 0), min(i + 3, nA - 1), max(j - 3, 0), min(j + 3, nv - 1)):
                continue
        seeds[n_kept] = seeds[s]
        n_kept += 1
    n_seed = n_kept
    if n_seed:
        ta, tv = np.empty(n_seed), np.empty(n_seed)
        b0a, b1a, b0v, b1v = np.empty(n_seed), np.empty(n_seed), np.empty(n_seed), np.empty(n_seed)
        for s in range(n_seed):
            i, j = seeds[s] // nv, seeds[s] % nv
            ta[s], tv[s] = a[i], v[j]
            b0a[s], b1a[s] = a[max(i - 2, 0)], a[min(i + 2, nA - 1)]
            b0v[s], b1v[s] = v[max(j - 2, 0)], v[min(j + 2, nv - 1)]
        xa, xv, tok, tvals, evaluated = refine(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, ta, tv,
                                               b0a, b1a, b0v, b1v, tol, False)
        n_points += evaluated
        for s in range(n_seed):
            pinned = xa[s] == b0a[s] or xa[s] == b1a[s] or xv[s] == b0v[s] or xv[s] == b1v[s]
            if tok[s] or not pinned:
                continue
            i, j = seeds[s] // nv, seeds[s] % nv
            r0, r1, c0, c1 = max(i - 4, 0), min(i + 5, nA), max(j - 4, 0), min(j + 5, nv)
            if _near_jump(n, g, r0, r1, c0, c1):  # one more try in a wider box
                b0a[s], b1a[s] = a[max(i - 3, 0)], a[min(i + 3, nA - 1)]
                b0v[s], b1v[s] = v[max(j - 3, 0)], v[min(j + 3, nv - 1)]
                wa, wv, wok, wvals, evaluated = refine(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi,
                                                       np.array([a[i]]), np.array([v[j]]), b0a[s:s + 1],
                                                       b1a[s:s + 1], b0v[s:s + 1], b1v[s:s + 1], tol, False)
                n_points += evaluated
                xa[s], xv[s], tok[s] = wa[0], wv[0], wok[0]
                tvals[:, s] = wvals[:, 0]
        hit = np.nonzero(tok)[0]
        return (0, n_points, xa[hit], xv[hit], _columns(tvals, hit), b0a[hit], b1a[hit], b0v[hit], b1v[hit])
    return 0, n_points, none, none, np.empty((5, 0), np.complex128), none, none, none, none


@njit(**_OPTS)
def _finish(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, ra, rv, vals, windows, tol, marginal_tol):
    """The continuum test, roots.merge and predict._build on the refined roots (ra, rv) with their values vals
    (P, P_a, P_v, G, N): (status, rejected, points evaluated, result rows)."""
    n_wind = ra.size
    win_a0, win_a1, win_v0, win_v1 = windows[0], windows[1], windows[2], windows[3]
    empty = np.empty((0, 10), np.complex128)
    n_points = 0
    # the continuum test (refined roots: up to 16 picked, none may be degenerate) ...
    npick = min(n_wind, 16)
    pick = _linspace(0.0, n_wind - 1.0, npick)
    for q in range(npick):
        k = int(pick[q])
        da_, dv_ = vals[1, k], vals[2, k]
        sin = abs(da_.real * dv_.imag - dv_.real * da_.imag) / (cabs(da_) * cabs(dv_))
        if not math.isfinite(sin):
            sin = 0.0
        if sin < _DEGENERATE_SIN:
            return 5, 0, n_points, empty
    # ... then roots.merge: sorted by v (then a), same root within 1e-12 plus four position uncertainties
    order = np.arange(n_wind)
    for x in range(1, n_wind):  # a stable insertion sort by (v, a): np.lexsort((a, v))
        y = x
        while y > 0 and (rv[order[y - 1]] > rv[order[y]]
                         or (rv[order[y - 1]] == rv[order[y]] and ra[order[y - 1]] > ra[order[y]])):
            order[y - 1], order[y] = order[y], order[y - 1]
            y -= 1
    ma, mv = ra[order], rv[order]
    mvals = np.empty((5, n_wind), np.complex128)
    for k in range(n_wind):
        mvals[:, k] = vals[:, order[k]]
    if n_wind >= 2:
        radius = np.empty(n_wind)
        for k in range(n_wind):
            s_min = _s_min(mvals[1, k], mvals[2, k])[0]
            rad = _MERGE_RADIUS + 4 * (cabs(1 + mvals[0, k]) / s_min if s_min > 0 else np.inf)
            radius[k] = min(rad, 1e-2)
        idx = np.nonzero(_greedy_unique(ma, mv, radius))[0]
        ma, mv, mvals = ma[idx], mv[idx], _columns(mvals, idx)
    # predict._build: the residual bound, then the Loeb labels
    k_all = ma.size
    good = np.empty(k_all, np.bool_)
    rejected = 0
    for k in range(k_all):
        good[k] = accepted(mvals[0, k], mvals[1, k], mvals[2, k], ma[k], mv[k], tol)
        rejected += not good[k]
    idx = np.nonzero(good)[0]
    ma, mv, mvals = ma[idx], mv[idx], _columns(mvals, idx)
    k_all = ma.size
    det = np.empty(k_all)
    cond = np.empty(k_all)
    label = np.empty(k_all, np.int64)
    dx_, ea_, ev_ = np.empty(k_all), np.empty(k_all), np.empty(k_all)
    for k in range(k_all):
        P, ra_, rv_ = mvals[0, k], mvals[1, k], mvals[2, k]
        det[k], cond[k] = _loeb_from(ma[k], mv[k], ra_, rv_)
        s_min, jaa, jvv, jav = _s_min(ra_, rv_)
        dx_[k] = min(4 * cabs(1 + P) / s_min if s_min > 0 else np.inf, 1e-2)
        ea, ev = jav, s_min ** 2 - jaa
        if math.hypot(ea, ev) == 0:
            ea, ev = (1.0, 0.0) if jaa <= jvv else (0.0, 1.0)
        nrm = math.hypot(ea, ev)
        ea_[k], ev_[k] = ea / nrm, ev / nrm
    for k in range(k_all):
        sd = _sign(det[k])
        undecided = False
        for side in range(2):
            if side == 0:
                ap, vp = ma[k] + dx_[k] * ea_[k], mv[k] + dx_[k] * ev_[k]
            else:
                ap, vp = ma[k] - dx_[k] * ea_[k], mv[k] - dx_[k] * ev_[k]
            _, pa, pv, _, _ = slopes_at(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, ap, vp)
            undecided |= _sign(_loeb_from(ap, vp, pa, pv)[0]) != sd
        n_points += 6
        if abs(cond[k]) < marginal_tol or undecided:
            label[k] = MARGINAL
        else:
            label[k] = STABLE if det[k] > 0 else UNSTABLE
    n_marg = 0
    for k in range(k_all):
        n_marg += label[k] == MARGINAL
    keep = np.ones(k_all, np.bool_)
    if n_marg > 1:  # a double root reached from several seeds: marginal roots within 1e-4 merged
        idx = np.empty(n_marg, np.int64)
        q = 0
        for k in range(k_all):
            if label[k] == MARGINAL:
                idx[q] = k
                q += 1
        kept = _greedy_unique(ma[idx], mv[idx], np.full(n_marg, 0.5e-4))  # sorted by v since the merge
        for q in range(n_marg):
            keep[idx[q]] = kept[q]
    out = np.empty((int(keep.sum()), 10), np.complex128)
    rnd = np.empty(k_all)
    for k in range(k_all):
        rnd[k] = np.rint(mv[k] * 1e10) / 1e10
    # np.lexsort((A, round(v, 10))): by rounded frequency, then amplitude (stable)
    order = np.nonzero(keep)[0]
    for x in range(1, order.size):
        y = x
        before, here = order[y - 1], order[y]
        while y > 0 and (rnd[before] > rnd[here] or (rnd[before] == rnd[here]
                                                     and math.exp(ma[before]) > math.exp(ma[here]))):
            order[y - 1], order[y] = order[y], order[y - 1]
            y -= 1
            if y > 0:
                before, here = order[y - 1], order[y]
    for q in range(order.size):
        k = order[q]
        A, w = math.exp(ma[k]), math.exp(mv[k])
        gk, nk = mvals[3, k], mvals[4, k]
        r = 1 + gk * nk
        edge = (abs(ma[k] - win_a0) <= _EDGE_TOL or abs(ma[k] - win_a1) <= _EDGE_TOL
                or abs(mv[k] - win_v0) <= _EDGE_TOL or abs(mv[k] - win_v1) <= _EDGE_TOL)
        res = cabs(r)
        rel = res / (1 + cabs(gk * nk))
        for val in (A, w, det[k], cond[k], res):
            if not math.isfinite(val):
                return 7, 0, n_points, empty
        if not (math.isfinite(nk.real) and math.isfinite(nk.imag)):
            return 9, 0, n_points, empty
        out[q, 0], out[q, 1], out[q, 2], out[q, 3], out[q, 4] = A, w, det[k], cond[k], label[k]
        out[q, 5], out[q, 6], out[q, 7], out[q, 8], out[q, 9] = res, rel, gk, nk, edge
    return 0, rejected, n_points, out


@njit(**_OPTS)
def _drive(num, den, zeros, poles, delay, kind, p, continuous, ln_lo, ln_hi, dom_lo, dom_hi, tail_c, head_c, head_d, bp,
           w_lo, w_hi, A_lo, A_hi, na, nw, tol, marginal_tol, mem_limit, bytes_per_point):
    """One loop end to end. Returns (status, floats, ints, roots): floats = (A_lo, A_hi, w_lo, w_hi, top, bottom,
    max step along w, max step along A, smallest and largest |pole/zero|), ints = (amplitude window case, grid
    rows, grid columns, jump intervals, candidate cells, evaluations for the grid, points evaluated, rejected,
    unstable real pole), roots = (k, 10) complex rows (A, w, det, cond, label, |1+GN|, relative residual, G, N,
    on edge)."""
    fl = np.full(10, np.nan)
    it = np.zeros(9, np.int64)
    empty = np.empty((0, 10), np.complex128)
    if zeros.size + poles.size > _MAX_PAIRWISE:
        return 11, fl, it, empty
    for i in range(poles.size):
        q = poles[i]
        if q.real > 0 and abs(q.imag) <= 1e-9 * cabs(q):
            it[8] = 1
    mag_lo, mag_hi = np.inf, -np.inf
    for r in (zeros, poles):
        for i in range(r.size):
            x = r[i]
            if math.isfinite(x.real) and math.isfinite(x.imag):
                mg = cabs(x)
                if mg > 0:
                    mag_lo, mag_hi = min(mag_lo, mg), max(mag_hi, mg)
    fl[8], fl[9] = mag_lo, mag_hi
    if w_lo != w_lo:  # default: two decades beyond the poles and zeros
        if mag_lo == np.inf:
            w_lo, w_hi = 1e-2, 1e2
        else:
            w_lo, w_hi = mag_lo * _WIN_LO, mag_hi * _WIN_HI
    fl[2], fl[3] = w_lo, w_hi
    for w in (w_lo, w_hi):
        g = plant(num, den, delay, w)
        if not (math.isfinite(g.real) and math.isfinite(g.imag)):
            return 8, fl, it, empty
    v = _linspace(math.log(w_lo), math.log(w_hi), nw)
    v, w_nodes, eps_v, status = _resolve_plant(zeros, poles, delay, v)
    if status:
        return status, fl, it, empty
    nv = v.size
    g = np.empty(nv, np.complex128)
    g_abs = np.empty(nv)
    any_g = False
    for j in range(nv):
        g[j] = plant(num, den, delay, w_nodes[j])
        if not (math.isfinite(g[j].real) and math.isfinite(g[j].imag)):
            return 8, fl, it, empty
        g_abs[j] = cabs(g[j])
        any_g |= g[j] != 0
    if not any_g:
        return 8, fl, it, empty
    n_eval = nv
    if A_lo != A_lo:
        A_lo, A_hi, case, top, bottom, status = _amplitude_window(num, den, zeros, poles, delay, kind, p, v, g, g_abs,
                                                                  eps_v, dom_lo, dom_hi, tail_c, head_c, head_d)
        if status:
            return status, fl, it, empty
        it[0] = case
        fl[4], fl[5] = top, bottom
    fl[0], fl[1] = A_lo, A_hi
    a = _linspace(math.log(A_lo), math.log(A_hi), na)
    if bp == bp and A_lo < bp < A_hi:
        a = _unique(np.concatenate((a, np.array([math.log(bp)]))))
    a, n, eps_a, n_n, status = _resolve_element(kind, p, a)
    if status:
        return status, fl, it, empty
    n_eval += n_n
    nA = a.size
    if bytes_per_point * nA * nv > mem_limit:
        return 8, fl, it, empty
    any_n = False
    for i in range(nA):
        any_n |= n[i] != 0
    if not any_n:
        return 8, fl, it, empty
    it[1], it[2], it[5] = nA, nv, n_eval
    big_v = big_a = 0.0
    jumps = 0
    for e in eps_v:
        if e <= _STEP:
            big_v = max(big_v, e)
        jumps += e > _STEP
    for e in eps_a:
        if e <= _STEP:
            big_a = max(big_a, e)
        jumps += e > _STEP
    fl[6], fl[7], it[3] = big_v, big_a, jumps
    ln_n = np.empty(nA, np.complex128)
    rg = np.empty(nv)
    for i in range(nA):
        ln_n[i] = _clog(n[i])
    for j in range(nv):
        rg[j] = math.log(g_abs[j])  # the real part of _clog(g[j])
    cells, arg_g = _candidate_cells(ln_n, eps_a, rg, g, eps_v)
    nc = cells.size
    it[4] = nc
    n_points = 0
    nz_cells, windings, status, n_terms = _windings(num, den, zeros, poles, delay, kind, p, continuous, a, v, n, g,
                                                    cells, ln_n, eps_a, rg, arg_g, eps_v)
    n_points += n_terms
    if status:
        return status, fl, it, empty
    n_hard = 0
    for c in range(nz_cells.size):
        n_hard += abs(windings[c]) != 1
    if n_hard > _EARLY_CONTINUUM_CHECK:
        return 1, fl, it, empty  # the Python driver looks for a curve of zeros first
    wind_cells = nz_cells[np.abs(windings) == 1]
    n_wind = wind_cells.size
    # refinement of the single-winding cells from the linear model's root, in the cell grown by half
    win_a0, win_a1, win_v0, win_v1 = a[0], a[nA - 1], v[0], v[nv - 1]
    window = np.array([win_a0, win_a1, win_v0, win_v1])
    if nz_cells.size == 0:  # no cell winds: nothing to refine or isolate (nor the work arrays for it)
        ra, rv = np.empty(0), np.empty(0)
        vals = np.empty((5, 0), np.complex128)
    else:
        sa, sv = np.empty(n_wind), np.empty(n_wind)
        lo_a, hi_a, lo_v, hi_v = np.empty(n_wind), np.empty(n_wind), np.empty(n_wind), np.empty(n_wind)
        for c in range(n_wind):
            i, j = wind_cells[c] // nv, wind_cells[c] % nv
            r00, r10 = 1 + n[i] * g[j], 1 + n[i + 1] * g[j]
            r01, r11 = 1 + n[i] * g[j + 1], 1 + n[i + 1] * g[j + 1]
            cl_a, ch_a, cl_v, ch_v = a[i], a[i + 1], v[j], v[j + 1]
            ha, hv = ch_a - cl_a, ch_v - cl_v
            ja = cdiv(r10 - r00 + r11 - r01, complex(2 * ha, 0.0))
            jv = cdiv(r01 - r00 + r11 - r10, complex(2 * hv, 0.0))
            rc = cdiv(r00 + r10 + r01 + r11, complex(4.0, 0.0))
            det = ja.real * jv.imag - jv.real * ja.imag
            da = -(jv.imag * rc.real - jv.real * rc.imag) / det
            dv = -(-ja.imag * rc.real + ja.real * rc.imag) / det
            if not math.isfinite(da):
                da = 0.0
            if not math.isfinite(dv):
                dv = 0.0
            sa[c] = min(max((cl_a + ch_a) / 2 + da, cl_a), ch_a)
            sv[c] = min(max((cl_v + ch_v) / 2 + dv, cl_v), ch_v)
            ga, gv = ha * 0.5, hv * 0.5
            lo_a[c], hi_a[c] = _npmax(cl_a - ga, win_a0), _npmin(ch_a + ga, win_a1)
            lo_v[c], hi_v[c] = _npmax(cl_v - gv, win_v0), _npmin(ch_v + gv, win_v1)
        ra, rv, ok, vals, evaluated = refine(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, sa, sv, lo_a, hi_a,
                                             lo_v, hi_v, tol, False)
        n_points += evaluated
        failed = np.zeros(n_wind, np.bool_)
        for c in range(n_wind):
            i, j = wind_cells[c] // nv, wind_cells[c] % nv
            cl_a, ch_a, cl_v, ch_v = a[i], a[i + 1], v[j], v[j + 1]
            ga, gv = (ch_a - cl_a) * 1e-9, (ch_v - cl_v) * 1e-9
            inside = (_npmax(cl_a - ga, win_a0) <= ra[c] <= _npmin(ch_a + ga, win_a1)
                      and _npmax(cl_v - gv, win_v0) <= rv[c] <= _npmin(ch_v + gv, win_v1))
            failed[c] = not (ok[c] and inside)
        kept = np.nonzero(~failed)[0]
        ra, rv, vals = ra[kept], rv[kept], _columns(vals, kept)
        # cells winding more than once, then the single-winding cells whose refinement failed: isolated (roots._isolate)
        for box_cells in (nz_cells[np.abs(windings) != 1], wind_cells[failed]):
            for c in range(box_cells.size):
                i, j = box_cells[c] // nv, box_cells[c] % nv
                status, xa, xv, xvals, n_iso = _isolate(num, den, zeros, poles, delay, kind, p, continuous, ln_lo,
                                                        ln_hi, a[i], a[i + 1], v[j], v[j + 1], window, tol, False,
                                                        0.0, 0.0)
                n_points += n_iso
                if status:
                    return status, fl, it, empty
                ra, rv = np.concatenate((ra, xa)), np.concatenate((rv, xv))
                vals = np.concatenate((vals, xvals), axis=1)
    status, n_seed_points, ta, tv, tvals, b0a, b1a, b0v, b1v = _tangent_seeds(
        num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, a, v, n, g, cells, nz_cells, tol, ln_n, eps_a, rg, arg_g,
        eps_v)
    n_points += n_seed_points
    if status:
        return status, fl, it, empty
    # a seed that refined to a root the windings did not show: everything in its box isolated, then the root itself
    for s in range(ta.size):
        status, xa, xv, xvals, n_iso = _isolate(num, den, zeros, poles, delay, kind, p, continuous, ln_lo, ln_hi,
                                                b0a[s], b1a[s], b0v[s], b1v[s], window, tol, True, ta[s], tv[s])
        n_points += n_iso
        if status:
            return status, fl, it, empty
        ra, rv = np.concatenate((ra, xa, ta[s:s + 1])), np.concatenate((rv, xv, tv[s:s + 1]))
        vals = np.concatenate((vals, xvals, tvals[:, s:s + 1]), axis=1)
    if ra.size == 0:
        it[6] = n_points
        return 0, fl, it, empty
    status, rejected, n_fin, out = _finish(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, ra, rv, vals,
                                           window, tol, marginal_tol)
    n_points += n_fin
    if status:
        return status, fl, it, empty
    it[7] = rejected
    it[6] = n_points
    return 0, fl, it, out


@njit(**_OPTS)
def _drive_one(num, den, zeros, poles, delay, kind, p, continuous, ln_lo, ln_hi, dom_lo, dom_hi, tail_c, head_c,
               head_d, bp, w_lo, w_hi, A_lo, A_hi, na, nw, tol, marginal_tol, mem_limit, bytes_per_point):
    return _drive(num, den, zeros, poles, delay, kind, p, continuous, ln_lo, ln_hi, dom_lo, dom_hi, tail_c, head_c,
                  head_d, bp, w_lo, w_hi, A_lo, A_hi, na, nw, tol, marginal_tol, mem_limit, bytes_per_point)


@njit(**_OPTS)
def _drive_rows(num, n_num, den, n_den, zeros, n_zeros, poles, n_poles, delay, kind, p, continuous, ln_lo, ln_hi,
                dom_lo, dom_hi, tail_c, head_c, head_d, bp, w_lo, w_hi, A_lo, A_hi, na, nw, tol, marginal_tol,
                mem_limit, bytes_per_point, start, stop, status, fl, it, roots, count):
    """_drive over the loops start..stop - 1 of a batch (rows of the arguments; num, den padded), written into
    their rows of the outputs (status, floats, ints, roots (L, MAX_ROOTS, 10), root counts). Releases the GIL:
    threads run disjoint row ranges at once."""
    for k in range(start, stop):
        s, f, i, r = _drive(num[k, :n_num[k]].copy(), den[k, :n_den[k]].copy(), zeros[k, :n_zeros[k]].copy(),
                            poles[k, :n_poles[k]].copy(), delay[k], kind[k], p[k].copy(),
                            continuous[k], ln_lo[k], ln_hi[k], dom_lo[k], dom_hi[k], tail_c[k], head_c[k],
                            head_d[k], bp[k], w_lo[k], w_hi[k], A_lo[k], A_hi[k], na, nw, tol, marginal_tol,
                            mem_limit, bytes_per_point)
        if s == 0 and r.shape[0] > MAX_ROOTS:
            s = 10
        status[k] = s
        fl[k] = f
        it[k] = i
        count[k] = 0
        if s == 0:
            count[k] = r.shape[0]
            roots[k, :r.shape[0]] = r


@njit(**_OPTS)
def _node_logs(n, g):
    """ln N at the amplitude nodes, ln|G| at the frequency nodes (the real part of its complex log, as the driver
    computes it) and arg G there, NaN until needed (the exclusions fill it)."""
    ln_n = np.empty(n.size, np.complex128)
    rg = np.empty(g.size)
    for i in range(n.size):
        ln_n[i] = _clog(n[i])
    for j in range(g.size):
        rg[j] = math.log(cabs(g[j]))
    return ln_n, rg, np.full(g.size, np.nan)


@njit(**_OPTS)
def _kept_seeds(num, den, zeros, poles, delay, kind, p, a, v, n, g, eps_a, eps_v, si, sj):
    """roots._refined_seeds for the Python driver on a compiled loop: the mask of the tangent seeds (si, sj) worth
    refining, decided as :func:`_tangent_seeds` decides (the exclusion :func:`_no_root_in`, sound: a dropped
    seed's refinement could accept nothing, so the roots found are the same)."""
    nA, nv = a.size, v.size
    ln_n, rg, arg_g = _node_logs(n, g)
    keep = np.ones(si.size, np.bool_)
    for s in range(si.size):
        i, j = si[s], sj[s]
        if _no_root_in(zeros, poles, num, den, delay, kind, p, a, v, ln_n, eps_a, g, rg, arg_g, eps_v,
                       max(i - 2, 0), min(i + 2, nA - 1), max(j - 2, 0), min(j + 2, nv - 1)):
            r0, r1, c0, c1 = max(i - 4, 0), min(i + 5, nA), max(j - 4, 0), min(j + 5, nv)
            keep[s] = _near_jump(n, g, r0, r1, c0, c1) and not _no_root_in(
                zeros, poles, num, den, delay, kind, p, a, v, ln_n, eps_a, g, rg, arg_g, eps_v, max(i - 3, 0),
                min(i + 3, nA - 1), max(j - 3, 0), min(j + 3, nv - 1))
    return keep


def kept_seeds(loop, a, v, n, g, eps_a, eps_v, si, sj):
    """The tangent seeds worth refining (bool mask) for the Python driver on a compiled loop (``loop``: the
    residual's kernel arrays, :func:`.residual.compiled_loop`); a, v: the grid (ln A, ln w); n, g: N and G at its
    nodes; eps_a, eps_v: its bounds; si, sj: the seeds' node indices."""
    num, den, zeros, poles, delay, kind, p = loop[:7]
    f, c = np.ascontiguousarray, np.complex128
    return _kept_seeds(num, den, zeros, poles, float(delay), kind, p, f(a, float), f(v, float), f(n, c), f(g, c),
                       f(eps_a, float), f(eps_v, float), f(si, np.int64), f(sj, np.int64))


def kept_seeds_dispatcher():
    """The numba dispatcher of :func:`kept_seeds` (for the compile announcement)."""
    return _kept_seeds


@njit(**_OPTS)
def _apart_cells(zeros, poles, delay, a, v, n, g, eps_a, eps_v, ci, cj):
    """roots._winding_cells for the Python driver on a compiled loop: the mask of the cells (ci, cj) that
    :func:`_cells_apart` proves free of anything the refinement could accept, decided as :func:`_windings`
    decides (from the same node logarithms)."""
    ln_n, rg, arg_g = _node_logs(n, g)
    return _cells_apart(zeros, poles, delay, a, v, ln_n, eps_a, g, rg, arg_g, eps_v, ci, cj)


def apart_cells(loop, a, v, n, g, eps_a, eps_v, ci, cj):
    """The cells (ci, cj) whose windings the Python driver on a compiled loop passes over (bool mask), as the
    compiled driver does (``loop``: the residual's kernel arrays, :func:`.residual.compiled_loop`; a, v: the
    grid; n, g: N and G at its nodes; eps_a, eps_v: its bounds)."""
    zeros, poles, delay = loop[2:5]
    f, c = np.ascontiguousarray, np.complex128
    return _apart_cells(zeros, poles, float(delay), f(a, float), f(v, float), f(n, c), f(g, c), f(eps_a, float),
                        f(eps_v, float), f(ci, np.int64), f(cj, np.int64))


def apart_cells_dispatcher():
    """The numba dispatcher of :func:`apart_cells` (for the compile announcement)."""
    return _apart_cells


# ------------------------------------------------------------------------------------------- the Python side


def solve_one_dispatcher():
    """The numba dispatcher of one loop's driver (for the compile announcement)."""
    return _drive_one


def solve_many_dispatcher():
    """The numba dispatcher of the batch driver (for the compile announcement)."""
    return _drive_rows


def solve_one(gpart, npart, w_lo, w_hi, A_lo, A_hi, na, nw, tol, marginal_tol, mem_limit=None):
    """The driver on one loop: (status, floats, ints, roots) as :func:`_drive` returns them (windows NaN:
    the defaults; ``mem_limit``: the memory bound in bytes, read here when None)."""
    num, den, zeros, poles, delay = gpart
    return _drive_one(num, den, zeros, poles, delay, *npart, float(w_lo), float(w_hi), float(A_lo), float(A_hi),
                      int(na), int(nw), float(tol), float(marginal_tol),
                      float(memory_limit() if mem_limit is None else mem_limit), _BYTES_PER_POINT)


_TASKS_PER_THREAD = 4  # a batch in about this many tasks per thread, taken as threads free up (balanced load) ...
_MIN_ROWS = 16  # ... of at least this many loops (a task costs ~50 us of CPU: dispatch and the threads' hand-off)
_POOL: list = []  # the batch's thread pool and its size, created at its first use (one per process)
if hasattr(os, "register_at_fork"):  # a forked worker process (a process pool) has none of its parent's threads
    os.register_at_fork(after_in_child=_POOL.clear)


def _pool() -> tuple[ThreadPoolExecutor, int]:
    """The threads that run a batch's row ranges, and how many: numba's thread count (``NUMBA_NUM_THREADS``, the
    cores by default). The kernel releases the GIL, so they run at once; a waiting thread sleeps (numba's OpenMP
    layer spins instead, which cost a 2-core machine ~10-40 us of CPU per loop between batch calls)."""
    if not _POOL:
        threads = max(1, int(numba_config.NUMBA_NUM_THREADS))
        _POOL.extend((ThreadPoolExecutor(threads, thread_name_prefix="dfloop-batch"), threads))
    return _POOL[0], _POOL[1]


def _padded(rows: list, dtype, width: int = 1) -> list:
    """[rows as one zero-padded 2-D array of ``dtype`` (at least ``width`` columns), their lengths] (a batch's
    ragged arguments: the coefficients and roots of its plants, its elements' parameters), in a few numpy calls
    for the whole batch instead of one assignment per row."""
    n = len(rows)
    lengths = np.fromiter(map(len, rows), np.int64, n)
    total = int(lengths.sum())
    out = np.zeros((n, max(width, int(lengths.max()) if n else 0)), dtype)
    if total:
        starts = np.cumsum(lengths) - lengths
        r = np.repeat(np.arange(n), lengths)
        out[r, np.arange(total) - np.repeat(starts, lengths)] = np.concatenate(rows)
    return [out, lengths]


def solve_many(parts, windows, na, nw, tol, marginal_tol):
    """The driver over loops [(gpart, npart), ...] with windows [(w_lo, w_hi, A_lo, A_hi), ...], its rows shared
    among the threads of :func:`_pool`: arrays (status, floats, ints, roots (L, MAX_ROOTS, 10), root counts)."""
    L = len(parts)
    padded = []
    for q in range(4):  # num, den, zeros, poles: rows padded to the longest, with their lengths
        padded += _padded([g[q] for g, _ in parts], complex if q >= 2 else float)
    p = _padded([npart[1] for _, npart in parts], float, 4)[0]
    kind = np.fromiter((npart[0] for _, npart in parts), np.int64, L)
    cont = np.fromiter((npart[2] for _, npart in parts), np.bool_, L)
    # delay, then the element's ln_lo, ln_hi, domain, tail and head constants and breakpoint: one row each
    cols = np.array([(g[4],) + npart[3:11] for g, npart in parts], float).reshape(L, 9).T.copy()
    win = np.asarray(windows, float).reshape(L, 4)
    out = (np.zeros(L, np.int64), np.empty((L, 10)), np.empty((L, 9), np.int64),
           np.empty((L, MAX_ROOTS, 10), np.complex128), np.zeros(L, np.int64))
    args = (*padded, cols[0], kind, p, cont, *cols[1:9], win[:, 0].copy(), win[:, 1].copy(), win[:, 2].copy(),
            win[:, 3].copy(), int(na), int(nw), float(tol), float(marginal_tol), float(memory_limit()),
            _BYTES_PER_POINT)
    pool, threads = _pool()
    rows = max(_MIN_ROWS, -(-L // (_TASKS_PER_THREAD * threads)))
    tasks = [(s, min(s + rows, L)) for s in range(0, L, rows)]
    if len(tasks) == 1:
        _drive_rows(*args, *tasks[0], *out)
    else:
        for done in [pool.submit(_drive_rows, *args, lo, hi, *out) for lo, hi in tasks]:
            done.result()
    return out
