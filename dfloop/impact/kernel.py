"""Exact event-driven simulation of the paper's two-mass clearance system (Fig. 4, eqs. 6-12).

Model: masses ``m1`` and ``m2`` with clearance ``h``; gap g = x2 - x1 in [0, h] (side A: g = 0, side B: g = h).
The force F cos(w t) acts on M2 only; M1 is free between impacts. Impacts follow Newton's law with restitution
eps (eq. 6) and momentum conservation (eq. 7), i.e. eqs. (8a)/(8b). Initial state: both at rest, x1 = 0,
g = h/2, force from t = 0. Chattering (infinitely many impacts in finite time) is cut when the post-impact
relative speed falls below ``chatter_tol * max(h w, F/(M2 w))`` while the force presses the masses together:
they then move as one body until the contact force changes sign (a closed-form instant).

Free flights are closed form in local time; impact instants are roots of the gap function bracketed by its
closed-form turning points and refined by Newton with a bisection safeguard to ~machine precision.
This closed form is the fast path of the exact event engine: with optional effects (see
:mod:`dfloop.impact.effects`) the same motion runs on the linear-mode engine, which equals it without effects
(tests/test_impact_effects.py) at about 5x the cost per impact (benchmarks/bench_effects.py).
:func:`forced_motion` is the one entry point and chooses; both runs follow the :class:`ForcedRun` protocol.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import _checks
from . import _core
from ._core import FREE, GAP, PHI0, STUCK_B, T0, U, U_POST, U_PRE, V1, V1_POST, V1_PRE, X1
from .effects import EffectsRun
from .model import (DEFAULT_CHATTER_TOL, EventLimitError, ForcedRun, ImpactEvents, ImpactParameters,
                    default_max_events, effects_tuple, event_limit_message, initial_state, run_periods)

__all__ = ["Trajectory", "simulate", "forced_motion", "KernelRun", "kernel_arrays"]

_SEGMENT_BYTES = 8 * _core.N_FLOAT_COLUMNS + 2  # one stored segment: the float row, mode and cause


@dataclass(frozen=True, repr=False)
class Trajectory(ImpactEvents):
    """Piecewise-analytic motion returned by :func:`simulate`.

    Segment k starts at ``t0[k]`` (phase ``phase0[k]`` = w t0 mod 2 pi) with state ``x1, v1, gap, u``
    (u = v2 - v1) and lasts to ``t0[k+1]`` (the last one to ``t_end``). ``mode`` is 0 (free flight),
    1 (stuck on side A) or 2 (stuck on side B); ``cause`` is 0 (start), 1/2 (impact on side A/B),
    3 (separation). Pre/post-impact velocities are stored per segment (meaningful where cause is 1 or 2).
    """

    params: ImpactParameters
    t_end: float
    t0: np.ndarray
    phase0: np.ndarray
    x1: np.ndarray
    v1: np.ndarray
    gap: np.ndarray
    u: np.ndarray
    v1_pre: np.ndarray
    u_pre: np.ndarray
    v1_post: np.ndarray
    u_post: np.ndarray
    mode: np.ndarray
    cause: np.ndarray
    effects: tuple = field(default=())

    # --- events -----------------------------------------------------------------------------------
    def _segment_velocities(self):
        return self.v1_pre, self.v1_pre + self.u_pre, self.v1_post, self.v1_post + self.u_post

    @property
    def stuck_intervals(self) -> np.ndarray:
        """(n, 3) array of [start, end, side] for the stuck phases (side 0 = A, 1 = B)."""
        ends = np.append(self.t0[1:], self.t_end)
        m = self.mode != FREE
        return np.column_stack([self.t0[m], ends[m], (self.mode[m] == STUCK_B).astype(float)])

    @property
    def segment_ends(self) -> np.ndarray:
        """End time of every segment (s)."""
        return np.append(self.t0[1:], self.t_end)

    # --- evaluation -------------------------------------------------------------------------------
    def evaluate(self, t) -> dict:
        """x1, v1, x2, v2 (m, m/s) and the gap at times ``t`` (s, array_like within [t0[0], t_end])."""
        t = np.asarray(t, dtype=float)
        if np.any(~np.isfinite(t)) or np.any(t < self.t0[0]) or np.any(t > self.t_end):
            raise ValueError(f"t must lie in [{self.t0[0]:g}, t_end = {self.t_end}]")
        k = np.searchsorted(self.t0, t, side="right") - 1
        s = t - self.t0[k]
        p = self.params
        w = p.omega
        th = w * s
        c0 = np.cos(self.phase0[k])
        s0 = np.sin(self.phase0[k])
        shp = c0 * 2.0 * np.sin(0.5 * th) ** 2 + s0 * _sin_minus_x(th)
        dshp = c0 * np.sin(th) - s0 * 2.0 * np.sin(0.5 * th) ** 2
        stuck = self.mode[k] != FREE
        Bc = p.force / ((p.m1 + p.m2) * w * w)
        B = p.force / (p.m2 * w * w)
        x1 = self.x1[k] + self.v1[k] * s + np.where(stuck, Bc * shp, 0.0)
        v1 = self.v1[k] + np.where(stuck, Bc * w * dshp, 0.0)
        gap = np.where(stuck, self.gap[k], self.gap[k] + self.u[k] * s + B * shp)
        u = np.where(stuck, 0.0, self.u[k] + B * w * dshp)
        return {"x1": x1, "v1": v1, "x2": x1 + gap, "v2": v1 + u, "gap": gap}

    def piece_integrals(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Exact integrals of x1(t) e^{-j w t} dt over pieces [starts, ends] that each lie inside one segment.

        Uses the closed form x1 = p0 + p1 (t - t0) + q cos(w t) of every segment (q = 0 in free flight).
        """
        starts = np.asarray(starts, dtype=float)
        ends = np.asarray(ends, dtype=float)
        k = np.searchsorted(self.t0, starts, side="right") - 1
        p = self.params
        w = p.omega
        Bc = p.force / ((p.m1 + p.m2) * w * w)
        stuck = self.mode[k] != FREE
        phi0 = self.phase0[k]
        q = np.where(stuck, -Bc, 0.0)
        p0 = self.x1[k] - q * np.cos(phi0)
        p1 = self.v1[k] + q * w * np.sin(phi0)
        return _core.fourier_pieces(p0, p1, q, phi0, w, starts - self.t0[k], ends - self.t0[k])

    def __repr__(self) -> str:
        p = self.params
        return (f"Trajectory(m1={p.m1:g}, m2={p.m2:g}, h={p.h:g}, eps={p.restitution:g}, F={p.force:g}, "
                f"omega={p.omega:g}, beta={p.beta:.4g}, t_end={self.t_end:g}, segments={self.t0.size}, "
                f"impacts={self.n_impacts}, stuck_phases={int(np.count_nonzero(self.mode != FREE))})")


