"""Roots of the residual R(A, w) = 1 + G(jw) N(A, w) over a window of (A, w).

Everything works in log coordinates a = ln A, v = ln w. Roots are detected by the winding number of R
around grid cells (the local topological degree: scale-free, no absolute cutoff), the phase along each
cell edge being followed by adaptive bisection so no phase step exceeds pi/2. Each root is then refined
by a Levenberg-Marquardt iteration on (Re R, Im R), clipped to a box inside the window. Cells whose
winding is not +-1, or whose refinement fails, are quadrisected (bounded depth). Tangent-like pairs of
roots, which cancel in a cell's winding, are found from local minima of |R| / (1 + |G N|).
"""
from __future__ import annotations

import numpy as np

from ..describing.base import DescribingFunction
from .plant import Plant

__all__ = ["Residual", "Box", "find_roots"]

_SPLIT_PHASE = np.pi / 2  # an edge step whose phase change exceeds this is bisected
_MAX_EDGE_DEPTH = 50  # bisection levels along an edge (2**-50 of its length)
_MAX_SEGMENTS = 4_000_000  # live edge segments at one level
_FD_STEP = 1e-6  # central-difference step in log coordinates
_MAX_LM_ITER = 100
_MAX_ISOLATE_DEPTH = 30
_TANGENT_THRESHOLD = 0.3  # local minima of |R| / (1 + |GN|) below this are searched for hidden roots
_MAX_TANGENT_SEEDS = 5000


