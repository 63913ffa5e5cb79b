"""Two-parameter design charts: where a loop has no limit cycle, a stable one, only unstable ones, or several.

A chart over two parameters (x, y) of a family of loops ``loop_at(x, y) -> (G, N)`` has regions separated by
curves on which the describing-function picture changes: folds and stability changes (the Loeb determinant
vanishes at a cycle), births from the linear loop at the edge of an element's linear range, births from
infinity or zero amplitude (the loop with N's limit is marginal), N's domain edges and jumps, and the window's
edges. :func:`design_chart` traces each such curve by pseudo-arclength continuation of its codimension-one condition
in (ln A, ln w, u_x, u_y) (u: the axes scaled to [0, 1]); the regions are read from
:func:`~dfloop.predict_limit_cycles` at a coarse grid of samples, and the filled picture assigns each fine-grid
point the label of the nearest sample on the same side of every traced curve.

Completeness: two neighbouring samples with different cycle counts must be separated by a traced curve. When
they are not, the segment between them is swept (:func:`dfloop.continuation.sweep`), its events seed new
curves, and the check is repeated (bounded); pairs still unseparated are listed in ``ChartResult.notes``.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from functools import partial
from typing import Callable

import numpy as np

from . import _checks
from .batch import run_batch
from .continuation import SweepResult, element_edges, sweep
from .describing.interop import as_element
from .progress import progress_bar
from .solve import as_plant, predict_limit_cycles
from .solve.errors import ContinuumError

__all__ = ["design_chart", "ChartResult", "Boundary", "ChartAxis"]

REGIONS = ("no cycle", "stable cycle", "only unstable cycles", "several cycles")
_FD = 1e-6
_FD_FOLD = 1e-5  # outer difference step for the fold condition (itself a difference quotient)
_XTOL = 1e-10
_MAX_NEWTON = 10
_COS_TURN = math.cos(math.radians(30))
_EDGE_IN = 1e-15  # relative offset inside an element edge (see continuation._inside)
_ROUNDS = 4  # completeness rounds (sweeps of unseparated sample pairs)
_PAIRS_PER_ROUND = 24


# ------------------------------------------------------------------------------------------------ axes


@dataclass(frozen=True)
class ChartAxis:
    """One parameter of a chart: its range, spacing, name and unit.

    Attributes
    ----------
    start, stop : float
        The range (start != stop).
    name, unit : str
        For the report, the CSV header and the plot axis (``"gain K"``, ``"delay T"``, ``"s"``).
    scale : str
        ``"linear"`` or ``"log"`` (samples, tracing coordinates and plot axis).
    gain : bool
        A loop gain: margins are also given in dB.
    """

    start: float
    stop: float
    name: str = "parameter"
    unit: str = ""
    scale: str = "linear"
    gain: bool = False

    def __post_init__(self):
        start = _checks.finite(f"{self.name} start", self.start)
        stop = _checks.finite(f"{self.name} stop", self.stop)
        if start == stop:
            raise ValueError(f"{self.name}: start and stop must differ; got {start!r}")
        if self.scale not in ("linear", "log"):
            raise ValueError(f"{self.name}: scale must be 'linear' or 'log'; got {self.scale!r}")
        if self.scale == "log" and not (start > 0 and stop > 0):
            raise ValueError(f"{self.name}: a log scale needs start > 0 and stop > 0; got {start!r}, {stop!r}")

    @property
    def label(self) -> str:
        """``name [unit]``."""
        return self.name + (f" [{self.unit}]" if self.unit else "")

    def value(self, u):
        """The parameter at scaled coordinate u (0 at start, 1 at stop)."""
        u = np.asarray(u, float)
        if self.scale == "log":
            return self.start * (self.stop / self.start) ** u
        return self.start + u * (self.stop - self.start)

    def u(self, value):
        """Scaled coordinate of a parameter value."""
        p = np.asarray(value, float)
        if self.scale == "log":
            return np.log(p / self.start) / math.log(self.stop / self.start)
        return (p - self.start) / (self.stop - self.start)


# ------------------------------------------------------------------------------------------- results


@dataclass(eq=False)
class Boundary:
    """One traced boundary curve of a chart.

    Attributes
    ----------
    kind : str
        The condition traced: ``"fold"`` (Loeb determinant zero: a stable and an unstable cycle meet, or a
        stability change), ``"linear range"`` (a cycle born from the linear loop at the edge of the element's
        linear range), ``"infinity"`` / ``"zero amplitude"`` (the loop with N's limit is marginal),
        ``"amplitude domain"``, ``"jump"``, ``"window edge"``.
    x, y : ndarray
        Points of the curve, in the axes' units, in order along the curve.
    amplitude, frequency : ndarray
        The cycle at each point (N's input unit, inf/0 for limits; rad/s).
    ends : (str, str)
        How each end of the curve was reached: ``"chart edge"``, ``"closed"``, ``"lost: <why>"``.
    """

    kind: str
    x: np.ndarray
    y: np.ndarray
    amplitude: np.ndarray
    frequency: np.ndarray
    ends: tuple = ("", "")
    _condition: object = field(default=None, repr=False)
    _Z: np.ndarray = field(default=None, repr=False)

    @property
    def label(self) -> str:
        """A legend entry."""
        return {"fold": "fold / stability change", "linear range": "birth from the linear loop",
                "infinity": "birth from infinity", "zero amplitude": "birth from zero amplitude",
                "amplitude domain": "edge of N's domain", "jump": "jump of N",
                "window edge": "window edge"}.get(self.kind, self.kind)

    def __repr__(self) -> str:
        return (f"Boundary({self.kind}, {self.x.size} points, x {self.x.min():.6g} .. {self.x.max():.6g}, "
                f"y {self.y.min():.6g} .. {self.y.max():.6g}, ends: {self.ends[0]} / {self.ends[1]})")


@dataclass(frozen=True)
class ChartMargin:
    """The nominal design point's distance to the chart's boundaries (the limit-cycle margin).

    Attributes
    ----------
    nominal : (float, float)
        The design point (axes' units).
    nearest : (float, float) or None
        The nearest boundary point, in the scaled plane (each axis scaled to [0, 1], log axes in log).
    distance : float
        Its distance in that scaled plane (inf without a boundary).
    kind : str
        The nearest boundary's kind.
    x_below, x_above, y_below, y_above : float or None
        Changes of one parameter (the other fixed) to the first boundary crossed, in its own unit
        (None: no boundary in the chart's range on that side).
    """

    nominal: tuple
    nearest: tuple | None
    distance: float
    kind: str
    x_below: float | None
    x_above: float | None
    y_below: float | None
    y_above: float | None
    x_axis: ChartAxis = None
    y_axis: ChartAxis = None

    def lines(self) -> list[str]:
        out = [f"limit-cycle margin of the design point ({self.x_axis.name} = {self.nominal[0]:.6g}, "
               f"{self.y_axis.name} = {self.nominal[1]:.6g}):"]
        if self.nearest is None:
            out.append("  no boundary in the chart")
        else:
            what = Boundary(self.kind, np.empty(0), np.empty(0), np.empty(0), np.empty(0)).label
            out.append(f"  nearest boundary ({what}) at ({self.nearest[0]:.6g}, {self.nearest[1]:.6g}): "
                       f"distance {self.distance:.4g} in the chart's scaled plane (each axis's range = 1)")
        for ax, lo, hi, p in ((self.x_axis, self.x_below, self.x_above, self.nominal[0]),
                              (self.y_axis, self.y_below, self.y_above, self.nominal[1])):
            u = f" {ax.unit}" if ax.unit else ""
            for side, d in (("down", lo), ("up", hi)):
                if d is None:
                    out.append(f"  {ax.name} {side}: no boundary within the chart")
                else:
                    db = f" ({20 * math.log10((p + d) / p):+.3g} dB)" if ax.gain and p != 0 and p + d > 0 else ""
                    out.append(f"  {ax.name} {side}: boundary at {p + d:.9g}{u}, change {d:+.6g}{u}{db}")
        return out

    def __repr__(self) -> str:
        return "\n".join(self.lines())


@dataclass(eq=False)
class ChartResult:
    """Regions and boundaries of a two-parameter chart.

    Attributes
    ----------
    x_axis, y_axis : ChartAxis
    boundaries : list of Boundary
        The traced curves.
    sample_x, sample_y : ndarray
        The coarse grid of samples (axes' units).
    sample_counts : ndarray of int, shape (ny, nx, 3)
        Stable, unstable and marginal cycles found by ``predict_limit_cycles`` at each sample (-1 where the
        solver met a continuum).
    grid_x, grid_y : ndarray
        The fine grid of the filled picture (``resolution`` per axis).
    labels : ndarray of str, shape (ny, nx)
        Region at each fine-grid point (one of ``REGIONS``), from the nearest sample on the same side of every
        boundary.
    nominal : (float, float) or None
    margin : ChartMargin or None
    notes : list of str
        What the reader must know (unseparated sample pairs, lost curves).
    n_solves : int
        ``predict_limit_cycles`` calls made (samples and the sweeps that seeded curves).
    exact_counts : ndarray of int, shape (ny, nx, 3), or None
        With ``exact=True``: stable and unstable exact orbits that :func:`dfloop.exact_cycle` found at each
        sample, started from the sample's and its neighbours' predictions (an orbit it cannot reach from them
        is not counted: a disagreement says the DF and the exact flow differ *there*, or that the exact orbit
        lies far from every prediction).
    exact_orbits : list of lists, or None
        ``exact_orbits[j][i]``: the orbits found at sample (i, j), ``[(amplitude, frequency, stable)]``.
    """

    x_axis: ChartAxis
    y_axis: ChartAxis
    boundaries: list
    sample_x: np.ndarray
    sample_y: np.ndarray
    sample_counts: np.ndarray
    grid_x: np.ndarray
    grid_y: np.ndarray
    labels: np.ndarray
    nominal: tuple | None = None
    margin: ChartMargin | None = None
    notes: list = field(default_factory=list)
    n_solves: int = 0
    exact_counts: np.ndarray | None = None
    exact_orbits: list | None = None

    @property
    def sample_labels(self) -> np.ndarray:
        """Region label at each sample."""
        return _labels(self.sample_counts)

    def exact_disagreements(self) -> list:
        """Samples where the exact orbits (``exact=True``) put the point in another region than the DF:
        ``[(x, y, DF region, exact region)]``; empty without the exact check."""
        if self.exact_counts is None:
            return []
        df_l, ex_l = _labels(self.sample_counts), _labels(self.exact_counts)
        return [(float(self.sample_x[i]), float(self.sample_y[j]), str(df_l[j, i]), str(ex_l[j, i]))
                for j in range(self.sample_y.size) for i in range(self.sample_x.size) if df_l[j, i] != ex_l[j, i]]

    def region_fractions(self) -> dict:
        """Share of the chart's fine grid in each region."""
        return {r: float(np.mean(self.labels == r)) for r in REGIONS}

    def __repr__(self) -> str:
        rows = [f"chart of {self.x_axis.label} in [{self.x_axis.start:.6g}, {self.x_axis.stop:.6g}] x "
                f"{self.y_axis.label} in [{self.y_axis.start:.6g}, {self.y_axis.stop:.6g}]: "
                f"{len(self.boundaries)} boundary curve(s), {self.sample_x.size} x {self.sample_y.size} region "
                f"samples, {self.n_solves} solves"]
        for i, b in enumerate(self.boundaries):
            rows.append(f"  {i}: {b.label}: {b.x.size} points, {self.x_axis.name} {b.x.min():.6g} .. "
                        f"{b.x.max():.6g}, {self.y_axis.name} {b.y.min():.6g} .. {b.y.max():.6g} "
                        f"(ends: {b.ends[0]} / {b.ends[1]})")
        fr = self.region_fractions()
        rows.append("regions: " + ", ".join(f"{r} {100 * fr[r]:.1f} %" for r in REGIONS if fr[r] > 0))
        if self.exact_counts is not None:
            bad = self.exact_disagreements()
            rows.append(f"exact orbits (exact_cycle) at the {self.sample_x.size * self.sample_y.size} samples: "
                        f"{'all in the DF region' if not bad else f'{len(bad)} in another region than the DF says'}")
            rows += [f"  ({x:.6g}, {y:.6g}): DF {a}, exact {b}" for x, y, a, b in bad]
        if self.margin is not None:
            rows += self.margin.lines()
        if self.notes:
            rows.append("notes:")
            rows += [f"  {n}" for n in self.notes]
        return "\n".join(rows)

    __str__ = __repr__

    def to_csv(self, path) -> None:
        """Every boundary point: curve, kind, x, y (axes' units), amplitude, frequency [rad/s]."""
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["curve", "kind", self.x_axis.label, self.y_axis.label, "amplitude", "frequency [rad/s]"])
            for i, b in enumerate(self.boundaries):
                for k in range(b.x.size):
                    w.writerow([i, b.kind, repr(float(b.x[k])), repr(float(b.y[k])), repr(float(b.amplitude[k])),
                                repr(float(b.frequency[k]))])

    def regions_to_csv(self, path) -> None:
        """Every region sample: x, y, region, stable, unstable and marginal cycle counts."""
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([self.x_axis.label, self.y_axis.label, "region", "stable", "unstable", "marginal"])
            labels = self.sample_labels
            exact = _labels(self.exact_counts) if self.exact_counts is not None else None
            if exact is not None:
                fh.seek(0)
                fh.truncate()
                w.writerow([self.x_axis.label, self.y_axis.label, "region", "stable", "unstable", "marginal",
                            "exact region", "exact stable", "exact unstable"])
            for j, y in enumerate(self.sample_y):
                for i, x in enumerate(self.sample_x):
                    c = self.sample_counts[j, i]
                    row = [repr(float(x)), repr(float(y)), labels[j, i], *map(int, c)]
                    if exact is not None:
                        row += [exact[j, i], int(self.exact_counts[j, i, 0]), int(self.exact_counts[j, i, 1])]
                    w.writerow(row)

    def plot(self, ax=None):
        """Filled regions, labelled boundary curves and the nominal point (:func:`dfloop.plot.chart.plot_chart`)."""
        from .plot.chart import plot_chart

        return plot_chart(self, ax=ax)


def _labels(counts: np.ndarray) -> np.ndarray:
    s, u, m = counts[..., 0], counts[..., 1], counts[..., 2]
    n = s + u + m
    out = np.where(n == 0, REGIONS[0], np.where((n == 1) & (s == 1), REGIONS[1],
                                                np.where(s == 0, REGIONS[2], REGIONS[3])))
    return np.where(s < 0, "continuum", out)


# ------------------------------------------------------------------------------------ the plane of loops


def _build(loop_at: Callable, x: float, y: float):
    try:
        loop = loop_at(x, y)
    except ValueError as exc:
        raise ValueError(f"loop_at({x!r}, {y!r}) failed: {exc}") from exc
    if not (isinstance(loop, (tuple, list)) and len(loop) == 2):
        raise ValueError(f"loop_at({x!r}, {y!r}) must return a pair (G, N); got {type(loop).__name__}")
    return as_plant(loop[0]), as_element(loop[1])


class _Plane:
    """The loops over the chart, in scaled coordinates (ux, uy) in [0, 1]^2, cached."""

    def __init__(self, loop_at: Callable, xa: ChartAxis, ya: ChartAxis, a_max: float):
        self.loop_at, self.xa, self.ya, self.a_max = loop_at, xa, ya, a_max
        self._cache: dict = {}

    def loop(self, ux: float, uy: float):
        key = (float(ux), float(uy))
        hit = self._cache.get(key)
        if hit is None:
            if len(self._cache) > 2048:
                self._cache.clear()
            hit = self._cache[key] = _build(self.loop_at, float(self.xa.value(ux)), float(self.ya.value(uy)))
        return hit

    def residual(self, A: float, w: float, ux: float, uy: float) -> complex:
        plant, N = self.loop(ux, uy)
        wa = np.array([w])
        n = N(np.array([A]), wa) if N.frequency_dependent else N(np.array([A]))
        return complex(1.0 + plant(wa)[0] * n[0])

    def edge_level(self, kind: str, side: int, ref: float, w: float, ux: float, uy: float) -> float:
        """The element's edge of this kind and side nearest to ``ref`` at (ux, uy)."""
        same = [e for e in element_edges(self.loop(ux, uy)[1], self.a_max) if e[0] == kind and e[1] == side]
        if not same and kind == "jump":  # a jump the sweep found by probing N: at a fixed amplitude
            return ref
        if not same:
            raise ValueError(f"the element has no {kind} edge at ({self.xa.value(ux):.6g}, {self.ya.value(uy):.6g})")
        e = min(same, key=lambda e: abs(math.log(e[2](w) / ref)))
        return e[2](w)


class _Condition:
    """A codimension-one condition: F(Z) = 0 with Z = (*own coordinates, ux, uy), len(F) = len(Z) - 1."""

    kind = ""

    def __init__(self, plane: _Plane):
        self.plane = plane

    def F(self, Z: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def cycle(self, Z: np.ndarray) -> tuple[float, float]:  # pragma: no cover - abstract
        raise NotImplementedError

    fd = _FD


class _Fold(_Condition):
    """Z = (ln A, ln w, ux, uy): R = 0 and the Loeb determinant det J / ((|R_a|^2 + |R_w|^2) / 2) = 0."""

    kind = "fold"
    fd = _FD_FOLD

    def F(self, Z):
        a, v, ux, uy = Z
        p = self.plane
        h = _FD
        r = p.residual(math.exp(a), math.exp(v), ux, uy)
        ra = (p.residual(math.exp(a + h), math.exp(v), ux, uy) - p.residual(math.exp(a - h), math.exp(v), ux, uy)) / (2 * h)
        rv = (p.residual(math.exp(a), math.exp(v + h), ux, uy) - p.residual(math.exp(a), math.exp(v - h), ux, uy)) / (2 * h)
        # the Loeb determinant over (|R_a|^2 + |R_w|^2) / 2: smooth with a simple zero both at a tangency
        # (backlash) and where R_a itself vanishes (the maximum of a dead-zone relay's N), unlike the crossing
        # angle's sine, which jumps there
        scale = 0.5 * (abs(ra) ** 2 + abs(rv) ** 2)
        det = (ra.real * rv.imag - rv.real * ra.imag) / scale if scale > 0 else 0.0
        return np.array([r.real, r.imag, det])

    def cycle(self, Z):
        return math.exp(Z[0]), math.exp(Z[1])


class _Edge(_Condition):
    """Z = (ln w, ux, uy): R = 0 with A on an element edge (kind, side) near ``ref``."""

    def __init__(self, plane, kind, side, ref):
        super().__init__(plane)
        self.kind, self.side, self.ref = kind, side, ref

    def amplitude(self, Z):
        v, ux, uy = Z
        level = self.plane.edge_level(self.kind, self.side, self.ref, math.exp(v), ux, uy)
        return level * (1 + self.side * max(_EDGE_IN, 8 * float(np.finfo(float).eps)))

    def F(self, Z):
        r = self.plane.residual(self.amplitude(Z), math.exp(Z[0]), Z[1], Z[2])
        return np.array([r.real, r.imag])

    def cycle(self, Z):
        return self.amplitude(Z), math.exp(Z[0])


class _Limit(_Condition):
    """Z = (ln w, ux, uy): 1 + G N(A_lim) = 0 with A_lim = inf or 0 (N's limit)."""

    def __init__(self, plane, amplitude):
        super().__init__(plane)
        self.A = amplitude
        self.kind = "infinity" if math.isinf(amplitude) else "zero amplitude"

    def F(self, Z):
        r = self.plane.residual(self.A, math.exp(Z[0]), Z[1], Z[2])
        return np.array([r.real, r.imag])

    def cycle(self, Z):
        return self.A, math.exp(Z[0])


class _Window(_Condition):
    """Z = (free log coordinate, ux, uy): R = 0 with ln A (index 0) or ln w (index 1) fixed on a window edge."""

    kind = "window edge"

    def __init__(self, plane, fixed_index, fixed_value):
        super().__init__(plane)
        self.i, self.value = fixed_index, fixed_value

    def _aw(self, Z):
        return (self.value, Z[0]) if self.i == 0 else (Z[0], self.value)

    def F(self, Z):
        a, v = self._aw(Z)
        r = self.plane.residual(math.exp(a), math.exp(v), Z[1], Z[2])
        return np.array([r.real, r.imag])

    def cycle(self, Z):
        a, v = self._aw(Z)
        return math.exp(a), math.exp(v)


# ----------------------------------------------------------------------------------------- the tracer


class _Tracer:
    def __init__(self, cond: _Condition, h_max: float, max_steps: int):
        self.c, self.h_max, self.max_steps = cond, h_max, max_steps
        self.failure = ""

    def jac(self, Z: np.ndarray, F0: np.ndarray) -> np.ndarray:
        m = Z.size
        J = np.empty((m - 1, m))
        h = self.c.fd
        for i in range(m):
            e = np.zeros(m)
            if i >= m - 2:  # a chart coordinate: one-sided towards the inside of [0, 1]
                s = h if Z[i] + h <= 1 else -h
                e[i] = s
                J[:, i] = (self.c.F(Z + e) - F0) / s
            else:
                e[i] = h
                J[:, i] = (self.c.F(Z + e) - self.c.F(Z - e)) / (2 * h)
        return J

    def correct(self, Z0: np.ndarray, n: np.ndarray, g: float):
        """Chord Newton on F(Z) = 0, n . Z = g (the Jacobian of the first iterate, refreshed when the iteration
        stops contracting fast); (Z, J at the solution) or None."""
        Z = np.array(Z0, float)
        prev = math.inf
        J = None
        for it in range(_MAX_NEWTON + 4):
            if not (-1e-9 <= Z[-2] <= 1 + 1e-9 and -1e-9 <= Z[-1] <= 1 + 1e-9):
                self.failure = "left the chart"
                return None
            Z[-2:] = np.clip(Z[-2:], 0.0, 1.0)
            try:
                F0 = self.c.F(Z)
                if J is None:
                    J = self.jac(Z, F0)
                dz = np.linalg.solve(np.vstack([J, n]), -np.append(F0, n @ Z - g))
            except (ValueError, np.linalg.LinAlgError) as exc:
                self.failure = f"corrector failed: {exc}"
                return None
            step = float(np.max(np.abs(dz)))
            if not math.isfinite(step) or (it > 0 and step > 0.5 * prev and step > 1e3 * _XTOL):
                self.failure = "corrector did not contract"
                return None
            if it > 0 and step > 0.1 * prev:
                J = None  # slow contraction: a fresh Jacobian next time
            Z, prev = Z + dz, step
            if step <= _XTOL:
                if not (-1e-9 <= Z[-2] <= 1 + 1e-9 and -1e-9 <= Z[-1] <= 1 + 1e-9):
                    self.failure = "left the chart"
                    return None
                Z[-2:] = np.clip(Z[-2:], 0.0, 1.0)
                return Z, self.jac(Z, self.c.F(Z))
        self.failure = "corrector did not converge"
        return None

    @staticmethod
    def tangent(J: np.ndarray) -> np.ndarray:
        t = np.linalg.svd(J)[2][-1]
        return t / np.linalg.norm(t)

    def trace(self, Z0: np.ndarray, t0: np.ndarray) -> tuple[list, str]:
        """Points from Z0 (excluded) along t0 until the chart's edge, a return to Z0, or loss."""
        out, Z, t, h = [], Z0, t0, self.h_max / 4
        for _ in range(self.max_steps):
            Zp = Z + h * t
            edge = None
            for i in (-2, -1):
                if Zp[i] < 0 or Zp[i] > 1:
                    bound = 0.0 if Zp[i] < 0 else 1.0
                    frac = (bound - Z[i]) / (Zp[i] - Z[i])
                    if edge is None or frac < edge[0]:
                        edge = (frac, i, bound)
            if edge is not None:
                frac, i, bound = edge
                e = np.zeros(Z.size)
                e[i] = 1.0
                got = self.correct(Z + frac * (Zp - Z), e, bound)
            else:
                got = self.correct(Zp, t, float(t @ Zp))
            ok = False
            if got is not None:
                Q, J = got
                tq = self.tangent(J)
                tq = tq if tq @ t >= 0 else -tq
                ok = tq @ t >= _COS_TURN and (edge is not None or np.max(np.abs(Q - Zp)) <= 0.5 * h)
            if not ok:
                h *= 0.5
                if h < 1e-8:
                    return out, f"lost: {self.failure or 'the step size underflowed'}"
                continue
            out.append(Q)
            if edge is not None:
                return out, "chart edge"
            if len(out) > 3 and np.linalg.norm(Q[-2:] - Z0[-2:]) < h and np.linalg.norm(Q - Z0) < 2 * h:
                return out, "closed"
            Z, t = Q, tq
            h = min(1.5 * h, self.h_max)
        raise RuntimeError(f"chart: a boundary curve exceeded max_steps={self.max_steps} steps in one direction; "
                           "pass a larger max_steps to design_chart()")

    def curve(self, Z0: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, tuple]:
        fwd, end_f = self.trace(Z0, t)
        if end_f == "closed":
            return np.array([Z0] + fwd + [Z0]), ("closed", "closed")
        back, end_b = self.trace(Z0, -t)
        return np.array(back[::-1] + [Z0] + fwd), (end_b, end_f)


# ------------------------------------------------------------------------------------------------ chart


def _solve_at(point, loop_at: Callable, options: dict):
    """Cycle counts (stable, unstable, marginal) at one (x, y), (-1, -1, -1) at a continuum, and the cycles'
    (amplitude, frequency)."""
    x, y = point
    plant, N = _build(loop_at, x, y)
    try:
        cycles = predict_limit_cycles(plant, N, **options)
    except ContinuumError:
        return (-1, -1, -1), []
    labels = [c.stability for c in cycles]
    return (labels.count("stable"), labels.count("unstable"), labels.count("marginal")), \
        [(float(c.amplitude), float(c.frequency)) for c in cycles]


def _exact_at(item, loop_at: Callable):
    """Exact periodic orbits (:func:`dfloop.exact_cycle`) started from the given predictions at one (x, y):
    the distinct orbits found, ``[(amplitude, frequency, stable)]``."""
    from .exact import exact_cycle

    (x, y), seeds = item
    G, N = loop_at(x, y)
    found = []
    for A, w in seeds:
        try:
            ex = exact_cycle(G, N, (A, w), globalise=False)   # the seeds are many: shooting alone from each
        except (ValueError, RuntimeError, ArithmeticError):  # no orbit from this seed (e.g. it collapses to rest)
            continue
        if ex.success and not any(abs(ex.amplitude / a - 1) < 1e-6 and abs(ex.frequency / f - 1) < 1e-6
                                  for a, f, _ in found):
            found.append((ex.amplitude, ex.frequency, bool(ex.stable)))
    return found


def _line_loop(value, loop_at, fixed, along_x):
    return loop_at(value, fixed) if along_x else loop_at(fixed, value)


@dataclass(frozen=True)
class _SegmentEvents:
    """What a seeding sweep sends back (picklable: no plants): its events and window."""

    events: tuple
    amplitude_window: tuple
    omega_window: tuple


def _sweep_segment(seg, loop_at: Callable, options: dict) -> _SegmentEvents:
    """The events of a sweep along one axis between two samples (the other parameter fixed)."""
    along_x, fixed, values = seg
    res: SweepResult = sweep(partial(_line_loop, loop_at=loop_at, fixed=fixed, along_x=along_x), values,
                             progress=False, **options)
    return _SegmentEvents(tuple(res.events), tuple(res.amplitude_window), tuple(res.omega_window))


def _segments_cross(p0, p1, segs) -> np.ndarray:
    """For points p0 (M, 2) and p1 (M, 2): whether the segment p0-p1 crosses any of segs (S, 4)."""
    if segs.size == 0:
        return np.zeros(p0.shape[0], bool)
    ax, ay = p0[:, None, 0], p0[:, None, 1]
    bx, by = p1[:, None, 0], p1[:, None, 1]
    cx, cy, dx, dy = segs[None, :, 0], segs[None, :, 1], segs[None, :, 2], segs[None, :, 3]

    def orient(px, py, qx, qy, rx, ry):
        return (qx - px) * (ry - py) - (qy - py) * (rx - px)

    o1 = orient(ax, ay, bx, by, cx, cy)
    o2 = orient(ax, ay, bx, by, dx, dy)
    o3 = orient(cx, cy, dx, dy, ax, ay)
    o4 = orient(cx, cy, dx, dy, bx, by)
    # a boundary ending exactly on the segment (on the chart's edge) separates too: touching counts
    return np.any((o1 * o2 <= 0) & (o3 * o4 <= 0) & ~((o1 == 0) & (o2 == 0)), axis=1)


def design_chart(loop_at: Callable[[float, float], tuple], x_axis: ChartAxis, y_axis: ChartAxis, *,
          nominal: tuple | None = None, samples: int = 13, resolution: int = 100, omega=None, amplitude=None,
          exact: bool = False, executor=None, progress: bool | None = None, max_steps: int = 5000,
          **solver_options) -> ChartResult:
    """Map a two-parameter family of loops: regions (no cycle / a stable cycle / only unstable / several) and
    the boundaries between them, traced as curves.

    Parameters
    ----------
    loop_at : callable
        ``loop_at(x, y) -> (G, N)`` at one point of the chart (called inside the axes' ranges only; picklable
        for a process-based executor: a module-level function or a :func:`functools.partial` of one).
    x_axis, y_axis : ChartAxis
        The two parameters: range, spacing (``"linear"`` / ``"log"``), name and unit.
    nominal : (float, float), optional
        The design point; its limit-cycle margin (distance to the nearest boundary) is computed.
    samples : int
        Region samples per axis (>= 3): ``predict_limit_cycles`` on a samples x samples grid.
    resolution : int
        Equivalent resolution per axis (>= 10): the boundary curves' largest step is 2 / resolution of the
        scaled chart, and the filled picture has resolution x resolution points.
    omega, amplitude : (float, float), optional
        Windows (rad/s; N's input unit), as for :func:`~dfloop.predict_limit_cycles`; default: the solver's.
    exact : bool
        Also look for the exact periodic orbits (:func:`dfloop.exact_cycle`, which needs a python-control
        plant) at every sample, started from the sample's predictions and its neighbours': where their counts
        differ from the DF's, the DF boundary is not the true one (``ChartResult.exact_disagreements``).
    executor : concurrent.futures.Executor, optional
        Runs the independent solves (the samples) and the seeding sweeps (``run_batch``; Dask included).
    progress : bool or None
        Progress bars.
    max_steps : int
        Bound on continuation steps per boundary curve and direction (RuntimeError beyond).
    **solver_options
        Passed to :func:`~dfloop.predict_limit_cycles`.

    Returns
    -------
    ChartResult
        Boundaries (arrays along each curve), region samples, the filled label grid, the nominal point's margin.

    Notes
    -----
    Each boundary is the solution curve of a codimension-one condition in Z = (own coordinates, ux, uy),
    ux, uy the axes scaled to [0, 1] (log axes in log): a fold or stability change, R = 0 and
    det J / ((|R_a|^2 + |R_w|^2) / 2) = 0 in (ln A, ln w, ux, uy); a birth at an element edge, R(A_edge, w) = 0 in
    (ln w, ux, uy); a birth from infinity or zero amplitude, 1 + G N(A_lim) = 0 in (ln w, ux, uy); a window
    edge, R = 0 with ln A or ln w fixed. Pseudo-arclength continuation: tangent from the null space of the
    Jacobian (central differences), Newton on the hyperplane orthogonal to it, the step halved when Newton
    fails to contract or the tangent turns by more than 30 degrees; a curve ends exactly on the chart's edge
    (Newton with that coordinate fixed). Curves are seeded by the events of sweeps between neighbouring
    samples whose cycle counts differ and that no traced curve separates yet.
    """
    if not isinstance(x_axis, ChartAxis) or not isinstance(y_axis, ChartAxis):
        raise ValueError(f"x_axis and y_axis must be ChartAxis; got {type(x_axis).__name__}, "
                         f"{type(y_axis).__name__}")
    samples = _checks.integer_at_least("samples", samples, 3)
    resolution = _checks.integer_at_least("resolution", resolution, 10)
    max_steps = _checks.integer_at_least("max_steps", max_steps, 1)
    if omega is not None:
        omega = _checks.window("omega", omega)
    if amplitude is not None:
        amplitude = _checks.window("amplitude", amplitude)
    if nominal is not None:
        try:
            nominal = (float(nominal[0]), float(nominal[1]))
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"nominal must be a pair (x, y); got {nominal!r}") from None
    options = dict(solver_options, omega=omega, amplitude=amplitude)

    # region samples
    us = np.linspace(0.0, 1.0, samples)
    sx, sy = x_axis.value(us), y_axis.value(us)
    pts = [(float(x), float(y)) for y in sy for x in sx]
    solved = run_batch(partial(_solve_at, loop_at=loop_at, options=options), pts, executor=executor,
                       progress=progress, label="chart: region samples")
    counts = np.array([c for c, _ in solved], int).reshape(samples, samples, 3)
    n_solves = len(pts)
    exact_counts = exact_orbits = None
    if exact:
        # seeds at each sample: its own predictions and its neighbours' (an orbit the DF misses here may be
        # found from a neighbour's prediction)
        cyc = [c for _, c in solved]
        items = []
        for j in range(samples):
            for i in range(samples):
                seeds = list(cyc[j * samples + i])
                for jj, ii in ((j - 1, i), (j + 1, i), (j, i - 1), (j, i + 1)):
                    if 0 <= jj < samples and 0 <= ii < samples:
                        seeds += cyc[jj * samples + ii]
                items.append(((float(sx[i]), float(sy[j])), seeds))
        orbits = run_batch(partial(_exact_at, loop_at=loop_at), items, executor=executor, progress=progress,
                           label="chart: exact orbits")
        exact_orbits = [orbits[j * samples:(j + 1) * samples] for j in range(samples)]
        exact_counts = np.array([[(sum(o[2] for o in cell), sum(not o[2] for o in cell), 0) for cell in row]
                                 for row in exact_orbits], int)

    a_max = amplitude[1] if amplitude is not None else 1e8
    plane = _Plane(loop_at, x_axis, y_axis, a_max)
    boundaries: list[Boundary] = []
    notes: list[str] = []
    h_max = 2.0 / resolution

    def segments() -> np.ndarray:
        segs = [np.column_stack([np.asarray(x_axis.u(b.x))[:-1], np.asarray(y_axis.u(b.y))[:-1],
                                 np.asarray(x_axis.u(b.x))[1:], np.asarray(y_axis.u(b.y))[1:]])
                for b in boundaries if b.x.size > 1]
        return np.vstack(segs) if segs else np.empty((0, 4))

    def unseparated() -> list:
        """Neighbouring sample pairs with different counts and no traced curve between them."""
        pairs = []
        for j in range(samples):
            for i in range(samples):
                for dj, di in ((0, 1), (1, 0)):
                    jj, ii = j + dj, i + di
                    if jj < samples and ii < samples and not np.array_equal(counts[j, i], counts[jj, ii]):
                        pairs.append(((j, i), (jj, ii)))
        if not pairs:
            return []
        p0 = np.array([[us[i], us[j]] for (j, i), _ in pairs])
        p1 = np.array([[us[i], us[j]] for _, (j, i) in pairs])
        crossed = _segments_cross(p0, p1, segments())
        return [p for p, c in zip(pairs, crossed) if not c]

    def on_traced(kind: str, ux: float, uy: float) -> bool:
        for b in boundaries:
            if b.kind == kind and b.x.size:
                d = np.hypot(np.asarray(x_axis.u(b.x)) - ux, np.asarray(y_axis.u(b.y)) - uy)
                if d.min() < 2 * h_max:
                    return True
        return False

    with progress_bar("chart: boundaries", None, enabled=progress) as bar:
        for _ in range(_ROUNDS):
            todo = unseparated()
            if not todo:
                break
            # one sweep per pair (the first pairs; later rounds take the rest), on the executor
            segs = []
            for (j, i), (jj, ii) in todo[:_PAIRS_PER_ROUND]:
                if j == jj:
                    segs.append((True, float(sy[j]), [float(sx[i]), float(sx[ii])]))
                else:
                    segs.append((False, float(sx[i]), [float(sy[j]), float(sy[jj])]))
            results = run_batch(partial(_sweep_segment, loop_at=loop_at, options=options), segs, executor=executor,
                                progress=False, label="chart: seeding sweeps")
            n_solves += 2 * len(segs)
            for (along_x, fixed, _), res in zip(segs, results):
                # a branch that leaves the window towards a birth from infinity / zero amplitude: the birth is the
                # boundary, the window edge next to it is not
                to_limit = {i for e in res.events if e.cause in ("infinity", "zero amplitude") for i in e.branches}
                for e in res.events:
                    if e.kind in ("entry", "exit") and set(e.branches) & to_limit:
                        continue
                    cond, Z0 = _seed(plane, e, along_x, fixed, x_axis, y_axis, res)
                    if cond is None:
                        continue
                    ux, uy = Z0[-2], Z0[-1]
                    if on_traced(cond.kind, ux, uy):
                        continue
                    tr = _Tracer(cond, h_max, max_steps)
                    n = np.zeros(Z0.size)
                    n[-1 if along_x else -2] = 1.0  # refine on the sweep's line
                    got = tr.correct(Z0, n, Z0[-1] if along_x else Z0[-2])
                    if got is None:
                        notes.append(f"could not refine the {cond.kind} at ({x_axis.value(ux):.6g}, "
                                     f"{y_axis.value(uy):.6g}): {tr.failure}")
                        continue
                    Z, J = got
                    Zs, ends = tr.curve(Z, tr.tangent(J))
                    cyc = np.array([cond.cycle(z) for z in Zs])
                    boundaries.append(Boundary(cond.kind, x_axis.value(Zs[:, -2]), y_axis.value(Zs[:, -1]),
                                               cyc[:, 0], cyc[:, 1], ends, cond, Zs))
                    for end in ends:
                        if end.startswith("lost"):
                            notes.append(f"a {cond.kind} curve was {end}")
                    bar.update(1)
        left = unseparated()
        for (j, i), (jj, ii) in left:
            notes.append(f"samples ({sx[i]:.6g}, {sy[j]:.6g}) and ({sx[ii]:.6g}, {sy[jj]:.6g}) differ "
                         f"({_labels(counts[j, i])} vs {_labels(counts[jj, ii])}) but no traced boundary "
                         "separates them")

    # the filled picture: nearest sample on the same side of every boundary
    gu = np.linspace(0.0, 1.0, resolution)
    GU, GV = np.meshgrid(gu, gu)
    P = np.column_stack([GU.ravel(), GV.ravel()])
    segs = segments()
    lab_s = _labels(counts)
    k = np.clip(np.rint(P * (samples - 1)).astype(int), 0, samples - 1)
    best = lab_s[k[:, 1], k[:, 0]]
    # candidates: the four surrounding samples, nearest first; keep the first not separated by a boundary
    fl = np.clip(np.floor(P * (samples - 1)).astype(int), 0, samples - 2)
    cands = [(fl[:, 0] + di, fl[:, 1] + dj) for di in (0, 1) for dj in (0, 1)]
    dist = np.array([np.hypot(us[ci] - P[:, 0], us[cj] - P[:, 1]) for ci, cj in cands])
    order = np.argsort(dist, axis=0)
    chosen = np.full(P.shape[0], False)
    for rank in range(4):
        for c, (ci, cj) in enumerate(cands):
            sel = (~chosen) & (order[rank] == c)
            if not sel.any():
                continue
            idx = np.flatnonzero(sel)
            for start in range(0, idx.size, 2000):
                part = idx[start:start + 2000]
                q = np.column_stack([us[ci[part]], us[cj[part]]])
                ok = ~_segments_cross(P[part], q, segs)
                best[part[ok]] = lab_s[cj[part[ok]], ci[part[ok]]]
                chosen[part[ok]] = True
    labels = best.reshape(resolution, resolution)

    notes = list(dict.fromkeys(notes))  # a failure met from several seeds is said once
    margin = _margin(nominal, boundaries, x_axis, y_axis) if nominal is not None else None
    return ChartResult(x_axis, y_axis, boundaries, sx, sy, counts, x_axis.value(gu), y_axis.value(gu), labels,
                       nominal, margin, notes, n_solves, exact_counts, exact_orbits)


def _seed(plane: _Plane, e, along_x: bool, fixed: float, xa: ChartAxis, ya: ChartAxis, res: _SegmentEvents):
    """The condition and starting point of the boundary through a sweep event (None for events that are not
    boundaries: continua, lost branches)."""
    if along_x:
        ux, uy = float(xa.u(e.parameter)), float(ya.u(fixed))
    else:
        ux, uy = float(xa.u(fixed)), float(ya.u(e.parameter))
    v = math.log(e.frequency)
    if e.kind in ("fold", "stability change"):
        return _Fold(plane), np.array([math.log(e.amplitude), v, ux, uy])
    if e.kind in ("birth", "death"):
        if e.cause in ("infinity", "zero amplitude"):
            return _Limit(plane, math.inf if e.cause == "infinity" else 0.0), np.array([v, ux, uy])
        edges = [e2 for e2 in element_edges(plane.loop(ux, uy)[1], plane.a_max) if e2[0] == e.cause]
        if not edges:
            return (_Edge(plane, "jump", 0, e.amplitude), np.array([v, ux, uy])) if e.cause == "jump" else (None, None)
        near = min(edges, key=lambda e2: abs(math.log(e2[2](e.frequency) / e.amplitude)))
        return _Edge(plane, e.cause, near[1], e.amplitude), np.array([v, ux, uy])
    if e.kind in ("entry", "exit"):
        # a window edge: which coordinate sits on it
        a_lo, a_hi = res.amplitude_window
        w_lo, w_hi = res.omega_window
        la, lv = math.log(e.amplitude), v
        for i, val in ((0, math.log(a_lo)), (0, math.log(a_hi)), (1, math.log(w_lo)), (1, math.log(w_hi))):
            if abs((la if i == 0 else lv) - val) < 1e-9:
                return _Window(plane, i, val), np.array([lv if i == 0 else la, ux, uy])
    return None, None


def _margin(nominal, boundaries, xa: ChartAxis, ya: ChartAxis) -> ChartMargin:
    ux0, uy0 = float(xa.u(nominal[0])), float(ya.u(nominal[1]))
    best = (math.inf, None, "")
    hits = {"x_below": None, "x_above": None, "y_below": None, "y_above": None}
    for b in boundaries:
        u, v = np.asarray(xa.u(b.x)), np.asarray(ya.u(b.y))
        if u.size == 1:
            d = math.hypot(u[0] - ux0, v[0] - uy0)
            if d < best[0]:
                best = (d, (float(b.x[0]), float(b.y[0])), b.kind)
            continue
        du, dv = np.diff(u), np.diff(v)
        L2 = du * du + dv * dv
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.clip(np.where(L2 > 0, ((ux0 - u[:-1]) * du + (uy0 - v[:-1]) * dv) / L2, 0.0), 0, 1)
        px, py = u[:-1] + s * du, v[:-1] + s * dv
        d = np.hypot(px - ux0, py - uy0)
        k = int(np.argmin(d))
        if d[k] < best[0]:
            best = (float(d[k]), (float(xa.value(px[k])), float(ya.value(py[k]))), b.kind)
        # crossings of the lines through the nominal point
        for coord, fixed0, along, nomv, key in ((v, uy0, u, ux0, "x"), (u, ux0, v, uy0, "y")):
            c0, c1 = coord[:-1] - fixed0, coord[1:] - fixed0
            idx = np.flatnonzero((c0 * c1 <= 0) & (c0 != c1))
            for i in idx:
                t = c0[i] / (c0[i] - c1[i])
                pos = along[i] + t * (along[i + 1] - along[i])
                if b._condition is not None:  # the exact crossing: Newton with the other coordinate fixed
                    tr = _Tracer(b._condition, 1.0, 1)
                    n = np.zeros(b._Z.shape[1])
                    n[-1 if key == "x" else -2] = 1.0
                    got = tr.correct(b._Z[i] + t * (b._Z[i + 1] - b._Z[i]), n, fixed0)
                    if got is not None:
                        pos = float(got[0][-2 if key == "x" else -1])
                axis = xa if key == "x" else ya
                p0 = nominal[0] if key == "x" else nominal[1]
                change = float(axis.value(pos)) - p0
                side = f"{key}_above" if pos > nomv else f"{key}_below"
                if hits[side] is None or abs(change) < abs(hits[side]):
                    hits[side] = change
    return ChartMargin(nominal, best[1], best[0], best[2], hits["x_below"], hits["x_above"], hits["y_below"],
                       hits["y_above"], xa, ya)