def _sin_minus_x(th: np.ndarray) -> np.ndarray:
    """sin(th) - th, vectorised, without cancellation for small |th|."""
    th = np.asarray(th, dtype=float)
    small = np.abs(th) < 1.0
    t2 = th * th
    term = -th * t2 / 6.0
    series = term.copy()
    for k in range(2, 12):
        term = term * (-t2 / ((2 * k) * (2 * k + 1)))
        series = series + term
    return np.where(small, series, np.sin(th) - th)


def simulate(m1: float, m2: float, h: float, restitution: float, force: float, omega: float, t_end: float, *,
             effects=(), max_events: int | None = None,
             chatter_tol: float = DEFAULT_CHATTER_TOL, initial=None) -> Trajectory:
    """Simulate the two-mass impact system over [0, t_end], from rest (g = h/2, x1 = 0) by default.

    Parameters
    ----------
    m1, m2 : float
        Masses (kg); F cos(w t) acts on ``m2``.
    h : float
        Clearance (m).
    restitution : float
        Coefficient of restitution eps in [0, 1].
    force, omega : float
        Force amplitude F (N) and frequency w (rad/s).
    t_end : float
        End time (s).
    effects : sequence of effect objects, optional
        Optional physics (:mod:`dfloop.impact.effects`). Empty: the paper's model (closed-form fast path).
    max_events : int, optional
        Bound on the number of events (impacts and separations); reaching it raises EventLimitError.
        Default: :func:`default_max_events` for the number of forcing periods in [0, t_end].
    chatter_tol : float
        Relative post-impact speed (of max(h w, F/(M2 w))) below which a converging chatter is cut into
        a stuck phase.
    initial : (x1, v1, gap, u), optional
        Initial state at t = 0 (m, m/s; gap = x2 - x1 in [0, h], u = v2 - v1), free flight. Default: rest
        with a centred gap, (0, 0, h/2, 0).

    Returns
    -------
    Trajectory or EffectsTrajectory
        The motion, with the same interface either way (:class:`dfloop.impact.model.ImpactEvents`,
        ``evaluate``, ``piece_integrals``).
    """
    p = ImpactParameters(m1, m2, h, restitution, force, omega)
    t_end = _checks.positive("t_end", t_end)
    run_periods(f"t_end = {t_end:g} s at omega = {p.omega:g} rad/s", t_end / p.period)
    chatter_tol = _checks.positive("chatter_tol", chatter_tol)
    effects = effects_tuple(effects)
    if max_events is None:
        max_events = default_max_events(p.restitution, chatter_tol, t_end / p.period)
    max_events = _checks.integer_at_least("max_events", max_events, 1)
    run = forced_motion(p, effects, chatter_tol, initial)
    run.advance(t_end, max_events)
    return run.trajectory()