class Residual:
    """R = 1 + P with P(a, v) = G(j e^v) N(e^a, e^v), evaluated with numpy broadcasting.

    Parameters
    ----------
    plant : Plant
        The linear part G.
    N : DescribingFunction
        The nonlinear element (amplitude-only or frequency-dependent).
    """

    def __init__(self, plant: Plant, N: DescribingFunction):
        self.plant = plant
        self.N = N
        self.frequency_dependent = bool(N.frequency_dependent)
        self.n_points = 0

    def _n(self, A: np.ndarray, w: np.ndarray | None) -> np.ndarray:
        n = self.N(A, w) if self.frequency_dependent else self.N(A)
        if np.isnan(n).any():
            k = np.flatnonzero(np.isnan(n).ravel())[0]
            a_bad = np.broadcast_to(A, n.shape).ravel()[k]
            raise ValueError(f"N returned NaN at amplitude {a_bad:g}")
        return n

    def terms(self, a, v) -> np.ndarray:
        """The loop product P = G N at scattered points (a, v) (broadcast)."""
        a, v = np.broadcast_arrays(np.asarray(a, float), np.asarray(v, float))
        w = np.exp(v)
        self.n_points += a.size
        return self.plant(w) * self._n(np.exp(a), w)

    def grid(self, a: np.ndarray, v: np.ndarray) -> np.ndarray:
        """P on the tensor grid a (rows) x v (columns), in one broadcast call."""
        w = np.exp(v)
        g = self.plant(w)
        self.n_points += a.size * v.size
        if self.frequency_dependent:
            n = self._n(np.exp(a)[:, None], w[None, :])
        else:
            n = self._n(np.exp(a), None)[:, None]
        return n * g[None, :]

    def jacobian(self, a: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """dR/da and dR/dv (complex) by central differences in log coordinates."""
        h = _FD_STEP
        k = a.size
        aa = np.concatenate([a + h, a - h, a, a])
        vv = np.concatenate([v, v, v + h, v - h])
        p = self.terms(aa, vv)
        return (p[:k] - p[k:2 * k]) / (2 * h), (p[2 * k:3 * k] - p[3 * k:]) / (2 * h)


class Box:
    """Axis-aligned boxes [a_lo, a_hi] x [v_lo, v_hi] in log coordinates (arrays of equal length)."""

    def __init__(self, a_lo, a_hi, v_lo, v_hi):
        self.a_lo, self.a_hi, self.v_lo, self.v_hi = (np.atleast_1d(np.asarray(x, float)) for x in
                                                      (a_lo, a_hi, v_lo, v_hi))

    def __len__(self) -> int:
        return self.a_lo.size

    def quadrisect(self) -> "Box":
        am, vm = (self.a_lo + self.a_hi) / 2, (self.v_lo + self.v_hi) / 2
        return Box(np.concatenate([self.a_lo, am, self.a_lo, am]), np.concatenate([am, self.a_hi, am, self.a_hi]),
                   np.concatenate([self.v_lo, self.v_lo, vm, vm]), np.concatenate([vm, vm, self.v_hi, self.v_hi]))

    def grown(self, factor: float, window: "Box") -> "Box":
        da, dv = (self.a_hi - self.a_lo) * factor, (self.v_hi - self.v_lo) * factor
        return Box(np.maximum(self.a_lo - da, window.a_lo), np.minimum(self.a_hi + da, window.a_hi),
                   np.maximum(self.v_lo - dv, window.v_lo), np.minimum(self.v_hi + dv, window.v_hi))

    def contains(self, a: float, v: float) -> np.ndarray:
        return (self.a_lo <= a) & (a <= self.a_hi) & (self.v_lo <= v) & (v <= self.v_hi)

    def take(self, mask) -> "Box":
        return Box(self.a_lo[mask], self.a_hi[mask], self.v_lo[mask], self.v_hi[mask])


def edge_phases(res: Residual, a0, v0, a1, v1, P0, P1) -> tuple[np.ndarray, list]:
    """Continuous change of arg R along straight segments (a0, v0) -> (a1, v1).

    Segments whose phase step exceeds pi/2 are bisected (vectorised, at most 50 levels). Returns the
    phase changes and the midpoints of segments still unresolved at the last level (a root on the edge).
    """
    total = np.zeros(np.size(a0))
    seg = np.arange(total.size)
    R0, R1 = 1.0 + P0, 1.0 + P1
    suspects = []
    for depth in range(_MAX_EDGE_DEPTH + 1):
        zero = (R0 == 0) | (R1 == 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(zero, 0.0, np.angle(R1 / np.where(zero, 1.0, R0)))
        if zero.any():
            suspects.extend(zip(np.where(R0 == 0, a0, a1)[zero], np.where(R0 == 0, v0, v1)[zero]))
        split = np.abs(d) > _SPLIT_PHASE
        if depth == _MAX_EDGE_DEPTH and split.any():
            suspects.extend(zip(((a0 + a1) / 2)[split], ((v0 + v1) / 2)[split]))
            split[:] = False
        np.add.at(total, seg[~split], d[~split])
        if not split.any():
            break
        if 2 * np.count_nonzero(split) > _MAX_SEGMENTS:
            raise RuntimeError(f"edge phase subdivision exceeded max_segments={_MAX_SEGMENTS}")
        a0, v0, a1, v1, R0, R1, seg = (x[split] for x in (a0, v0, a1, v1, R0, R1, seg))
        am, vm = (a0 + a1) / 2, (v0 + v1) / 2
        Rm = 1.0 + res.terms(am, vm)
        a0, v0, R0 = np.concatenate([a0, am]), np.concatenate([v0, vm]), np.concatenate([R0, Rm])
        a1, v1, R1 = np.concatenate([am, a1]), np.concatenate([vm, v1]), np.concatenate([Rm, R1])
        seg = np.concatenate([seg, seg])
    return total, suspects


def grid_windings(res: Residual, a: np.ndarray, v: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, list]:
    """Winding number of R around every cell of the tensor grid (counter-clockwise in (a, v))."""
    na, nv = P.shape
    A0, V0 = np.meshgrid(a[:-1], v, indexing="ij")
    A1 = np.broadcast_to(a[1:, None], A0.shape)
    ph_a, s1 = edge_phases(res, A0.ravel(), V0.ravel(), A1.ravel(), V0.ravel(), P[:-1].ravel(), P[1:].ravel())
    B0, W0 = np.meshgrid(a, v[:-1], indexing="ij")
    W1 = np.broadcast_to(v[None, 1:], W0.shape)
    ph_v, s2 = edge_phases(res, B0.ravel(), W0.ravel(), B0.ravel(), W1.ravel(), P[:, :-1].ravel(),
                           P[:, 1:].ravel())
    ph_a = ph_a.reshape(na - 1, nv)
    ph_v = ph_v.reshape(na, nv - 1)
    turn = ph_a[:, :-1] + ph_v[1:, :] - ph_a[:, 1:] - ph_v[:-1, :]
    return np.rint(turn / (2 * np.pi)).astype(int), s1 + s2


def box_windings(res: Residual, box: Box) -> tuple[np.ndarray, list]:
    """Winding number of R around each box (counter-clockwise in (a, v))."""
    k = len(box)
    ca = np.concatenate([box.a_lo, box.a_hi, box.a_hi, box.a_lo])
    cv = np.concatenate([box.v_lo, box.v_lo, box.v_hi, box.v_hi])
    P = res.terms(ca, cv)
    nxt = np.concatenate([np.arange(k, 4 * k), np.arange(k)])
    ph, suspects = edge_phases(res, ca, cv, ca[nxt], cv[nxt], P, P[nxt])
    turn = ph.reshape(4, k).sum(axis=0)
    return np.rint(turn / (2 * np.pi)).astype(int), suspects


def refine(res: Residual, a, v, box: Box, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Levenberg-Marquardt on (Re R, Im R) from (a, v), each point clipped to its box.

    Returns the final (a, v) and a mask of points with |R| <= tol (1 + |G N|). Bounded by 100 iterations.
    """
    a, v = np.array(a, float), np.array(v, float)
    P = res.terms(a, v)
    rel = np.abs(1 + P) / (1 + np.abs(P))
    lam = np.full(a.size, 1e-12)
    done = rel <= tol
    failed = np.zeros(a.size, bool)
    for _ in range(_MAX_LM_ITER):
        act = np.flatnonzero(~done & ~failed)
        if act.size == 0:
            break
        ra, rv = res.jacobian(a[act], v[act])
        r = 1 + P[act]
        # real 2x2 normal equations of J = [[Re ra, Re rv], [Im ra, Im rv]]
        jaa = np.abs(ra) ** 2
        jvv = np.abs(rv) ** 2
        jav = (ra.conj() * rv).real
        ga = (ra.conj() * r).real
        gv = (rv.conj() * r).real
        l = lam[act] * (jaa + jvv)
        m11, m22 = jaa + l, jvv + l
        det = m11 * m22 - jav ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            da = -(m22 * ga - jav * gv) / det
            dv = -(m11 * gv - jav * ga) / det
        ok_step = np.isfinite(da) & np.isfinite(dv)
        da, dv = np.where(ok_step, da, 0.0), np.where(ok_step, dv, 0.0)
        at = np.clip(a[act] + da, box.a_lo[act], box.a_hi[act])
        vt = np.clip(v[act] + dv, box.v_lo[act], box.v_hi[act])
        Pt = res.terms(at, vt)
        relt = np.abs(1 + Pt) / (1 + np.abs(Pt))
        better = (relt < rel[act]) & ok_step
        acc, rej = act[better], act[~better]
        a[acc], v[acc], P[acc], rel[acc] = at[better], vt[better], Pt[better], relt[better]
        lam[acc] = np.maximum(lam[acc] / 10, 1e-15)
        lam[rej] *= 100
        done = rel <= tol
        failed |= lam > 1e8
    return a, v, done


def _isolate(res: Residual, box: Box, window: Box, tol: float, hint: tuple[float, float] | None = None):
    """Quadrisect one box until its roots sit in boxes of winding +-1, then refine those (bounded)."""
    found_a, found_v = [], []
    queue = box
    for _ in range(_MAX_ISOLATE_DEPTH):
        if len(queue) == 0:
            break
        kids = queue.quadrisect()
        wind, suspects = box_windings(res, kids)
        single = np.abs(wind) == 1
        if single.any():
            sb = kids.take(single)
            a, v, ok = refine(res, (sb.a_lo + sb.a_hi) / 2, (sb.v_lo + sb.v_hi) / 2, sb.grown(0.5, window), tol)
            found_a.extend(a[ok])
            found_v.extend(v[ok])
            single[single] = ok  # failed refinements are subdivided further
        keep = ~single & (wind != 0)
        if hint is not None:
            keep |= (wind == 0) & kids.contains(*hint)
        for sa, sv in suspects:
            keep |= kids.contains(sa, sv)
        queue = kids.take(keep)
    if len(queue):
        # bound reached: what is left is a multiple (e.g. tangent) root smaller than the box size
        a, v, ok = refine(res, (queue.a_lo + queue.a_hi) / 2, (queue.v_lo + queue.v_hi) / 2,
                          queue.grown(1.0, window), tol)
        found_a.extend(a[ok])
        found_v.extend(v[ok])
    return found_a, found_v


def _local_minima(m: np.ndarray) -> np.ndarray:
    """Mask of grid nodes not larger than any of their 8 neighbours."""
    pad = np.pad(m, 1, constant_values=np.inf)
    c = pad[1:-1, 1:-1]
    mask = np.ones(m.shape, bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                mask &= c <= pad[1 + di:pad.shape[0] - 1 + di, 1 + dj:pad.shape[1] - 1 + dj]
    return mask


def merge(a: np.ndarray, v: np.ndarray, dist: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Merge points closer than ``dist`` (log coordinates, both axes); sorted by v."""
    order = np.lexsort((a, v))
    a, v = a[order], v[order]
    keep_a, keep_v = [], []
    for x, y in zip(a, v):
        if any(abs(x - ka) <= dist and abs(y - kv) <= dist for ka, kv in zip(keep_a[-8:], keep_v[-8:])):
            continue
        keep_a.append(x)
        keep_v.append(y)
    return np.asarray(keep_a), np.asarray(keep_v)


def find_roots(res: Residual, a: np.ndarray, v: np.ndarray, P: np.ndarray, tol: float):
    """All roots of R in the window spanned by the grid (a, v) with loop products P = G N on it.

    Returns arrays (a, v) of refined roots (|R| <= tol (1 + |GN|)), merged and sorted by frequency.
    """
    window = Box(a[0], a[-1], v[0], v[-1])
    wind, suspects = grid_windings(res, a, v, P)
    ii, jj = np.nonzero(wind)
    cells = Box(a[ii], a[ii + 1], v[jj], v[jj + 1])
    single = np.abs(wind[ii, jj]) == 1
    roots_a, roots_v = [], []
    sb = cells.take(single)
    ra, rv, ok = refine(res, (sb.a_lo + sb.a_hi) / 2, (sb.v_lo + sb.v_hi) / 2, sb.grown(0.5, window), tol)
    roots_a.extend(ra[ok])
    roots_v.extend(rv[ok])
    hard = cells.take(~single)
    failed = sb.take(~ok)
    for box in (hard, failed):
        for k in range(len(box)):
            fa, fv = _isolate(res, box.take([k]), window, tol)
            roots_a.extend(fa)
            roots_v.extend(fv)
    # roots lying on grid edges (edge phase unresolved at the finest level), incl. the window boundary
    if suspects:
        sa, sv = np.array(suspects).T
        da, dv = np.max(np.diff(a)), np.max(np.diff(v))
        sbox = Box(np.maximum(sa - da, a[0]), np.minimum(sa + da, a[-1]),
                   np.maximum(sv - dv, v[0]), np.minimum(sv + dv, v[-1]))
        xa, xv, ok = refine(res, sa, sv, sbox, tol)
        roots_a.extend(xa[ok])
        roots_v.extend(xv[ok])
    # tangent-like pairs cancel in a cell's winding: search from local minima of the relative residual
    m = np.abs(1 + P) / (1 + np.abs(P))
    seeds = _local_minima(m) & (m < _TANGENT_THRESHOLD)
    si, sj = np.nonzero(seeds)
    if si.size > _MAX_TANGENT_SEEDS:
        best = np.argsort(m[si, sj])[:_MAX_TANGENT_SEEDS]
        si, sj = si[best], sj[best]
    if si.size:
        lo_i, hi_i = np.maximum(si - 1, 0), np.minimum(si + 1, a.size - 1)
        lo_j, hi_j = np.maximum(sj - 1, 0), np.minimum(sj + 1, v.size - 1)
        sbox = Box(a[lo_i], a[hi_i], v[lo_j], v[hi_j])
        ta, tv, ok = refine(res, a[si], v[sj], sbox, tol)
        known_a, known_v = np.asarray(roots_a), np.asarray(roots_v)
        for k in np.flatnonzero(ok):
            if known_a.size and np.min(np.maximum(np.abs(known_a - ta[k]), np.abs(known_v - tv[k]))) < 1e-5:
                continue
            # a root the windings did not show: isolate everything in its neighbourhood
            fa, fv = _isolate(res, sbox.take([k]), window, tol, hint=(ta[k], tv[k]))
            roots_a.extend(fa + [ta[k]])
            roots_v.extend(fv + [tv[k]])
    if not roots_a:
        return np.empty(0), np.empty(0)
    return merge(np.asarray(roots_a), np.asarray(roots_v))
