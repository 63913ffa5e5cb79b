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
    """One wrap of phase differences d into [-pi, pi] (d in (-3 pi, 3 pi)); pi and -pi stay as they are."""
    return np.where(d > np.pi, d - _TWO_PI, np.where(d < -np.pi, d + _TWO_PI, d))


def _indices(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row-major (i, j) int64 index arrays of the True entries of a 2-D mask."""
    i, j = np.nonzero(mask)
    return i.astype(np.int64), j.astype(np.int64)


def _neighbourhood(x: np.ndarray, fill, reduce) -> np.ndarray:
    """``reduce`` over the 8 neighbours of each entry of 2-D x (outside the array counts as ``fill``)."""
    na, nv = x.shape
    pad = np.pad(x, 1, constant_values=fill)
    out = None
    for di in range(3):
        for dj in range(3):
            if di == 1 and dj == 1:
                continue
            s = pad[di:di + na, dj:dj + nv]
            out = s.copy() if out is None else reduce(out, s, out=out)
    return out


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
    zero = (theta == 0.0) & (R.real == 0.0) & (R.imag == 0.0)
    ba_i, ba_j = _indices((np.abs(ph_a) > split) | zero[:-1, :] | zero[1:, :])
    bv_i, bv_j = _indices((np.abs(ph_v) > split) | zero[:, :-1] | zero[:, 1:])
    return ph_a, ph_v, ba_i, ba_j, bv_i, bv_j


def nonzero_windings(ph_a: np.ndarray, ph_v: np.ndarray):
    """Cells (i, j) with non-zero winding (counter-clockwise in (a, v)) and their windings.

    ph_a (na-1, nv) and ph_v (na, nv-1) are the phase steps (rad) along the edges; the winding of cell (i, j)
    is the sum of the steps around it over 2 pi, rounded to the nearest integer (half to even). Returns
    int64 arrays (i, j, winding) in row-major order.
    """
    turn = ph_a[:, :-1] + ph_v[1:, :] - ph_a[:, 1:] - ph_v[:-1, :]
    w = np.rint(turn / _TWO_PI)
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
    re = ln_n.real[:na, None] + ln_g.real[None, :nv]
    e = eps_a[:na, None] + eps_v[None, :nv]
    im = _wrap(ln_n.imag[:na, None] + ln_g.imag[None, :nv] - np.pi)  # args in (-pi, pi]: one wrap suffices
    return _indices(~(np.abs(re) > e) & (re * re + im * im <= e * e))


def tangent_seeds(P: np.ndarray, ci: np.ndarray, cj: np.ndarray, threshold: float, allowed: np.ndarray):
    """Grid nodes where m = |1 + P|^2 / (1 + |P|^2) (scale-free, 0 only at roots) is a local minimum
    (8 neighbours) below ``threshold``, excluding nodes within one node of a cell of non-zero winding
    (cells ci, cj) and nodes where ``allowed`` is False.

    Returns int64 index arrays (i, j) of the seeds in row-major order and m at them.
    """
    na, nv = P.shape
    near_allowed = allowed | _neighbourhood(allowed, False, np.logical_or)
    pr, pi = P.real, P.imag
    q = pr * pr + pi * pi
    with np.errstate(invalid="ignore", over="ignore"):
        m = np.where(near_allowed, (q + 2.0 * pr + 1.0) / (1.0 + q), np.inf)  # inf: never read as a minimum
    explained = np.zeros((na, nv), dtype=bool)
    for di in range(-1, 3):  # the 4 x 4 nodes from one before a cell's corners to one after
        ii = ci + di
        for dj in range(-1, 3):
            jj = cj + dj
            ok = (ii >= 0) & (ii < na) & (jj >= 0) & (jj < nv)
            explained[ii[ok], jj[ok]] = True
    lower = _neighbourhood(m, np.inf, np.fmin)  # fmin: a NaN neighbour is never lower, as in a < test
    si, sj = _indices(~(m >= threshold) & ~explained & allowed & ~(lower < m))
    return si, sj, m[si, sj]
