"""Adaptive table of a complex function of two variables: adaptive 1-D tables (lines) stacked along y.

See :mod:`dfloop.impact.table` for the 1-D tables, their blocks, jumps and error estimates.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from .table import Samples, Table1D, TableSettings, TableValues, _regime_key

__all__ = ["Table2D"]


class Table2D:
    """Adaptive table of a complex function of (x, y): 1-D tables in x (lines) at adaptive values of y.

    Between lines the value is interpolated in y at fixed x (cubic Lagrange on four lines, linear at
    the edges or with ``settings.method == 'linear'``); a y-interval is refined until the midpoint line
    agrees with that interpolant to ``settings.tol`` at its regular samples. Where the lines used
    disagree on the regime at x, the nearer line's value is returned, flagged invalid.

    Windows may be sheared: ``extend(..., shear=s)`` covers {(x, y): lo <= x + s y <= hi, y in y_window}
    (e.g. x = ln beta = ln F - ln(M2 h) - 2 ln w with y = ln w is a rectangle in (ln F, ln w) for s = 2).
    Every line covers only the x range its own y-intervals need (the union of the windows asked for, over
    the y-intervals whose interpolation stencil uses the line), not the union over all y.
    """

    def __init__(self, settings: TableSettings | None = None, y_settings: TableSettings | None = None):
        self.settings = settings or TableSettings()
        self.y_settings = y_settings or self.settings
        self.y = np.empty(0)
        self.lines: list[Table1D] = []
        self.yerr = np.empty(0)          # relative error estimate of the y-interpolation per y-interval
        self.ychecked = np.empty(0, dtype=bool)
        self.windows = np.empty((0, 5))  # every window asked for: (x_lo, x_hi, shear, y_lo, y_hi)
        self._n_checked = 0              # samples spent on checks in y (not stored)

    @property
    def n_sampled(self) -> int:
        """Sampler evaluations made by this object: its lines' and its checks in y."""
        return sum(line.n_sampled for line in self.lines) + self._n_checked

    @classmethod
    def build(cls, sampler: Callable[[np.ndarray, float], Samples], x_window, y_window,
              settings=None, y_settings=None, progress=None, shear: float = 0.0) -> "Table2D":
        """Tabulate ``sampler(x_array, y)`` over {lo <= x + shear y <= hi} x y_window."""
        table = cls(settings, y_settings)
        table.extend(sampler, x_window, y_window, progress, shear)
        return table

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
        return need

    def covers(self, x_window, y_window, shear: float = 0.0) -> bool:
        if not self.lines or not (self.y[0] <= y_window[0] and y_window[1] <= self.y[-1]):
            return False
        need = self._required(self.y, np.array([[x_window[0], x_window[1], shear, y_window[0], y_window[1]]]))
        return all(line.covers(lo, hi) for line, (lo, hi) in zip(self.lines, need) if not np.isnan(lo))

    def _cover(self, sampler, progress) -> None:
        """Extend every line over the x range its y-intervals need (no-op where already covered)."""
        need = self._required(self.y, self.windows)
        for yk, line, (lo, hi) in zip(self.y, self.lines, need):
            if not np.isnan(lo):
                line.extend(lambda x, yk=yk: sampler(x, yk), lo, max(hi, lo + self.settings.base_dx), progress)

    def extend(self, sampler, x_window, y_window, progress=None, shear: float = 0.0) -> None:
        """Grow to cover {x_window[0] <= x + shear y <= x_window[1]} x y_window: add lines in y, refine in y,
        and extend every line over the x range it needs."""
        xlo, xhi = float(x_window[0]), float(x_window[1])
        ylo, yhi = float(y_window[0]), float(y_window[1])
        if not (ylo < yhi and math.isfinite(ylo) and math.isfinite(yhi)):
            raise ValueError(f"y window must satisfy lo < hi (finite), got ({ylo}, {yhi})")
        if not (xlo < xhi and math.isfinite(xlo) and math.isfinite(xhi)):
            raise ValueError(f"x window must satisfy lo < hi (finite), got ({xlo}, {xhi})")
        if not math.isfinite(shear):
            raise ValueError(f"shear must be finite, got {shear!r}")
        self.windows = np.vstack([self.windows, [xlo, xhi, float(shear), ylo, yhi]])
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
        old_y, old_err, old_checked = self.y, self.yerr, self.ychecked
        for yk in new_y:
            k = int(np.searchsorted(self.y, yk))
            self.y = np.insert(self.y, k, yk)
            self.lines.insert(k, Table1D(self.settings))
        # y-intervals between two old adjacent lines keep their attributes; new ones are to be checked
        self.yerr = np.full(self.y.size - 1, np.inf)
        self.ychecked = np.zeros(self.y.size - 1, dtype=bool)
        if old_y.size > 1:
            pos = np.searchsorted(self.y, old_y)
            keep = np.diff(pos) == 1
            self.yerr[pos[:-1][keep]] = old_err[keep]
            self.ychecked[pos[:-1][keep]] = old_checked[keep]
        blocks = np.array([np.unique(line.block).size for line in self.lines])
        self._cover(sampler, progress)
        # a y-interval whose stencil lines grew in x was checked on less than it now serves: check it again
        grown = np.array([np.unique(line.block).size for line in self.lines]) > blocks
        first, w = self._stencil_first(np.arange(self.y.size - 1), self.y.size)
        for k in np.flatnonzero([np.any(grown[f:f + w]) for f in first]):
            self.ychecked[k] = False
        self._refine(sampler, progress)

    def _check_points(self, k: int, ym: float) -> np.ndarray:
        """x at which the y-interpolant of interval k is checked at ym: a grid of spacing
        min(probe_dx, base_dx / 2) over the x range the windows ask for inside the interval, where every
        line of the interval's stencil holds its block."""
        st = self.settings
        lo, hi = self._required(self.y[k:k + 2], self.windows)[0]
        if np.isnan(lo):
            return np.empty(0)
        n = int(math.ceil((hi - lo) / min(st.probe_dx, 0.5 * st.base_dx))) + 1
        x = np.linspace(lo, hi, max(n, 2))
        first, w = self._stencil_first(np.array([k]), self.y.size)
        for j in range(int(first[0]), int(first[0]) + w):
            x = x[self.lines[j].contains(x)]
        return x

    def _refine(self, sampler, progress) -> None:
        """Check every unchecked y-interval at its midpoint on a grid of x (:meth:`_check_points`); an
        interval that fails gets a full line there (both halves to be checked), one that passes keeps its
        measured discrepancy as its error estimate and costs no line."""
        st = self.y_settings
        max_gen = int(math.ceil(math.log2(max(self.y[-1] - self.y[0], st.min_dx) / st.min_dx))) + 4
        for _ in range(max_gen):
            todo = np.flatnonzero(~self.ychecked)
            if todo.size == 0:
                return
            width = np.diff(self.y)
            for k in todo[::-1]:                       # right to left keeps indices of the rest valid
                if width[k] < 2 * st.min_dx:
                    self.ychecked[k] = True
                    continue
                ym = 0.5 * (self.y[k] + self.y[k + 1])
                xs = self._check_points(k, ym)
                disc = 0.0
                if xs.size:
                    sm = Table1D(self.settings)._sample(lambda x, ym=ym: sampler(x, ym), xs, progress,
                                                        "check in y")
                    pred = self.evaluate(xs, np.full(xs.size, ym))
                    use = sm.regular & pred.valid & (pred.regime == _regime_key(sm.regime, sm.regular))
                    scale = np.maximum(np.abs(sm.value), self.settings.abs_floor)
                    disc = float((np.abs(pred.value - sm.value)[use] / scale[use]).max(initial=0.0))
                    self._n_checked += xs.size
                self.yerr[k] = disc
                if disc <= st.tol:
                    self.ychecked[k] = True
                    continue
                # the midpoint line covers what it will need once inserted
                y_new = np.insert(self.y, k + 1, ym)
                lo, hi = self._required(y_new, self.windows)[k + 1]
                line_m = Table1D(self.settings)
                if not np.isnan(lo):
                    line_m.extend(lambda x, ym=ym: sampler(x, ym), lo, max(hi, lo + self.settings.base_dx),
                                  progress)
                self.y = y_new
                self.lines.insert(k + 1, line_m)
                self.yerr = np.insert(self.yerr, k + 1, disc)
                self.ychecked = np.insert(self.ychecked, k + 1, False)
            self._cover(sampler, progress)
        raise RuntimeError(f"2-D table refinement bound of {max_gen} generations in y reached")

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
        ys = self.y[stencil]
        weights = np.ones(stencil.shape)
        for a in range(stencil.shape[1]):              # Lagrange weights in y
            for b in range(stencil.shape[1]):
                if a != b:
                    weights[:, a] *= (yq - ys[:, b]) / (ys[:, a] - ys[:, b])
        value = np.sum(weights * vals, axis=1)
        same = np.all(regs == regs[:, :1], axis=1)
        near = np.where(yq - self.y[k] <= self.y[k + 1] - yq, k, k + 1)
        near_col = near - stencil[:, 0]
        rows = np.arange(yq.size)
        scale = np.maximum(np.abs(value), self.settings.abs_floor)
        error = np.max(errs, axis=1) + self.yerr[k] * scale
        value = np.where(same, value, vals[rows, near_col])
        spread = np.max(np.abs(vals - vals[rows, near_col][:, None]), axis=1)
        error = np.where(same, error, spread)
        ok = same & np.all(valid, axis=1)
        regime = np.where(same, regs[:, 0], regs[rows, near_col])
        return TableValues(value.reshape(shape), error.reshape(shape), ok.reshape(shape), regime.reshape(shape))

    def to_arrays(self) -> dict[str, np.ndarray]:
        arrays = {"y": self.y, "yerr": self.yerr, "ychecked": self.ychecked, "windows": self.windows}
        for j, line in enumerate(self.lines):
            arrays.update(line.to_arrays(prefix=f"line{j}."))
        return arrays

    @classmethod
    def from_arrays(cls, arrays, settings, y_settings=None) -> "Table2D":
        table = cls(settings, y_settings)
        table.y = np.asarray(arrays["y"])
        table.yerr = np.asarray(arrays["yerr"])
        table.ychecked = np.asarray(arrays["ychecked"])
        table.windows = np.asarray(arrays["windows"], dtype=float).reshape(-1, 5)
        table.lines = [Table1D.from_arrays(arrays, settings, prefix=f"line{j}.") for j in range(table.y.size)]
        return table

    def __repr__(self) -> str:
        if not self.lines:
            return "Table2D(empty)"
        return (f"Table2D(x=[{self.lines[0].lo:.4g}, {self.lines[0].hi:.4g}], y=[{self.y[0]:.4g}, "
                f"{self.y[-1]:.4g}], lines={self.y.size}, samples={sum(l.x.size for l in self.lines)})")
