"""Roots of the residual R(A, w) = 1 + G(jw) N(A, w) over a window of (A, w).

Everything works in log coordinates a = ln A, v = ln w. Roots are detected by the winding number of R
around grid cells (the local topological degree: scale-free, no absolute cutoff), the phase along each
cell edge being followed by adaptive bisection so no phase step exceeds pi/2. Each root is then refined
by a Levenberg-Marquardt iteration on (Re R, Im R), clipped to a box inside the window. Cells whose
winding is not +-1, or whose refinement fails, are quadrisected (bounded depth). Tangent-like pairs of
roots, which cancel in a cell's winding, are found from local minima of |R|^2 / (1 + |G N|^2).

N may jump (regime changes of a tabulated DF, N = 0 beyond a limit frequency). A segment shorter than
``_JUMP_LENGTH`` across which R still changes by more than ``_JUMP_SIZE`` (1 + |G N|) is a discontinuity:
it is not bisected further and its phase step is taken along the chord from R- to R+ (the straight
homotopy from N- to N+). A box that still winds when it is smaller than ``JUMP_BOX`` and touches a
discontinuity holds no root of the continuous equation: it is a *jump crossing*, where G(jw) passes
through the gap of a -1/N jump, and is reported as such instead of being refined further.
"""
from __future__ import annotations

import math

import numpy as np

from ..describing.base import DescribingFunction
from .errors import ContinuumError
from ._kernels import edge_steps, nonzero_windings, tangent_seeds
from .grid import MONOTONE_WIDTH, STEP, chord_deviation, chord_gap, clog
from .plant import Plant

__all__ = ["Residual", "Box", "OuterProduct", "find_roots", "dominant_steps", "greedy_unique", "accepted", "residual_bound",
           "unresolved_boxes", "seed_excluded"]

_SPLIT_PHASE = np.pi / 2  # an edge step whose phase change exceeds this is bisected
_MAX_EDGE_DEPTH = 50  # bisection levels along an edge (2**-50 of its length)
_MAX_SEGMENTS = 4_000_000  # live edge segments at one level
_FD_STEP = 1e-6  # central-difference step in log coordinates
_MAX_LM_ITER = 100
_POLISH = 1e-4  # refinement continues (while it improves) down to this fraction of the tolerance
_MAX_ISOLATE_DEPTH = 40  # quadrisections of a box: 2**-40 of a grid cell, below any resolvable separation
_MAX_LIVE_BOXES = 4096  # boxes alive at one level of one isolation; more means a curve of zeros, not points
_EARLY_CONTINUUM_CHECK = 64  # edge zeros + multiple windings on the grid beyond which a continuum is sought first
_MERGE_RADIUS = 1e-12  # refined points closer than this (log units) plus their uncertainty are one root
_TANGENT_THRESHOLD = 0.1  # local minima of |R|^2 / (1 + |GN|^2) below this are searched for hidden roots
_MAX_TANGENT_SEEDS = 5000
_SEED_MARGIN = 0.005  # a tangent seed's box where |ln(G N) - j pi| >= this provably everywhere is not refined ...
_SEED_SPLITS = 64  # ... proved with at most this many halvings of the pieces covering ln N and ln G ...
_SEED_TESTS = 4096  # ... and this many tests of a pair of pieces
# live boxes crowding in a region this small (log units) are one multiple root: a double root is located only to
# about sqrt(rounding) (1.5e-8) along its degenerate direction, where Re R or Im R stays at rounding level and zeros
# appear on many box edges; distinct simple roots are isolated by winding long before their boxes number thousands
_MULTIPLE_ROOT_SPAN = 1e-6
_JUMP_LENGTH = 1e-9  # segments shorter than this (log units, i.e. relative in A and w) ...
_JUMP_SIZE = 1e-3  # ... across which R changes by more than this times 1 + |G N| are discontinuities
_JUMP_KEEP = 0.9  # ... and one of whose halves still carries this fraction of the change (not a steep slope)
JUMP_BOX = 1e-7  # a winding box narrower than this (log units) touching a discontinuity is a jump crossing
_JUMP_DOMINANCE = 4.0  # a grid step of G N this many times larger than both neighbouring steps is a jump
_MEMO_BATCH = 64  # batches of at most this many points are remembered by Residual.slopes ...
_MEMO_SIZE = 8192  # ... up to this many points (then the memo starts again)


def dominant_steps(P: np.ndarray) -> np.ndarray:
    """Steps of P along axis 0 larger than ``_JUMP_DOMINANCE`` times both neighbouring steps: a
    discontinuity, which refining the grid would not shrink. Shape (n - 1, m)."""
    d = np.abs(np.diff(P, axis=0))
    if d.shape[0] < 2:
        return np.zeros(d.shape, bool)
    before = np.vstack([d[1:2], d[:-1]])  # the first/last step are compared with their one neighbour
    after = np.vstack([d[1:], d[-2:-1]])
    return d > _JUMP_DOMINANCE * np.maximum(before, after)