def forced_motion(params: ImpactParameters, effects=(), chatter_tol: float = DEFAULT_CHATTER_TOL, initial=None, *,
                  closed_form: bool = True) -> ForcedRun:
    """The forced motion as a continuable run of the exact event engine (:class:`ForcedRun` protocol).

    Parameters
    ----------
    params : ImpactParameters
    effects : tuple, optional
        Validated effect objects; any effect needs the linear-mode engine.
    chatter_tol : float
        See :func:`simulate`.
    initial : (x1, v1, gap, u), optional
        Free-flight state at t = 0 (m, m/s); default rest with a centred gap.
    closed_form : bool
        Without effects, use the closed-form free flight (default: the same motion, about 5x faster per impact);
        False runs the paper's model on the linear-mode engine (the general path, for comparison).
    """
    if effects or not closed_form:
        return EffectsRun(params, effects, chatter_tol, initial)
    return KernelRun(params, chatter_tol, initial)


class KernelRun(ForcedRun):
    """A continuable run of the paper's model (closed-form fast path) that keeps only the segments since
    :meth:`forget`: the :class:`ForcedRun` protocol.

    ``advance(t)`` moves the motion on to time t (s); ``forget()`` drops the stored segments except the
    current one (bounded memory for long transients); ``trajectory()`` is the motion since the last forget.

    Parameters
    ----------
    params : ImpactParameters
    chatter_tol : float
        See :func:`simulate`.
    initial : (x1, v1, gap, u), optional
        Free-flight state at t = 0 (m, m/s); default rest with a centred gap.
    """

    def __init__(self, params: ImpactParameters, chatter_tol: float = DEFAULT_CHATTER_TOL, initial=None,
                 capacity: int = 256):
        p = self.params = params
        self._kernel_params, self._state = kernel_arrays(p, chatter_tol, initial)
        x1, v1, gap, u = self._state[2:6]
        self._seg, self._mode, self._cause = _core.empty_buffers(max(int(capacity), 2))
        self._seg[0] = [0.0, 0.0, x1, v1, gap, u, v1, u, v1, u]
        self._mode[0] = FREE
        self._cause[0] = _core.START
        self._n = 1
        self.n_events = 0           # events since t = 0
        self.t = 0.0                # time reached (s); the kernel state holds the last event


    def advance(self, t_end: float, max_events: int, keep: bool = True) -> None:
        """Run on to ``t_end`` (s); raises EventLimitError when the events since t = 0 would exceed max_events.

        ``keep=False`` drops stored segments whenever the buffer fills (memory bounded by its capacity).
        """
        while True:
            cap = self._seg.shape[0]
            limit = min(cap, self._n + max(max_events - self.n_events, 0))
            n0 = self._n
            n, status = _core.run_kernel(self._kernel_params, self._state, t_end, self._seg[:limit],
                                         self._mode[:limit], self._cause[:limit], self._n)
            self.n_events += n - n0
            self._n = n
            if status == _core.DONE:
                self.t = max(self.t, float(t_end))
                return
            t_now = float(self._state[0])
            if self.n_events >= max_events:
                raise EventLimitError(event_limit_message(max_events, t_now, t_end, self.params.period))
            if keep:
                expected = 4 * (t_end - t_now) / self.params.period + 16
                self._grow(int(max(2 * cap, cap + expected)))
            else:
                self.forget()

    def _grow(self, capacity: int) -> None:
        """Larger buffers, within the memory bound (``DFLOOP_MEMORY_LIMIT``): a run that needs more stops with
        an EventLimitError saying so (the growth is otherwise sized from the periods left, not the events)."""
        most = max(2, _checks.memory_limit() // _SEGMENT_BYTES)
        if self._seg.shape[0] >= most:
            gib = self._n * _SEGMENT_BYTES / 2**30
            raise EventLimitError(f"the run's record reached {self._n} segments ({gib:.2g} GiB, the memory limit) "
                                  f"at t = {float(self._state[0]):.6g} s; shorten the run, or raise the limit with "
                                  "the environment variable DFLOOP_MEMORY_LIMIT (GiB)")
        seg, mode, cause = _core.empty_buffers(min(capacity, most))
        n = self._n
        seg[:n], mode[:n], cause[:n] = self._seg[:n], self._mode[:n], self._cause[:n]
        self._seg, self._mode, self._cause = seg, mode, cause

    def forget(self) -> None:
        """Drop every stored segment but the current one (the motion stays exact)."""
        last = self._n - 1
        self._seg[0], self._mode[0], self._cause[0] = self._seg[last], self._mode[last], self._cause[last]
        self._n = 1

    def trajectory(self) -> "Trajectory":
        """The motion from the last :meth:`forget` (or t = 0) to the current time."""
        n = self._n
        seg = self._seg[:n]
        return Trajectory(params=self.params, t_end=self.t, t0=seg[:, T0].copy(), phase0=seg[:, PHI0].copy(),
                          x1=seg[:, X1].copy(), v1=seg[:, V1].copy(), gap=seg[:, GAP].copy(),
                          u=seg[:, U].copy(), v1_pre=seg[:, V1_PRE].copy(), u_pre=seg[:, U_PRE].copy(),
                          v1_post=seg[:, V1_POST].copy(), u_post=seg[:, U_POST].copy(),
                          mode=self._mode[:n].astype(np.int64), cause=self._cause[:n].astype(np.int64))


def kernel_arrays(p: ImpactParameters, chatter_tol: float = DEFAULT_CHATTER_TOL, initial=None):
    """(params, state) arrays of :func:`dfloop.impact._core.run_kernel` for a free-flight start at t = 0
    (``initial`` (x1, v1, gap, u) in m, m/s; default rest with a centred gap)."""
    x1, v1, gap, u = (0.0, 0.0, 0.5 * p.h, 0.0) if initial is None else initial_state(initial, p.h)
    v_stick = chatter_tol * max(p.h * p.omega, p.force / (p.m2 * p.omega))
    return (np.array([p.m1, p.m2, p.h, p.force, p.omega, p.restitution, v_stick]),
            np.array([0.0, 0.0, x1, v1, gap, u, float(FREE), -1.0]))
