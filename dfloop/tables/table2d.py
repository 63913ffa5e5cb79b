"""Adaptive table of a complex function of two variables: adaptive 1-D tables (lines) stacked along y.

See :mod:`dfloop.tables.table1d` for the 1-D tables, their blocks, jumps and error estimates.
"""
from __future__ import annotations

import copy
import math
import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from typing import Callable

import numpy as np

from .table1d import Samples, Table1D, TableSettings, TableValues, regime_key

__all__ = ["Table2D"]


def _take(s: Samples, idx: np.ndarray) -> Samples:
    """Rows ``idx`` of a batch of samples (spread and uncertainty made explicit)."""
    n = np.asarray(s.value).size
    spread = np.zeros(n) if s.spread is None else np.asarray(s.spread, dtype=float)
    unc = np.zeros(n) if s.uncertainty is None else np.asarray(s.uncertainty, dtype=float)
    return Samples(np.asarray(s.value)[idx], np.asarray(s.regime)[idx], np.asarray(s.regular)[idx],
                   {k: np.asarray(v)[idx] for k, v in s.extra.items()}, spread[idx], unc[idx])


def _workers(n_tasks: int) -> int:
    return max(1, min(n_tasks, os.cpu_count() or 1))


def _map(fn, items: list) -> list:
    """[fn(item) for item in items], run concurrently in threads (the simulations release the GIL)."""
    if _workers(len(items)) == 1:
        return [fn(item) for item in items]
    with ThreadPoolExecutor(_workers(len(items))) as pool:
        return list(pool.map(fn, items))


_NO_PROFILE = (np.empty(0), np.empty(0))
_ISOLATED_FRACTION = 0.1     # a y check may fail at up to this fraction of its points ...
_ISOLATED_RUN = 2            # ... in runs of at most this many neighbours (a kink crossing the interval)


def _isolated(fail: np.ndarray, n_used: int) -> bool:
    """Whether the failed points of a check in y are isolated: few (at most _ISOLATED_FRACTION of the points
    where the table answers, at least one allowed), each run at most _ISOLATED_RUN neighbours long."""
    n_fail = int(np.count_nonzero(fail))
    if n_fail > max(1, int(_ISOLATED_FRACTION * n_used)):
        return False
    edges = np.diff(np.concatenate([[0], fail.astype(np.int8), [0]]))
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    return bool(runs.max(initial=0) <= _ISOLATED_RUN)


class _Reuse:
    """A sampler at one y that serves the samples already taken there (exact x matches) from memory.

    The checks in y sample on the lattice of the lines' own base grid and first midpoints, so when a check
    fails and a line is built at that y, the line's first samples are the check's (same x, bit for bit).
    """

    def __init__(self, sampler: Callable[[np.ndarray], Samples], x: np.ndarray, samples: Samples):
        self.sampler, self.samples = sampler, samples
        self.index = {float(v): i for i, v in enumerate(np.asarray(x, dtype=float))}
        self.reused = 0

    def __call__(self, x: np.ndarray) -> Samples:
        x = np.asarray(x, dtype=float)
        pos = np.array([self.index.get(float(v), -1) for v in x], dtype=np.int64)
        hit = pos >= 0
        self.reused += int(np.count_nonzero(hit))
        if np.all(hit):
            return _take(self.samples, pos)
        fresh = _take(self.sampler(x[~hit]), slice(None))
        if not np.any(hit):
            return fresh
        old = _take(self.samples, pos[hit])
        order = np.argsort(np.concatenate([np.flatnonzero(hit), np.flatnonzero(~hit)]), kind="stable")

        def cat(a, b):
            return np.concatenate([np.asarray(a), np.asarray(b)])[order]

        extra = {k: cat(old.extra[k], fresh.extra[k]) for k in old.extra}
        return Samples(cat(old.value, fresh.value), cat(old.regime, fresh.regime), cat(old.regular, fresh.regular),
                       extra, cat(old.spread, fresh.spread), cat(old.uncertainty, fresh.uncertainty))


