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

Completeness: :func:`dfloop.predict_limit_cycles` is run at every given value (independently, on any
executor); every cycle it finds either lies on a traced curve or seeds a new trace, so branches born
between two values (a pair from a fold, or one entering through the window edge) are traced back to their
birth. Points of a traced curve that the solver did not report are listed in ``SweepResult.notes``.
"""
from __future__ import annotations

import csv
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
from .solve.stability import MARGINAL_TOL

__all__ = ["sweep", "SweepResult", "Branch", "SweepEvent"]

_FD = 1e-6  # central-difference step in ln A, ln w and q (q: the parameter range scaled to [0, 1])
_XTOL = 1e-11  # Newton converged when the update is below this (max norm)
_MAX_NEWTON = 12
_H0, _HMAX, _HMIN = 0.02, 0.1, 1e-9  # arclength steps in (ln A, ln w, q)
_COS_TURN = math.cos(math.radians(30))  # a step may turn the tangent by at most 30 degrees
_BISECT = 80  # bound on the probes that locate an event inside a step
_MATCH = 1e-6  # a solver's cycle lies on a traced curve when within this (ln A, ln w)
_MATCH_MARGINAL = 1e-3  # ... or within this for a cycle the solver called marginal (a double root)
_SAME_Q = 1e-12  # a point this close to a given value (in q) lies on it
_CACHE = 512  # loops kept per sweep (the corrector asks for the same parameter values repeatedly)


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
        ``"fold"``, ``"stability change"``, ``"enters <edge>"``, ``"leaves <edge>"``, ``"lost: <why>"``.
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
                f"A {self.amplitude[0]:.6g} -> {self.amplitude[-1]:.6g}, omega {self.frequency[0]:.6g} -> "
                f"{self.frequency[-1]:.6g} rad/s, {self.start} -> {self.end})")


@dataclass(frozen=True)
class SweepEvent:
    """Where branches are born, die or change stability.

    Attributes
    ----------
    kind : str
        ``"fold"`` (a stable and an unstable cycle meet and vanish together), ``"entry"`` / ``"exit"`` (a
        branch crosses an edge of the window, in the order of the sweep), ``"stability change"`` (a branch
        point: curves cross), ``"lost"`` (continuation could not go on; see ``detail``).
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

    def __str__(self) -> str:
        ids = ", ".join(map(str, self.branches))
        return (f"{self.kind} at p={self.parameter:.9g}: A={self.amplitude:.6g}, omega={self.frequency:.6g} rad/s; "
                f"branch{'es' if len(self.branches) > 1 else ''} {ids}" + (f" ({self.detail})" if self.detail else ""))


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
        Anything the reader must know: cycles continuation found that the solver missed at a given value.
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

    def __repr__(self) -> str:
        p = self.parameter + (f" [{self.unit}]" if self.unit else "")
        head = (f"sweep of {p} over {self.values[0]:.6g} .. {self.values[-1]:.6g} ({self.values.size} values): "
                f"{len(self.branches)} branch(es), {len(self.events)} event(s); window A in "
                f"[{self.amplitude_window[0]:.4g}, {self.amplitude_window[1]:.4g}], omega in "
                f"[{self.omega_window[0]:.4g}, {self.omega_window[1]:.4g}] rad/s")
        rows = [head]
        if not self.branches:
            rows.append("no limit cycle in the window at the given values")
        else:
            rows.append(f"{'#':>3} {'stability':>10} {p + ' from':>16} {'to':>12} {'A from':>12} {'to':>12} "
                        f"{'omega from':>11} {'to':>11}  start -> end")
            for b in self.branches:
                rows.append(f"{b.index:>3} {b.kind:>10} {b.parameter[0]:>16.6g} {b.parameter[-1]:>12.6g} "
                            f"{b.amplitude[0]:>12.6g} {b.amplitude[-1]:>12.6g} {b.frequency[0]:>11.6g} "
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
        """Amplitude and frequency of every branch against the parameter.

        Stable branches solid, unstable dashed, marginal dotted; folds as black dots, window entries and
        exits as crosses. ``ax``: a pair of matplotlib Axes (amplitude, frequency); new ones by default.

        Returns
        -------
        (Axes, Axes)
            The amplitude and frequency axes (the figure is ``axes[0].figure``).
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(2, 1, sharex=True, figsize=(6.4, 6.0), constrained_layout=True)
        try:
            ax_a, ax_w = ax
        except (TypeError, ValueError):
            raise ValueError("ax must be a pair of Axes (amplitude, frequency)") from None
        style = {"stable": dict(color="C0", ls="-"), "unstable": dict(color="C3", ls="--"),
                 "marginal": dict(color="C1", ls=":")}
        seen = set()
        for b in sorted(self.branches, key=lambda b: ("stable", "unstable", "marginal").index(b.kind)):
            k = b.kind
            label = None if k in seen else f"{k} cycles"
            seen.add(k)
            ax_a.plot(b.parameter, b.amplitude, label=label, **style[k])
            ax_w.plot(b.parameter, b.frequency, **style[k])
        marks = {"fold": dict(marker="o", color="k", ls="none", ms=5),
                 "entry": dict(marker="x", color="0.3", ls="none"), "exit": dict(marker="x", color="0.3", ls="none"),
                 "stability change": dict(marker="s", color="C2", ls="none", ms=5),
                 "lost": dict(marker="*", color="C1", ls="none", ms=8)}
        for kind, st in marks.items():
            ev = [e for e in self.events if e.kind == kind]
            if ev:
                label = "window edge" if kind in ("entry", "exit") else kind
                label = None if label in seen else label
                seen.add(label)
                ax_a.plot([e.parameter for e in ev], [e.amplitude for e in ev], label=label, **st)
                ax_w.plot([e.parameter for e in ev], [e.frequency for e in ev], **st)
        a_unit = f" [{self.amplitude_unit}]" if self.amplitude_unit else ""
        ax_a.set_ylabel(f"amplitude {self.amplitude_name}{a_unit}")
        ax_w.set_ylabel("frequency \u03c9 [rad/s]")
        ax_w.set_xlabel(self.parameter + (f" [{self.unit}]" if self.unit else ""))
        for a, attr in ((ax_a, "amplitude"), (ax_w, "frequency")):
            vals = np.concatenate([getattr(b, attr) for b in self.branches]) if self.branches else np.empty(0)
            if vals.size and vals.max() > 20 * vals.min():
                a.set_yscale("log")
        lo, hi = sorted((float(self.values[0]), float(self.values[-1])))
        ax_w.set_xlim(lo, hi)
        if seen:
            ax_a.legend(loc="best", fontsize="small")
        return ax_a, ax_w


def _end_word(end: str, default: str) -> str:
    if end.startswith("enters"):
        return "entry"
    if end.startswith("leaves"):
        return "exit"
    if end.startswith("lost"):
        return "lost"
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
    def conditioning(self) -> float:
        s = 0.5 * float(np.sum(self.J[:, :2] ** 2))
        return self.det / s if s > 0 else 0.0

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

    def admissible(self, X: np.ndarray) -> bool:
        """Inside [0, 1] in q, within one unit (ln) of the window, in N's amplitude domain and G's range."""
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
        if not (float(lo) < A * (1 - 2 * _FD) and A * (1 + 2 * _FD) < float(hi)):
            self.last_failure = "reached the edge of N's amplitude domain"
            return False
        return True

    def jacobian(self, X: np.ndarray) -> tuple[complex, np.ndarray]:
        """R at X and the real 2 x 3 Jacobian of (Re R, Im R) in (ln A, ln w, q): central differences in
        ln A, ln w; a one-sided difference in q (towards the inside of the range, so no loop outside it is
        built). The q column only steers Newton and the predictor: the roots, the Loeb determinant and so
        the folds do not depend on its accuracy."""
        a, v, q = X
        q = min(max(q, 0.0), 1.0)
        h = _FD
        r = self.residual(q, a + np.array([0, h, -h, 0, 0]), v + np.array([0, 0, 0, h, -h]))
        hq = h if q + h <= 1 else -h  # one-sided: one more loop per Jacobian (see the docstring)
        rq = (self.residual(q + hq, a, v)[()] - r[0]) / hq
        ra, rv = (r[1] - r[2]) / (2 * h), (r[3] - r[4]) / (2 * h)
        J = np.array([[ra.real, rv.real, rq.real], [ra.imag, rv.imag, rq.imag]])
        return complex(r[0]), J

    def correct(self, X0: np.ndarray, n: np.ndarray, g: float) -> _Point | None:
        """Newton on R(X) = 0, n . X = g from X0; None unless it converges, contracting, inside the domain."""
        X = np.array(X0, float)
        prev = np.inf
        for it in range(_MAX_NEWTON):
            if not self.admissible(X):
                return None
            R, J = self.jacobian(X)
            F = np.array([R.real, R.imag, n @ X - g])
            try:
                dx = np.linalg.solve(np.vstack([J, n]), -F)
            except np.linalg.LinAlgError:
                self.last_failure = "singular corrector"
                return None
            step = float(np.max(np.abs(dx)))
            if not math.isfinite(step) or (it > 0 and step > 0.5 * prev and step > 1e3 * _XTOL):
                self.last_failure = "corrector did not contract"
                return None
            X, prev = X + dx, step
            if step <= _XTOL:
                if not self.admissible(X):
                    return None
                return _Point(X, J, it + 1)
        self.last_failure = "corrector did not converge"
        return None


# ------------------------------------------------------------------------------------------- the tracer


_EQ = np.array([0.0, 0.0, 1.0])


@dataclass
class _Node:
    """A point of a traced curve: what it is (``tag``) and the given value it lies on (``k``, or -1)."""

    point: _Point
    tag: str  # "seed", "step", "value", "fold", "stability change", "range", "exit", "lost", "closed"
    k: int = -1
    detail: str = ""


class _Tracer:
    def __init__(self, family: _Family, qs: np.ndarray, max_steps: int):
        self.f, self.qs, self.max_steps = family, qs, max_steps

    # -- helpers ---------------------------------------------------------------------------------------
    def _at_q(self, P: _Point, Q: _Point, q: float) -> _Point | None:
        """The curve point at parameter q between P and Q (q strictly between theirs or equal to Q's)."""
        dq = Q.X[2] - P.X[2]
        s = (q - P.X[2]) / dq if dq != 0 else 0.5
        return self.f.correct(P.X + s * (Q.X - P.X), _EQ, q)

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
            raise RuntimeError(f"could not locate where a branch crosses {name} near A={math.exp(P.X[0]):.6g}, "
                               f"omega={math.exp(P.X[1]):.6g} rad/s, p={self.f.value(P.X[2]):.6g}")
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
                raise RuntimeError(f"continuation could not land on the given value p={self.f.value(q):.9g} "
                                   f"near A={math.exp(P.X[0]):.6g}, omega={math.exp(P.X[1]):.6g} rad/s")
            out.append(_Node(V, "value", k))

    def _value_index(self, q: float) -> int:
        hit = np.flatnonzero(np.abs(self.qs - q) <= _SAME_Q)
        return int(hit[0]) if hit.size else -1

    # -- one direction ---------------------------------------------------------------------------------
    def trace(self, seed: _Point, t0: np.ndarray) -> list[_Node]:
        """Follow the curve from ``seed`` along ``t0`` until it leaves the range or window, closes, or is lost."""
        out: list[_Node] = []
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
            if Q is not None:
                tq = Q.tangent * (1.0 if Q.tangent @ t >= 0 else -1.0)
                ok = (tq @ t >= _COS_TURN) and (np.max(np.abs(Q.X - (P.X + h * t))) <= 0.5 * h or at_end)
            if Q is None or not ok:
                h *= 0.5
                if h < _HMIN:
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
        if (b.X[2] - seed.X[2]) * (f.X[2] - seed.X[2]) > 0:  # the seed is (next to) a fold: locate it
            tb = seed.X - b.X
            tb /= np.linalg.norm(tb)
            Fd = self._fold(b, tb, f)
            head = _Node(Fd, "fold", self._value_index(Fd.X[2]))
        return back[::-1] + [head] + fwd


# --------------------------------------------------------------------------------- curves -> branches


def _label(P: _Point, marginal_tol: float) -> str:
    if abs(P.conditioning) < marginal_tol:
        return "marginal"
    return "stable" if P.det > 0 else "unstable"


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
    return "closed curve"


def _assemble(curves, family: _Family, marginal_tol: float, name: str):
    branches, events = [], []
    for nodes in curves:
        pieces, _ = _pieces(nodes)
        ids = []
        for piece in pieces:
            q = np.array([n.point.X[2] for n in piece])
            order = np.argsort(q, kind="stable") if q[-1] >= q[0] else np.arange(q.size)[::-1]
            first, last = piece[order[0]], piece[order[-1]]
            lab = np.array([_label(piece[i].point, marginal_tol) for i in order])
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
                    events.append(SweepEvent("entry" if low else "exit", branches=(idx,),
                                             detail=("enters " if low else "leaves ") + node.detail, **where))
                elif node.tag == "lost":
                    events.append(SweepEvent("lost", branches=(idx,), detail=node.detail, **where))
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
                detail = (f"a stable and an unstable cycle meet; the pair exists for {name} {side} {p:.9g}"
                          if {ba.kind, bb.kind} == {"stable", "unstable"} else f"a {ba.kind} and a {bb.kind} cycle meet")
                events.append(SweepEvent("fold", branches=(a, b), detail=detail, **where))
            else:
                events.append(SweepEvent("stability change", branches=(a, b),
                                         detail=f"{branches[a].kind} -> {branches[b].kind} (branch point)", **where))
    events.sort(key=lambda e: (e.parameter - family.p0) / family.span)  # in the order of the sweep
    return branches, events


# ------------------------------------------------------------------------------------------------ sweep


def _predict_at(value: float, loop_at: Callable, options: dict) -> LimitCycles:
    plant, N = _build_loop(loop_at, value)
    return predict_limit_cycles(plant, N, **options)


def _check_values(values) -> np.ndarray:
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"values must be a 1-D sequence of numbers; got {values!r}") from None
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
          **solver_options) -> SweepResult:
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
    **solver_options
        Passed to :func:`~dfloop.predict_limit_cycles` (``grid``, ``tol``, ``marginal_tol``).

    Returns
    -------
    SweepResult
        Branches (arrays of parameter, amplitude, frequency, stability), events (folds located by bracketing
        along the curve, window entries/exits at the exact edge, stability changes), per-value solver results.

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
    a_win = amplitude or (min(c.amplitude_window[0] for c in cycles), max(c.amplitude_window[1] for c in cycles))
    w_win = omega or (min(c.omega_window[0] for c in cycles), max(c.omega_window[1] for c in cycles))
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

    branches, events = _assemble(curves, family, marginal_tol, parameter)
    notes = []
    for b in branches:
        for j in np.flatnonzero(b.value_index >= 0):
            k = b.value_index[j]
            if not matches(k, np.log([b.amplitude[j], b.frequency[j]])):
                notes.append(f"at {parameter}={vals[k]:.9g} the solver did not report the cycle at "
                             f"A={b.amplitude[j]:.6g}, omega={b.frequency[j]:.6g} rad/s that continuation found "
                             f"(branch {b.index})")
    for e in events:
        if e.kind == "lost":
            warnings.warn(f"sweep: a branch was lost at {parameter}={e.parameter:.6g} (A={e.amplitude:.6g}, "
                          f"omega={e.frequency:.6g} rad/s): {e.detail}", stacklevel=2)
    N0 = family.loop(0.0)[1]
    return SweepResult(values=vals, branches=branches, events=events, cycles=cycles, amplitude_window=a_win,
                       omega_window=w_win, parameter=parameter, unit=unit,
                       amplitude_name=getattr(N0, "input_name", "A"), amplitude_unit=getattr(N0, "input_unit", ""),
                       notes=notes)
