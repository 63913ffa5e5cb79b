"""Compiled single-pass loops over the (A, w) grid (numba): phase steps, cell windings, tangent seeds."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["edge_steps", "nonzero_windings", "tangent_seeds", "candidate_cells"]

_TWO_PI = 2.0 * math.pi


@njit(cache=True)
def _wrap(d):
    if d > math.pi:
        return d - _TWO_PI
    if d < -math.pi:
        return d + _TWO_PI
    return d


@njit(cache=True)
def _is_zero(theta, R, i, j):
    return theta[i, j] == 0.0 and R[i, j].real == 0.0 and R[i, j].imag == 0.0


@njit(cache=True)
def edge_steps(theta, R, split):
    """Wrapped steps of theta = arg R along both grid directions, and the edges that need bisection.

    Returns ph_a (na-1, nv), ph_v (na, nv-1), and index arrays (i, j) of edges whose step exceeds
    ``split`` or that touch an exact zero of R (along a, then along v).
    """
    na, nv = R.shape
    ph_a = np.empty((na - 1, nv))
    ph_v = np.empty((na, nv - 1))
    for i in range(na - 1):
        for j in range(nv):
            ph_a[i, j] = _wrap(theta[i + 1, j] - theta[i, j])
    for i in range(na):
        for j in range(nv - 1):
            ph_v[i, j] = _wrap(theta[i, j + 1] - theta[i, j])
    ba_i, ba_j = [0], [0]
    bv_i, bv_j = [0], [0]
    ba_i.pop(), ba_j.pop(), bv_i.pop(), bv_j.pop()
    for i in range(na - 1):
        for j in range(nv):
            if abs(ph_a[i, j]) > split or _is_zero(theta, R, i, j) or _is_zero(theta, R, i + 1, j):
                ba_i.append(i)
                ba_j.append(j)
    for i in range(na):
        for j in range(nv - 1):
            if abs(ph_v[i, j]) > split or _is_zero(theta, R, i, j) or _is_zero(theta, R, i, j + 1):
                bv_i.append(i)
                bv_j.append(j)
    return (ph_a, ph_v, np.array(ba_i, dtype=np.int64), np.array(ba_j, dtype=np.int64),
            np.array(bv_i, dtype=np.int64), np.array(bv_j, dtype=np.int64))


@njit(cache=True)
def nonzero_windings(ph_a, ph_v):
    """Cells (i, j) with non-zero winding (counter-clockwise in (a, v)) and their windings."""
    na, nv = ph_v.shape[0], ph_a.shape[1]
    ci, cj, cw = [0], [0], [0]
    ci.pop(), cj.pop(), cw.pop()
    for i in range(na - 1):
        for j in range(nv - 1):
            turn = ph_a[i, j] + ph_v[i + 1, j] - ph_a[i, j + 1] - ph_v[i, j]
            w = int(round(turn / _TWO_PI))
            if w != 0:
                ci.append(i)
                cj.append(j)
                cw.append(w)
    return np.array(ci, dtype=np.int64), np.array(cj, dtype=np.int64), np.array(cw, dtype=np.int64)


@njit(cache=True)
def candidate_cells(ln_n, eps_a, ln_g, eps_v):
    """Cells (i, j) of the tensor grid that may hold a root of 1 + G N (amplitude-only N).

    ln_n, ln_g: complex logs of N at the amplitude nodes and of G at the frequency nodes; eps_a, eps_v:
    bounds on the change of those logs within each interval (from its left node). A root needs
    ln(N G) = j pi (mod 2 pi j), so the cell is kept iff |ln(N_i G_j) - j pi| (phase wrapped) is at most
    eps_a[i] + eps_v[j]. Returns index arrays (i, j), sorted by i then j.
    """
    ci, cj = [0], [0]
    ci.pop(), cj.pop()
    for i in range(ln_n.size - 1):
        ea = eps_a[i]
        for j in range(ln_g.size - 1):
            re = ln_n[i].real + ln_g[j].real
            e = ea + eps_v[j]
            if abs(re) > e:
                continue
            im = _wrap(ln_n[i].imag + ln_g[j].imag - math.pi)  # args in (-pi, pi]: one wrap suffices
            if re * re + im * im <= e * e:
                ci.append(i)
                cj.append(j)
    return np.array(ci, dtype=np.int64), np.array(cj, dtype=np.int64)


@njit(cache=True)
def tangent_seeds(P, ci, cj, threshold, allowed):
    """Grid nodes where m = |1 + P|^2 / (1 + |P|^2) (scale-free, 0 only at roots) is a local minimum
    (8 neighbours) below ``threshold``, excluding nodes within one node of a cell of non-zero winding
    (cells ci, cj) and nodes where ``allowed`` is False."""
    na, nv = P.shape
    m = np.full((na, nv), np.inf)  # filled only around allowed nodes (all a local-minimum test reads)
    for i in range(na):
        for j in range(nv):
            if not allowed[i, j]:
                continue
            for ii in range(max(i - 1, 0), min(i + 2, na)):
                for jj in range(max(j - 1, 0), min(j + 2, nv)):
                    if m[ii, jj] == np.inf:
                        pr, pi = P[ii, jj].real, P[ii, jj].imag
                        q = pr * pr + pi * pi
                        m[ii, jj] = (q + 2.0 * pr + 1.0) / (1.0 + q)
    explained = np.zeros((na, nv), dtype=np.bool_)
    for k in range(ci.size):
        for i in range(max(ci[k] - 1, 0), min(ci[k] + 3, na)):
            for j in range(max(cj[k] - 1, 0), min(cj[k] + 3, nv)):
                explained[i, j] = True
    si, sj, sm = [0], [0], [0.0]
    si.pop(), sj.pop(), sm.pop()
    for i in range(na):
        for j in range(nv):
            x = m[i, j]
            if x >= threshold or explained[i, j] or not allowed[i, j]:
                continue
            is_min = True
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    ii, jj = i + di, j + dj
                    if (di != 0 or dj != 0) and 0 <= ii < na and 0 <= jj < nv and m[ii, jj] < x:
                        is_min = False
            if is_min:
                si.append(i)
                sj.append(j)
                sm.append(x)
    return np.array(si, dtype=np.int64), np.array(sj, dtype=np.int64), np.array(sm)