class Table2D:
    """Adaptive table of a complex function of (x, y): 1-D tables in x (lines) at adaptive values of y.

    Between lines the value is interpolated in y at fixed x (cubic Lagrange on four lines, linear with fewer
    lines or with ``settings.method == 'linear'``). Each y-interval is checked at its midpoint on a grid of x:
    it gets a new line there unless value and regime agree with the interpolant to ``y_settings.tol``
    everywhere the table answers valid, or fail at isolated points only (a kink of the function crossing
    the interval); the error measured at each check point is kept and added to ``error``. Where the lines
    used disagree on the regime at x, the nearer line's value is returned, flagged invalid.

    ``y_rate`` r > 0 interpolates in the coordinate exp(-r y) instead of y; ``x_min`` bounds every window
    from below (the caller answers x < x_min itself, e.g. exactly).

    Windows may be sheared: ``extend(..., shear=s)`` covers {(x, y): lo <= x + s y <= hi, y in y_window}
    (e.g. x = ln beta = ln F - ln(M2 h) - 2 ln w with y = ln w is a rectangle in (ln F, ln w) for s = 2).
    Every line covers only the x range its own y-intervals need (the union of the windows asked for, over
    the y-intervals whose interpolation stencil uses the line), not the union over all y.
    """

    def __init__(self, settings: TableSettings | None = None, y_settings: TableSettings | None = None,
                 y_rate: float = 0.0, x_min: float = -math.inf):
        self.settings = settings or TableSettings()
        self.y_settings = y_settings or self.settings
        if not (math.isfinite(y_rate) and y_rate >= 0):
            raise ValueError(f"y_rate must be finite and >= 0, got {y_rate!r}")
        if math.isnan(x_min) or x_min == math.inf:
            raise ValueError(f"x_min must be a number or -inf, got {x_min!r}")
        self.y_rate = float(y_rate)
        self.x_min = float(x_min)
        self.y = np.empty(0)
        self.lines: list[Table1D] = []
        self.yerr = np.empty(0)          # largest relative error of the y-interpolation per y-interval
        self.ychecked = np.empty(0, dtype=bool)
        self.yprof: list[tuple[np.ndarray, np.ndarray]] = []   # per y-interval: check points x, relative error
        self.windows = np.empty((0, 5))  # every window asked for: (x_lo, x_hi, shear, y_lo, y_hi)
        self._n_checked = 0              # samples spent on checks in y (not stored)
        self._n_reused = 0               # of those, samples served again to a line built at the check's y

    @property
    def n_sampled(self) -> int:
        """Sampler evaluations made by this object: its lines' and its checks in y (each sample once)."""
        return sum(line.n_sampled for line in self.lines) + self._n_checked - self._n_reused

    @classmethod
    def build(cls, sampler: Callable[[np.ndarray, float], Samples], x_window, y_window,
              settings=None, y_settings=None, progress=None, shear: float = 0.0, y_rate: float = 0.0,
              x_min: float = -math.inf) -> "Table2D":
        """Tabulate ``sampler(x_array, y)`` over {lo <= x + shear y <= hi, x >= x_min} x y_window."""
        table = cls(settings, y_settings, y_rate, x_min)
        table.extend(sampler, x_window, y_window, progress, shear)
        return table

    def _coordinate(self, y: np.ndarray) -> np.ndarray:
        """The coordinate of the interpolation in y: exp(-y_rate y), or y itself for y_rate = 0."""
        return np.exp(-self.y_rate * y) if self.y_rate else y

    def _stencil_first(self, k: np.ndarray, ny: int) -> tuple[np.ndarray, int]:
        """First line and width of the y-interpolation stencil of y-intervals k."""
        if self.settings.method != "linear" and ny >= 4:
            return np.clip(k - 1, 0, ny - 4), 4
        return k, 2

    def _required(self, y: np.ndarray, windows: np.ndarray) -> np.ndarray:
        """(lo, hi) x range per line at ``y`` that the windows need (nan where none)."""
        ny = y.size
        need = np.full((ny, 2), np.nan)
        if ny < 2:
            return need
        first, width = self._stencil_first(np.arange(ny - 1), ny)
        for x_lo, x_hi, s, y_lo, y_hi in windows:
            a, b = np.maximum(y[:-1], y_lo), np.minimum(y[1:], y_hi)
            for k in np.flatnonzero(a <= b):
                lo = min(x_lo - s * a[k], x_lo - s * b[k])
                hi = max(x_hi - s * a[k], x_hi - s * b[k])
                j = slice(first[k], first[k] + width)
                need[j, 0] = np.fmin(need[j, 0], lo)
                need[j, 1] = np.fmax(need[j, 1], hi)
        need[need[:, 1] < self.x_min] = np.nan
        need[:, 0] = np.maximum(need[:, 0], self.x_min)
        return need

    def covers(self, x_window, y_window, shear: float = 0.0) -> bool:
        """Whether the window is covered by finished lines and checked y-intervals (a table saved during
        an interrupted build is not: extending it resumes the build)."""
        if not self.lines or not (self.y[0] <= y_window[0] and y_window[1] <= self.y[-1]):
            return False
        if not np.all(self.ychecked):
            return False
        need = self._required(self.y, np.array([[x_window[0], x_window[1], shear, y_window[0], y_window[1]]]))
        return all(line.covers(lo, hi) for line, (lo, hi) in zip(self.lines, need) if not np.isnan(lo))

    def _cover(self, sampler, progress, checkpoint) -> None:
        """Extend every line over the x range its y-intervals need (no-op where already covered).

        Lines are extended concurrently, each on a copy that replaces the line once finished (so a
        checkpoint never sees a line half-built); a line's content depends on its own y and blocks only.
        """
        need = self._required(self.y, self.windows)
        span = [(lo, max(hi, lo + self.settings.base_dx)) for lo, hi in need]
        todo = [j for j, (lo, hi) in enumerate(span) if not np.isnan(lo) and not self.lines[j].covers(lo, hi)]

        def grow(j):
            line = copy.deepcopy(self.lines[j])
            line.extend(lambda x, yk=self.y[j]: sampler(x, yk), *span[j], progress)
            return line

        if not todo:
            return
        with ThreadPoolExecutor(_workers(len(todo))) as pool:
            futures = {pool.submit(grow, j): j for j in todo}
            for done in as_completed(futures):
                self.lines[futures[done]] = done.result()
                if checkpoint is not None:
                    checkpoint()

    def extend(self, sampler, x_window, y_window, progress=None, shear: float = 0.0, checkpoint=None) -> None:
        """Grow to cover {x_window[0] <= x + shear y <= x_window[1]} x y_window: add lines in y, refine in y,
        and extend every line over the x range it needs.

        ``checkpoint()``, if given, is called after every finished line (e.g. to save the table): the saved
        state is consistent, and extending a table saved mid-build resumes it (unchecked y-intervals and
        unfinished lines are done then)."""
        xlo, xhi = float(x_window[0]), float(x_window[1])
        ylo, yhi = float(y_window[0]), float(y_window[1])
        if not (ylo < yhi and math.isfinite(ylo) and math.isfinite(yhi)):
            raise ValueError(f"y window must satisfy lo < hi (finite), got ({ylo}, {yhi})")
        if not (xlo < xhi and math.isfinite(xlo) and math.isfinite(xhi)):
            raise ValueError(f"x window must satisfy lo < hi (finite), got ({xlo}, {xhi})")
        if not math.isfinite(shear):
            raise ValueError(f"shear must be finite, got {shear!r}")
        row = np.array([xlo, xhi, float(shear), ylo, yhi])
        if not np.any(np.all(self.windows == row, axis=1)):
            self.windows = np.vstack([self.windows, row])
        dy = self.y_settings.base_dx
        if not self.lines:
            new_y = np.linspace(ylo, yhi, max(2, int(math.ceil((yhi - ylo) / dy)) + 1))
        else:
            parts = []
            if ylo < self.y[0]:
                n = max(1, int(math.ceil((self.y[0] - ylo) / dy)))
                parts.append(np.linspace(ylo, self.y[0], n + 1)[:-1])
            if yhi > self.y[-1]:
                n = max(1, int(math.ceil((yhi - self.y[-1]) / dy)))
                parts.append(np.linspace(self.y[-1], yhi, n + 1)[1:])
            new_y = np.concatenate(parts) if parts else np.empty(0)
        old_y, old_err, old_checked, old_prof = self.y, self.yerr, self.ychecked, self.yprof
        for yk in new_y:
            k = int(np.searchsorted(self.y, yk))
            self.y = np.insert(self.y, k, yk)
            self.lines.insert(k, Table1D(self.settings))
        # y-intervals between two old adjacent lines keep their attributes; new ones are to be checked
        self.yerr = np.full(self.y.size - 1, np.inf)
        self.ychecked = np.zeros(self.y.size - 1, dtype=bool)
        self.yprof = [_NO_PROFILE] * (self.y.size - 1)
        if old_y.size > 1:
            pos = np.searchsorted(self.y, old_y)
            keep = np.diff(pos) == 1
            self.yerr[pos[:-1][keep]] = old_err[keep]
            self.ychecked[pos[:-1][keep]] = old_checked[keep]
            for i in np.flatnonzero(keep):
                self.yprof[pos[i]] = old_prof[i]
        if old_y.size < 4 <= self.y.size and self.settings.method != "linear":
            self.ychecked[:] = False                   # the stencil grows from linear to cubic: check again
        blocks = np.array([np.unique(line.block).size for line in self.lines])
        self._cover(sampler, progress, checkpoint)
        # a y-interval whose stencil lines grew in x was checked on less than it now serves: check it again
        grown = np.array([np.unique(line.block).size for line in self.lines]) > blocks
        first, w = self._stencil_first(np.arange(self.y.size - 1), self.y.size)
        for k in np.flatnonzero([np.any(grown[f:f + w]) for f in first]):
            self.ychecked[k] = False
        self._refine(sampler, progress, checkpoint)

    def _check_points(self, k: int) -> np.ndarray:
        """x at which the y-interpolant of interval k is checked at its midpoint: the lattice of the lines'
        base grids halved until its spacing is at most min(probe_dx, base_dx / 2) (the points a line built
        there samples first), over the x range the windows ask for inside the interval (one lattice step
        beyond each end), where every line of the interval's stencil holds its block."""
        st = self.settings
        lo, hi = self._required(self.y[k:k + 2], self.windows)[0]
        if np.isnan(lo):
            return np.empty(0)
        halvings = max(1, int(math.ceil(math.log2(st.base_dx / min(st.probe_dx, 0.5 * st.base_dx)) - 1e-9)))
        spacing = st.base_dx / 2 ** halvings
        n_base = max(1, int(round(st.block_dx / st.base_dx)))
        parts = []
        for kb in Table1D(st).blocks_for(lo - spacing, hi + spacing):
            a, b = st.origin + kb * st.block_dx, st.origin + (kb + 1) * st.block_dx   # as Table1D.extend
            x = np.linspace(a, b, n_base + 1)
            x[0], x[-1] = a, b
            for _ in range(halvings):                  # midpoints as Table1D._refine computes them
                finer = np.empty(2 * x.size - 1)
                finer[0::2], finer[1::2] = x, 0.5 * (x[:-1] + x[1:])
                x = finer
            parts.append(x)
        x = np.unique(np.concatenate(parts))
        x = x[(x >= lo - spacing) & (x <= hi + spacing)]
        first, w = self._stencil_first(np.array([k]), self.y.size)
        for j in range(int(first[0]), int(first[0]) + w):
            x = x[self.lines[j].contains(x)]
        return x

    def _peak_factor(self, k: int, ym: float) -> float:
        """max over y-interval k of the interpolation's error polynomial |prod_j (t - t_j)| (t: the coordinate
        of y, t_j its stencil's lines), over its value at the check point ym (>= 1): the factor from the error
        measured at ym to the interval's largest (e.g. 1.07 for a cubic's end interval on equal spacing)."""
        first, w = self._stencil_first(np.array([k]), self.y.size)
        nodes = self._coordinate(self.y[int(first[0]):int(first[0]) + w])
        t = self._coordinate(np.append(np.linspace(self.y[k], self.y[k + 1], 65), ym))
        poly = np.abs(np.prod(t[:, None] - nodes[None, :], axis=1))
        return float(max(1.0, poly[:-1].max() / poly[-1]))

    def _check(self, k: int, sampler, progress):
        """Check y-interval k at its midpoint (reads the table only): check points, relative error there,
        failed points, points where the table answers valid, and the samples for a line built there."""
        st = self.y_settings
        ym = 0.5 * (self.y[k] + self.y[k + 1])
        xs = self._check_points(k)
        if xs.size == 0:
            return xs, np.zeros(0), np.zeros(0, dtype=bool), 0, None
        sm = Table1D(self.settings)._sample(lambda x: sampler(x, ym), xs, progress, "check in y")
        pred = self.evaluate(xs, np.full(xs.size, ym))
        # where the table would answer valid: the value must match, and so must the regime (a regime window
        # between lines of one regime is a failure too)
        scale = np.maximum(np.abs(sm.value), self.settings.abs_floor)
        rel = np.where(pred.valid, np.abs(pred.value - sm.value) / scale, 0.0) * self._peak_factor(k, ym)
        other = pred.valid & (pred.regime != regime_key(sm.regime, sm.regular))
        fail = pred.valid & ((rel > st.tol) | other)
        return xs, rel, fail, int(np.count_nonzero(pred.valid)), _Reuse(lambda x: sampler(x, ym), xs, sm)

    def _refine(self, sampler, progress, checkpoint=None) -> None:
        """Check every unchecked y-interval at its midpoint on a grid of x (:meth:`_check_points`); an
        interval that fails (not at isolated points only) gets a full line there (both halves to be checked,
        the line reusing the check's samples), one that is accepted keeps the errors measured at the check
        points (``yprof``, the largest in ``yerr``) and costs no line.

        One generation at a time: its checks run concurrently on the table as it was, then its new lines
        are built concurrently and inserted (the result does not depend on the threads' timing)."""
        st = self.y_settings
        max_gen = int(math.ceil(math.log2(max(self.y[-1] - self.y[0], st.min_dx) / st.min_dx))) + 4
        for _ in range(max_gen):
            todo = np.flatnonzero(~self.ychecked)
            if todo.size == 0:
                return
            width = np.diff(self.y)
            split = []
            for k, (xs, rel, fail, n_used, reuse) in zip(todo, _map(lambda k: self._check(k, sampler, progress),
                                                                     list(todo))):
                self._n_checked += xs.size
                self.yerr[k] = float(rel.max(initial=0.0))
                self.yprof[k] = (xs, rel)
                # accepted with its measured error: passed, failed at isolated points, or too narrow to split
                if not np.any(fail) or _isolated(fail, n_used) or width[k] < 2 * st.min_dx:
                    self.ychecked[k] = True
                else:
                    split.append((k, reuse))

            def build(item):
                k, reuse = item                    # the midpoint line covers what it needs once inserted
                ym = 0.5 * (self.y[k] + self.y[k + 1])
                lo, hi = self._required(np.insert(self.y, k + 1, ym), self.windows)[k + 1]
                line = Table1D(self.settings)
                if not np.isnan(lo):
                    line.extend(reuse or (lambda x: sampler(x, ym)), lo, max(hi, lo + self.settings.base_dx),
                                progress)
                return ym, line

            for (k, reuse), (ym, line) in reversed(list(zip(split, _map(build, split)))):   # right to left
                self._n_reused += 0 if reuse is None else reuse.reused
                self.y = np.insert(self.y, k + 1, ym)
                self.lines.insert(k + 1, line)
                self.yerr[k] = np.inf
                self.yprof[k] = _NO_PROFILE
                self.yerr = np.insert(self.yerr, k + 1, np.inf)
                self.ychecked = np.insert(self.ychecked, k + 1, False)
                self.yprof.insert(k + 1, _NO_PROFILE)
                if self.y.size == 4 and self.settings.method != "linear":
                    self.ychecked[:] = False           # the stencil grows from linear to cubic: check again
                if checkpoint is not None:
                    checkpoint()
            self._cover(sampler, progress, checkpoint)
        raise RuntimeError(f"2-D table refinement bound of {max_gen} generations in y reached")

    def _y_error(self, k: np.ndarray, xq: np.ndarray) -> np.ndarray:
        """Relative error of the y-interpolation at (xq, interval k): the largest measured by the interval's
        check at the 2 + 2 check points around xq (``yerr`` where the check had no points or none was made)."""
        out = self.yerr[k].astype(float)
        for j in np.unique(k):
            xs, rel = self.yprof[j]
            if xs.size:
                m = np.flatnonzero(k == j)
                pos = np.searchsorted(xs, xq[m])
                near = np.clip(pos[:, None] + np.arange(-2, 2), 0, xs.size - 1)
                out[m] = rel[near].max(axis=1)
        return out

    def evaluate(self, xq, yq) -> TableValues:
        """Interpolate at (xq, yq) (broadcast) inside the window; outside raises ValueError."""
        xq, yq = np.broadcast_arrays(np.asarray(xq, dtype=float), np.asarray(yq, dtype=float))
        shape = xq.shape
        xq, yq = xq.ravel(), yq.ravel()
        if np.any(np.isnan(yq)):
            raise ValueError("table query contains NaN")
        if yq.size and (yq.min() < self.y[0] or yq.max() > self.y[-1]):
            raise ValueError(f"table query y in [{yq.min():.6g}, {yq.max():.6g}] outside the table window "
                             f"[{self.y[0]:.6g}, {self.y[-1]:.6g}]: extend the table first")
        ny = self.y.size
        k = np.clip(np.searchsorted(self.y, yq, side="right") - 1, 0, ny - 2)
        first, width = self._stencil_first(k, ny)
        stencil = first[:, None] + np.arange(width)
        vals = np.empty(stencil.shape, dtype=complex)
        errs = np.empty(stencil.shape)
        valid = np.ones(stencil.shape, dtype=bool)
        regs = np.empty(stencil.shape, dtype=np.int64)
        for j in np.unique(stencil):
            m = stencil == j
            rows = np.any(m, axis=1)
            tv = self.lines[j].evaluate(xq[rows])
            col = np.argmax(m[rows], axis=1)
            r = np.flatnonzero(rows)
            vals[r, col], errs[r, col], valid[r, col], regs[r, col] = tv.value, tv.error, tv.valid, tv.regime
        ys, tq = self._coordinate(self.y)[stencil], self._coordinate(yq)
        weights = np.ones(stencil.shape)
        for a in range(stencil.shape[1]):              # Lagrange weights in the coordinate of y
            for b in range(stencil.shape[1]):
                if a != b:
                    weights[:, a] *= (tq - ys[:, b]) / (ys[:, a] - ys[:, b])
        value = np.sum(weights * vals, axis=1)
        same = np.all(regs == regs[:, :1], axis=1)
        near = np.where(yq - self.y[k] <= self.y[k + 1] - yq, k, k + 1)
        near_col = near - stencil[:, 0]
        rows = np.arange(yq.size)
        scale = np.maximum(np.abs(value), self.settings.abs_floor)
        error = np.max(errs, axis=1) + self._y_error(k, xq) * scale
        value = np.where(same, value, vals[rows, near_col])
        spread = np.max(np.abs(vals - vals[rows, near_col][:, None]), axis=1)
        error = np.where(same, error, spread)
        ok = same & np.all(valid, axis=1)
        regime = np.where(same, regs[:, 0], regs[rows, near_col])
        return TableValues(value.reshape(shape), error.reshape(shape), ok.reshape(shape), regime.reshape(shape))

    def to_arrays(self) -> dict[str, np.ndarray]:
        arrays = {"y": self.y, "y_rate": np.array(self.y_rate), "x_min": np.array(self.x_min), "yerr": self.yerr,
                  "ychecked": self.ychecked, "windows": self.windows,
                  "yprof.n": np.array([p[0].size for p in self.yprof], dtype=np.int64),
                  "yprof.x": np.concatenate([p[0] for p in self.yprof] + [np.empty(0)]),
                  "yprof.rel": np.concatenate([p[1] for p in self.yprof] + [np.empty(0)])}
        for j, line in enumerate(self.lines):
            arrays.update(line.to_arrays(prefix=f"line{j}."))
        return arrays

    @classmethod
    def from_arrays(cls, arrays, settings, y_settings=None) -> "Table2D":
        table = cls(settings, y_settings, float(arrays["y_rate"]), float(arrays["x_min"]))
        table.y = np.asarray(arrays["y"])
        table.yerr = np.asarray(arrays["yerr"])
        table.ychecked = np.asarray(arrays["ychecked"])
        table.windows = np.asarray(arrays["windows"], dtype=float).reshape(-1, 5)
        cut = np.cumsum(np.asarray(arrays["yprof.n"], dtype=np.int64))[:-1]
        table.yprof = list(zip(np.split(np.asarray(arrays["yprof.x"], dtype=float), cut),
                               np.split(np.asarray(arrays["yprof.rel"], dtype=float), cut)))
        table.lines = [Table1D.from_arrays(arrays, settings, prefix=f"line{j}.") for j in range(table.y.size)]
        return table

    def __repr__(self) -> str:
        if not self.lines:
            return "Table2D(empty)"
        return (f"Table2D(x=[{self.lines[0].lo:.4g}, {self.lines[0].hi:.4g}], y=[{self.y[0]:.4g}, "
                f"{self.y[-1]:.4g}], lines={self.y.size}, samples={sum(l.x.size for l in self.lines)})")