class OuterProduct:
    """The loop product P[i, j] = N_i G_j of an amplitude-only N on the tensor grid, computed where it is read.

    Indexing as an (na, nv) array: with two index arrays (elementwise pairs) or two slices (a block); the values
    are bit-identical to ``N[:, None] * G[None, :]``, whose na x nv array (411 MB for the 64 x 402,116 grid of a
    relay around a delay on [0.1, 1e5] rad/s, ~2 s of page faults) the candidate cells never need.
    """

    ndim = 2

    def __init__(self, n: np.ndarray, g: np.ndarray):
        self.n, self.g = np.asarray(n), np.asarray(g)
        self.shape = (self.n.size, self.g.size)
        self.size = self.n.size * self.g.size

    def __getitem__(self, key) -> np.ndarray:
        i, j = key
        if isinstance(i, slice) and isinstance(j, slice):
            return np.multiply.outer(self.n[i], self.g[j])
        return self.n[i] * self.g[j]


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
        self.continuous = bool(getattr(N, "continuous", False))  # no jump of N anywhere (the element says so)
        self.n_points = 0
        self.unresolved: list[tuple[float, float, float, float, int]] = []  # winding boxes left without a root
        self._memo: dict[tuple[float, float], tuple] = {}  # (a, v) -> (P, dP/da, dP/dv, G, N) of small batches

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

    def slopes(self, a, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """P = G N and its derivatives dP/da, dP/dv at points (a, v) (1-D arrays, log coordinates).

        dG/dv is exact for rational G (:meth:`Plant.log_slope`), a central difference otherwise; N is
        differentiated by central differences of step ``_FD_STEP`` (log units), shorter next to the edges of
        N's amplitude domain (:meth:`_fd_steps`). Small batches (the points
        of a refinement) are remembered, so the merge, the stability test and the result, which read the
        same refined points again, cost no evaluation (:meth:`factors`).
        """
        return self._point_values(a, v)[:3]

    def factors(self, a, v) -> tuple[np.ndarray, np.ndarray]:
        """G and N at points (a, v) (1-D arrays, log coordinates), remembered like :meth:`slopes`."""
        return self._point_values(a, v)[3:]

    def _point_values(self, a, v) -> tuple[np.ndarray, ...]:
        a, v = np.broadcast_arrays(np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(v, float)))
        if a.size <= _MEMO_BATCH:
            keys = list(zip(a.tolist(), v.tolist()))
            hits = [self._memo.get(key) for key in keys]
            if all(h is not None for h in hits):
                return tuple(np.array(col) for col in zip(*hits)) if hits else (np.empty(0, complex),) * 5
        out = self._evaluate_slopes(a, v)
        if a.size <= _MEMO_BATCH:
            if len(self._memo) + a.size > _MEMO_SIZE:
                self._memo.clear()
            self._memo.update(zip(keys, zip(*(x.tolist() for x in out))))
        return out

    def _fd_steps(self, a: np.ndarray, v: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Central-difference steps (log units) for N along a and v: ``_FD_STEP``, shrunk to a quarter of the
        distance to the edges of N's amplitude domain so no difference point leaves it.

        At a domain edge N is continuous but not smooth (a dead band ends: N rises from 0 like a power of
        the distance to the edge); a root next to the edge (|G| ~ 1e8 at a resonance needs |N| ~ 1e-8, i.e. a
        relative distance ~ 1e-8) would otherwise get a difference with one point in the dead band, a wrong
        Jacobian, and a refinement that never converges. Along v the edge moves (its slope is differenced
        once on the domain function itself): the v-step keeps the moved edge a quarter-distance away too.
        """
        h = _FD_STEP
        if self.frequency_dependent:
            up, dn = np.exp(h), np.exp(-h)
            lo3, hi3 = (np.asarray(x, float).reshape(3, -1) for x in
                        self.N.amplitude_domain(np.concatenate([w, w * up, w * dn])))
            lo, hi = lo3[0], hi3[0]
            with np.errstate(divide="ignore", invalid="ignore"):  # an edge at 0 or inf does not move: NaN, 0
                slope = np.fmax(np.abs(np.log(lo3[1]) - np.log(lo3[2])),
                                np.abs(np.log(hi3[1]) - np.log(hi3[2]))) / (2 * h)
            slope = np.where(np.isfinite(slope), slope, 0.0)
        else:
            lo, hi = (np.broadcast_to(np.asarray(x, float), a.shape) for x in self.N.amplitude_domain())
            slope = np.zeros(a.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            gap = np.minimum(a - np.log(lo), np.log(hi) - a)
        gap = np.where(np.isnan(gap), np.inf, gap)
        floor = 64 * _rounding(a)  # at the rounding level the edge cannot be kept out; the step stays resolvable
        h_a = np.clip(0.25 * gap, floor, h)
        with np.errstate(divide="ignore", invalid="ignore"):
            h_v = np.where(slope > 0, 0.25 * gap / slope, h)
        return h_a, np.clip(h_v, 64 * _rounding(v), h)

    def _evaluate_slopes(self, a: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        k, h = a.size, _FD_STEP
        A, w = np.exp(a), np.exp(v)
        if self.plant.exact:
            g = self.plant(w)
            g_v = g * self.plant.log_slope(w)
        else:
            gg = self.plant(np.concatenate([w, w * np.exp(h), w * np.exp(-h)]))
            g, g_v = gg[:k], (gg[k:2 * k] - gg[2 * k:]) / (2 * h)
        h_a, h_v = self._fd_steps(a, v, w)
        if self.frequency_dependent:
            nn = self._n(np.concatenate([A, A * np.exp(h_a), A * np.exp(-h_a), A, A]),
                         np.concatenate([w, w, w, w * np.exp(h_v), w * np.exp(-h_v)]))
            n_v = (nn[3 * k:4 * k] - nn[4 * k:]) / (2 * h_v)
        else:
            nn = self._n(np.concatenate([A, A * np.exp(h_a), A * np.exp(-h_a)]), None)
            n_v = 0.0
        self.n_points += nn.size
        n, n_a = nn[:k], (nn[k:2 * k] - nn[2 * k:3 * k]) / (2 * h_a)
        return g * n, g * n_a, g_v * n + g * n_v, g, n

    def jacobian(self, a: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """dR/da and dR/dv (complex) at points (a, v) (see :meth:`slopes`)."""
        return self.slopes(a, v)[1:]


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


def edge_phases(res: Residual, a0, v0, a1, v1, P0, P1) -> tuple[np.ndarray, list, list]:
    """Continuous change of arg R along straight segments (a0, v0) -> (a1, v1).

    Segments whose phase step exceeds pi/2 are bisected (vectorised, at most 50 levels), except across
    a discontinuity of N (never for an element that states it is continuous, ``N.continuous``: there a steep
    rise of N from 0 at the edge of a dead band, under a |G| of 1e8 at a resonance, looks like a jump at
    every length down to rounding, yet holds a root) (a segment shorter than ``_JUMP_LENGTH`` over which R still changes by more than
    ``_JUMP_SIZE`` (1 + |G N|), and one of whose halves still carries ``_JUMP_KEEP`` of that change: a
    continuous R, however steep, shares it between the halves and is bisected on), where the step along the
    chord is taken. Returns the phase changes,
    the midpoints of segments still unresolved at the last level (a root on the edge) and the midpoints
    of the discontinuities met.
    """
    total = np.zeros(np.size(a0))
    seg = np.arange(total.size)
    R0, R1 = 1.0 + P0, 1.0 + P1
    suspects, jumps = [], []
    for depth in range(_MAX_EDGE_DEPTH + 1):
        zero = (R0 == 0) | (R1 == 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(zero, 0.0, np.angle(R1 / np.where(zero, 1.0, R0)))
        if zero.any():
            suspects.extend(zip(np.where(R0 == 0, a0, a1)[zero], np.where(R0 == 0, v0, v1)[zero]))
        split = np.abs(d) > _SPLIT_PHASE
        short = np.maximum(np.abs(a1 - a0), np.abs(v1 - v0)) < _JUMP_LENGTH
        jump = split & short & (not res.continuous) & (np.abs(R1 - R0) > _JUMP_SIZE * (1 + np.maximum(np.abs(R0 - 1), np.abs(R1 - 1))))
        if jump.any():
            # a discontinuity keeps (nearly) its whole change in one half; a steep but continuous R (a resonance
            # of damping 1e-6, N's dead-band edge) shares it between the halves: that one is bisected further
            k = np.flatnonzero(jump)
            Rh = 1.0 + res.terms((a0[k] + a1[k]) / 2, (v0[k] + v1[k]) / 2)
            whole = np.abs(R1[k] - R0[k])
            jump[k] = np.maximum(np.abs(Rh - R0[k]), np.abs(R1[k] - Rh)) >= _JUMP_KEEP * whole
            jumps.extend(zip(((a0 + a1) / 2)[jump], ((v0 + v1) / 2)[jump]))
            split &= ~jump
        if depth == _MAX_EDGE_DEPTH and split.any():
            suspects.extend(zip(((a0 + a1) / 2)[split], ((v0 + v1) / 2)[split]))
            split[:] = False
        total += np.bincount(seg[~split], weights=d[~split], minlength=total.size)
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
    return total, suspects, jumps


def grid_windings(res: Residual, a: np.ndarray, v: np.ndarray, P: np.ndarray, cells=None):
    """Cells of the tensor grid with non-zero winding of R (counter-clockwise in (a, v)).

    Phase steps between neighbouring nodes come from arg R at the nodes; only edges whose step exceeds
    pi/2 (or touch a zero of R) are followed by adaptive bisection. ``cells`` = (i, j) restricts the
    work to those cells (all others are known to hold no root). Returns cell indices (i, j), their
    windings, and suspected roots on edges.
    """
    if cells is None:
        R = 1.0 + P
        ph_a, ph_v, ai, aj, vi, vj = edge_steps(np.angle(R), R, _SPLIT_PHASE)
        suspects = []
        if ai.size:
            ph_a[ai, aj], s1, _ = edge_phases(res, a[ai], v[aj], a[ai + 1], v[aj], P[ai, aj], P[ai + 1, aj])
            suspects += s1
        if vi.size:
            ph_v[vi, vj], s2, _ = edge_phases(res, a[vi], v[vj], a[vi], v[vj + 1], P[vi, vj], P[vi, vj + 1])
            suspects += s2
        ii, jj, wind = nonzero_windings(ph_a, ph_v)
        return ii, jj, wind, suspects
    i, j = cells
    # corners counter-clockwise: (i, j) -> (i+1, j) -> (i+1, j+1) -> (i, j+1) -> (i, j)
    ci = np.concatenate([i, i + 1, i + 1, i])
    cj = np.concatenate([j, j, j + 1, j + 1])
    nxt = np.concatenate([np.arange(i.size, 4 * i.size), np.arange(i.size)])
    Pc = P[ci, cj]
    R0, R1 = 1.0 + Pc, 1.0 + Pc[nxt]
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.angle(R1 / R0)
    hard = (np.abs(d) > _SPLIT_PHASE) | (R0 == 0) | (R1 == 0)
    suspects = []
    if hard.any():
        d[hard], suspects, _ = edge_phases(res, a[ci[hard]], v[cj[hard]], a[ci[nxt][hard]], v[cj[nxt][hard]],
                                           Pc[hard], Pc[nxt][hard])
    wind = np.rint(d.reshape(4, i.size).sum(axis=0) / (2 * np.pi)).astype(int)
    nz = wind != 0
    return i[nz], j[nz], wind[nz], suspects


def box_windings(res: Residual, box: Box) -> tuple[np.ndarray, list, list]:
    """Winding number of R around each box (counter-clockwise in (a, v)), suspected roots on the edges
    and discontinuities met on the edges (see :func:`edge_phases`)."""
    k = len(box)
    ca = np.concatenate([box.a_lo, box.a_hi, box.a_hi, box.a_lo])
    cv = np.concatenate([box.v_lo, box.v_lo, box.v_hi, box.v_hi])
    P = res.terms(ca, cv)
    nxt = np.concatenate([np.arange(k, 4 * k), np.arange(k)])
    ph, suspects, jumps = edge_phases(res, ca, cv, ca[nxt], cv[nxt], P, P[nxt])
    turn = ph.reshape(4, k).sum(axis=0)
    return np.rint(turn / (2 * np.pi)).astype(int), suspects, jumps


def at_rounding_level(P, P_a, P_v, a, v) -> np.ndarray:
    """Whether the Newton step J^-1 R at (a, v) is below the rounding of a and v (8 float spacings, plus
    what the rounding of the other coordinate implies through their coupling):
    the root is then located as well as double precision allows, even where |1 + G N| cannot reach
    tol (1 + |G N|) because R turns too steeply (e.g. a resonance of damping 1e-9: |dR/d ln w| ~ 1e9)."""
    r = 1 + P
    det = P_a.real * P_v.imag - P_v.real * P_a.imag
    with np.errstate(divide="ignore", invalid="ignore"):
        da = (P_v.imag * r.real - P_v.real * r.imag) / det
        dv = (P_a.real * r.imag - P_a.imag * r.real) / det
    # the best a for a given v moves by -(Re(conj(R_a) R_v) / |R_a|^2) per unit of v (and symmetrically):
    # the rounding of one coordinate limits the other through that coupling
    with np.errstate(divide="ignore", invalid="ignore"):
        jav = (P_a.conj() * P_v).real
        ka, kv = np.abs(jav / np.abs(P_a) ** 2), np.abs(jav / np.abs(P_v) ** 2)
    ua, uv = 8 * _rounding(a), 8 * _rounding(v)
    ka, kv = np.where(np.isfinite(ka), ka, 0.0), np.where(np.isfinite(kv), kv, 0.0)
    return (np.abs(da) <= ua + ka * uv) & (np.abs(dv) <= uv + kv * ua)


def residual_bound(P, P_a, P_v, a, v, tol: float) -> np.ndarray:
    """The residual a returned root must satisfy: |1 + G N| <= max(tol (1 + |G N|), 32 (|R_a| u_a + |R_v| u_v)),
    u the rounding unit of the log coordinate (:func:`_rounding`): the first-order change of R over the
    rounding of (ln A, ln w), the floor where R turns faster than ln A, ln w can be represented (a resonance
    of damping 1e-12). A point inside a dead band (R = 1, slopes ~0) never satisfies it."""
    return np.maximum(tol * (1 + np.abs(P)), 32 * (np.abs(P_a) * _rounding(a) + np.abs(P_v) * _rounding(v)))


def accepted(P, P_a, P_v, a, v, tol: float) -> np.ndarray:
    """Whether points are roots: within :func:`residual_bound` (the central test every returned cycle passes)."""
    with np.errstate(invalid="ignore"):
        return np.abs(1 + P) <= residual_bound(P, P_a, P_v, np.asarray(a, float), np.asarray(v, float), tol)


def _rounding(x: np.ndarray) -> np.ndarray:
    """The rounding unit of log coordinates x: their float spacing, at least one roundoff (exp(x)
    carries a relative error of that size however small x is)."""
    return np.maximum(np.spacing(np.abs(x)), np.finfo(float).eps)


def refine(res: Residual, a, v, box: Box, tol: float, certified: bool = False
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Levenberg-Marquardt on (Re R, Im R) from (a, v), each point clipped to its box.

    Every trial point is evaluated together with its finite-difference neighbours, so an accepted step
    costs one call. Returns the final (a, v) and a mask of points with |R| <= tol (1 + |G N|) or
    a Newton step at the rounding level of (a, v) (:func:`at_rounding_level`), and within
    :func:`residual_bound` in either case. With ``certified`` (each box is known to hold a root: its winding
    is +-1), a point where the iteration ends within :func:`residual_bound` also counts: R is then at the
    floor set by the rounding of (ln A, ln w), though the Newton step is not (a nearly singular Jacobian, e.g.
    a root 1e-12 from the edge of a dead band under |G| = 3e10, where N itself carries a relative rounding
    error of 1e-5 and dR/da, dR/dv are nearly parallel).
    Bounded by 100 iterations. A residual with its own ``refine`` (the compiled one) runs the same iteration.
    """
    if hasattr(res, "refine"):
        return res.refine(a, v, box, tol, certified)
    a, v = np.array(a, float), np.array(v, float)
    P, ra, rv = res.slopes(a, v)
    rel = np.abs(1 + P) / (1 + np.abs(P))
    lam = np.full(a.size, 1e-12)
    polish = tol * _POLISH  # keep going past tol while it pays: flat residuals need it for position
    done = (rel <= polish) | at_rounding_level(P, ra, rv, a, v)
    failed = np.zeros(a.size, bool)
    for _ in range(_MAX_LM_ITER):
        act = np.flatnonzero(~done & ~failed)
        if act.size == 0:
            break
        r, ja, jv = 1 + P[act], ra[act], rv[act]
        # real 2x2 normal equations of J = [[Re ra, Re rv], [Im ra, Im rv]]
        jaa = np.abs(ja) ** 2
        jvv = np.abs(jv) ** 2
        jav = (ja.conj() * jv).real
        ga = (ja.conj() * r).real
        gv = (jv.conj() * r).real
        # Marquardt's diagonal damping: invariant under rescaling either coordinate (a resonance makes
        # |dR/dv| 1e9 times |dR/da|, which an isotropic damping would let freeze the a-step)
        m11, m22 = jaa * (1 + lam[act]), jvv * (1 + lam[act])
        det = m11 * m22 - jav ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            da = -(m22 * ga - jav * gv) / det
            dv = -(m11 * gv - jav * ga) / det
        ok_step = np.isfinite(da) & np.isfinite(dv)
        da, dv = np.where(ok_step, da, 0.0), np.where(ok_step, dv, 0.0)
        # a step below the rounding of its coordinate only flips between neighbouring floats: drop it so
        # the other coordinate can converge (a root between two adjacent floats of ln w at a resonance)
        # (then the step of the other coordinate alone is taken)
        fine_a = np.abs(da) <= 2 * _rounding(a[act])
        fine_v = np.abs(dv) <= 2 * _rounding(v[act])
        with np.errstate(divide="ignore", invalid="ignore"):
            da = np.where(fine_a, 0.0, np.where(fine_v, -ga / jaa, da))
            dv = np.where(fine_v, 0.0, np.where(fine_a, -gv / jvv, dv))
        da, dv = np.where(np.isfinite(da), da, 0.0), np.where(np.isfinite(dv), dv, 0.0)
        at = np.clip(a[act] + da, box.a_lo[act], box.a_hi[act])
        vt = np.clip(v[act] + dv, box.v_lo[act], box.v_hi[act])
        Pt, rat, rvt = res.slopes(at, vt)
        relt = np.abs(1 + Pt) / (1 + np.abs(Pt))
        better = (relt < rel[act]) & ok_step
        pinned = ((at == box.a_lo[act]) | (at == box.a_hi[act]) | (vt == box.v_lo[act]) | (vt == box.v_hi[act]))
        # converging to a non-zero minimum, or pressed against the box towards a root outside it
        # (a slow decrease with a sizeable step is not a stall: the other coordinate is still converging)
        small = (np.abs(da) <= 1e-9 * (1 + np.abs(a[act]))) & (np.abs(dv) <= 1e-9 * (1 + np.abs(v[act])))
        stalled = better & (((relt > (1 - 1e-3) * rel[act]) & small) | (pinned & (relt > 0.5 * rel[act])))
        acc, rej = act[better], act[~better]
        failed[act[stalled]] = True
        a[acc], v[acc], P[acc], rel[acc] = at[better], vt[better], Pt[better], relt[better]
        ra[acc], rv[acc] = rat[better], rvt[better]
        lam[acc] = np.maximum(lam[acc] / 10, 1e-15)
        lam[rej] *= 100
        done = (rel <= polish) | at_rounding_level(P, ra, rv, a, v)
        failed |= (lam > 1e8) & ~done
    ok = accepted(P, ra, rv, a, v, tol)
    return a, v, ok if certified else ok & ((rel <= tol) | at_rounding_level(P, ra, rv, a, v))


def _span(box: Box) -> float:
    """The largest side (log units) of the bounding box of ``box``'s boxes."""
    return float(max(box.a_hi.max() - box.a_lo.min(), box.v_hi.max() - box.v_lo.min()))


def _touches(box: Box, points: list) -> np.ndarray:
    """Mask of boxes containing (edges included) at least one of ``points`` [(a, v), ...]."""
    if not points:
        return np.zeros(len(box), bool)
    pa, pv = np.array(points).T
    inside = ((box.a_lo[:, None] <= pa) & (pa <= box.a_hi[:, None])
              & (box.v_lo[:, None] <= pv) & (pv <= box.v_hi[:, None]))
    return inside.any(axis=1)


_START_LATTICE = 9  # starts per side of a box whose centre did not refine (the best of 9 x 9 is taken)


def _best_starts(res: Residual, box: Box) -> tuple[np.ndarray, np.ndarray]:
    """Per box, the point of a ``_START_LATTICE`` x ``_START_LATTICE`` lattice (ends included) with the smallest
    |1 + G N| / (1 + |G N|) where G N != 0: a start off a dead band (where R = 1 and its slopes vanish, so a
    refinement from there cannot move), e.g. when the box centre of a root next to the band's edge lies in it."""
    t = np.linspace(0.0, 1.0, _START_LATTICE)
    ta, tv = (x.ravel() for x in np.meshgrid(t, t))
    pa = box.a_lo[:, None] + ta[None, :] * (box.a_hi - box.a_lo)[:, None]
    pv = box.v_lo[:, None] + tv[None, :] * (box.v_hi - box.v_lo)[:, None]
    P = res.terms(pa, pv)
    with np.errstate(invalid="ignore"):
        rel = np.where(P != 0, np.abs(1 + P) / (1 + np.abs(P)), np.inf)
    k = np.argmin(rel, axis=1)
    rows = np.arange(len(box))
    return pa[rows, k], pv[rows, k]


_CHASE_SPLIT = 4  # a box of winding +-1 is split 4 x 4 per round of _chase ...
_MAX_CHASE = 30  # ... for at most this many rounds (4^-30 of its sides, below any float spacing)


def _chase(res: Residual, box: Box, tol: float) -> tuple[float, float, bool]:
    """Root of one box known to wind once: refined (certified, inside the box) from the best of a lattice of
    starts; failing that, the box is split ``_CHASE_SPLIT`` x ``_CHASE_SPLIT`` and the sub-box that winds is
    followed (bounded by ``_MAX_CHASE`` rounds and by the float spacing of its sides). Next to a dead-band edge
    under a huge |G|, R jumps from 1 to hundreds within 1e-9 and most starts lie on the flat side.
    Returns (a, v, found)."""
    a = v = np.nan
    for _ in range(_MAX_CHASE):
        ra, rv, ok = refine(res, *_best_starts(res, box), box, tol, certified=True)
        a, v = float(ra[0]), float(rv[0])
        if ok[0]:
            return a, v, True
        t = np.linspace(0.0, 1.0, _CHASE_SPLIT + 1)
        ea = box.a_lo[0] + t * (box.a_hi[0] - box.a_lo[0])
        ev = box.v_lo[0] + t * (box.v_hi[0] - box.v_lo[0])
        if np.any(np.diff(ea) <= 2 * _rounding(ea[1:])) or np.any(np.diff(ev) <= 2 * _rounding(ev[1:])):
            break  # the sides reach the float spacing: nothing left to split
        ia, iv = (x.ravel() for x in np.meshgrid(np.arange(_CHASE_SPLIT), np.arange(_CHASE_SPLIT)))
        kids = Box(ea[ia], ea[ia + 1], ev[iv], ev[iv + 1])
        wind = box_windings(res, kids)[0]
        hit = np.flatnonzero(np.abs(wind) == 1)
        if hit.size != 1:
            break  # the root sits on a sub-box edge, or the winding splits: not a single root to follow
        box = kids.take(hit)
    return a, v, False


def _isolate(res: Residual, box: Box, window: Box, tol: float, hint: tuple[float, float] | None = None):
    """Quadrisect one box until its roots sit in boxes of winding +-1, then refine those (bounded).

    Returns the refined roots (a, v) and the jump crossings [(a, v, winding), ...]: boxes narrower than
    ``JUMP_BOX`` that still wind, hold no refinable root and touch a discontinuity of N (never for a
    continuous N). A box that still winds when the depth bound is reached and whose refinement fails is
    recorded in ``res.unresolved`` (a_lo, a_hi, v_lo, v_hi, winding): a root may lie there.
    """
    found_a, found_v, crossings = [], [], []
    queue, queue_wind = box, np.zeros(len(box), int)
    for _ in range(_MAX_ISOLATE_DEPTH):
        if len(queue) == 0:
            break
        kids = queue.quadrisect()
        wind, suspects, jumps = box_windings(res, kids)
        single = np.abs(wind) == 1
        if single.any():
            sb = kids.take(single)
            a, v, ok = refine(res, (sb.a_lo + sb.a_hi) / 2, (sb.v_lo + sb.v_hi) / 2, sb.grown(0.5, window), tol,
                              certified=True)
            ok &= sb.grown(1e-9, window).contains(a, v)
            found_a.extend(a[ok])
            found_v.extend(v[ok])
            single[single] = ok  # failed refinements are subdivided further
        keep = ~single & (wind != 0)
        tiny = np.maximum(kids.a_hi - kids.a_lo, kids.v_hi - kids.v_lo) < JUMP_BOX
        crossing = keep & tiny & _touches(kids, jumps)
        crossings.extend(zip((kids.a_lo + kids.a_hi)[crossing] / 2, (kids.v_lo + kids.v_hi)[crossing] / 2,
                             wind[crossing]))
        keep &= ~crossing
        if hint is not None:
            keep |= (wind == 0) & kids.contains(*hint)
        if len(suspects) > _MAX_LIVE_BOXES:  # zeros on that many edges: a curve of zeros, not points
            sa, sv = np.array(suspects).T
            check_continuum(res, sa, sv, window, tol)
        keep |= _touches(kids, suspects[:_MAX_LIVE_BOXES])
        queue, queue_wind = kids.take(keep), wind[keep]
        if len(queue) > _MAX_LIVE_BOXES and _span(queue) < _MULTIPLE_ROOT_SPAN:
            # the live boxes crowd around one point smaller than a resolvable separation: a multiple (tangent)
            # root whose neighbourhood has zeros of Re R or Im R on many edges; refined below as one box
            queue = Box(*(np.array([f(x)]) for f, x in ((np.min, queue.a_lo), (np.max, queue.a_hi),
                                                          (np.min, queue.v_lo), (np.max, queue.v_hi))))
            queue_wind = np.array([int(queue_wind.sum())])
            break
        if len(queue) > _MAX_LIVE_BOXES:
            check_continuum(res, (queue.a_lo + queue.a_hi) / 2, (queue.v_lo + queue.v_hi) / 2, window, tol)
            raise RuntimeError(f"root isolation kept {len(queue)} boxes alive (bound {_MAX_LIVE_BOXES}) without "
                               "isolating the roots; narrow the window around "
                               f"A in [{np.exp(queue.a_lo.min()):.6g}, {np.exp(queue.a_hi.max()):.6g}], omega in "
                               f"[{np.exp(queue.v_lo.min()):.6g}, {np.exp(queue.v_hi.max()):.6g}] rad/s")
    if len(queue):
        # bound reached: what is left is a multiple (e.g. tangent) root smaller than the box size
        a, v, ok = refine(res, (queue.a_lo + queue.a_hi) / 2, (queue.v_lo + queue.v_hi) / 2,
                          queue.grown(1.0, window), tol)
        single = np.flatnonzero(~ok & (np.abs(queue_wind) == 1))
        if single.size:
            # a box known to hold one root: refined inside the box itself, the residual bound alone accepts (see
            # refine); a nearly singular Jacobian (dR/da, dR/dv parallel to 1e-5 next to a dead-band edge)
            # otherwise lets the iteration slide along its null direction out of the box
            for k in single:
                a[k], v[k], ok[k] = _chase(res, queue.take([k]), tol)
        found_a.extend(a[ok])
        found_v.extend(v[ok])
        lost = ~ok & (queue_wind != 0)  # still winding, no root refined: say so (GridReport.uncertified)
        res.unresolved.extend(zip(queue.a_lo[lost].tolist(), queue.a_hi[lost].tolist(), queue.v_lo[lost].tolist(),
                                  queue.v_hi[lost].tolist(), queue_wind[lost].tolist()))
    return found_a, found_v, crossings


_DEGENERATE_SIN = 1e-4  # |sin| of the crossing angle below which a root is checked for a curve of zeros
_MAX_WALK = 60  # predictor-corrector steps along a curve of zeros, each way
_MAX_WALK_ROOTS = 4  # degenerate roots walked from


def _null_direction(ra: complex, rv: complex) -> np.ndarray:
    """Unit vector (da, dv) along which R does not change to first order (smallest singular vector)."""
    J = np.array([[ra.real, rv.real], [ra.imag, rv.imag]])
    return np.linalg.svd(J)[2][-1]


def check_continuum(res: Residual, a: np.ndarray, v: np.ndarray, window: Box, tol: float,
                    refined: bool = False) -> None:
    """Raise :class:`ContinuumError` (a ValueError) when points near (a, v) lie on a whole curve of zeros of R (a continuum of
    solutions, where G(jw) lies on -1/N): no isolated limit cycle exists there.

    From up to ``_MAX_WALK_ROOTS`` points whose refined root has a degenerate Jacobian (|sin| of the angle
    between dR/da and dR/dv below ``_DEGENERATE_SIN``), walk along the null direction of the Jacobian by
    predictor-corrector steps (each corrected by :func:`refine` in a box that excludes the previous point).
    Three consecutive successful steps make a curve: an isolated (tangent) root has no neighbour. Bounded
    by ``_MAX_WALK`` steps each way.
    """
    a, v = np.asarray(a, float), np.asarray(v, float)
    if a.size == 0:
        return
    pick = np.unique(np.linspace(0, a.size - 1, min(a.size, 16)).astype(int))
    ext = max(window.a_hi[0] - window.a_lo[0], window.v_hi[0] - window.v_lo[0])
    if refined:
        ra_, rv_ = a[pick], v[pick]
    else:
        ra_, rv_, ok = refine(res, a[pick], v[pick], window.take(np.zeros(pick.size, int)), tol)
        ra_, rv_ = ra_[ok], rv_[ok]
    if ra_.size == 0:
        return
    _, da, dv = res.slopes(ra_, rv_)
    with np.errstate(divide="ignore", invalid="ignore"):
        sin = np.abs(da.real * dv.imag - dv.real * da.imag) / (np.abs(da) * np.abs(dv))
    sin = np.where(np.isfinite(sin), sin, 0.0)
    for k in np.flatnonzero(sin < _DEGENERATE_SIN)[:_MAX_WALK_ROOTS]:
        visited = [(ra_[k], rv_[k])]
        for sign in (1.0, -1.0):
            pos, d, step = np.array([ra_[k], rv_[k]]), sign * _null_direction(da[k], dv[k]), 1e-3 * ext
            for _ in range(_MAX_WALK):
                trial = pos + step * d
                box = Box(trial[0] - step / 2, trial[0] + step / 2, trial[1] - step / 2, trial[1] + step / 2)
                box = Box(np.maximum(box.a_lo, window.a_lo), np.minimum(box.a_hi, window.a_hi),
                          np.maximum(box.v_lo, window.v_lo), np.minimum(box.v_hi, window.v_hi))
                if box.a_lo[0] >= box.a_hi[0] or box.v_lo[0] >= box.v_hi[0]:
                    break
                na_, nv_, good = refine(res, trial[:1], trial[1:], box, tol)
                new = np.array([na_[0], nv_[0]])
                if not good[0] or np.max(np.abs(new - pos)) < step / 4:
                    break
                _, ja, jv = res.slopes(new[:1], new[1:])
                nd = _null_direction(ja[0], jv[0])
                d, pos, step = (nd if nd @ d >= 0 else -nd), new, min(2 * step, 0.05 * ext)
                visited.append(tuple(new))
        if len(visited) >= 4:
            pa, pv = np.exp(np.array(visited).T)
            raise ContinuumError((float(pa.min()), float(pa.max())), (float(pv.min()), float(pv.max())))


def _merge_crossings(crossings: list) -> np.ndarray:
    """Jump crossings (a, v, winding) closer than 1e-6 (max norm, log units) merged; rows sorted by v."""
    out: list = []
    for a, v, w in sorted(crossings, key=lambda c: (c[1], c[0])):
        if not any(max(abs(a - b), abs(v - u)) < 1e-6 for b, u, _ in out):
            out.append((a, v, w))
    return np.array(out, dtype=float).reshape(-1, 3)


def merge(res: Residual, a: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge refined points that are the same root; sorted by v.

    Two points are the same root when closer (max norm, log coordinates) than 1e-12 plus four times
    their position uncertainties |R| / s_min(J), s_min the smaller singular value of the Jacobian.
    """
    order = np.lexsort((a, v))
    a, v = a[order], v[order]
    if a.size < 2:
        return a, v
    P, ra, rv = res.slopes(a, v)
    jaa, jvv, jav = np.abs(ra) ** 2, np.abs(rv) ** 2, (ra.conj() * rv).real
    half_tr, det = (jaa + jvv) / 2, jaa * jvv - jav ** 2
    s_min = np.sqrt(np.maximum(half_tr - np.sqrt(np.maximum(half_tr ** 2 - det, 0)), 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = _MERGE_RADIUS + 4 * np.where(s_min > 0, np.abs(1 + P) / s_min, np.inf)
    radius = np.minimum(radius, 1e-2)
    keep = greedy_unique(a, v, radius)
    return a[keep], v[keep]


def greedy_unique(a: np.ndarray, v: np.ndarray, radius) -> np.ndarray:
    """Indices of points kept in order, dropping each point within radius[k] + radius[m] (max norm) of
    an earlier kept point m.

    Memory O(n): the points are sorted by v and each one is compared only with those within
    radius[k] + max(radius) of it in v (a delay plant has ~1e4 roots: the n x n pair matrix took GBs);
    the python loop runs only over points with such a neighbour.
    """
    a, v = np.asarray(a, float), np.asarray(v, float)
    radius = np.broadcast_to(np.asarray(radius, float), a.shape)
    if a.size < 2:
        return np.arange(a.size)
    order = np.argsort(v, kind="stable")
    vs = v[order]
    reach = (radius + radius.max()) * (1 + 1e-9)  # a prefilter only, widened against rounding
    lo, hi = np.searchsorted(vs, v - reach, "left"), np.searchsorted(vs, v + reach, "right")
    keep = np.ones(a.size, bool)
    for k in np.flatnonzero(hi - lo > 1):  # every point lies in its own window
        m = order[lo[k]:hi[k]]
        m = m[m < k]
        m = m[keep[m]]
        if m.size and np.any(np.maximum(np.abs(a[k] - a[m]), np.abs(v[k] - v[m])) <= radius[k] + radius[m]):
            keep[k] = False
    return np.flatnonzero(keep)


def _linear_guess(P: np.ndarray, i: np.ndarray, j: np.ndarray, cells: Box) -> tuple[np.ndarray, np.ndarray]:
    """Root of the linear model of R fitted to each cell's four corners (clipped to the cell)."""
    r00, r10, r01, r11 = 1 + P[i, j], 1 + P[i + 1, j], 1 + P[i, j + 1], 1 + P[i + 1, j + 1]
    ha, hv = cells.a_hi - cells.a_lo, cells.v_hi - cells.v_lo
    ja = (r10 - r00 + r11 - r01) / (2 * ha)
    jv = (r01 - r00 + r11 - r10) / (2 * hv)
    rc = (r00 + r10 + r01 + r11) / 4
    det = ja.real * jv.imag - jv.real * ja.imag
    with np.errstate(divide="ignore", invalid="ignore"):
        da = -(jv.imag * rc.real - jv.real * rc.imag) / det
        dv = -(-ja.imag * rc.real + ja.real * rc.imag) / det
    da, dv = np.where(np.isfinite(da), da, 0.0), np.where(np.isfinite(dv), dv, 0.0)
    return (np.clip((cells.a_lo + cells.a_hi) / 2 + da, cells.a_lo, cells.a_hi),
            np.clip((cells.v_lo + cells.v_hi) / 2 + dv, cells.v_lo, cells.v_hi))


def _near_jump(P: np.ndarray, i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """Whether a dominant step of P (:func:`dominant_steps`) lies within n nodes of each node (i, j).

    For an :class:`OuterProduct` P = N G, every column's steps along the amplitudes are |G_j| times N's own steps,
    so a step dominates its neighbours in some column exactly when it does in N's samples (and G is not 0 in every
    column of the patch); along the frequencies likewise with G's samples: two 1-D tests per node instead of one
    per row and column of its patch (the compiled driver's ``_near_jump`` decides alike)."""
    out = np.zeros(i.size, bool)
    for k, (x, y) in enumerate(zip(i.tolist(), j.tolist())):
        rows, cols = slice(max(x - n - 1, 0), x + n + 2), slice(max(y - n - 1, 0), y + n + 2)
        if isinstance(P, OuterProduct):
            pn, pg = P.n[rows, None], P.g[cols, None]
            out[k] = (np.any(pg) and dominant_steps(pn).any()) or (np.any(pn) and dominant_steps(pg).any())
        else:
            patch = P[rows, cols]
            out[k] = dominant_steps(patch).any() or dominant_steps(patch.T).any()
    return out


def _node_boxes(a: np.ndarray, v: np.ndarray, i: np.ndarray, j: np.ndarray, n: int) -> Box:
    """Boxes spanning n grid nodes on each side of nodes (i, j), clipped to the grid."""
    return Box(a[np.maximum(i - n, 0)], a[np.minimum(i + n, a.size - 1)],
               v[np.maximum(j - n, 0)], v[np.minimum(j + n, v.size - 1)])


def _wrap(d: float) -> float:
    """d wrapped to [-pi, pi) (d within (-5 pi, 5 pi): sums and differences of two args and pi)."""
    for _ in range(2):
        if d >= math.pi:
            d -= 2 * math.pi
        elif d < -math.pi:
            d += 2 * math.pi
    return d


def _gap(l0: complex, l1: complex, t: complex, e: float) -> float:
    """How far (log units, arg modulo 2 pi) the rectangle spanned by l0, l1 (ln N at the ends of a piece where
    ln|N| and arg N are monotone and arg N turns by less than pi) lies from the disc of radius e around t
    (j pi - ln G at the left end of a piece of G, e the exact bound on ln G's change over it)."""
    x0, x1 = min(l0.real, l1.real), max(l0.real, l1.real)
    dy = _wrap(l1.imag - l0.imag)
    yc, hy = l0.imag + 0.5 * dy, 0.5 * abs(dy)
    dx = max(x0 - t.real, t.real - x1, 0.0)
    dd = max(abs(_wrap(t.imag - yc)) - hy, 0.0)
    return math.sqrt(dx * dx + dd * dd) - e


def _log(x: float) -> float:
    """ln x, -inf at 0 (as numpy)."""
    return math.log(x) if x > 0 else -math.inf


def _variation(plant: Plant, w0: float, w1: float) -> float:
    """:meth:`Plant.log_variation` on one interval [w0, w1], in scalar arithmetic (the same bound)."""
    rise = fall = pos = neg = 0.0
    zeros, poles = plant.roots
    for sg, roots in ((1.0, zeros), (-1.0, poles)):
        for r in roots.tolist():
            x, y = -r.real, r.imag
            turn = sg * math.atan2(x * (w1 - w0), x * x + (w0 - y) * (w1 - y))
            m0, m1 = 0.5 * _log(x * x + (w0 - y) ** 2), 0.5 * _log(x * x + (w1 - y) ** 2)
            low = _log(abs(x)) if w0 < y < w1 else min(m0, m1)
            rise += (m1 - low) if sg > 0 else (m0 - low)
            fall += (m0 - low) if sg > 0 else (m1 - low)
            pos += max(turn, 0.0)
            neg += min(turn, 0.0)
    return math.hypot(max(pos, -neg + float(plant.delay) * (w1 - w0)), max(rise, fall))


def _clog1(z: complex) -> complex:
    return complex(math.log(abs(z)), math.atan2(z.imag, z.real))


def seed_excluded(res: Residual, a: np.ndarray, v: np.ndarray, ln_n: np.ndarray, eps_a: np.ndarray, ln_g: np.ndarray,
                  eps_v: np.ndarray, i0: int, i1: int, j0: int, j1: int) -> bool:
    """Whether the box a[i0]..a[i1] x v[j0]..v[j1] provably holds no point where |1 + G N| is within 0.125 % of
    1 + |G N|: no root, and nothing :func:`refine` could accept there (tol < 1e-3).

    A root needs ln N(a) = j pi - ln G(v) (mod 2 pi j): the curve ln N over the box's amplitudes must meet the
    curve j pi - ln G over its frequencies. On each interval of N's grid ln|N| and arg N are monotone (the
    monotone rule of :func:`~dfloop.solve.grid.resolve_sampled`, the promise the candidate cells rest on), so ln N
    there stays in the rectangle its ends span; j pi - ln G stays within :meth:`Plant.log_variation` of its value
    at either end of an interval (the exact bound, rational G), and within
    :func:`~dfloop.solve.grid.chord_deviation` of the chord between those values (from its curvature), so a pair
    is apart when the rectangle lies ``_SEED_MARGIN`` beyond both discs or beyond the thickened chord
    (:func:`~dfloop.solve.grid.chord_gap`). Every pair of an N piece and a G piece closer
    than that is replaced by the pairs of the halves of the piece whose uncertainty binds the better of the two
    tests (N's rectangle against G's chord deviation, or against its disc radius; N or G evaluated at the
    midpoint the first time a piece is halved), with at most ``_SEED_SPLITS`` halvings and ``_SEED_TESTS`` pair
    tests; a pair one of whose N ends lies within ``_SEED_MARGIN`` of one of its G ends ends the search at once
    (:func:`_close_ends`: no halving could separate it). When all pairs are ``_SEED_MARGIN`` apart,
    |ln(G N) - j pi| >= 0.005 throughout the box, so |1 + G N| / (1 + |G N|) >= 0.00125 > tol (the relative
    residual is sqrt(sinh^2(x/2) + sin^2(y/2)) / cosh(x/2) at ln(G N) - j pi = x + j y). Intervals N cannot be bounded on (a jump, N = 0 at an end, a turn left at the
    monotone width) and plants without poles and zeros are never excluded. ln_n, ln_g: complex logs of N and G at
    the grid nodes; eps_a, eps_v: the grid's bounds.
    """
    plant = res.plant
    if not plant.exact or plant.frequency_map is not None or res.frequency_dependent:
        return False
    npc = []  # N pieces: [a0, a1, ln N(a0), ln N(a1)]
    for i in range(i0, i1):
        if not (eps_a[i] <= STEP and a[i + 1] - a[i] > MONOTONE_WIDTH * (1 + abs(a[i]))):
            return False
        if not (math.isfinite(ln_n[i].real) and math.isfinite(ln_n[i + 1].real)):
            return False
        npc.append([a[i], a[i + 1], complex(ln_n[i]), complex(ln_n[i + 1])])
    zeros, poles = plant.roots
    delay = float(plant.delay)
    gpc = []  # G pieces: [v0, v1, j pi - ln G(v0), j pi - ln G(v1), bound, chord deviation]
    for j in range(j0, j1):
        if not (math.isfinite(eps_v[j]) and math.isfinite(ln_g[j].real) and math.isfinite(ln_g[j + 1].real)):
            return False
        gpc.append([v[j], v[j + 1], complex(-ln_g[j].real, math.pi - ln_g[j].imag),
                    complex(-ln_g[j + 1].real, math.pi - ln_g[j + 1].imag), float(eps_v[j]),
                    chord_deviation(zeros, poles, delay, float(v[j]), float(v[j + 1]))])
    pairs = [(p, q) for p in range(len(npc)) for q in range(len(gpc))]
    n_child, g_child = [-1] * len(npc), [-1] * len(gpc)  # the pieces are binary trees: halves made once, shared
    splits = tests = 0
    while pairs:
        p, q = pairs.pop()
        xa0, xa1, l0, l1 = npc[p]
        xv0, xv1, t0, t1, e, h = gpc[q]
        tests += 1
        lens = max(_gap(l0, l1, t0, e), _gap(l0, l1, t1, e))
        if lens >= _SEED_MARGIN:
            continue
        chord = chord_gap(l0, l1, t0, t1, e, h)
        if chord >= _SEED_MARGIN:
            continue
        if tests > _SEED_TESTS or _close_ends(l0, l1, t0, t1):
            return False
        # halve the piece whose uncertainty binds the better test: G's is h against its chord, e against the discs
        if math.hypot(l1.real - l0.real, _wrap(l1.imag - l0.imag)) >= (h if chord >= lens else e):  # N's halves
            if n_child[p] < 0:
                splits += 1
                if splits > _SEED_SPLITS:
                    return False
                xm = 0.5 * (xa0 + xa1)
                nm = complex(np.asarray(res.N(np.array([math.exp(xm)])), complex).ravel()[0])
                if not (math.isfinite(nm.real) and math.isfinite(nm.imag)) or nm == 0:
                    return False
                lm = _clog1(nm)
                n_child[p] = len(npc)
                npc += [[xa0, xm, l0, lm], [xm, xa1, lm, l1]]
                n_child += [-1, -1]
            pairs += [(n_child[p], q), (n_child[p] + 1, q)]
        else:  # the G piece's halves
            if g_child[q] < 0:
                splits += 1
                if splits > _SEED_SPLITS:
                    return False
                xm = 0.5 * (xv0 + xv1)
                w0, wm, w1 = math.exp(xv0), math.exp(xm), math.exp(xv1)
                gm = complex(plant(np.array([wm]))[0])
                if not (math.isfinite(gm.real) and math.isfinite(gm.imag)) or gm == 0:
                    return False
                lgm = _clog1(gm)
                tm = complex(-lgm.real, math.pi - lgm.imag)
                e0, e1 = _variation(plant, w0, wm), _variation(plant, wm, w1)
                if not (math.isfinite(e0) and math.isfinite(e1)):
                    return False
                g_child[q] = len(gpc)
                gpc += [[xv0, xm, t0, tm, e0, chord_deviation(zeros, poles, delay, xv0, xm)],
                        [xm, xv1, tm, t1, e1, chord_deviation(zeros, poles, delay, xm, xv1)]]
                g_child += [-1, -1]
            pairs += [(p, g_child[q]), (p, g_child[q] + 1)]
    return True


def _close_ends(l0: complex, l1: complex, t0: complex, t1: complex) -> bool:
    """Whether an end of the N piece (l0, l1) lies within ``_SEED_MARGIN`` of an end of the G piece (t0, t1), arg
    modulo 2 pi: then the box holds a point where ln N and j pi - ln G are that close, every pair of pieces holding
    both fails both tests of :func:`seed_excluded` (each disc, and the thickened chord, holds its G end), and no
    number of halvings can prove the box: the search would end at its budget with the same answer."""
    return any(math.hypot(l.real - t.real, _wrap(l.imag - t.imag)) < _SEED_MARGIN for l in (l0, l1) for t in (t0, t1))


def cell_apart(res: Residual, a: np.ndarray, v: np.ndarray, ln_n: np.ndarray, eps_a: np.ndarray, ln_g: np.ndarray,
               eps_v: np.ndarray, i: int, j: int) -> bool:
    """Whether the cell a[i]..a[i+1] x v[j]..v[j+1] provably holds no point where |1 + G N| is within 0.125 % of
    1 + |G N|: :func:`seed_excluded`'s test of one pair of pieces (the cell's own), without halving. R then has no
    zero in the cell: it winds 0 around it."""
    plant = res.plant
    if not plant.exact or plant.frequency_map is not None or res.frequency_dependent:
        return False
    if not (eps_a[i] <= STEP and a[i + 1] - a[i] > MONOTONE_WIDTH * (1 + abs(a[i]))):
        return False
    if not (math.isfinite(ln_n[i].real) and math.isfinite(ln_n[i + 1].real) and math.isfinite(eps_v[j])
            and math.isfinite(ln_g[j].real) and math.isfinite(ln_g[j + 1].real)):
        return False
    l0, l1, e = complex(ln_n[i]), complex(ln_n[i + 1]), float(eps_v[j])
    t0 = complex(-ln_g[j].real, math.pi - ln_g[j].imag)
    t1 = complex(-ln_g[j + 1].real, math.pi - ln_g[j + 1].imag)
    if max(_gap(l0, l1, t0, e), _gap(l0, l1, t1, e)) >= _SEED_MARGIN:
        return True
    zeros, poles = plant.roots
    h = chord_deviation(zeros, poles, float(plant.delay), float(v[j]), float(v[j + 1]))
    return chord_gap(l0, l1, t0, t1, e, h) >= _SEED_MARGIN


def _winding_cells(res: Residual, a, v, P, cells, bounds):
    """The candidate cells whose windings are computed: all but those with an edge step that turns R by pi/2 or
    more (which the winding would bisect, evaluating G and N) that :func:`cell_apart` proves free of zeros of R
    (they wind 0). The same windings and roots; fewer evaluations. Decided as the compiled driver decides: in its
    kernel on a compiled loop once the driver is ready (``res.apart_cells``)."""
    i, j = cells
    if i.size == 0:
        return cells
    corners = [1.0 + P[i + di, j + dj] for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1))]  # counter-clockwise
    easy = np.ones(i.size, bool)
    for q in range(4):  # every step turns R by less than pi/2 (with a margin): the winding passes it anyway
        r0, r1 = corners[q], corners[(q + 1) % 4]
        x = r1.real * r0.real + r1.imag * r0.imag
        y = r1.imag * r0.real - r1.real * r0.imag
        easy &= x > 1e-6 * np.abs(y)
    hard = np.flatnonzero(~easy)
    if hard.size == 0:
        return cells
    compiled = getattr(res, "apart_cells", None)
    apart = None if compiled is None else compiled(a, v, P, i[hard], j[hard], bounds)
    if apart is None:
        eps_a, eps_v = bounds
        ln_n, ln_g = clog(P.n), clog(P.g)
        apart = np.array([cell_apart(res, a, v, ln_n, eps_a, ln_g, eps_v, ci, cj)
                          for ci, cj in zip(i[hard].tolist(), j[hard].tolist())], bool)
    keep = np.ones(i.size, bool)
    keep[hard[apart]] = False
    return i[keep], j[keep]


def _refined_seeds(res: Residual, a, v, P, si: np.ndarray, sj: np.ndarray, bounds) -> np.ndarray:
    """The tangent seeds worth refining: a seed whose +-2-node box provably holds nothing the refinement could
    accept (:func:`seed_excluded`) is dropped, unless the wider +-3-node retry next to a jump of N could still
    run and its box is not excluded too. The refinements of the seeds kept give exactly what refining all of
    them gives (every refinement of a dropped seed fails)."""
    compiled = getattr(res, "kept_seeds", None)  # a compiled loop: the same exclusion, in its kernel when ready
    keep = None if compiled is None else compiled(a, v, P, si, sj, bounds)
    if keep is not None:
        return keep
    eps_a, eps_v = bounds
    ln_n, ln_g = clog(P.n), clog(P.g)
    na, nv = a.size, v.size
    keep = np.ones(si.size, bool)
    for k, (i, j) in enumerate(zip(si.tolist(), sj.tolist())):
        if seed_excluded(res, a, v, ln_n, eps_a, ln_g, eps_v, max(i - 2, 0), min(i + 2, na - 1), max(j - 2, 0),
                         min(j + 2, nv - 1)):
            keep[k] = bool(_near_jump(P, np.array([i]), np.array([j]), 3)[0]) and not seed_excluded(
                res, a, v, ln_n, eps_a, ln_g, eps_v, max(i - 3, 0), min(i + 3, na - 1), max(j - 3, 0),
                min(j + 3, nv - 1))
    return keep


def find_roots(res: Residual, a: np.ndarray, v: np.ndarray, P: np.ndarray, tol: float, cells=None, bounds=None):
    """All roots of R in the window spanned by the grid (a, v) with loop products P = G N on it.

    ``cells`` = (i, j): the only cells that can hold a root (see ``candidate_cells``); None for all. P is an
    array, or with ``cells`` an :class:`OuterProduct` (only read at the candidate cells and their neighbours).
    ``bounds`` = (eps_a, eps_v), the grid's bounds per interval (with ``cells``): tangent seeds whose boxes
    provably hold no root are then not refined (:func:`_refined_seeds`).
    Returns arrays (a, v) of refined roots (|R| <= tol (1 + |GN|)), merged and sorted by frequency,
    and the jump crossings of N as rows (a, v, winding) sorted by frequency. Raises ValueError when
    the roots form a continuum (:func:`check_continuum`).
    """
    window = Box(a[0], a[-1], v[0], v[-1])
    wound = cells
    if cells is not None and bounds is not None and isinstance(P, OuterProduct):
        wound = _winding_cells(res, a, v, P, cells, bounds)  # cells proved free of zeros wind 0
    ii, jj, wind, suspects = grid_windings(res, a, v, P, wound)
    if len(suspects) + np.count_nonzero(np.abs(wind) > 1) > _EARLY_CONTINUUM_CHECK:
        # many zeros on grid edges or multiple windings: look for a curve of zeros before isolating
        pts = np.array(suspects + list(zip((a[ii] + a[ii + 1]) / 2, (v[jj] + v[jj + 1]) / 2))).T
        check_continuum(res, pts[0], pts[1], window, tol)
    if cells is None:  # every node, row-major
        nodes = np.arange(P.size, dtype=np.int64)
    else:  # the corners of the candidate cells, row-major (the work then scales with them, not the grid)
        nodes = np.unique(np.concatenate([(cells[0] + di) * P.shape[1] + cells[1] + dj
                                          for di in (0, 1) for dj in (0, 1)]))
    cells = Box(a[ii], a[ii + 1], v[jj], v[jj + 1])
    single = np.abs(wind) == 1
    roots_a, roots_v, crossings = [], [], []
    sb = cells.take(single)
    a0, v0 = _linear_guess(P, ii[single], jj[single], sb)
    ra, rv, ok = refine(res, a0, v0, sb.grown(0.5, window), tol)
    ok &= sb.grown(1e-9, window).contains(ra, rv)  # a neighbour's root does not account for this cell's
    roots_a.extend(ra[ok])
    roots_v.extend(rv[ok])
    hard = cells.take(~single)
    failed = sb.take(~ok)
    for box in (hard, failed):
        for k in range(len(box)):
            fa, fv, fc = _isolate(res, box.take([k]), window, tol)
            roots_a.extend(fa)
            roots_v.extend(fv)
            crossings.extend(fc)
    # roots lying on grid edges (edge phase unresolved at the finest level), incl. the window boundary
    if suspects:
        sa, sv = np.array(suspects).T
        da, dv = np.max(np.diff(a)), np.max(np.diff(v))
        sbox = Box(np.maximum(sa - da, a[0]), np.minimum(sa + da, a[-1]),
                   np.maximum(sv - dv, v[0]), np.minimum(sv + dv, v[-1]))
        xa, xv, ok = refine(res, sa, sv, sbox, tol)
        roots_a.extend(xa[ok])
        roots_v.extend(xv[ok])
        # a root on a grid edge leaves the windings of the cells around it undefined, so a partner of opposite
        # degree next to it (a clustered pair) shows in no winding: isolate each such root's neighbourhood
        # (distinct roots only: several suspects usually refine to the same one)
        _, first = np.unique(np.round(np.column_stack([xa[ok], xv[ok]]), 12), axis=0, return_index=True)
        for k in np.flatnonzero(ok)[np.sort(first)]:
            fa, fv, fc = _isolate(res, sbox.take([k]), window, tol, hint=(xa[k], xv[k]))
            roots_a.extend(fa)
            roots_v.extend(fv)
            crossings.extend(fc)
    # tangent-like pairs cancel in a cell's winding: search from local minima of the relative residual
    si, sj, sm = tangent_seeds(P, ii, jj, _TANGENT_THRESHOLD, nodes // P.shape[1], nodes % P.shape[1])
    if si.size > _MAX_TANGENT_SEEDS:
        best = np.argsort(sm)[:_MAX_TANGENT_SEEDS]
        si, sj = si[best], sj[best]
    if si.size and bounds is not None and isinstance(P, OuterProduct):
        keep = _refined_seeds(res, a, v, P, si, sj, bounds)
        si, sj = si[keep], sj[keep]
    if si.size:
        sbox = _node_boxes(a, v, si, sj, 2)
        ta, tv, ok = refine(res, a[si], v[sj], sbox, tol)
        # a seed next to a jump of N pressed against its box (its root may hide next to a jump crossing
        # of opposite winding, which cancels it in the cell's winding): one more try in a wider box
        pinned = (ta == sbox.a_lo) | (ta == sbox.a_hi) | (tv == sbox.v_lo) | (tv == sbox.v_hi)
        retry = np.flatnonzero(~ok & pinned)
        if retry.size:
            retry = retry[_near_jump(P, si[retry], sj[retry], 3)]
        if retry.size:
            wide = _node_boxes(a, v, si[retry], sj[retry], 3)
            ta[retry], tv[retry], ok[retry] = refine(res, a[si[retry]], v[sj[retry]], wide, tol)
            for name in ("a_lo", "a_hi", "v_lo", "v_hi"):
                getattr(sbox, name)[retry] = getattr(wide, name)
        for k in np.flatnonzero(ok):
            # a root the windings did not show (or showed only on a grid edge, where its partner of opposite
            # degree may hide in the same cell): isolate everything in its neighbourhood
            fa, fv, fc = _isolate(res, sbox.take([k]), window, tol, hint=(ta[k], tv[k]))
            roots_a.extend(fa + [ta[k]])
            roots_v.extend(fv + [tv[k]])
            crossings.extend(fc)
    if not roots_a:
        return np.empty(0), np.empty(0), _merge_crossings(crossings)
    check_continuum(res, np.asarray(roots_a), np.asarray(roots_v), window, tol, refined=True)
    return (*merge(res, np.asarray(roots_a), np.asarray(roots_v)), _merge_crossings(crossings))


def unresolved_boxes(res: Residual, a: np.ndarray, v: np.ndarray) -> list[tuple[float, float, float, float]]:
    """The boxes of ``res.unresolved`` (windings of R left without a refined root) that hold none of the
    returned roots (a, v), as (A_lo, A_hi, w_lo, w_hi) in the element's amplitude unit and rad/s, merged
    when they overlap."""
    out: list[list[float]] = []
    for a_lo, a_hi, v_lo, v_hi, _ in sorted(res.unresolved):
        if np.any((a_lo <= a) & (a <= a_hi) & (v_lo <= v) & (v <= v_hi)):
            continue
        for b in out:
            if a_lo <= b[1] and b[0] <= a_hi and v_lo <= b[3] and b[2] <= v_hi:
                b[:] = [min(b[0], a_lo), max(b[1], a_hi), min(b[2], v_lo), max(b[3], v_hi)]
                break
        else:
            out.append([a_lo, a_hi, v_lo, v_hi])
    return [tuple(float(np.exp(x)) for x in b) for b in out]
