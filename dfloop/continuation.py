"""Parameter sweeps that follow each limit cycle: continuation of 1 + G N = 0 in a scalar parameter.

The cycles of a one-parameter family of loops form curves in (ln A, ln w, p). :func:`sweep` traces each
curve by pseudo-arclength continuation (tangent predictor, Newton corrector on the arclength hyperplane,
step control), so a cycle is followed from value to value instead of being re-solved and matched by eye.
A fold (turning point in p, where a stable and an unstable cycle meet) is passed, not lost, and is located
by a bracketing root search (Illinois regula falsi) on dp/ds along the curve; leaving the window ends a
branch at the exact crossing of its edge.

The tangent of the curve is the cross product of the gradients of Re R and Im R (R = 1 + G N) in
(ln A, ln w, q); its q component is U_a V_v - U_v V_a, the Loeb determinant in log coordinates. So dp/ds
and the Loeb determinant have the same sign up to the direction of travel: stability changes exactly at
folds, except at a branch point (two curves crossing), where the tangent field flips; such points are
reported as "stability change" events.

Births and deaths: a branch that reaches an edge of the element (N constant beyond it: the linear loop; the end of
N's domain; a jump of N) ends exactly on it (Newton with the edge as constraint), and a branch that leaves the
amplitude window towards A -> inf or 0 where N has a finite limit is born (or dies) where the loop with that limit
is marginal (Newton in (ln w, q)). A continuum of solutions at one given value (the solver's ContinuumError) is
recorded as an event. Labels use the solver's marginal test (:func:`dfloop.solve.stability.label_roots`).

Completeness: :func:`dfloop.predict_limit_cycles` is run at every given value (independently, on any
executor); every cycle it finds either lies on a traced curve or seeds a new trace, so branches born
between two values (a pair from a fold, or one entering through the window edge) are traced back to their
birth. Points of a traced curve that the solver did not report are listed in ``SweepResult.notes``. A curve
that meets no given value (a pair born and dying between two values: an isola, a short-lived fold pair) is
found by the valley scan (:class:`_ValleyScan`): the bottoms of the valleys of |1 + G N| over the window are
followed across each interval and searched where their depth can reach zero; an interval the search cannot
decide within its bound is listed in ``SweepResult.unresolved``. Two branches that end on an element edge at
the same point from either side (a quantizer's threshold) are one fold.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import warnings
from dataclasses import dataclass, field
from functools import partial
from typing import Callable

import numpy as np

from . import _checks
from .batch import run_batch, solver_options as batch_solver_options
from .describing.interop import as_element
from .progress import progress_bar
from .solve import LimitCycles, as_plant, predict_limit_cycles
from .solve.errors import ContinuumError
from .solve.stability import MARGINAL_TOL, label_roots

__all__ = ["sweep", "SweepResult", "Branch", "SweepEvent", "UnresolvedInterval"]

_FD = 1e-6  # central-difference step in ln A, ln w and q (q: the parameter range scaled to [0, 1])
_XTOL = 1e-11  # Newton converged when the update is below this (max norm)
_MAX_NEWTON = 12
_H0, _HMAX, _HMIN = 0.02, 0.1, 1e-9  # arclength steps in (ln A, ln w, q)
_COS_TURN = math.cos(math.radians(30))  # a step may turn the tangent by at most 30 degrees
_BISECT = 80  # bound on the probes that locate an event inside a step
_MATCH = 1e-6  # a solver's cycle lies on a traced curve when within this (ln A, ln w)
_MATCH_MARGINAL = 1e-3  # ... or within this for a cycle the solver called marginal (a double root)
_SAME_Q = 1e-12  # a point this close to a given value (in q) lies on it
_CACHE = 2048  # loops kept per sweep (the corrector and the labels ask for the same parameter values again)
_EDGE_IN = 1e-15  # an element edge is approached this far (in ln A, at least 8 ulps) on the branch's side
_MAX_BREAKPOINTS = 64  # breakpoints of a static element examined as possible edges
_LIMIT_NEWTON = 40  # Newton iterations for a birth from infinity / zero amplitude
_LAND_NEWTON = 60  # Newton iterations of the fallback that lands on a given value next to an element edge
# the valley scan (pairs born and dying between two given values; see _ValleyScan)
_PROBES = 3  # default: sub-intervals scanned per interval between given values
_SCAN_A, _SCAN_V = 48, 96  # least grid nodes in ln A and ln w of the valley grid
_SCAN_A_DECADE, _SCAN_V_DECADE = 8, 32  # ... and at least this many per decade of the window
_FLAT = 1 - 1e-9  # grid minima of |R| / (1 + |G N|) at or above this are plateaus (N = 0), not valleys
_MAX_VALLEYS = 12  # valleys settled per probe (the deepest)
_LM = 60  # Newton iterations that settle a valley's bottom
_SETTLED = 1e-9  # ... settled when a step moves less than this (ln A, ln w): the depth is then exact to ~1e-18
_SCAN_FD = 1e-4  # difference step (ln A, ln w) of the gradient and Hessian of |R|^2 there
_SCAN_NEWTON = 0.5  # largest step (ln A, ln w) of the Newton-on-R step tried first
_SCAN_ESCAPE = 0.05  # first step (ln A, ln w) along a negative curvature of |R|^2 (halved until |R| decreases)
_ROOT = 1e-10  # a bottom with |R| / (1 + |G N|) below this is a root
_GOLDEN = 80  # bound on the probes of the search on one valley's depth
_Q_BRACKET = 1e-12  # ... and on its bracket (in q)
_DIP = 0.6  # the depth's tangents meeting above this times the smaller end depth: no root between
_SCANNED = "; found between the given values by the valley scan"


# ----------------------------------------------------------------------------------------- result objects


@dataclass(frozen=True, eq=False)
class Branch:
    """One branch of limit cycles: a piece of a traced curve between events, monotone in the parameter.

    Attributes
    ----------
    index : int
        Position in ``SweepResult.branches`` (events refer to branches by it).
    parameter, amplitude, frequency : ndarray
        The points in the order of the sweep (the order of ``values``): given values, continuation steps
        and event points. Amplitude in N's input unit, frequency in rad/s.
    stability : ndarray of str
        ``"stable"``, ``"unstable"`` or ``"marginal"`` (Loeb criterion) at each point; constant along a
        branch except at its ends when they are folds (marginal there).
    value_index : ndarray of int
        Index into ``SweepResult.values`` where the point lies at a given value, else -1.
    start, end : str
        How the branch begins and ends in the order of the sweep: ``"sweep start"``, ``"sweep end"``,
        ``"fold"``, ``"stability change"``, ``"enters <edge>"``, ``"leaves <edge>"``, ``"born ..."`` /
        ``"dies ..."`` (at an element edge: see ``SweepEvent.cause``), ``"lost: <why>"``.
    """

    index: int
    parameter: np.ndarray
    amplitude: np.ndarray
    frequency: np.ndarray
    stability: np.ndarray
    value_index: np.ndarray
    start: str
    end: str

    @property
    def kind(self) -> str:
        """The branch's stability (``"stable"``, ``"unstable"``, or ``"marginal"`` if only marginal points)."""
        labels = [s for s in self.stability if s != "marginal"]
        return max(set(labels), key=labels.count) if labels else "marginal"

    def at_values(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(parameter, amplitude, frequency) at the given values only."""
        m = self.value_index >= 0
        return self.parameter[m], self.amplitude[m], self.frequency[m]

    def __repr__(self) -> str:
        return (f"Branch({self.index}, {self.kind}, p {self.parameter[0]:.6g} -> {self.parameter[-1]:.6g}, "
                f"amplitude {self.amplitude[0]:.6g} -> {self.amplitude[-1]:.6g}, frequency {self.frequency[0]:.6g} -> "
                f"{self.frequency[-1]:.6g} rad/s, {self.start} -> {self.end})")


@dataclass(frozen=True)
class ContinuumAt:
    """The solver met a continuum of solutions at one given value (``SweepResult.cycles`` holds this there).

    Attributes
    ----------
    amplitude_range, omega_range : (float, float)
        The part of the continuum the solver followed (N's input unit; rad/s).
    message : str
        The solver's explanation.
    """

    amplitude_range: tuple
    omega_range: tuple
    message: str = ""

    def __len__(self) -> int:
        return 0

    def __iter__(self):
        return iter(())


@dataclass(frozen=True)
class SweepEvent:
    """Where branches are born, die or change stability.

    Attributes
    ----------
    kind : str
        ``"fold"`` (a stable and an unstable cycle meet and vanish together), ``"birth"`` / ``"death"`` (a
        branch begins / ends in the order of the sweep at an element edge, from infinity or from zero
        amplitude: see ``cause``), ``"continuum"`` (at this isolated value 1 + G N = 0 along a whole curve:
        the sweep goes on past it), ``"entry"`` / ``"exit"`` (a branch crosses an edge of the window, in the
        order of the sweep), ``"stability change"`` (a branch point: curves cross), ``"lost"`` (continuation
        could not go on; see ``detail``).
    parameter, amplitude, frequency : float
        Where (parameter in its unit, amplitude in N's input unit, frequency in rad/s).
    branches : tuple of int
        The branches that meet there.
    detail : str
        A sentence for the report.
    """

    kind: str
    parameter: float
    amplitude: float
    frequency: float
    branches: tuple
    detail: str = ""
    cause: str = ""
    name: str = "p"

    def __str__(self) -> str:
        ids = ", ".join(map(str, self.branches))
        where = f"branch{'es' if len(self.branches) > 1 else ''} {ids}" if self.branches else "no branch"
        return (f"{self.kind} at {self.name}={self.parameter:.9g}: amplitude={self.amplitude:.6g}, "
                f"frequency={self.frequency:.6g} rad/s; {where}" + (f" ({self.detail})" if self.detail else ""))


@dataclass(eq=False)
class SweepResult:
    """Branches of limit cycles over a parameter range and the events between them.

    Attributes
    ----------
    values : ndarray
        The given parameter values, in the order given.
    branches : list of Branch
    events : list of SweepEvent
        In the order of the sweep.
    cycles : list of LimitCycles
        :func:`~dfloop.predict_limit_cycles` at each given value (the completeness check).
    amplitude_window, omega_window : (float, float)
        The window the branches were traced in (amplitude in N's input unit, frequency in rad/s).
    parameter, unit : str
        Name and unit of the parameter (for labels).
    amplitude_name, amplitude_unit : str
        Name and unit of N's input amplitude (from the element at the first value).
    notes : list of str
        Anything the reader must know: cycles continuation found that the solver missed at a given value,
        intervals the valley scan could not decide (also in ``unresolved``).
    unresolved : list of UnresolvedInterval
        Parameter intervals where a pair of cycles born and dying between two given values may have escaped:
        the valley scan came within 1e-9 of a root there and its bound ran out (empty when every interval
        was decided; see docs/sweep.md, "Pairs born and dying between two values").
    """

    values: np.ndarray
    branches: list
    events: list
    cycles: list
    amplitude_window: tuple
    omega_window: tuple
    parameter: str = "parameter"
    unit: str = ""
    amplitude_name: str = "A"
    amplitude_unit: str = ""
    notes: list = field(default_factory=list)
    unresolved: list = field(default_factory=list)

    def __repr__(self) -> str:
        p = self.parameter + (f" [{self.unit}]" if self.unit else "")
        head = (f"sweep of {p} over {self.values[0]:.6g} .. {self.values[-1]:.6g} ({self.values.size} values): "
                f"{len(self.branches)} branch(es), {len(self.events)} event(s); amplitude window "
                f"[{self.amplitude_window[0]:.4g}, {self.amplitude_window[1]:.4g}], omega window "
                f"[{self.omega_window[0]:.4g}, {self.omega_window[1]:.4g}] rad/s")
        rows = [head]
        if not self.branches:
            rows.append("no limit cycle in the window at the given values")
        else:
            rows.append(f"{'#':>3} {'stability':>10} {p + ' from':>16} {'to':>12} {'amplitude from':>14} {'to':>12} "
                        f"{'frequency from':>14} {'to':>11}  start -> end")
            for b in self.branches:
                rows.append(f"{b.index:>3} {b.kind:>10} {b.parameter[0]:>16.6g} {b.parameter[-1]:>12.6g} "
                            f"{b.amplitude[0]:>14.6g} {b.amplitude[-1]:>12.6g} {b.frequency[0]:>14.6g} "
                            f"{b.frequency[-1]:>11.6g}  {b.start} -> {b.end}")
        if self.events:
            rows.append("events:")
            rows += [f"  {e}" for e in self.events]
        if self.notes:
            rows.append("notes:")
            rows += [f"  {n}" for n in self.notes]
        return "\n".join(rows)

    __str__ = __repr__

    def folds(self) -> list:
        """The fold events."""
        return [e for e in self.events if e.kind == "fold"]

    def margin(self, nominal: float, gain: bool = False) -> "LimitCycleMargin":
        """How far the parameter can move from ``nominal`` (in either direction) before a limit cycle appears
        or disappears, and before a stable one does.

        Parameters
        ----------
        nominal : float
            The design value, inside the swept range (the parameter's unit).
        gain : bool
            The parameter is a loop gain: the margins are also given in dB (20 log10 of the ratio).

        Returns
        -------
        LimitCycleMargin
            The nearest events below and above ``nominal`` (births, deaths, folds, stability changes, and
            window edges when no physical event is in range).
        """
        nominal = _checks.finite("nominal", nominal)
        lo, hi = sorted((float(self.values[0]), float(self.values[-1])))
        if not lo <= nominal <= hi:
            raise ValueError(f"nominal must lie in the swept range [{lo:.6g}, {hi:.6g}]; got {nominal!r}")
        if gain and not (lo > 0 or hi < 0):
            raise ValueError(f"a gain margin in dB needs a range of one sign; got [{lo:.6g}, {hi:.6g}]")

        def stable_involved(e):
            return e.kind == "stability change" or any(self.branches[i].kind == "stable" for i in e.branches)

        physical = [e for e in self.events if e.kind in ("fold", "birth", "death", "stability change")]
        found = {}
        for key, pick in (("any", lambda e: True), ("stable", stable_involved)):
            ev = [e for e in physical if pick(e)]
            found[key] = (max((e for e in ev if e.parameter < nominal), key=lambda e: e.parameter, default=None),
                          min((e for e in ev if e.parameter > nominal), key=lambda e: e.parameter, default=None))
        return LimitCycleMargin(self.parameter, self.unit, nominal, gain, (lo, hi), *found["stable"], *found["any"])
    def to_dict(self) -> dict:
        """Plain data: ``values``, ``branches`` (each: ``index``, ``parameter``, ``amplitude``, ``frequency``,
        ``stability``, ``value_index`` as lists, ``start``, ``end``, ``kind``), ``events`` (their fields), the
        windows, ``parameter``, ``unit``, ``amplitude_name``, ``amplitude_unit``, ``notes`` and ``unresolved``
        (their fields). The solver's
        cycles at each value are in ``cycles`` (``[c.to_dict() for c in result.cycles]``)."""
        from dataclasses import asdict

        from .export import plain

        branches = [dict(plain({k: getattr(b, k) for k in ("index", "parameter", "amplitude", "frequency",
                                                             "stability", "value_index", "start", "end")}),
                         kind=b.kind) for b in self.branches]
        return {"values": plain(self.values), "branches": branches,
                "events": [plain(asdict(e)) for e in self.events],
                "amplitude_window": plain(self.amplitude_window), "omega_window": plain(self.omega_window),
                "parameter": self.parameter, "unit": self.unit, "amplitude_name": self.amplitude_name,
                "amplitude_unit": self.amplitude_unit, "notes": list(self.notes),
                "unresolved": [plain(asdict(u)) for u in self.unresolved]}

    def to_csv(self, path) -> None:
        """Write every branch point: branch, parameter, amplitude, frequency (rad/s), stability, and what
        the point is (``value`` at a given value, ``step`` of the continuation, or the event at a branch end:
        ``fold``, ``entry``, ``exit``, ``stability change``, ``sweep start``/``sweep end``, ``lost``)."""
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            unit = f" [{self.unit}]" if self.unit else ""
            a_unit = f" [{self.amplitude_unit}]" if self.amplitude_unit else ""
            w.writerow(["branch", f"{self.parameter}{unit}", f"amplitude {self.amplitude_name}{a_unit}",
                        "frequency [rad/s]", "stability", "point"])
            for b in self.branches:
                n = b.parameter.size
                for i in range(n):
                    what = "value" if b.value_index[i] >= 0 else "step"
                    if i == 0:
                        what = _end_word(b.start, what)
                    elif i == n - 1:
                        what = _end_word(b.end, what)
                    w.writerow([b.index, repr(float(b.parameter[i])), repr(float(b.amplitude[i])),
                                repr(float(b.frequency[i])), b.stability[i], what])

    def plot(self, ax=None):
        """Amplitude and frequency of every branch against the parameter: :func:`dfloop.plot.sweep.plot_sweep`.

        ``ax``: a pair of matplotlib Axes (amplitude, frequency); new ones by default. Returns a
        :class:`control.ControlPlot` (``axes[0, 0]`` amplitude, ``axes[1, 0]`` frequency).
        """
        from .plot.sweep import plot_sweep

        return plot_sweep(self, ax)


@dataclass(frozen=True)
class LimitCycleMargin:
    """How far a parameter can change from its nominal value before a limit cycle appears or disappears.

    Attributes
    ----------
    parameter, unit : str
        Name and unit of the parameter.
    nominal : float
        The design value.
    gain : bool
        Whether the parameter is a gain (margins also in dB).
    range : (float, float)
        The swept range: without an event on one side, the margin there is at least the distance to its end.
    stable_below, stable_above : SweepEvent or None
        The nearest events below / above the nominal value where a stable cycle appears, disappears or
        changes stability.
    any_below, any_above : SweepEvent or None
        The nearest events of any cycle (stable or unstable).
    """

    parameter: str
    unit: str
    nominal: float
    gain: bool
    range: tuple
    stable_below: SweepEvent | None
    stable_above: SweepEvent | None
    any_below: SweepEvent | None
    any_above: SweepEvent | None

    def distance(self, side: str, which: str = "stable") -> tuple[float, bool]:
        """(signed change of the parameter to the nearest event on ``side`` ("below"/"above"), exact) for
        ``which`` in ("stable", "any"); exact is False when no event is in the range (the value is then the
        distance to the range's end, a lower bound)."""
        e = getattr(self, f"{which}_{side}")
        end = self.range[0] if side == "below" else self.range[1]
        return ((e.parameter if e is not None else end) - self.nominal, e is not None)

    def decibels(self, change: float) -> float:
        """20 log10((nominal + change) / nominal) (gains)."""
        return 20 * math.log10((self.nominal + change) / self.nominal) if self.nominal + change != 0 else -math.inf

    def lines(self) -> list[str]:
        """The report's sentences."""
        u = f" {self.unit}" if self.unit else ""
        out = [f"limit-cycle margin of {self.parameter} from the nominal {self.nominal:.6g}{u}:"]
        for which, what in (("stable", "a stable cycle appears, disappears or changes stability"),
                            ("any", "any cycle appears or disappears")):
            for side in ("below", "above"):
                d, exact = self.distance(side, which)
                e = getattr(self, f"{which}_{side}")
                db = f" ({self.decibels(d):+.3g} dB)" if self.gain else ""
                if exact:
                    out.append(f"  {side}: {what} at {self.parameter} = {e.parameter:.9g}{u} ({e.kind}"
                               f"{': ' + e.cause if e.cause and e.cause != e.kind else ''}): change {d:+.6g}{u}{db}")
                else:
                    out.append(f"  {side}: {what}: no event down to the range's end" if side == "below" else
                               f"  {side}: {what}: no event up to the range's end")
                    out[-1] += f" ({self.nominal + d:.6g}{u}): margin beyond {d:+.6g}{u}{db}"
        return out

    def __repr__(self) -> str:
        return "\n".join(self.lines())


def _end_word(end: str, default: str) -> str:
    if end.startswith("enters"):
        return "entry"
    if end.startswith("leaves"):
        return "exit"
    if end.startswith("lost"):
        return "lost"
    if end.startswith("born"):
        return "birth"
    if end.startswith("dies"):
        return "death"
    return end if end in ("fold", "stability change", "sweep start", "sweep end") else default


# -------------------------------------------------------------------------------- the family of loops


def _build_loop(loop_at: Callable, value: float):
    try:
        loop = loop_at(value)
    except ValueError as exc:
        raise ValueError(f"loop_at({value!r}) failed: {exc}") from exc
    if not (isinstance(loop, (tuple, list)) and len(loop) == 2):
        raise ValueError(f"loop_at({value!r}) must return a pair (G, N); got {type(loop).__name__}")
    G, N = loop
    try:
        return as_plant(G), as_element(N)
    except ValueError as exc:
        raise ValueError(f"loop_at({value!r}): {exc}") from exc


@dataclass
class _Point:
    """A solution X = (ln A, ln w, q) with the Jacobian J (2 x 3) of (Re R, Im R) there."""

    X: np.ndarray
    J: np.ndarray
    iterations: int = 0

    @property
    def det(self) -> float:
        """Loeb determinant in log coordinates (> 0: stable)."""
        J = self.J
        return float(J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0])

    @property
    def tangent(self) -> np.ndarray:
        c = np.cross(self.J[0], self.J[1])
        n = np.linalg.norm(c)
        return c / n if n > 0 else c


class _Family:
    """The loops along the sweep, as functions of q in [0, 1] (p = p0 + q (p1 - p0)), and the corrector."""

    def __init__(self, loop_at: Callable, values: np.ndarray, qs: np.ndarray, log_window: tuple):
        self.loop_at, self.p0, self.span = loop_at, float(values[0]), float(values[-1] - values[0])
        self.values, self.qs = values, qs
        self.log_window = log_window  # (a_lo, a_hi, v_lo, v_hi)
        self._cache: dict = {}
        self._edges: dict = {}
        self._edges_of: dict = {}
        self.last_failure = ""

    def value(self, q: float) -> float:
        """The parameter at q (exactly the given value on a given value's q)."""
        hit = np.flatnonzero(np.abs(self.qs - q) <= _SAME_Q)
        return float(self.values[hit[0]]) if hit.size else self.p0 + q * self.span

    def loop(self, q: float):
        q = float(q)
        hit = self._cache.get(q)
        if hit is None:
            if len(self._cache) >= _CACHE:
                self._cache.clear()
            hit = self._cache[q] = _build_loop(self.loop_at, self.value(q))
        return hit

    def residual(self, q: float, a, v) -> np.ndarray:
        plant, N = self.loop(q)
        A, w = np.exp(np.asarray(a, float)), np.exp(np.asarray(v, float))
        n = N(A, w) if N.frequency_dependent else N(A)
        return 1.0 + plant(w) * n

    # -- the element's edges: where a branch can begin or end inside the window -------------------------
    def edges(self, q: float) -> list:
        """The element's amplitude edges at q: ``(kind, side, level)`` with ``level(w) -> A`` (N's input unit)
        and ``side`` +1 when branches live above the level, -1 below, 0 on both sides (a jump of N).

        kinds: ``"linear range"`` (N constant on the other side: the linear loop, a continuum when marginal),
        ``"amplitude domain"`` (N's domain ends; N -> 0 there for most elements, so no branch reaches it),
        ``"jump"`` (N jumps at a breakpoint). Read from the element's ``amplitude_domain`` and, for static
        elements, its ``breakpoints``; the flatness and jump tests are numerical (exact equality of N on
        either side), so they hold for any element exposing breakpoints.
        """
        q = float(q)
        hit = self._edges.get(q)
        if hit is not None:
            return hit
        if len(self._edges) >= _CACHE:
            self._edges.clear()
        N = self.loop(q)[1]
        hit = self._edges_of.get(id(N))  # one element object serves many q (a gain sweep): its edges once
        if hit is None or hit[0] is not N:
            if len(self._edges_of) >= _CACHE:
                self._edges_of.clear()
            hit = self._edges_of[id(N)] = (N, element_edges(N, math.exp(self.log_window[1] + 1)))
        self._edges[q] = hit[1]
        return hit[1]

    def edge_value(self, edge: tuple, X: np.ndarray) -> float:
        """a - ln(level) at X (signed distance in ln A from the edge; > 0 above it)."""
        level = edge[2](math.exp(X[1]))
        if not 0 < level < math.inf:
            return math.inf if edge[1] >= 0 else -math.inf
        return float(X[0] - math.log(level))

    def edge_crossed(self, P: np.ndarray, X: np.ndarray):
        """The first element edge crossed by the segment P -> X: (fraction, edge) or None."""
        best = None
        for edge in self.edges(min(max(P[2], 0.0), 1.0)):
            gp = self.edge_value(edge, P)
            gx = self.edge_value(edge, X)
            if not (math.isfinite(gp) and math.isfinite(gx)):
                continue
            side = edge[1] if edge[1] != 0 else (1 if gp > 0 else -1)
            if side * gp > 0 and side * gx <= 0:
                frac = gp / (gp - gx)
                if best is None or frac < best[0]:
                    best = (frac, edge, side)
        return best

    def admissible(self, X: np.ndarray, edge_side: int = 0) -> bool:
        """Inside [0, 1] in q, within one unit (ln) of the window, in N's amplitude domain and G's range
        (``edge_side``: the point lies on an element edge, on that side of it: the domain test is waived)."""
        a, v, q = X
        a_lo, a_hi, v_lo, v_hi = self.log_window
        if not (-1e-12 <= q <= 1 + 1e-12 and a_lo - 1 < a < a_hi + 1 and v_lo - 1 < v < v_hi + 1):
            self.last_failure = "left the parameter range or the window"
            return False
        plant, N = self.loop(min(max(q, 0.0), 1.0))
        w = math.exp(v)
        if not (plant.domain[0] < w * (1 - 2 * _FD) and w * (1 + 2 * _FD) < plant.domain[1]):
            self.last_failure = "left the plant's frequency range"
            return False
        lo, hi = N.amplitude_domain(w) if N.frequency_dependent else N.amplitude_domain()
        A = math.exp(a)
        if edge_side == 0 and not (float(lo) < A * (1 - 2 * _FD) and A * (1 + 2 * _FD) < float(hi)):
            self.last_failure = "reached the edge of N's amplitude domain"
            return False
        return True

    def jacobian(self, X: np.ndarray, side_a: int = 0) -> tuple[complex, np.ndarray]:
        """R at X and the real 2 x 3 Jacobian of (Re R, Im R) in (ln A, ln w, q): central differences in
        ln A, ln w; a one-sided difference in q (towards the inside of the range, so no loop outside it is
        built). The q column only steers Newton and the predictor: the roots, the Loeb determinant and so
        the folds do not depend on its accuracy. ``side_a`` = +1 / -1: a one-sided difference in ln A
        towards that side (on an element edge, where N is not differentiable)."""
        a, v, q = X
        q = min(max(q, 0.0), 1.0)
        h = _FD
        da = np.array([0, h, -h, 0, 0]) if side_a == 0 else np.array([0, side_a * h, 0, 0, 0])
        r = self.residual(q, a + da, v + np.array([0, 0, 0, h, -h]))
        hq = h if q + h <= 1 else -h  # one-sided: one more loop per Jacobian (see the docstring)
        rq = (self.residual(q + hq, a, v)[()] - r[0]) / hq
        ra = (r[1] - r[2]) / (2 * h) if side_a == 0 else (r[1] - r[0]) / (side_a * h)
        rv = (r[3] - r[4]) / (2 * h)
        J = np.array([[ra.real, rv.real, rq.real], [ra.imag, rv.imag, rq.imag]])
        return complex(r[0]), J

    def slopes_at(self, q: float) -> Callable:
        """``slopes(a, v) -> (P, dP/da, dP/dv)`` of the loop at q (central differences), for the shared
        marginal test :func:`dfloop.solve.stability.label_roots`."""
        def slopes(a, v):
            a, v = np.asarray(a, float), np.asarray(v, float)
            h, k = _FD, a.size
            r = self.residual(q, np.concatenate([a, a + h, a - h, a, a]), np.concatenate([v, v, v, v + h, v - h]))
            r0, rap, ram, rvp, rvm = (r[i * k:(i + 1) * k] for i in range(5))
            return r0 - 1.0, (rap - ram) / (2 * h), (rvp - rvm) / (2 * h)
        return slopes

    def correct(self, X0: np.ndarray, n: np.ndarray, g: float, edge: tuple | None = None) -> _Point | None:
        """Newton on R(X) = 0, n . X = g from X0; None unless it converges, contracting, inside the domain.

        With ``edge = (element edge, side)`` the third equation is instead ln A = ln level(w; q) (approached by
        ``_EDGE_IN`` on ``side``): the point where a branch meets the edge."""
        X = np.array(X0, float)
        prev = np.inf
        side = 0 if edge is None else edge[1]
        for it in range(_MAX_NEWTON):
            if edge is not None:  # the edge's level at the current (w, q), and its slopes in ln w and q
                level = self._edge_level(edge[0], X)
                if level is None:
                    return None
                X[0] = _inside(level, side)
            if not self.admissible(X, side):
                return None
            R, J = self.jacobian(X, side)
            if edge is None:
                row, f3 = n, n @ X - g
            else:
                row, f3 = self._edge_row(edge[0], X), 0.0
                if row is None:
                    return None
            F = np.array([R.real, R.imag, f3])
            try:
                dx = np.linalg.solve(np.vstack([J, row]), -F)
            except np.linalg.LinAlgError:
                self.last_failure = "singular corrector"
                return None
            step = float(np.max(np.abs(dx)))
            if not math.isfinite(step) or (it > 0 and step > 0.5 * prev and step > 1e3 * _XTOL):
                self.last_failure = "corrector did not contract"
                return None
            X, prev = X + dx, step
            if step <= _XTOL:
                if edge is not None:
                    level = self._edge_level(edge[0], X)
                    if level is None:
                        return None
                    X[0] = _inside(level, side)
                if not self.admissible(X, side):
                    return None
                return _Point(X, self.jacobian(X, side)[1] if edge is not None else J, it + 1)
        self.last_failure = "corrector did not converge"
        return None

    def land(self, X0: np.ndarray, q: float, ref: np.ndarray) -> _Point | None:
        """The curve point at parameter q next to X0, by a Newton in (ln A, ln w) that stays on ``ref``'s side
        of every element edge; None if it does not converge.

        The fallback of :meth:`correct` where a branch runs close to an element edge: next to a square-root edge
        (a quantizer's threshold, a dead-zone relay's: dN/dA -> inf there) a full Newton step from the far side
        lands across the edge, where N is another function, and the plain corrector fails. Here a step that
        would cross an edge goes 0.9 of the way to it (so the iterates approach a square-root edge from the
        branch's side, where Newton converges monotonically); one-sided differences in ln A within 4 difference
        steps of an edge, towards the branch's side."""
        X = np.array([X0[0], X0[1], q], float)
        sides = []
        for edge in self.edges(q):
            g = self.edge_value(edge, ref)
            if math.isfinite(g) and g != 0:
                sides.append((edge, 1 if g > 0 else -1))
        for edge, s in sides:  # start on ref's side of every edge
            g = self.edge_value(edge, X)
            if math.isfinite(g) and s * g <= 0:
                X[0] = ref[0]
        for _ in range(_LAND_NEWTON):
            if not self.admissible(X, 1 if sides else 0):
                return None
            near = [s for e, s in sides if abs(self.edge_value(e, X)) < 4 * _FD]
            side_a = near[0] if near else 0
            R, J = self.jacobian(X, side_a)
            try:
                d = np.linalg.solve(J[:, :2], -np.array([R.real, R.imag]))
            except np.linalg.LinAlgError:
                self.last_failure = "singular corrector"
                return None
            dx = np.array([d[0], d[1], 0.0])
            for edge, s in sides:  # fraction to the boundary
                g0, g1 = self.edge_value(edge, X), self.edge_value(edge, X + dx)
                if math.isfinite(g0) and math.isfinite(g1) and s * g1 <= 0 < s * g0:
                    dx *= 0.9 * g0 / (g0 - g1)
            if not np.all(np.isfinite(dx)):
                self.last_failure = "corrector did not converge"
                return None
            X = X + dx
            if float(np.max(np.abs(dx))) <= _XTOL:
                if not self.admissible(X, 1 if sides else 0):
                    return None
                return _Point(X, self.jacobian(X, side_a)[1], _MAX_NEWTON)
        self.last_failure = f"Newton at a given value did not converge in {_LAND_NEWTON} iterations"
        return None

    def _edge_level(self, edge: tuple, X: np.ndarray) -> float | None:
        """ln of the edge's level at X's (w, q) (the edge of the loop at X's q), or None (with the reason in
        ``last_failure``) where the loop at X's q has no such edge (it disappeared: a threshold or hysteresis
        swept to zero, an edge reached tangentially at the end of its existence) or its level is not a
        positive finite amplitude there: the corrector then fails and the caller halves its step or ends the
        branch as ``lost``, instead of stopping the sweep."""
        q = min(max(float(X[2]), 0.0), 1.0)
        kind, side, ref = edge[0], edge[1], edge[2](1.0)
        same = [e for e in self.edges(q) if e[0] == kind and e[1] == side]
        if not same and kind == "jump":  # a jump found by probing N (not a declared breakpoint): fixed level
            same = [edge]
        if not same:
            self.last_failure = f"the element's {kind} edge disappeared at p={self.value(q):.9g}"
            return None
        if 0 < ref < math.inf:  # the same edge, moved
            e = min(same, key=lambda e: abs(math.log(e[2](1.0) / ref)) if 0 < e[2](1.0) < math.inf else math.inf)
        else:
            e = same[0]
        level = e[2](math.exp(X[1]))
        if not 0 < level < math.inf:
            self.last_failure = (f"the element's {kind} edge has no positive finite level at p={self.value(q):.9g}, "
                                 f"omega={math.exp(X[1]):.6g} rad/s (got {level!r})")
            return None
        return math.log(level)

    def _edge_row(self, edge: tuple, X: np.ndarray) -> np.ndarray | None:
        """Gradient of a - ln level(w, q) in (a, v, q) (finite differences; zero for a fixed level); None where
        the level is not defined (see :meth:`_edge_level`)."""
        base = self._edge_level(edge, X)
        h = _FD
        hq = h if X[2] + h <= 1 else -h
        up_v, up_q = self._edge_level(edge, X + [0, h, 0]), self._edge_level(edge, X + [0, 0, hq])
        if base is None or up_v is None or up_q is None:
            return None
        return np.array([1.0, -(up_v - base) / h, -(up_q - base) / hq])

    def jump_near(self, X: np.ndarray, direction: float):
        """A jump of N in amplitude within 1e-5 (in ln A: a few difference steps, across which the corrector
        fails) of X in ``direction`` (sign of d ln A): the amplitudes either side of it, located by bisection to
        rounding, or None. For elements that do not declare their
        breakpoints: a branch that cannot be continued is checked for one before it is called lost."""
        if direction == 0:
            return None
        plant, N = self.loop(min(max(float(X[2]), 0.0), 1.0))
        w = np.array([math.exp(X[1])])

        def n(a):
            A = np.array([math.exp(a)])
            return complex((N(A, w) if N.frequency_dependent else N(A))[0])

        a0, a1 = float(X[0]), float(X[0]) + math.copysign(10 * _FD, direction)
        try:
            n0, n1 = n(a0), n(a1)
        except ValueError:
            return None
        if not abs(n1 - n0) > 1e-3 * max(abs(n0), abs(n1)):  # a smooth N changes by ~1e-5 here
            return None
        for _ in range(_BISECT):  # keep a0 on X's side, a1 across the jump
            mid = 0.5 * (a0 + a1)
            if mid in (a0, a1):
                break
            if abs(n(mid) - n0) <= 1e-3 * max(abs(n0), 1e-300):
                a0 = mid
            else:
                a1 = mid
        return math.exp(a0), math.exp(a1)

    def limit_birth(self, X: np.ndarray, amplitude: float):
        """Where a branch that runs to A -> ``amplitude`` (inf or 0) is born: the parameter at which
        1 + G(jw) N(amplitude, w) = 0 (the loop with N's limit is marginal), by Newton in (ln w, q) from X.

        Returns (q, ln w) or None (no finite non-zero limit of N, or no convergence inside the range)."""
        v, q = float(X[1]), min(max(float(X[2]), 0.0), 1.0)

        def r(v_, q_):
            plant, N = self.loop(q_)
            w = np.array([math.exp(v_)])
            n = N(np.array([amplitude]), w) if N.frequency_dependent else N(np.array([amplitude]))
            return complex((1.0 + plant(w) * n)[0])

        try:
            n0 = r(v, q) - 1.0
        except ValueError:
            return None
        if not (np.isfinite(n0) and n0 != 0):
            return None
        for _ in range(_LIMIT_NEWTON):
            try:
                R = r(v, q)
                hq = _FD if q + _FD <= 1 else -_FD
                rv = (r(v + _FD, q) - r(v - _FD, q)) / (2 * _FD)
                rq = (r(v, q + hq) - R) / hq
                d = np.linalg.solve(np.array([[rv.real, rq.real], [rv.imag, rq.imag]]), -np.array([R.real, R.imag]))
            except (ValueError, np.linalg.LinAlgError):
                return None
            v, q = v + d[0], q + d[1]
            if not (-1e-12 <= q <= 1 + 1e-12 and math.isfinite(v)):
                return None
            q = min(max(q, 0.0), 1.0)
            if max(abs(d[0]), abs(d[1])) <= _XTOL:
                return q, v
        return None


def _inside(a_edge: float, side: int) -> float:
    """ln A just inside an edge at ln A = a_edge, on ``side`` (+1 above): a few ulps, so that N is evaluated on
    the branch's side (N has a square-root edge for a relay with hysteresis: the point is then exact to
    about sqrt(1e-15) ~ 3e-8)."""
    return a_edge + side * max(8 * float(np.spacing(abs(a_edge))), _EDGE_IN)


def element_edges(N, a_max: float) -> list:
    """An element's amplitude edges where a branch of cycles can begin or end: ``(kind, side, level)`` with
    ``level(w) -> A`` (N's input unit), ``side`` +1 when cycles live above the level, -1 below, 0 on both
    sides. Kinds: ``"amplitude domain"`` (the ends of ``N.amplitude_domain``, when finite and non-zero),
    ``"linear range"`` (N is constant on one side of a breakpoint: the linear loop), ``"jump"`` (N jumps at a
    breakpoint). Breakpoints come from ``N.breakpoints(A_max=a_max)`` when the element has them."""
    if N.frequency_dependent:
        return [("amplitude domain", 1, lambda w, N=N: float(N.amplitude_domain(w)[0])),
                ("amplitude domain", -1, lambda w, N=N: float(N.amplitude_domain(w)[1]))]
    lo, hi = (float(x) for x in N.amplitude_domain())
    out = [("amplitude domain", 1, lambda w, x=lo: x), ("amplitude domain", -1, lambda w, x=hi: x)]
    out = [e for e in out if 0 < e[2](1.0) < math.inf]
    return out + _breakpoint_edges(N, lo, hi, a_max)


def _breakpoint_edges(N, lo: float, hi: float, a_max: float) -> list:
    """Edges at a static element's breakpoints: where N is constant on one side ("linear range") or jumps."""
    bp = getattr(N, "breakpoints", None)
    if bp is None:
        return []
    try:
        pts = np.asarray(bp(A_max=a_max), float).ravel()[:_MAX_BREAKPOINTS]
    except ValueError:
        return []
    out = []
    for b in pts:
        if not lo < b < hi:
            continue
        probe = N(np.array([b * (1 - 1e-3), b * (1 - 1e-9), b, b * (1 + 1e-9), b * (1 + 1e-3), b * 0.5, b * 2.0]))
        below = probe[[0, 1, 5]]
        above = probe[[3, 4, 6]]
        if np.all(below == probe[2]) and probe[2] != 0:
            out.append(("linear range", 1, lambda w, x=float(b): x))
        elif np.all(above == probe[2]) and probe[2] != 0:
            out.append(("linear range", -1, lambda w, x=float(b): x))
        elif abs(probe[3] - probe[1]) > 1e-6 * max(abs(probe[3]), abs(probe[1])):
            out.append(("jump", 0, lambda w, x=float(b): x))
    return out


# ------------------------------------------------------------------------------------------- the tracer


_EQ = np.array([0.0, 0.0, 1.0])


@dataclass
class _Node:
    """A point of a traced curve: what it is (``tag``) and the given value it lies on (``k``, or -1)."""

    point: _Point
    tag: str  # "seed", "step", "value", "fold", "stability change", "range", "exit", "lost", "closed"
    k: int = -1
    detail: str = ""


class _Unlanded(Exception):
    """A traced branch cannot reach a point it must have (a given value, a window edge): it ends at ``point``
    as ``lost``, with the reason, instead of stopping the sweep."""

    def __init__(self, point: _Point, why: str):
        super().__init__(why)
        self.point, self.why = point, why


class _Tracer:
    def __init__(self, family: _Family, qs: np.ndarray, max_steps: int):
        self.f, self.qs, self.max_steps = family, qs, max_steps

    # -- helpers ---------------------------------------------------------------------------------------
    def _at_q(self, P: _Point, Q: _Point, q: float) -> _Point | None:
        """The curve point at parameter q between P and Q (q strictly between theirs or equal to Q's): the
        corrector from the interpolated point, else the edge-aware Newton (:meth:`_Family.land`) from it and
        from the nearer end (a branch running into an element edge approaches it tangentially: the
        interpolation is then off the curve by more than the plain corrector's reach)."""
        dq = Q.X[2] - P.X[2]
        s = (q - P.X[2]) / dq if dq != 0 else 0.5
        X0 = P.X + s * (Q.X - P.X)
        V = self.f.correct(X0, _EQ, q)
        if V is not None:
            return V
        near, far = (P, Q) if s <= 0.5 else (Q, P)
        for start in (X0, near.X, far.X):
            V = self.f.land(start, q, P.X)
            if V is not None and self._on_piece(V, P, Q):
                return V
        return None

    @staticmethod
    def _on_piece(V: _Point, P: _Point, Q: _Point) -> bool:
        """V lies on the curve piece between P and Q, not on another curve at the same q: within the box of
        P and Q in (ln A, ln w), widened by the piece's size (the piece is monotone in q and short)."""
        lo, hi = np.minimum(P.X[:2], Q.X[:2]), np.maximum(P.X[:2], Q.X[:2])
        pad = float(np.max(hi - lo)) + 1e-9
        return bool(np.all(V.X[:2] >= lo - pad) and np.all(V.X[:2] <= hi + pad))

    def _locate(self, P: _Point, t: np.ndarray, Q: _Point, g: Callable[[_Point], float]) -> tuple:
        """Bracket the sign change of ``g`` between P and Q along t (Illinois regula falsi, bisection when a
        probe fails); returns the points just before and just after it. Stops at a bracket of 1e-12 (in
        arclength) or when the corrector fails or lands on a crossing curve (next to a branch point)."""
        lo, hi, Xlo, Xhi = 0.0, float(t @ (Q.X - P.X)), P, Q
        sgn = np.sign(g(Q))
        glo, ghi = g(P) * sgn, g(Q) * sgn  # glo < 0 < ghi
        side = 0
        for _ in range(_BISECT):
            if hi - lo <= 1e-12 * max(1.0, hi):
                break
            mid = (lo * ghi - hi * glo) / (ghi - glo) if ghi > glo else 0.5 * (lo + hi)
            if not lo < mid < hi:
                mid = 0.5 * (lo + hi)
            M = self.f.correct(P.X + mid * t, t, float(t @ P.X) + mid)
            if M is None or abs(M.tangent @ t) < _COS_TURN:  # no solution, or one on a crossing curve
                mid = 0.5 * (lo + hi)
                M = self.f.correct(P.X + mid * t, t, float(t @ P.X) + mid)
                if M is None or abs(M.tangent @ t) < _COS_TURN:
                    break
            gm = g(M) * sgn
            if gm > 0:
                hi, ghi, Xhi = mid, gm, M
                glo, side = (glo / 2 if side == 1 else glo), 1
            elif gm < 0:
                lo, glo, Xlo = mid, gm, M
                ghi, side = (ghi / 2 if side == -1 else ghi), -1
            else:
                return M, M
        return Xlo, Xhi

    def _fold(self, P: _Point, t: np.ndarray, Q: _Point) -> _Point:
        """The turning point in p between P and Q: where the oriented dp/ds changes sign."""
        lo, hi = self._locate(P, t, Q, lambda M: float(M.tangent @ t) * M.tangent[2])
        return lo if abs(lo.det) < abs(hi.det) else hi

    def _branch_point(self, P: _Point, t: np.ndarray, Q: _Point) -> _Point:
        """Where the Loeb determinant changes sign without a fold: the corrector degenerates at the crossing of
        two curves, so the bracket is closed by linear interpolation of the determinant."""
        lo, hi = self._locate(P, t, Q, lambda M: M.det)
        w = lo.det / (lo.det - hi.det)
        X = lo.X + w * (hi.X - lo.X)
        return _Point(X, self.f.jacobian(X)[1])

    def _jump_end(self, P: _Point, t: np.ndarray) -> _Point | None:
        """Where a branch that cannot be continued meets a jump of N next to P (None if there is none)."""
        hit = self.f.jump_near(P.X, t[0])
        if hit is None:
            return None
        edge = ("jump", 0, lambda w, x=hit[0]: x)  # hit[0]: the last amplitude on P's side, to rounding
        side = 1 if P.X[0] > math.log(hit[0]) else -1  # one-sided differences on P's side
        return self.f.correct(P.X, t, 0.0, edge=(edge, side))

    def _edge_crossing(self, P: _Point, Q: _Point):
        """(edge name, point) where the segment P -> Q first leaves the (ln A, ln w) window, or None."""
        a_lo, a_hi, v_lo, v_hi = self.f.log_window
        best = None
        for i, bound, lower, name in ((0, a_lo, True, "the amplitude window's lower edge"),
                                      (0, a_hi, False, "the amplitude window's upper edge"),
                                      (1, v_lo, True, "the frequency window's lower edge"),
                                      (1, v_hi, False, "the frequency window's upper edge")):
            out = Q.X[i] < bound if lower else Q.X[i] > bound
            if out and Q.X[i] != P.X[i]:
                frac = (bound - P.X[i]) / (Q.X[i] - P.X[i])
                if best is None or frac < best[0]:
                    best = (frac, i, bound, name)
        if best is None:
            return None
        frac, i, bound, name = best
        e = np.zeros(3)
        e[i] = 1.0
        E = self.f.correct(P.X + frac * (Q.X - P.X), e, bound)
        if E is None:
            raise _Unlanded(P, f"could not locate where the branch crosses {name} ({self.f.last_failure})")
        return name, E

    def _values_between(self, P: _Point, Q: _Point, out: list) -> None:
        """Append the curve's points at given values in (q_P, q_Q] (a monotone piece of the curve)."""
        q0, q1 = P.X[2], Q.X[2]
        lo, hi = min(q0, q1), max(q0, q1)
        ks = [k for k, q in enumerate(self.qs) if lo < q <= hi] if q1 > q0 else \
            [k for k, q in enumerate(self.qs) if lo <= q < hi][::-1]
        for k in ks:
            q = self.qs[k]
            if abs(q - q1) <= _SAME_Q or abs(q - q0) <= _SAME_Q:
                continue  # an end point lies on the value (it gets the value index)
            V = self._at_q(P, Q, q)
            if V is None:
                raise _Unlanded(P, f"could not land on the given value p={self.f.value(q):.9g} "
                                   f"({self.f.last_failure})")
            out.append(_Node(V, "value", k))
            P = V

    def _value_index(self, q: float) -> int:
        hit = np.flatnonzero(np.abs(self.qs - q) <= _SAME_Q)
        return int(hit[0]) if hit.size else -1

    # -- one direction ---------------------------------------------------------------------------------
    def trace(self, seed: _Point, t0: np.ndarray) -> list[_Node]:
        """Follow the curve from ``seed`` along ``t0`` until it leaves the range or window, closes, or is lost
        (then the last node is ``lost``, with the reason: a sweep never stops on one branch's failure)."""
        out: list[_Node] = []
        try:
            return self._trace(seed, t0, out)
        except _Unlanded as exc:
            out.append(_Node(exc.point, "lost", -1, exc.why))
            return out

    def _trace(self, seed: _Point, t0: np.ndarray, out: list) -> list[_Node]:
        P, t, h = seed, t0, _H0
        for _ in range(self.max_steps):
            Xp = P.X + h * t
            qp = Xp[2]
            at_end = qp > 1 or qp < 0
            if at_end:
                bound = 1.0 if qp > 1 else 0.0
                s = (bound - P.X[2]) / t[2]
                Q = self.f.correct(P.X + s * t, _EQ, bound)
            else:
                Q = self.f.correct(Xp, t, float(t @ Xp))
            # an element edge (linear range, domain, jump) crossed by the step: the branch ends on it
            cross = self.f.edge_crossed(P.X, Q.X if Q is not None else Xp)
            if cross is not None:
                frac, el, side = cross
                target = Q.X if Q is not None else Xp
                E = self.f.correct(P.X + frac * (target - P.X), t, 0.0, edge=(el, side))
                if E is None or float(t @ (E.X - P.X)) <= 0:
                    h *= 0.5
                    if h < _HMIN:
                        out.append(_Node(P, "lost", -1, self.f.last_failure or "the step size underflowed"))
                        return out
                    continue
                start = P
                if (E.X[2] - P.X[2]) * t[2] < 0 and t[2] != 0:  # the branch turned back in p before the edge
                    F = self._fold(P, t, E)
                    self._values_between(P, F, out)
                    out.append(_Node(F, "fold", self._value_index(F.X[2])))
                    start = F
                self._values_between(start, E, out)
                out.append(_Node(E, "edge", self._value_index(E.X[2]), el[0]))
                return out
            if Q is not None:
                tq = Q.tangent * (1.0 if Q.tangent @ t >= 0 else -1.0)
                ok = (tq @ t >= _COS_TURN) and (np.max(np.abs(Q.X - (P.X + h * t))) <= 0.5 * h or at_end)
            if Q is None or not ok:
                h *= 0.5
                if h < _HMIN:
                    E = self._jump_end(P, t)
                    if E is not None:
                        self._values_between(P, E, out)
                        out.append(_Node(E, "edge", self._value_index(E.X[2]), "jump"))
                        return out
                    out.append(_Node(P, "lost", -1, self.f.last_failure or "the step size underflowed"))
                    return out
                continue
            # events inside the step P -> Q, in the order met
            edge = self._edge_crossing(P, Q)
            end_node = None
            if edge is not None:
                name, Q = edge
                tq = Q.tangent * (1.0 if Q.tangent @ t >= 0 else -1.0)
                end_node = _Node(Q, "exit", self._value_index(Q.X[2]), name)
            elif at_end:
                end_node = _Node(Q, "range", self._value_index(Q.X[2]))
            start = P
            if np.sign(tq[2]) != np.sign(t[2]) and tq[2] != 0 and t[2] != 0:  # dp/ds changes sign: a fold
                F = self._fold(P, t, Q)
                self._values_between(start, F, out)
                out.append(_Node(F, "fold", self._value_index(F.X[2])))
                start = F
            elif np.sign(Q.det) != np.sign(P.det) and Q.det != 0 and P.det != 0:  # branch point
                S = self._branch_point(P, t, Q)
                self._values_between(start, S, out)
                out.append(_Node(S, "stability change", self._value_index(S.X[2])))
                start = S
            self._values_between(start, Q, out)
            if end_node is not None:
                out.append(end_node)
                return out
            k = self._value_index(Q.X[2])
            out.append(_Node(Q, "value" if k >= 0 else "step", k))
            if self._closes(seed, P, t, Q):
                out.append(_Node(seed, "closed", -1))
                return out
            if Q.iterations <= 3:
                h = min(1.5 * h, _HMAX)
            P, t = Q, tq
        raise RuntimeError(f"continuation exceeded max_steps={self.max_steps} steps on one branch (at "
                           f"p={self.f.value(P.X[2]):.6g}, A={math.exp(P.X[0]):.6g}, omega={math.exp(P.X[1]):.6g} "
                           "rad/s); pass a larger max_steps to sweep()")

    def _closes(self, seed: _Point, P: _Point, t: np.ndarray, Q: _Point) -> bool:
        """True when the step P -> Q passes through the seed (a closed curve, an isola)."""
        if P is seed:
            return False
        d = seed.X - P.X
        s, length = float(t @ d), float(t @ (Q.X - P.X))
        if not (0 < s <= length) or np.linalg.norm(d - s * t) > length:
            return False
        M = self.f.correct(P.X + s * t, t, float(t @ seed.X))
        return M is not None and np.max(np.abs(M.X - seed.X)) < 1e-7

    def curve(self, seed: _Point, k: int) -> list[_Node]:
        """The whole curve through ``seed`` (both directions), ordered along the curve."""
        t0 = seed.tangent
        if t0[2] < 0:
            t0 = -t0
        fwd = self.trace(seed, t0)
        head = _Node(seed, "seed", k)
        if fwd[-1].tag == "closed":
            return [head] + fwd
        back = self.trace(seed, -t0)
        b, f = back[0].point, fwd[0].point
        plain = back[0].tag in ("step", "value", "range") and fwd[0].tag in ("step", "value", "range")
        if plain and (b.X[2] - seed.X[2]) * (f.X[2] - seed.X[2]) > 0:  # the seed is (next to) a fold: locate it
            tb = seed.X - b.X
            tb /= np.linalg.norm(tb)
            Fd = self._fold(b, tb, f)
            head = _Node(Fd, "fold", self._value_index(Fd.X[2]))
        # a trace that ended at once (the seed on the range's end) repeats the seed: keep the end's node
        same = any(np.max(np.abs(n.point.X - head.point.X)) <= 1e-12 for n in (back[0], fwd[0]))
        return back[::-1] + ([] if same and head.tag == "seed" else [head]) + fwd


# --------------------------------------------------------------------------------- curves -> branches


def _label(node: _Node, family: _Family, marginal_tol: float) -> str:
    """The shared marginal test (:func:`dfloop.solve.stability.label_roots`, as in predict_limit_cycles) at a
    curve point; on an element edge, where N is not differentiable, the crossing angle of the one-sided
    Jacobian decides."""
    P = node.point
    if node.tag == "edge":
        ra, rv = complex(*P.J[:, 0]), complex(*P.J[:, 1])
        scale = abs(ra) * abs(rv)
        if scale == 0 or abs(P.det) / scale < marginal_tol:
            return "marginal"
        return "stable" if P.det > 0 else "unstable"
    q = min(max(float(P.X[2]), 0.0), 1.0)
    return str(label_roots(family.slopes_at(q), P.X[:1], P.X[1:2], marginal_tol)[2][0])


_EDGE_TEXT = {"linear range": ("born from the linear loop at the edge of the element's linear range",
                               "dies into the linear loop at the edge of the element's linear range"),
              "amplitude domain": ("born at the edge of N's amplitude domain", "dies at the edge of N's amplitude domain"),
              "jump": ("born where N jumps", "dies where N jumps")}


def _pieces(nodes: list[_Node]) -> tuple[list[list[_Node]], bool]:
    """Split a curve at folds and stability changes; a closed curve is rotated to start at a split point."""
    closed = nodes[-1].tag == "closed"
    if closed:
        nodes = nodes[:-1]
        cuts = [i for i, n in enumerate(nodes) if n.tag in ("fold", "stability change")]
        if cuts:
            nodes = nodes[cuts[0]:] + nodes[:cuts[0] + 1]
        else:
            nodes = nodes + [nodes[0]]
    pieces, cur = [], [nodes[0]]
    for n in nodes[1:]:
        cur.append(n)
        if n.tag in ("fold", "stability change"):
            pieces.append(cur)
            cur = [n]
    if len(cur) > 1:
        pieces.append(cur)
    return pieces, closed


def _end_text(node: _Node, low_end: bool) -> str:
    if node.tag == "range":
        return "sweep start" if low_end else "sweep end"
    if node.tag == "exit":
        return ("enters " if low_end else "leaves ") + node.detail
    if node.tag == "lost":
        return f"lost: {node.detail}"
    if node.tag in ("fold", "stability change"):
        return node.tag
    if node.tag == "edge":
        return _EDGE_TEXT[node.detail][0 if low_end else 1]
    return "closed curve"


def _limit_event(node: _Node, family: _Family, low: bool, idx: int, name: str):
    """A branch leaving the amplitude window towards A -> inf or A -> 0 where N has a finite non-zero limit:
    the birth (or death) of the cycle from the loop with N's limit, when that loop is marginal in the range."""
    if node.tag != "exit" or "amplitude" not in node.detail:
        return None
    upper = "upper" in node.detail
    hit = family.limit_birth(node.point.X, math.inf if upper else 0.0)
    if hit is None:
        return None
    q, v = hit
    p = family.value(q)
    # the limit lies beyond the exit, on the side the branch leaves to: before its start, after its end
    before = low
    if (q < node.point.X[2]) != low and q != node.point.X[2]:
        return None
    kind = "birth" if before else "death"
    where = "infinity" if upper else "zero amplitude"
    return SweepEvent(kind, parameter=p, amplitude=math.inf if upper else 0.0, frequency=math.exp(v),
                      branches=(idx,), cause=where, name=name,
                      detail=f"{'born from' if before else 'dies at'} {where}: the loop with N's limit "
                             f"(A -> {'inf' if upper else '0'}) is marginal at {name} = {p:.9g}")


def _assemble(curves, family: _Family, marginal_tol: float, name: str, scanned=frozenset()):
    """Branches and events from the traced curves (``scanned``: indices of the curves the valley scan found
    between the given values; their events say so)."""
    branches, events = [], []
    for c, nodes in enumerate(curves):
        first_event = len(events)
        pieces, _ = _pieces(nodes)
        ids = []
        for piece in pieces:
            q = np.array([n.point.X[2] for n in piece])
            order = np.argsort(q, kind="stable") if q[-1] >= q[0] else np.arange(q.size)[::-1]
            first, last = piece[order[0]], piece[order[-1]]
            lab = np.array([_label(piece[i], family, marginal_tol) for i in order])
            for j, i in enumerate(order):  # interior points take the branch's label when marginal by rounding
                if piece[i].tag in ("fold", "stability change"):
                    lab[j] = "marginal"
            idx = len(branches)
            branches.append(Branch(
                index=idx, parameter=np.array([family.value(piece[i].point.X[2]) for i in order]),
                amplitude=np.exp([piece[i].point.X[0] for i in order]),
                frequency=np.exp([piece[i].point.X[1] for i in order]), stability=lab,
                value_index=np.array([piece[i].k for i in order], int),
                start=_end_text(first, True), end=_end_text(last, False)))
            ids.append(idx)
            for node, low in ((first, True), (last, False)):
                X = node.point.X
                where = dict(parameter=family.value(X[2]), amplitude=math.exp(X[0]), frequency=math.exp(X[1]))
                if node.tag == "exit":
                    events.append(SweepEvent("entry" if low else "exit", branches=(idx,), name=name,
                                             cause="window edge",
                                             detail=("enters " if low else "leaves ") + node.detail, **where))
                    limit = _limit_event(node, family, low, idx, name)
                    if limit is not None:
                        events.append(limit)
                elif node.tag == "edge":
                    events.append(SweepEvent("birth" if low else "death", branches=(idx,), name=name,
                                             cause=node.detail, detail=_EDGE_TEXT[node.detail][0 if low else 1],
                                             **where))
                elif node.tag == "lost":
                    events.append(SweepEvent("lost", branches=(idx,), detail=node.detail, name=name, **where))
        # events shared by consecutive pieces of the curve
        for j in range(len(pieces) - 1 + (nodes[-1].tag == "closed" and len(pieces) > 1)):
            node = pieces[j][-1]
            a, b = ids[j], ids[(j + 1) % len(ids)]
            X = node.point.X
            p = family.value(X[2])
            where = dict(parameter=p, amplitude=math.exp(X[0]), frequency=math.exp(X[1]))
            if node.tag == "fold":
                ba, bb = branches[a], branches[b]
                side = ">" if min(ba.parameter.min(), bb.parameter.min()) >= p - 1e-12 * max(1.0, abs(p)) else "<"
                events.append(SweepEvent("fold", branches=(a, b), detail=_fold_text(ba, bb, side, p, name, family),
                                         name=name, cause="fold", **where))
            else:
                events.append(SweepEvent("stability change", branches=(a, b), name=name, cause="branch point",
                                         detail=f"{branches[a].kind} -> {branches[b].kind} (branch point)", **where))
        if c in scanned:  # say where the curve came from
            for i in range(first_event, len(events)):
                events[i] = dataclasses.replace(
                    events[i], detail=events[i].detail + _SCANNED)
    branches, events = _edge_folds(branches, events, family, name)
    events.sort(key=lambda e: (e.parameter - family.p0) / family.span)  # in the order of the sweep
    return branches, events


def _fold_text(ba: Branch, bb: Branch, side: str, p: float, name: str, family: _Family, where: str = "") -> str:
    """The fold's sentence: which cycles meet, and whether the pair is born or dies in the order of the sweep."""
    if {ba.kind, bb.kind} != {"stable", "unstable"}:
        return f"a {ba.kind} and a {bb.kind} cycle meet{where}"
    born = (side == ">") == (family.span > 0)
    return (f"a stable and an unstable cycle {'are born' if born else 'die'} together{where}; the pair exists for "
            f"{name} {side} {p:.9g}")


def _edge_folds(branches: list, events: list, family: _Family, name: str) -> tuple[list, list]:
    """Two branches that end (or begin) at the same point of an element edge from either side of it are one
    fold: a stable and an unstable cycle meet there (a quantizer's threshold, where N is continuous with a
    square-root edge). The two deaths (births) become one ``fold`` event, located where the loop with N at the
    edge's level is marginal (Newton in (ln w, q), :meth:`_Family.limit_birth`), else midway between the two
    ends (they lie 1e-15 in ln A on either side of the edge: ~1e-8 apart)."""
    ends = [i for i, e in enumerate(events) if e.kind in ("birth", "death") and e.cause in _EDGE_TEXT
            and len(e.branches) == 1]
    merged, drop = [], set()
    for x, i in enumerate(ends):
        for j in ends[x + 1:]:
            e, f = events[i], events[j]
            if i in drop or j in drop or e.kind != f.kind or e.cause != f.cause:
                continue
            A = e.amplitude
            if not (abs(f.amplitude - A) <= 1e-9 * A and abs(f.frequency - e.frequency) <= 1e-6 * e.frequency
                    and abs(f.parameter - e.parameter) <= 1e-6 * abs(family.span)):
                continue
            ba, bb = branches[e.branches[0]], branches[f.branches[0]]
            if np.median(ba.amplitude - A) * np.median(bb.amplitude - A) >= 0:
                continue  # both on one side of the edge: two branches, not a fold
            lo, hi = sorted((e.parameter, f.parameter))
            p, w = 0.5 * (lo + hi), 0.5 * (e.frequency + f.frequency)
            X = np.array([math.log(A), math.log(w), (p - family.p0) / family.span])
            hit = family.limit_birth(X, A)
            if hit is not None:
                ph = family.value(hit[0])
                if lo - 1e-6 * abs(family.span) <= ph <= hi + 1e-6 * abs(family.span):
                    p, w = ph, math.exp(hit[1])
            born = e.kind == "birth"
            side = ">" if born == (family.span > 0) else "<"
            for b in (ba, bb):
                branches[b.index] = dataclasses.replace(b, **({"start": "fold"} if born else {"end": "fold"}))
            detail = _fold_text(ba, bb, side, p, name, family, f" on the element's edge at A = {A:.9g} ({e.cause})")
            merged.append(SweepEvent("fold", parameter=p, amplitude=A, frequency=w, branches=(ba.index, bb.index),
                                     detail=detail + (_SCANNED if _SCANNED in e.detail else ""),
                                     cause="element edge", name=name))
            drop.update((i, j))
    return branches, [e for k, e in enumerate(events) if k not in drop] + merged


# ------------------------------------------------------------------------- pairs born between given values


@dataclass(frozen=True)
class UnresolvedInterval:
    """A parameter interval where a pair of cycles may be born and die unseen: the valley scan's search on
    a valley's depth ran out of its bound before it found a root or excluded one.

    Attributes
    ----------
    low, high : float
        The interval (parameter unit), in increasing order.
    amplitude, frequency : float
        Where the deepest point of the valley lies (N's input unit; rad/s).
    depth : float
        |1 + G N| / (1 + |G N|) there: how close the loop comes to a cycle at the searched points.
    why : str
        The bound that ran out, and how to raise it.
    """

    low: float
    high: float
    amplitude: float
    frequency: float
    depth: float
    why: str

    def __str__(self) -> str:
        return (f"a pair of cycles may exist for p in [{self.low:.9g}, {self.high:.9g}] near A={self.amplitude:.6g}, "
                f"omega={self.frequency:.6g} rad/s (|1 + G N| comes within {self.depth:.2g} of 0): {self.why}")


@dataclass
class _Bottom:
    """The bottom of a valley of |R| over the (ln A, ln w) window at one q: ``X`` = (a, v, q), ``depth`` =
    |R| / (1 + |G N|), ``level`` = |R| and ``slope`` = d|R|/dq along the bottom (= the partial derivative:
    the bottom's motion does not count at a minimum), ``root`` when the bottom is a root (depth <= 1e-10)."""

    X: np.ndarray
    depth: float
    level: float
    slope: float
    root: bool


class _ValleyScan:
    """Finds the curves of cycles that meet no given value: an isola, or a pair born at a fold and ending at a
    fold, an element edge or the window inside one interval between given values.

    Such a pair is born at a double root, where |R| (R = 1 + G N) has a valley over the (A, w) window whose
    bottom touches zero; just outside the pair's interval that valley's bottom is positive and falls
    linearly towards zero. The scan finds every valley (local minimum of |R| / (1 + |G N|) on a grid of the
    window) at the given values and at ``probes - 1`` equally spaced points inside each interval between them,
    settles each bottom by a damped Newton iteration, follows it to the neighbouring probe and reads the bottom's
    depth and its slope in p at both. A bottom that is a root at an interior probe seeds a trace; a depth whose
    slopes point inwards at both ends of a sub-interval is searched (:meth:`_search`): a root, or no root, or
    the interval reported (:class:`UnresolvedInterval`) when the search's bound runs out."""

    def __init__(self, family: _Family, probes: int):
        self.f, self.probes = family, probes
        a_lo, a_hi, v_lo, v_hi = family.log_window
        na = max(_SCAN_A, int(math.ceil(_SCAN_A_DECADE * (a_hi - a_lo) / math.log(10))))
        nv = max(_SCAN_V, int(math.ceil(_SCAN_V_DECADE * (v_hi - v_lo) / math.log(10))))
        self.a = np.linspace(a_lo, a_hi, na)
        self.v = np.linspace(v_lo, v_hi, nv)
        self.unresolved: list[UnresolvedInterval] = []
        self.evaluations = 0
        self.grain = 1.0 / 32  # lattice (in q) of the searches' first probes: set by roots()
        self._minima: list = []  # the grid minima of the last call of valleys()

    def on_branch_side(self, X: np.ndarray) -> bool:
        """X lies where branches live: inside N's amplitude domain and not inside an element's linear range
        (there 1 + G N = 0 is the linear loop's marginal condition, a continuum, not a cycle)."""
        q = min(max(float(X[2]), 0.0), 1.0)
        for edge in self.f.edges(q):
            if edge[1] != 0:
                g = self.f.edge_value(edge, X)
                if math.isfinite(g) and edge[1] * g <= 0:
                    return False
        return self.f.admissible(X)

    # -- valleys at one q ------------------------------------------------------------------------------
    def _grid(self, q: float) -> tuple[np.ndarray, np.ndarray]:
        """The grid nodes at q: the fixed grid plus the element's edges and the plant's poles and zeros."""
        a_lo, a_hi, v_lo, v_hi = self.f.log_window
        plant, N = self.f.loop(q)
        a, v = self.a, self.v
        levels = [e[2](1.0) for e in self.f.edges(q)]
        extra = [math.log(x) + d for x in levels if 0 < x < math.inf for d in (-1e-6, 1e-6)]
        a = np.unique(np.concatenate([a, [x for x in extra if a_lo < x < a_hi]]))
        roots = getattr(plant, "roots", None)
        if roots is not None:
            mags = np.abs(np.concatenate([np.ravel(r) for r in roots]))
            mags = mags[(mags > 0) & np.isfinite(mags)]
            v = np.unique(np.concatenate([v, [x for x in np.log(mags) if v_lo < x < v_hi]]))
        return a, v

    def valleys(self, q: float, known: list = ()) -> list[_Bottom]:
        """The settled bottoms of the valleys of |R| / (1 + |G N|) at q (the ``_MAX_VALLEYS`` deepest), except
        those whose grid minimum lies within two grid steps of a ``known`` bottom or of a grid minimum of the
        previous call (a valley already followed from the previous probe: a long curved valley has several
        grid minima, all settling to one bottom)."""
        plant, N = self.f.loop(q)
        a, v = self._grid(q)
        A, w = np.exp(a), np.exp(v)
        try:
            g = plant(w)
            n = N(A[:, None], w[None, :]) if N.frequency_dependent else N(A)[:, None]
        except ValueError:
            return []
        gn = n * g[None, :]
        self.evaluations += gn.size
        with np.errstate(invalid="ignore", over="ignore"):
            f = np.abs(1.0 + gn) / (1.0 + np.abs(gn))
        f = np.where(np.isfinite(f), f, np.inf)
        pad = np.pad(f, 1, constant_values=np.inf)
        nb = np.stack([pad[1 + di:pad.shape[0] - 1 + di, 1 + dj:pad.shape[1] - 1 + dj]
                       for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj])
        finite_nb = np.where(np.isfinite(nb), nb, -np.inf)
        mask = (f <= nb.min(axis=0)) & (f < finite_nb.max(axis=0)) & (f < _FLAT)
        i, j = np.nonzero(mask)
        order = np.argsort(f[i, j], kind="stable")
        out: list[_Bottom] = []
        da, dv = 2 * (self.a[1] - self.a[0]), 2 * (self.v[1] - self.v[0])
        seen = [K.X[:2] for K in known] + (self._minima if known else [])
        self._minima = [np.array([a[i[k]], v[j[k]]]) for k in order]
        for k in order:
            if len(out) >= _MAX_VALLEYS:
                break
            if any(abs(a[i[k]] - x[0]) <= da and abs(v[j[k]] - x[1]) <= dv for x in seen):
                continue
            B = self.settle(np.array([a[i[k]], v[j[k]], q]))
            if B is not None and not any(np.max(np.abs(B.X[:2] - o.X[:2])) < 1e-6 for o in list(out) + list(known)):
                out.append(B)
        return out

    def _local(self, X: np.ndarray) -> tuple[complex, np.ndarray, np.ndarray, np.ndarray] | None:
        """R at X, the gradient and Hessian of phi = |R|^2 / 2 in (a, v) (central differences of step
        ``_SCAN_FD`` on a 3 x 3 stencil: one evaluation of the loop), and R's derivatives (R_a, R_v)."""
        h = _SCAN_FD
        da = np.array([0, h, -h, 0, 0, h, h, -h, -h])
        dv = np.array([0, 0, 0, h, -h, h, -h, h, -h])
        try:
            r = self.f.residual(X[2], X[0] + da, X[1] + dv)
        except ValueError:
            return None
        self.evaluations += 9
        if not np.all(np.isfinite(r)):
            return None
        ra, rv = (r[1] - r[2]) / (2 * h), (r[3] - r[4]) / (2 * h)
        raa, rvv = (r[1] - 2 * r[0] + r[2]) / h ** 2, (r[3] - 2 * r[0] + r[4]) / h ** 2
        rav = (r[5] - r[6] - r[7] + r[8]) / (4 * h * h)
        R = complex(r[0])

        def dot(x, y):  # Re(conj(x) y)
            return x.real * y.real + x.imag * y.imag
        grad = np.array([dot(R, ra), dot(R, rv)])
        H = np.array([[dot(ra, ra) + dot(R, raa), dot(ra, rv) + dot(R, rav)],
                      [dot(ra, rv) + dot(R, rav), dot(rv, rv) + dot(R, rvv)]])
        return R, grad, H, np.array([ra, rv])

    def settle(self, X0: np.ndarray) -> _Bottom | None:
        """The bottom of the valley of |R| that X0 = (a, v, q) lies in, at X0's q: Newton on R = 0 while it
        halves |R| (towards a root), else damped Newton on
        phi = |R|^2 / 2 in (a, v) (the Hessian shifted to be positive definite, plus a step down a negative
        curvature: a pair's two roots lie either side of a ridge of |R|; a step is taken only when phi
        decreases), kept inside the window; at most ``_LM`` iterations, settled when a step moves less than
        ``_SETTLED`` or the bottom is a root."""
        a_lo, a_hi, v_lo, v_hi = self.f.log_window
        X = np.array(X0, float)
        cur = self._local(X)
        if cur is None:
            return None
        mu = 0.0
        for _ in range(_LM):
            R, grad, H, dR = cur
            if abs(R) <= _ROOT * (1 + abs(R - 1.0)):
                break
            Jr = np.array([[dR[0].real, dR[1].real], [dR[0].imag, dR[1].imag]])
            try:  # Newton on R = 0 first: quadratic towards a root, taken when it halves |R|
                d = np.linalg.solve(Jr, -np.array([R.real, R.imag]))
            except np.linalg.LinAlgError:
                d = np.full(2, np.inf)
            if np.all(np.isfinite(d)) and np.max(np.abs(d)) <= _SCAN_NEWTON:
                Y = X.copy()
                Y[0] = min(max(X[0] + d[0], a_lo), a_hi)
                Y[1] = min(max(X[1] + d[1], v_lo), v_hi)
                nxt = self._local(Y)
                if nxt is not None and abs(nxt[0]) <= 0.5 * abs(R):
                    moved = float(np.max(np.abs(Y[:2] - X[:2])))
                    X, cur = Y, nxt
                    if moved <= _SETTLED:
                        break
                    continue
            # on the window's edge with the descent pointing out: that coordinate stays (projected Newton)
            lows, highs = (a_lo, v_lo), (a_hi, v_hi)
            free = np.array([not ((X[i] <= lows[i] and grad[i] > 0) or (X[i] >= highs[i] and grad[i] < 0))
                             for i in range(2)])
            if not free.any():
                break
            H = np.where(np.outer(free, free), H, np.diag(np.where(free, 0.0, 1.0)))
            grad = np.where(free, grad, 0.0)
            lams, vecs = np.linalg.eigh(H)
            mu = max(mu, -2 * lams[0], 1e-14 * float(np.trace(np.abs(H))) + 1e-300)
            escape = np.zeros(2)
            if lams[0] < 0:  # a saddle or a ridge (between the two roots of a pair): go down its negative curvature
                e = vecs[:, 0] * (-1.0 if vecs[:, 0] @ grad > 0 else 1.0)
                escape = _SCAN_ESCAPE * e * free
            moved = 0.0
            while mu < 1e30:
                d = np.linalg.solve(H + mu * np.eye(2), -grad) + escape
                escape = 0.5 * escape
                Y = X.copy()
                Y[0] = min(max(X[0] + d[0], a_lo), a_hi)
                Y[1] = min(max(X[1] + d[1], v_lo), v_hi)
                moved = float(np.max(np.abs(Y[:2] - X[:2])))
                if moved <= _SETTLED:
                    break
                nxt = self._local(Y)
                if nxt is not None and abs(nxt[0]) < abs(R):
                    X, cur, mu = Y, nxt, mu / 10
                    break
                mu = max(10 * mu, 1e-8 * float(np.trace(np.abs(H))))
            if moved <= _SETTLED or mu >= 1e30:
                break
        R = cur[0]
        hq = _FD if X[2] + _FD <= 1 else -_FD
        try:
            Rq = (complex(self.f.residual(X[2] + hq, X[0], X[1])[()]) - R) / hq
        except ValueError:
            return None
        depth = abs(R) / (1 + abs(R - 1.0))
        slope = (R.real * Rq.real + R.imag * Rq.imag) / abs(R) if abs(R) > 0 else 0.0
        return _Bottom(X, float(depth), abs(R), float(slope), depth <= _ROOT)

    # -- one valley between two probes ------------------------------------------------------------------
    @staticmethod
    def _tangents(lo: _Bottom, hi: _Bottom) -> tuple[float, float] | None:
        """Where the depth's tangent lines at lo and hi (lo before hi in q) meet, (q, depth), when the slopes
        point inwards at both (the depth has a minimum between them); else None."""
        s0, s1 = lo.slope, hi.slope
        if not (s0 < 0 < s1):
            return None
        q0, q1 = lo.X[2], hi.X[2]
        qx = (hi.level - lo.level + s0 * q0 - s1 * q1) / (s0 - s1)
        qx = min(max(qx, q0), q1)
        return qx, max(lo.level + s0 * (qx - q0), hi.level + s1 * (qx - q1))

    def _search(self, B0: _Bottom, B1: _Bottom) -> _Bottom | None:
        """A root of the valley between the bottoms B0 and B1 (at two probes), or None.

        The depth d(q) of a valley that holds a pair for q in (q1, q2) falls linearly to zero at q1 and rises
        linearly from q2: the tangent lines at two points either side meet at depth <= 0 (exactly at the dip
        for a V). So the search probes where the tangents meet (kept 1 % of the bracket from its ends),
        replaces the end with the same slope sign, and stops at a root; it concludes there is none when the
        tangents meet above ``_DIP`` times the smaller end depth (a convex depth stays above its tangents; the
        slack admits d ~ |q - q*|^0.4). A search that reaches ``_GOLDEN`` probes or a bracket of ``_Q_BRACKET``
        (in q) undecided records the interval (:class:`UnresolvedInterval`)."""
        lo, hi = (B0, B1) if B0.X[2] < B1.X[2] else (B1, B0)
        why = f"the search on the valley's depth reached its bound of {_GOLDEN} probes"
        for _ in range(_GOLDEN):
            meet = self._tangents(lo, hi)
            if meet is None or meet[1] > _DIP * min(lo.level, hi.level):
                return None
            width = hi.X[2] - lo.X[2]
            if width <= _Q_BRACKET:
                why = f"the search on the valley's depth narrowed to a bracket of {_Q_BRACKET:g} (q) undecided"
                break
            X = (lo if meet[0] - lo.X[2] <= hi.X[2] - meet[0] else hi).X.copy()
            q = min(max(meet[0], lo.X[2] + 0.01 * width), hi.X[2] - 0.01 * width)
            if width > 8 * self.grain:  # on a lattice while the bracket is wide: searches share their loops
                snapped = round(q / self.grain) * self.grain
                q = snapped if lo.X[2] + 0.01 * width <= snapped <= hi.X[2] - 0.01 * width else q
            X[2] = q
            B = self.settle(X)
            if B is None:
                why = f"a valley bottom could not be settled at p={self.f.value(X[2]):.9g}"
                break
            if B.root:
                return B
            if B.slope < 0:
                lo = B
            elif B.slope > 0:
                hi = B
            else:
                return None
        best = min((lo, hi), key=lambda b: b.depth)
        p0, p1 = sorted((self.f.value(lo.X[2]), self.f.value(hi.X[2])))
        self.unresolved.append(UnresolvedInterval(p0, p1, math.exp(best.X[0]), math.exp(best.X[1]), best.depth,
                                                  why + "; add given values inside the interval to decide"))
        return None

    # -- the whole range ---------------------------------------------------------------------------------
    def roots(self, qs: np.ndarray) -> list[_Bottom]:
        """Roots found inside the intervals between the given values (each a bottom with ``root``)."""
        probes = []
        for k in range(qs.size - 1):
            probes += [qs[k] + (qs[k + 1] - qs[k]) * j / self.probes for j in range(self.probes)]
        probes.append(float(qs[-1]))
        self.grain = float(np.min(np.abs(np.diff(probes)))) / 32
        given = set(range(0, len(probes), self.probes))
        found = []
        here = self.valleys(probes[0])
        for j in range(len(probes) - 1):
            pairs, ahead = [], []
            for B in here:  # each valley followed to the next probe ...
                X = B.X.copy()
                X[2] = probes[j + 1]
                C = self.settle(X)
                if C is not None:
                    pairs.append((B, C))
                    if not any(np.max(np.abs(C.X[:2] - Y.X[:2])) <= 1e-6 for Y in ahead):
                        ahead.append(C)
            fresh = self.valleys(probes[j + 1], ahead)
            for C in fresh:  # ... and the valleys new there followed back
                X = C.X.copy()
                X[2] = probes[j]
                B = self.settle(X)
                if B is not None:
                    pairs.append((B, C))
            here = sorted(ahead + fresh, key=lambda b: b.depth)[:_MAX_VALLEYS]
            if (j + 1) not in given:
                found += [C for C in here if C.root]
            for B, C in pairs:
                if not (B.root or C.root):
                    hit = self._search(B, C)
                    if hit is not None:
                        found.append(hit)
        return found


# ------------------------------------------------------------------------------------------------ sweep


def _on_curves(tracer: _Tracer, curves: list, X: np.ndarray, tol: float = _MATCH) -> bool:
    """X = (ln A, ln w, q) lies on one of the traced curves (within ``tol`` in ln A, ln w): the curve's point at
    X's q on each monotone piece between two nodes that spans it (:meth:`_Tracer._at_q`)."""
    q = float(X[2])
    for nodes in curves:
        for n0, n1 in zip(nodes[:-1], nodes[1:]):
            P, Q = n0.point, n1.point
            if np.max(np.abs(P.X - X)) <= tol or np.max(np.abs(Q.X - X)) <= tol:
                return True
            if not min(P.X[2], Q.X[2]) < q < max(P.X[2], Q.X[2]):
                continue
            lo, hi = np.minimum(P.X[:2], Q.X[:2]), np.maximum(P.X[:2], Q.X[:2])
            pad = float(np.max(hi - lo)) + 1e-6
            if np.any(X[:2] < lo - pad) or np.any(X[:2] > hi + pad):
                continue
            V = tracer._at_q(P, Q, q)
            if V is not None and np.max(np.abs(V.X[:2] - X[:2])) <= tol:
                return True
    return False


def _predict_at(value: float, loop_at: Callable, options: dict) -> LimitCycles | ContinuumAt:
    """The solver's cycles at one value, or the continuum it met there (a picklable record, not the error)."""
    plant, N = _build_loop(loop_at, value)
    try:
        return predict_limit_cycles(plant, N, **options)
    except ContinuumError as exc:
        return ContinuumAt(tuple(exc.amplitude_range), tuple(exc.omega_range), str(exc))


def _check_values(values) -> np.ndarray:
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"values must be a 1-D sequence of numbers; got {_checks.show(values)}") from None
    if v.ndim != 1 or v.size < 2:
        raise ValueError(f"values must be a 1-D sequence of at least 2 numbers; got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"values must be finite; got {values!r}")
    d = np.diff(v)
    if not (np.all(d > 0) or np.all(d < 0)):
        raise ValueError("values must be strictly increasing or strictly decreasing")
    return v


def sweep(loop_at: Callable[[float], tuple], values, *, omega=None, amplitude=None, executor=None,
          progress: bool | None = None, parameter: str = "parameter", unit: str = "", max_steps: int = 20_000,
          probes: int = _PROBES, **solver_options) -> SweepResult:
    """Follow every limit cycle of a one-parameter family of loops across a range of the parameter.

    Parameters
    ----------
    loop_at : callable
        ``loop_at(value) -> (G, N)``: the plant and element at one parameter value (any scalar of the study:
        a gain, a clearance, a coefficient). Called at the given values and at values between them (the
        continuation's steps), never outside the range. Must be picklable for a process-based executor.
    values : sequence of float
        Strictly monotone parameter values; the range is [values[0], values[-1]]. At each one the cycles are
        also solved independently (the completeness check), and each branch has a point there.
    omega, amplitude : (float, float), optional
        Windows (rad/s; N's input unit). Default: the union of the solver's default windows at the values.
    executor : concurrent.futures.Executor, optional
        Runs the independent solves at the given values (e.g. a Dask ``client.get_executor()``). The
        continuation itself runs here.
    progress : bool or None
        Progress bars (None: only when the work takes more than a second).
    parameter, unit : str
        Name and unit of the parameter, for the report, the CSV and the plot labels.
    max_steps : int
        Bound on continuation steps per branch direction; exceeding it raises RuntimeError.
    probes : int
        The valley scan looks at ``probes - 1`` equally spaced points inside each interval between given
        values as well as at the values (>= 1): it finds the pairs of cycles born and dying between two values
        (docs/sweep.md), or lists the interval in ``unresolved``.
    **solver_options
        Passed to :func:`~dfloop.predict_limit_cycles` (``grid``, ``tol``, ``marginal_tol``). The branch points'
        stability labels use the solver's marginal test (:func:`dfloop.solve.stability.label_roots`) with the
        same ``marginal_tol``.

    Returns
    -------
    SweepResult
        Branches (arrays of parameter, amplitude, frequency, stability), events (folds located by bracketing
        along the curve; births and deaths at element edges (linear range, N's domain, jumps) by Newton on the
        edge, from infinity or zero amplitude by Newton on the loop with N's limit; continua at single values;
        window entries/exits at the exact edge; stability changes), per-value solver results (a
        :class:`ContinuumAt` where the solver met a continuum: the sweep goes on past it).

    Notes
    -----
    The curve is traced in (ln A, ln w, q), q = (p - values[0]) / (values[-1] - values[0]), by
    pseudo-arclength continuation: predictor along the tangent (the cross product of the gradients of
    Re R and Im R, R = 1 + G N), Newton corrector on the hyperplane orthogonal to it, step halved when the
    corrector does not contract, moves more than half a step from the prediction or turns the tangent by
    more than 30 degrees. Derivatives are central differences (1e-6 in each coordinate).
    """
    vals = _check_values(values)
    max_steps = _checks.integer_at_least("max_steps", max_steps, 1)
    probes = _checks.integer_at_least("probes", probes, 1)
    batch_solver_options(solver_options, exclude=("omega", "amplitude"))  # before any solve
    parameter, unit = _checks.text("parameter", parameter), _checks.text("unit", unit)
    progress = _checks.flag("progress", progress, none=True)
    if omega is not None:
        omega = _checks.window("omega", omega)
    if amplitude is not None:
        amplitude = _checks.window("amplitude", amplitude)
    options = dict(solver_options, omega=omega, amplitude=amplitude)
    cycles = run_batch(partial(_predict_at, loop_at=loop_at, options=options), vals.tolist(), executor=executor,
                       chunksize=1, progress=progress, label=f"sweep of {parameter}: solves")
    solved = [c for c in cycles if isinstance(c, LimitCycles)]
    if not solved:
        raise ValueError(f"sweep of {parameter}: the solver met a continuum of solutions at every value; give "
                         "values where the describing-function equation has isolated roots")
    a_win = amplitude or (min(c.amplitude_window[0] for c in solved), max(c.amplitude_window[1] for c in solved))
    w_win = omega or (min(c.omega_window[0] for c in solved), max(c.omega_window[1] for c in solved))
    qs = (vals - vals[0]) / (vals[-1] - vals[0])
    qs[-1] = 1.0
    family = _Family(loop_at, vals, qs,
                     (math.log(a_win[0]), math.log(a_win[1]), math.log(w_win[0]), math.log(w_win[1])))
    tracer = _Tracer(family, qs, max_steps)
    marginal_tol = float(solver_options.get("marginal_tol", MARGINAL_TOL))

    # the solver's cycles, refined at their value (the matching is then to ~1e-11, not to the solver's tol)
    known = []
    for k, found in enumerate(cycles):
        for c in found:
            X = np.array([math.log(c.amplitude), math.log(c.frequency), qs[k]])
            P = family.correct(X, _EQ, qs[k])
            if P is None:
                P = _Point(X, family.jacobian(X)[1])
            known.append((k, P, c.stability == "marginal"))
    known.sort(key=lambda x: x[2])  # seeds at double roots last: the curve through them is usually traced already
    by_value: dict = {}
    for j, (k, _, _) in enumerate(known):
        by_value.setdefault(k, []).append(j)

    def matches(k: int, x: np.ndarray) -> list:
        """The solver's cycles at value k within the matching tolerance of x = (ln A, ln w)."""
        return [j for j in by_value.get(k, ()) if np.max(np.abs(known[j][1].X[:2] - x))
                <= (_MATCH_MARGINAL if known[j][2] else _MATCH)]

    covered = [False] * len(known)
    curves = []
    with progress_bar(f"sweep of {parameter}: continuation", len(known), enabled=progress) as bar:
        for i, (k, P, _) in enumerate(known):
            if covered[i]:
                continue
            nodes = tracer.curve(P, k)
            curves.append(nodes)
            hit = {i}.union(*(matches(n.k, n.point.X[:2]) for n in nodes if n.k >= 0))
            for j in hit:
                if not covered[j]:
                    covered[j] = True
                    bar.update(1)

    # pairs of cycles born and dying between two given values: the valley scan finds a root on each such curve
    scan = _ValleyScan(family, probes)
    scanned = set()
    with progress_bar(f"sweep of {parameter}: valley scan", 1, enabled=progress) as bar:
        for B in scan.roots(qs):
            if _on_curves(tracer, curves, B.X) or not scan.on_branch_side(B.X):
                continue
            P = family.correct(B.X, _EQ, B.X[2])
            if P is None:  # next to a fold (a double root): the settled bottom as the seed, matched more loosely
                P = _Point(B.X, family.jacobian(B.X)[1])
            if _on_curves(tracer, curves, P.X, _MATCH if P.iterations else _MATCH_MARGINAL):
                continue
            scanned.add(len(curves))
            curves.append(tracer.curve(P, tracer._value_index(P.X[2])))
        bar.update(1)

    branches, events = _assemble(curves, family, marginal_tol, parameter, scanned)
    for k, c in enumerate(cycles):  # isolated values where the loop has a whole curve of solutions
        if isinstance(c, ContinuumAt):
            (a0, a1), (w0, w1) = c.amplitude_range, c.omega_range
            touching = tuple(b.index for b in branches if np.any(b.value_index == k))
            events.append(SweepEvent("continuum", parameter=float(vals[k]), amplitude=a1, frequency=0.5 * (w0 + w1),
                                     branches=touching, cause="continuum", name=parameter,
                                     detail=f"1 + G N = 0 along a whole curve through A in [{a0:.6g}, {a1:.6g}], "
                                            f"omega in [{w0:.6g}, {w1:.6g}] rad/s at this value only; the sweep "
                                            "goes on past it"))
    events.sort(key=lambda e: (e.parameter - family.p0) / family.span)
    notes = []
    for b in branches:
        for j in np.flatnonzero(b.value_index >= 0):
            k = b.value_index[j]
            if isinstance(cycles[k], ContinuumAt):
                continue
            if not matches(k, np.log([b.amplitude[j], b.frequency[j]])):
                notes.append(f"at {parameter}={vals[k]:.9g} the solver did not report the cycle at "
                             f"A={b.amplitude[j]:.6g}, omega={b.frequency[j]:.6g} rad/s that continuation found "
                             f"(branch {b.index})")
    for u in scan.unresolved:
        notes.append(str(u).replace("for p in", f"for {parameter} in"))
        warnings.warn(f"sweep: {notes[-1]}", stacklevel=2)
    for e in events:
        if e.kind == "lost":
            warnings.warn(f"sweep: a branch was lost at {parameter}={e.parameter:.6g} (A={e.amplitude:.6g}, "
                          f"omega={e.frequency:.6g} rad/s): {e.detail}", stacklevel=2)
    N0 = family.loop(0.0)[1]
    return SweepResult(values=vals, branches=branches, events=events, cycles=cycles, amplitude_window=a_win,
                       omega_window=w_win, parameter=parameter, unit=unit,
                       amplitude_name=getattr(N0, "input_name", "A"), amplitude_unit=getattr(N0, "input_unit", ""),
                       notes=notes, unresolved=list(scan.unresolved))
