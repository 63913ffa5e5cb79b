"""Single-pass array kernels over the (A, w) grid (numpy broadcasting): phase steps, cell windings, candidate
cells, tangent seeds.

These were numba loops; as whole-array numpy expressions they cost the same on the dense benchmarks and need no
JIT compilation, so the solver's first call in a fresh process does not pay seconds of compiling (see
``docs/solver.md``). Every function evaluates the same floating-point expressions in the same order as the
loops it replaces, so its results are bit-identical to them; index arrays come out in row-major order (sorted
by i, then j).
"""
from __future__ import annotations

import numpy as np

__all__ = ["edge_steps", "nonzero_windings", "tangent_seeds", "candidate_cells"]

_TWO_PI = 2.0 * np.pi


def _wrap(d: np.ndarray) -> np.ndarray:
    """One wrap, in place, of phase differences d into [-pi, pi] (d in (-3 pi, 3 pi)); +-pi stay as they are."""
    np.subtract(d, _TWO_PI, out=d, where=d > np.pi)
    np.add(d, _TWO_PI, out=d, where=d < -np.pi)
    return d


def _indices(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row-major (i, j) int64 index arrays of the True entries of a 2-D mask."""
    i, j = np.nonzero(mask)
    return i.astype(np.int64), j.astype(np.int64)


def _m(P: np.ndarray) -> np.ndarray:
    """Relative residual |1 + P|^2 / (1 + |P|^2) of loop products P (0 only at roots; NaN where P is not finite)."""
    pr, pi = P.real, P.imag
    q = pr * pr + pi * pi
    with np.errstate(invalid="ignore", over="ignore"):
        return (q + 2.0 * pr + 1.0) / (1.0 + q)


def edge_steps(theta: np.ndarray, R: np.ndarray, split: float):
    """Wrapped steps of theta = arg R along both grid directions, and the edges that need bisection.

    Parameters
    ----------
    theta : (na, nv) float array, arg R in (-pi, pi] (rad).
    R : (na, nv) complex array, the residual at the grid nodes.
    split : float, a step larger than this in modulus (rad) needs bisection.

    Returns
    -------
    ph_a (na-1, nv), ph_v (na, nv-1), and int64 index arrays (i, j) of edges whose step exceeds ``split`` or
    that touch an exact zero of R (along a, then along v; each in row-major order).
    """
    ph_a = _wrap(theta[1:, :] - theta[:-1, :])
    ph_v = _wrap(theta[:, 1:] - theta[:, :-1])
    zero = (R == 0.0) & (theta == 0.0)  # arg(-0 - 0j) = -pi: such a node is not treated as a zero
    ba_i, ba_j = _indices((np.abs(ph_a) > split) | zero[:-1, :] | zero[1:, :])
    bv_i, bv_j = _indices((np.abs(ph_v) > split) | zero[:, :-1] | zero[:, 1:])
    return ph_a, ph_v, ba_i, ba_j, bv_i, bv_j


def nonzero_windings(ph_a: np.ndarray, ph_v: np.ndarray):
    """Cells (i, j) with non-zero winding (counter-clockwise in (a, v)) and their windings.

    ph_a (na-1, nv) and ph_v (na, nv-1) are the phase steps (rad) along the edges; the winding of cell (i, j)
    is the sum of the steps around it over 2 pi, rounded to the nearest integer (half to even). Returns
    int64 arrays (i, j, winding) in row-major order.
    """
    w = ph_a[:, :-1] + ph_v[1:, :]
    w -= ph_a[:, 1:]
    w -= ph_v[:-1, :]
    w /= _TWO_PI
    np.rint(w, out=w)
    ci, cj = _indices(w != 0)
    return ci, cj, w[ci, cj].astype(np.int64)


def candidate_cells(ln_n: np.ndarray, eps_a: np.ndarray, ln_g: np.ndarray, eps_v: np.ndarray):
    """Cells (i, j) of the tensor grid that may hold a root of 1 + G N (amplitude-only N).

    ln_n, ln_g: complex logs of N at the amplitude nodes and of G at the frequency nodes; eps_a, eps_v:
    bounds on the change of those logs within each interval (from its left node). A root needs
    ln(N G) = j pi (mod 2 pi j), so the cell is kept iff |ln(N_i G_j) - j pi| (phase wrapped) is at most
    eps_a[i] + eps_v[j]. Returns int64 index arrays (i, j), sorted by i then j.
    """
    na, nv = ln_n.size - 1, ln_g.size - 1
    if na < 1 or nv < 1:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    rn, rg = ln_n.real[:na], ln_g.real[:nv]
    # a kept cell has |rn_i + rg_j| <= eps_a[i] + eps_v[j] <= reach_i: pair each i only with the j whose rg_j is
    # within reach of -rn_i (sorted search, widened well beyond rounding; non-finite bounds: every j)
    reach = eps_a[:na] + np.max(eps_v[:nv])
    with np.errstate(invalid="ignore"):
        slack = 1e-9 * (np.abs(rn) + reach)
        lo, hi = -rn - reach - slack, -rn + reach + slack
    lo[np.isnan(lo)], hi[np.isnan(hi)] = -np.inf, np.inf
    order = np.argsort(rg, kind="stable")
    start = np.searchsorted(rg[order], lo, "left")
    count = np.maximum(np.searchsorted(rg[order], hi, "right") - start, 0)
    i = np.repeat(np.arange(na, dtype=np.int64), count)
    j = order[np.repeat(start - np.cumsum(count) + count, count) + np.arange(i.size)]
    # the test on those pairs, as a loop over all cells evaluates it
    re = rn[i] + rg[j]
    e = eps_a[i] + eps_v[j]
    im = _wrap(ln_n.imag[i] + ln_g.imag[j] - np.pi)  # args in (-pi, pi]: one wrap suffices
    keep = np.sort((i * nv + j)[~(np.abs(re) > e) & (re * re + im * im <= e * e)])
    return keep // nv, keep % nv


def tangent_seeds(P: np.ndarray, ci: np.ndarray, cj: np.ndarray, threshold: float, si: np.ndarray, sj: np.ndarray):
    """Grid nodes where m = |1 + P|^2 / (1 + |P|^2) (scale-free, 0 only at roots) is a local minimum
    (8 neighbours) below ``threshold``, among the candidate nodes (si, sj) (row-major int64 index arrays: the
    work scales with their number, not with the grid), excluding nodes within one node of a cell of non-zero
    winding (cells ci, cj).

    Returns int64 index arrays (i, j) of the seeds in row-major order and m at them.
    """
    na, nv = P.shape
    # drop the 4 x 4 nodes from one before a winding cell's corners to one after
    ei = (ci[:, None] + np.repeat(np.arange(-1, 3), 4)[None, :]).ravel()
    ej = (cj[:, None] + np.tile(np.arange(-1, 3), 4)[None, :]).ravel()
    inside = (ei >= 0) & (ei < na) & (ej >= 0) & (ej < nv)
    if ei.size:
        free = ~np.isin(si * nv + sj, ei[inside] * nv + ej[inside])
        si, sj = si[free], sj[free]
    x = _m(P[si, sj])  # m only where it is read (allowed nodes and, below, their neighbours), as in a loop
    low = ~(x >= threshold)
    si, sj, x = si[low], sj[low], x[low]
    is_min = np.ones(si.size, dtype=bool)
    for di in (-1, 0, 1):  # a local minimum: no neighbour lower (a NaN neighbour is never lower)
        ii = si + di
        for dj in (-1, 0, 1):
            if di or dj:
                jj = sj + dj
                ok = np.flatnonzero((ii >= 0) & (ii < na) & (jj >= 0) & (jj < nv))
                is_min[ok[_m(P[ii[ok], jj[ok]]) < x[ok]]] = False
    return si[is_min], sj[is_min], x[is_min]
