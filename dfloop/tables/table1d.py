"""Adaptive tabulation of an expensive complex function of one or two variables, with regime jumps.

A *sampler* maps a batch of points to :class:`Samples`: a complex value, an integer regime label
(samples with equal labels belong to the same smooth branch) and a ``regular`` flag (False where the
value is only an average, e.g. chaotic motion). :class:`Table1D` places samples where the function
varies fast (midpoint-versus-interpolant check against a relative tolerance), brackets every jump
between regimes (or in value) by bisection and never interpolates across one. Every interpolated
value comes with an error estimate (the discrepancy measured by the check that accepted its interval)
and a validity flag. :class:`dfloop.tables.table2d.Table2D` stacks these tables (lines) along a second
coordinate.

Determinism: a 1-D table is a union of canonical *blocks* [origin + k block_dx, origin + (k+1) block_dx]
(``TableSettings.origin`` and ``block_dx``). Each block is sampled on its own base grid and refined using
its own samples only, and interpolation never crosses a block edge, so the value at x depends on x's block
alone: extending a table (in any order) only adds blocks, never changes existing ones. A sampler may also
report a per-sample ``spread`` (how far other branches of a non-unique function lie from the value, inf
for a failed sample): it is added to the error estimate and makes the value invalid.

Two optional hooks of :meth:`Table1D.extend`, both block-local (so the content stays order-independent):
a cheap *prober* that says whether the function at points between two samples of one regime is still that
branch (regime windows wider than ``TableSettings.window_dx`` cannot hide between samples), and a *follow*
that continues another branch found at a sample to its neighbours until it ends (a whole region of
non-unique values is flagged, not only the samples where the sampler's own search found it).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np
from scipy.interpolate import PchipInterpolator, make_interp_spline

__all__ = ["Samples", "TableSettings", "Table1D", "TableValues", "regime_key", "settings_dict"]

IRREGULAR = -1          # regime label used internally for every non-regular sample
_METHODS = ("linear", "pchip", "cubic")


@dataclass(frozen=True)
class Samples:
    """What a sampler returns for a batch of n points.

    Attributes
    ----------
    value : complex array (n,)
    regime : int array (n,)
        Label of the smooth branch; a change of label between neighbours is a jump.
    regular : bool array (n,)
        False where the value is not trustworthy as a smooth function (irregular motion).
    extra : dict of str -> array (n,)
        Diagnostics stored with each sample (impact counts, periodicity, ...).
    spread : float array (n,) or None
        Distance from ``value`` to the farthest other branch found at the point (0: unique; inf: the
        sample failed). Where > 0 the table's value is not valid and its error estimate includes it.
    uncertainty : float array (n,) or None
        Absolute uncertainty of each sampled value itself (e.g. an unconverged transient); added to the
        error estimate of the intervals it bounds, without making them invalid.
    """

    value: np.ndarray
    regime: np.ndarray
    regular: np.ndarray
    extra: dict = field(default_factory=dict)
    spread: np.ndarray | None = None
    uncertainty: np.ndarray | None = None


@dataclass(frozen=True)
class TableSettings:
    """Build settings of an adaptive table (x is the table coordinate, e.g. ln beta).

    tol : relative tolerance of the interpolant, |error| <= tol * max(|value|, abs_floor).
    abs_floor : absolute floor of the error scale (keeps refinement bounded near zeros of the value).
    base_dx : spacing of the initial grid in x.
    min_dx : narrowest interval the refinement creates; intervals failing there keep their measured error.
    jump_dx : width to which jumps in value between regular samples are bracketed by bisection (other
        regime changes, e.g. edges of irregular regions, are bracketed to edge_dx).
    edge_dx : width to which edges of irregular regions and regime changes without a jump in value are
        bracketed (the band flagged invalid around them).
    jump_rel : a failing interval at min_dx whose end values differ by more than jump_rel * scale is a jump.
    method : interpolation inside smooth segments: 'linear', 'pchip' or 'cubic' (not-a-knot spline).
    max_samples : bound on the number of samples; exceeding it raises RuntimeError.
    probe_dx : widest interval between two regular samples that is accepted without a probe inside it
        (intervals wider than this are split even when the value check passed, so a regime window wider
        than probe_dx cannot hide between two samples of the same regime).
    window_dx : spacing of the cheap regime probes (see :meth:`Table1D.extend`'s ``prober``): every interval
        between two regular samples of one regime is probed at points at most window_dx apart (a regime
        window wider than window_dx cannot hide there); inf: none. Used only when a prober is given.
    block_dx : length of the canonical blocks (a multiple of base_dx is best).
    origin : anchor of the block lattice (x = origin + k block_dx are block edges).
    """

    tol: float = 1e-4
    abs_floor: float = 1e-9
    base_dx: float = 0.1
    min_dx: float = 1e-4
    jump_dx: float = 1e-6
    edge_dx: float = 1e-3
    jump_rel: float = 1e-2
    method: str = "cubic"
    max_samples: int = 50_000
    probe_dx: float = math.inf
    window_dx: float = math.inf
    block_dx: float = 1.0
    origin: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.probe_dx, (int, float)) and self.probe_dx > 0 and not math.isnan(self.probe_dx)):
            raise ValueError(f"probe_dx must be a number > 0 (inf: no probes), got {self.probe_dx!r}")
        if not (isinstance(self.origin, (int, float)) and math.isfinite(self.origin)):
            raise ValueError(f"origin must be a finite number, got {self.origin!r}")
        if not (isinstance(self.window_dx, (int, float)) and self.window_dx > 0 and not math.isnan(self.window_dx)):
            raise ValueError(f"window_dx must be a number > 0 (inf: no window probes), got {self.window_dx!r}")
        for name in ("tol", "base_dx", "min_dx", "jump_dx", "edge_dx", "jump_rel", "block_dx"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        if not (math.isfinite(self.abs_floor) and self.abs_floor >= 0):
            raise ValueError(f"abs_floor must be finite and >= 0, got {self.abs_floor!r}")
        if self.method not in _METHODS:
            raise ValueError(f"method must be one of {_METHODS}, got {self.method!r}")
        if int(self.max_samples) < 4:
            raise ValueError(f"max_samples must be >= 4, got {self.max_samples!r}")


@dataclass(frozen=True)
class TableValues:
    """Interpolated values with, per entry, the error estimate, validity and regime label."""

    value: np.ndarray
    error: np.ndarray
    valid: np.ndarray
    regime: np.ndarray

    def __repr__(self) -> str:
        return (f"TableValues(n={self.value.size}, valid={int(np.count_nonzero(self.valid))}, "
                f"max_error={float(np.max(self.error, initial=0.0)):.3g})")


def regime_key(regime: np.ndarray, regular: np.ndarray) -> np.ndarray:
    """Regime labels with every non-regular sample mapped to ``IRREGULAR`` (the key that decides jumps)."""
    return np.where(regular, regime, IRREGULAR).astype(np.int64)


class Table1D:
    """Adaptive table of a complex function of one variable x over a growing union of canonical blocks.

    Build with :meth:`build`; grow with :meth:`extend`; evaluate with :meth:`evaluate`.
    ``n_sampled`` counts every sampler evaluation made by this object (0 for a table loaded from disk).
    Adjacent blocks share their edge x, sampled once in each (``block`` says which block a sample is in).
    """

    def __init__(self, settings: TableSettings | None = None):
        self.settings = settings or TableSettings()
        self.x = np.empty(0)
        self.value = np.empty(0, dtype=complex)
        self.regime = np.empty(0, dtype=np.int64)
        self.regular = np.empty(0, dtype=bool)
        self.spread = np.empty(0)
        self.uncertainty = np.empty(0)
        self.block = np.empty(0, dtype=np.int64)
        self.extra: dict[str, np.ndarray] = {}
        # per interval (len n - 1)
        self.err = np.empty(0)          # absolute error estimate of the interpolant on the interval
        self.checked = np.empty(0, dtype=bool)
        self.value_jump = np.empty(0, dtype=bool)
        self.probed = np.empty(0, dtype=bool)  # window-probed (building a block only; not stored)
        self.n_sampled = 0
        self.n_probed = 0                       # cheap probes run by this object (not stored)
        self._segments = None

    # ------------------------------------------------------------------ building
    @classmethod
    def build(cls, sampler: Callable[[np.ndarray], Samples], lo: float, hi: float,
              settings: TableSettings | None = None, progress: Callable[[int, str], None] | None = None,
              checkpoint: Callable[[], None] | None = None, prober=None, follow=None) -> "Table1D":
        """Tabulate ``sampler`` over the blocks covering [lo, hi] (x units), refined to ``settings.tol``
        (``prober``, ``follow``: see :meth:`extend`)."""
        table = cls(settings)
        table.extend(sampler, lo, hi, progress, checkpoint, prober, follow)
        return table

    @property
    def lo(self) -> float:
        return float(self.x[0]) if self.x.size else math.nan

    @property
    def hi(self) -> float:
        return float(self.x[-1]) if self.x.size else math.nan

    def blocks_for(self, lo: float, hi: float) -> np.ndarray:
        """Indices of the canonical blocks that cover [lo, hi]."""
        st = self.settings
        k_lo = math.floor((lo - st.origin) / st.block_dx + 1e-12)
        k_hi = max(math.ceil((hi - st.origin) / st.block_dx - 1e-12), k_lo + 1)
        return np.arange(k_lo, k_hi, dtype=np.int64)

    def missing_blocks(self, lo: float, hi: float) -> np.ndarray:
        """Blocks covering [lo, hi] that this table does not hold yet."""
        need = self.blocks_for(lo, hi)
        return need[~np.isin(need, self.block)]

    def covers(self, lo: float, hi: float) -> bool:
        return bool(self.x.size) and self.missing_blocks(lo, hi).size == 0

    def contains(self, x) -> np.ndarray:
        """Boolean per x: True where x lies in a block this table holds (there :meth:`evaluate` answers)."""
        st = self.settings
        kf = (np.asarray(x, dtype=float) - st.origin) / st.block_dx
        right, left = np.floor(kf + 1e-12).astype(np.int64), np.ceil(kf - 1e-12).astype(np.int64) - 1
        return np.isin(right, self.block) | np.isin(left, self.block)

    def extend(self, sampler: Callable[[np.ndarray], Samples], lo: float, hi: float,
               progress: Callable[[int, str], None] | None = None,
               checkpoint: Callable[[], None] | None = None,
               prober: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None,
               follow: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None) -> None:
        """Add the missing canonical blocks covering [lo, hi], each built and refined on its own.

        ``checkpoint()``, if given, is called after every finished block (e.g. to save the table).
        ``prober(xp, xa, xb)``, if given, returns ``(settled, samples)`` per probe point xa < xp < xb:
        ``settled`` True where the function there is recognised cheaply as the same smooth branch as at the
        samples xa and xb; elsewhere ``samples`` (value, regime, regular) says what the probe found, and it
        is the same branch when its regime is the interval's and its value passes the refinement's check
        against the interpolant. Every interval between two regular samples of one regime is probed at
        points at most ``settings.window_dx`` apart; a probe of another branch is
        sampled and the table refined around it like any other sample, so a regime window is bracketed
        as soon as one probe falls inside it.
        ``follow(x_from, x_to, value_to)``, if given, continues another branch found at sample x_from (its
        ``spread`` > 0) to the neighbouring sample x_to and returns the distance of that branch from the
        value at x_to (0: the branch is gone there); it is applied from every sample with another branch to
        its neighbours until the branches end, so a region of coexisting branches is flagged as a whole
        and not only at the samples where a sampler's own search found them.
        """
        lo, hi = float(lo), float(hi)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(f"table window must satisfy lo < hi (finite), got ({lo}, {hi})")
        st = self.settings
        n_base = max(1, int(round(st.block_dx / st.base_dx)))
        for k in self.missing_blocks(lo, hi):
            a, b = st.origin + k * st.block_dx, st.origin + (k + 1) * st.block_dx   # shared edges, exactly
            part = Table1D(st)
            part.n_sampled = self.n_sampled
            x = np.linspace(a, b, n_base + 1)
            x[0], x[-1] = a, b
            part._insert(x, part._sample(sampler, x, progress, f"block {k}: base grid", self.x.size))
            part._refine(sampler, progress, self.x.size)
            if prober is not None and math.isfinite(st.window_dx):
                part._probe_windows(sampler, prober, progress, self.x.size)
            if follow is not None:
                part._follow_branches(follow)
            self.n_probed += part.n_probed
            part.block = np.full(part.x.size, k, dtype=np.int64)
            self.n_sampled = part.n_sampled
            self._merge(part)
            if checkpoint is not None:
                checkpoint()
        if progress is not None:
            progress(self.n_sampled, "done")

    def _merge(self, part: "Table1D") -> None:
        """Add a finished block; a zero-width interval joins it to an adjacent block (a seam, no jump)."""
        names = ("x", "value", "regime", "regular", "spread", "uncertainty", "block")
        cat = {n: np.concatenate([getattr(self, n), getattr(part, n)]) for n in names}
        order = np.lexsort((cat["block"], cat["x"]))
        n_self = self.x.size
        keys = set(self.extra) | set(part.extra)
        extra = {}
        for k in keys:
            a = self.extra.get(k, np.full(n_self, np.nan))
            b = part.extra.get(k, np.full(part.x.size, np.nan))
            extra[k] = np.concatenate([a, b])[order]
        # interval attributes travel with their left sample; seams (block changes) get (0, checked, no jump)
        def right_attr(src, name, fill):
            out = np.full(src.x.size, fill, dtype=getattr(src, name).dtype)
            out[:-1] = getattr(src, name)
            return out

        blk = cat["block"][order]
        seam = blk[:-1] != blk[1:]
        attrs = []
        for name, fill in (("err", 0.0), ("checked", True), ("value_jump", False)):
            a = np.concatenate([right_attr(self, name, fill), right_attr(part, name, fill)])[order][:-1]
            a[seam] = fill
            attrs.append(a)
        for n in names:
            setattr(self, n, cat[n][order])
        self.extra = extra
        self.err, self.checked, self.value_jump = attrs
        self._segments = None

    def seams(self) -> np.ndarray:
        """Boolean per interval: True for the zero-width joints between blocks."""
        return self.block[:-1] != self.block[1:]

    def _sample(self, sampler, x, progress, stage, offset: int = 0) -> Samples:
        if offset + self.x.size + x.size > self.settings.max_samples:
            raise RuntimeError(f"table bound max_samples={self.settings.max_samples} reached "
                               f"(tolerance {self.settings.tol:g} too tight or window too wide): raise "
                               f"TableSettings.max_samples")
        s = sampler(x)
        value = np.asarray(s.value, dtype=complex).reshape(x.shape)
        if not np.all(np.isfinite(value)):
            raise RuntimeError("sampler returned a non-finite value")
        self.n_sampled += x.size
        if progress is not None:
            progress(self.n_sampled, stage)
        spread, unc = (np.zeros(x.shape) if a is None else np.asarray(a, dtype=float).reshape(x.shape)
                       for a in (s.spread, s.uncertainty))
        return Samples(value, np.asarray(s.regime, dtype=np.int64).reshape(x.shape),
                       np.asarray(s.regular, dtype=bool).reshape(x.shape),
                       {k: np.asarray(v).reshape(x.shape) for k, v in s.extra.items()}, spread, unc)

    def _insert(self, xn: np.ndarray, s: Samples, err=None, checked=None, value_jump=None) -> None:
        """Insert samples; new intervals get (err, checked, value_jump) pairs (left, right) if given."""
        n_old = self.x.size
        old_x, old_probed = self.x, self.probed
        x = np.concatenate([self.x, xn])
        order = np.argsort(x, kind="stable")
        self.x = x[order]
        self.value = np.concatenate([self.value, s.value])[order]
        self.regime = np.concatenate([self.regime, s.regime])[order]
        self.regular = np.concatenate([self.regular, s.regular])[order]
        self.spread = np.concatenate([self.spread, s.spread])[order]
        self.uncertainty = np.concatenate([self.uncertainty, s.uncertainty])[order]
        self.block = np.zeros(self.x.size, dtype=np.int64)
        keys = set(self.extra) | set(s.extra)
        for k in keys:
            old = self.extra.get(k, np.full(n_old, np.nan))
            add = s.extra.get(k, np.full(xn.size, np.nan))
            self.extra[k] = np.concatenate([old, add])[order]
        # interval attributes: each new interval inherits from the interval it splits
        rank = np.empty_like(order)
        rank[order] = np.arange(order.size)
        new_err = np.full(self.x.size - 1, np.inf)
        new_checked = np.zeros(self.x.size - 1, dtype=bool)
        new_vj = np.zeros(self.x.size - 1, dtype=bool)
        new_probed = np.zeros(self.x.size - 1, dtype=bool)
        if old_probed.size == n_old - 1 and n_old > 1:
            # a new point inside a window-probed interval leaves both its sides probed
            parent = np.clip(np.searchsorted(old_x, xn) - 1, 0, n_old - 2)
            r = rank[n_old:]
            for pos in (r - 1, r):
                ok = (pos >= 0) & (pos < new_probed.size)
                new_probed[pos[ok]] |= old_probed[parent[ok]]
        if n_old > 1:
            # an old interval (i, i+1) whose endpoints stayed adjacent keeps its attributes
            left, right = rank[:n_old - 1], rank[1:n_old]
            keep = right == left + 1
            new_err[left[keep]] = self.err[keep]
            new_checked[left[keep]] = self.checked[keep]
            new_vj[left[keep]] = self.value_jump[keep]
            if old_probed.size == n_old - 1:
                new_probed[left[keep]] = old_probed[keep]
        if err is not None:
            r = rank[n_old:]                   # position of each new point
            for side, pos in ((0, r - 1), (1, r)):
                new_err[pos] = err[:, side]
                new_checked[pos] = checked[:, side]
                new_vj[pos] = value_jump[:, side]
        self.err, self.checked, self.value_jump, self.probed = new_err, new_checked, new_vj, new_probed
        self._segments = None

    def _scale(self, v: np.ndarray) -> np.ndarray:
        return np.maximum(np.abs(v), self.settings.abs_floor)

    def jumps(self) -> np.ndarray:
        """Boolean per interval: True where the interval brackets a jump (regime change or value jump)."""
        key = regime_key(self.regime, self.regular)
        return (key[:-1] != key[1:]) | self.value_jump

    def _refine(self, sampler, progress, offset: int = 0) -> None:
        st = self.settings
        max_gen = 2 * int(math.ceil(math.log2(max(self.x[-1] - self.x[0], st.jump_dx) / st.jump_dx))) + 16
        for generation in range(max_gen):
            jump = self.jumps()
            width = np.diff(self.x)
            smooth = ~jump & self.regular[:-1] & self.regular[1:]
            irregular = ~jump & ~smooth
            self.err[irregular] = np.abs(np.diff(self.value))[irregular]
            self.checked[irregular] = True
            # intervals too narrow to split are closed with their last measured discrepancy
            narrow = smooth & ~self.checked & (width < 2 * st.min_dx)
            if np.any(narrow):
                dv = np.abs(np.diff(self.value))
                never = narrow & np.isinf(self.err)       # bisection leftovers: bound by the change across
                self.err[never] = dv[never]
                scale = self._scale(np.minimum(np.abs(self.value[:-1]), np.abs(self.value[1:])))
                self.checked[narrow] = True
                new_vj = narrow & (self.err > st.tol * scale) & (dv > st.jump_rel * scale)
                self.value_jump |= new_vj
                self._reopen_neighbours(new_vj)
                jump = self.jumps()
                smooth = ~jump & self.regular[:-1] & self.regular[1:]
            # unchecked intervals, and regime probes inside accepted ones wider than probe_dx
            check = np.flatnonzero(smooth & (~self.checked | (width > st.probe_dx)))
            # value jumps between regular samples are bracketed to jump_dx; edges of irregular regions and
            # regime changes with a continuous value (bifurcations) only to edge_dx
            dv = np.abs(np.diff(self.value))
            scale = self._scale(np.minimum(np.abs(self.value[:-1]), np.abs(self.value[1:])))
            sharp = self.regular[:-1] & self.regular[1:] & (dv > st.jump_rel * scale)
            bisect = np.flatnonzero(jump & (width > np.where(sharp, st.jump_dx, st.edge_dx)))
            if check.size == 0 and bisect.size == 0:
                break
            idx = np.concatenate([check, bisect])
            xm = 0.5 * (self.x[idx] + self.x[idx + 1])
            predicted = self._interpolate(xm[:check.size], check)
            s = self._sample(sampler, xm, progress, f"refine {generation}", offset)
            err = np.empty((idx.size, 2))
            checked = np.zeros((idx.size, 2), dtype=bool)
            vj = np.zeros((idx.size, 2), dtype=bool)
            nc = check.size
            disc = np.abs(predicted - s.value[:nc])
            ok = disc <= st.tol * self._scale(s.value[:nc])
            err[:nc] = disc[:, None]
            checked[:nc] = ok[:, None]
            # a check whose midpoint falls in a new regime has found a jump: reopen its neighbours
            km = regime_key(s.regime[:nc], s.regular[:nc])
            key = regime_key(self.regime, self.regular)
            found = (km != key[check]) | (km != key[check + 1])
            err[nc:] = np.inf
            old_vj = self.value_jump[bisect]
            va, vb, vm = self.value[bisect], self.value[bisect + 1], s.value[nc:]
            left_bigger = np.abs(vm - va) >= np.abs(vb - vm)
            vj[nc:, 0] = old_vj & left_bigger
            vj[nc:, 1] = old_vj & ~left_bigger
            # the side of a value-jump bracket without the jump becomes an ordinary interval to check
            self._insert(xm, s, err, checked, vj)
            if np.any(found):
                self._reopen_near_points(xm[:nc][found])
        else:
            raise RuntimeError(f"table refinement bound of {max_gen} generations reached")
        self._segments = None

    def _probe_windows(self, sampler, prober, progress, offset: int = 0) -> None:
        """Probe every interval between two regular samples of one regime (unique value) at spacing
        <= window_dx with ``prober``; sample the probes that may be another regime and refine around them,
        until every such interval is probed."""
        st = self.settings
        bound = 64
        for _ in range(bound):
            width = np.diff(self.x)
            same = (~self.jumps() & self.regular[:-1] & self.regular[1:]
                    & (self.spread[:-1] == 0) & (self.spread[1:] == 0))
            todo = np.flatnonzero(same & ~self.probed & (width > st.window_dx))
            self.probed[same & (width <= st.window_dx)] = True
            if todo.size == 0:
                return
            counts = np.ceil(width[todo] / st.window_dx).astype(np.int64)
            owner = np.repeat(todo, counts - 1)
            frac = np.concatenate([np.arange(1, c) / c for c in counts])
            xp = self.x[owner] + frac * width[owner]
            settled, s = prober(xp, self.x[owner], self.x[owner + 1])
            settled = np.asarray(settled, dtype=bool).reshape(xp.shape)
            # a probe that ran to its own motion is the same branch when its regime is the interval's and its
            # value passes the refinement's check against the interpolant there
            key = regime_key(self.regime, self.regular)[owner]
            pv = np.nan_to_num(np.asarray(s.value, dtype=complex).reshape(xp.shape))
            pkey = regime_key(np.asarray(s.regime).reshape(xp.shape), np.asarray(s.regular).reshape(xp.shape))
            close = np.abs(pv - self._interpolate(xp, owner)) <= st.tol * self._scale(pv)
            ok = settled | ((pkey == key) & close)
            self.n_probed += xp.size
            self.probed[todo] = True
            new = xp[~ok]
            if new.size == 0:
                continue
            s = self._sample(sampler, new, progress, "window probes", offset)
            inf = np.full((new.size, 2), np.inf)
            no = np.zeros((new.size, 2), dtype=bool)
            self._insert(new, s, inf, no, no.copy())
            self._reopen_near_points(new)
            self._refine(sampler, progress, offset)
        raise RuntimeError(f"window probing did not finish in {bound} rounds (window_dx={st.window_dx:g})")

    def _follow_branches(self, follow) -> None:
        """Continue other branches (spread > 0, finite) to neighbouring samples with none, until they end."""
        tried = set()
        for _ in range(self.x.size + 1):
            has = np.isfinite(self.spread) & (self.spread > 0) & self.regular
            pairs = [(i, j) for i in np.flatnonzero(has) for j in (i - 1, i + 1)
                     if 0 <= j < self.x.size and self.regular[j] and self.spread[j] == 0 and (i, j) not in tried]
            if not pairs:
                return
            tried.update(pairs)
            src, dst = np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])
            dst, first = np.unique(dst, return_index=True)     # one continuation per sample and round
            src = src[first]
            found = np.asarray(follow(self.x[src], self.x[dst], self.value[dst]), dtype=float)
            self.spread[dst] = np.maximum(self.spread[dst], found)
            if "branches" in self.extra:
                self.extra["branches"][dst] += found > 0
            self._segments = None
        raise RuntimeError("branch continuation did not end")

    def _reopen_neighbours(self, new_jump: np.ndarray, reach: int = 2) -> None:
        for i in np.flatnonzero(new_jump):
            lo, hi = max(0, i - reach), min(self.err.size, i + reach + 1)
            sel = np.arange(lo, hi)
            sel = sel[sel != i]
            self.checked[sel] = False

    def _reopen_near_points(self, xp: np.ndarray, reach: int = 2) -> None:
        pos = np.searchsorted(self.x, xp)
        for p in pos:
            lo, hi = max(0, p - reach - 1), min(self.err.size, p + reach)
            self.checked[lo:hi] = False

    # ------------------------------------------------------------------ evaluation
    def _segment_ids(self):
        if self._segments is None:
            breaks = self.jumps() | self.seams()      # interpolation never crosses a jump or a block edge
            self._segments = (np.concatenate([[0], np.cumsum(breaks)]), breaks, {})
        return self._segments

    def _interpolant(self, seg: int):
        seg_of, _, cache = self._segment_ids()
        if seg not in cache:
            idx = np.flatnonzero(seg_of == seg)
            x, y = self.x[idx], np.column_stack([self.value[idx].real, self.value[idx].imag])
            method = self.settings.method if self.regular[idx[0]] else "linear"
            if idx.size == 1:
                cache[seg] = lambda q, y0=y[0]: np.broadcast_to(y0, (np.size(q), 2))
            elif method == "linear" or idx.size == 2:
                cache[seg] = lambda q, x=x, y=y: np.column_stack(
                    [np.interp(q, x, y[:, 0]), np.interp(q, x, y[:, 1])])
            elif method == "pchip":
                cache[seg] = PchipInterpolator(x, y, extrapolate=True)
            else:
                # not-a-knot cubic spline (a parabola through three points), from a banded solve
                cache[seg] = make_interp_spline(x, y, k=min(3, idx.size - 1))
        return cache[seg]

    def _interval_error(self) -> np.ndarray:
        """Error estimate per interval: the largest discrepancy measured on it and its two neighbours
        (a single midpoint check can be small by coincidence)."""
        e = self.err.copy()
        e[1:] = np.maximum(e[1:], self.err[:-1])
        e[:-1] = np.maximum(e[:-1], self.err[1:])
        jump = self.jumps()
        return np.where(jump, np.abs(np.diff(self.value)), np.where(np.isinf(e), self.err, e))

    def _interpolate(self, q: np.ndarray, interval: np.ndarray) -> np.ndarray:
        """Interpolated values at q lying in the given non-jump intervals (segment-wise)."""
        seg_of, breaks, _ = self._segment_ids()
        out = np.empty(q.size, dtype=complex)
        segs = seg_of[interval]
        for seg in np.unique(segs):
            m = segs == seg
            y = np.asarray(self._interpolant(int(seg))(q[m]))
            out[m] = y[:, 0] + 1j * y[:, 1]
        return out

    def evaluate(self, q) -> TableValues:
        """Interpolate at points q (x units) inside the table window; outside raises ValueError.

        Inside a jump bracket the value of the nearer end is returned, flagged invalid, with the jump
        size as its error estimate.
        """
        q = np.asarray(q, dtype=float)
        flat = q.ravel()
        if np.any(np.isnan(flat)):
            raise ValueError("table query contains NaN")
        if flat.size and (flat.min() < self.x[0] or flat.max() > self.x[-1]):
            raise ValueError(f"table query [{flat.min():.6g}, {flat.max():.6g}] outside the table window "
                             f"[{self.x[0]:.6g}, {self.x[-1]:.6g}]: extend the table first")
        i = np.clip(np.searchsorted(self.x, flat, side="right") - 1, 0, self.x.size - 2)
        gap = np.diff(self.block) > 1                  # two blocks with missing ones between them
        if np.any(gap[i]):
            raise ValueError(f"table query at x = {flat[gap[i]][0]:.6g} falls between two blocks that were "
                             f"built apart: extend the table over it first")
        jump = self.jumps()[i]
        value = np.empty(flat.size, dtype=complex)
        err = np.empty(flat.size)
        smooth = ~jump
        value[smooth] = self._interpolate(flat[smooth], i[smooth])
        err[smooth] = self._interval_error()[i[smooth]]
        ij = i[jump]
        nearer = np.where(flat[jump] - self.x[ij] <= self.x[ij + 1] - flat[jump], ij, ij + 1)
        value[jump] = self.value[nearer]
        err[jump] = np.abs(self.value[ij + 1] - self.value[ij])
        # other branches found at the ends (non-unique N) or failed samples: in the error, and not valid
        spread = np.maximum(self.spread[i], self.spread[i + 1])
        err = err + spread + np.maximum(self.uncertainty[i], self.uncertainty[i + 1])
        key = regime_key(self.regime, self.regular)
        valid = smooth & self.regular[i] & self.regular[i + 1] & (spread == 0)
        regime = key[i]
        regime[jump] = key[nearer]
        shape = q.shape
        return TableValues(value.reshape(shape), err.reshape(shape), valid.reshape(shape), regime.reshape(shape))

    # ------------------------------------------------------------------ persistence
    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The table's state as named arrays (for :mod:`dfloop.tables.cache`)."""
        arrays = {"x": self.x, "value": self.value, "regime": self.regime, "regular": self.regular,
                  "spread": self.spread, "uncertainty": self.uncertainty, "block": self.block,
                  "err": self.err, "checked": self.checked, "value_jump": self.value_jump}
        arrays.update({f"extra.{k}": v for k, v in self.extra.items()})
        return {prefix + k: v for k, v in arrays.items()}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], settings: TableSettings, prefix: str = "") -> "Table1D":
        table = cls(settings)
        for name in ("x", "value", "regime", "regular", "spread", "uncertainty", "block", "err", "checked",
                     "value_jump"):
            setattr(table, name, np.asarray(arrays[prefix + name]))
        table.extra = {k[len(prefix) + 6:]: np.asarray(v) for k, v in arrays.items()
                       if k.startswith(prefix + "extra.")}
        return table

    def __repr__(self) -> str:
        if not self.x.size:
            return "Table1D(empty)"
        return (f"Table1D(x=[{self.lo:.4g}, {self.hi:.4g}], blocks={np.unique(self.block).size}, "
                f"samples={self.x.size}, "
                f"jumps={int(np.count_nonzero(self.jumps()))}, regular={int(np.count_nonzero(self.regular))}, "
                f"method={self.settings.method!r}, tol={self.settings.tol:g})")


def settings_dict(settings: TableSettings) -> dict:
    """Settings as a plain dict (for cache keys and provenance)."""
    return asdict(settings)
