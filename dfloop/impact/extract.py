"""Describing function of the impact system, N(F, w) = X1 / F, from exact trajectories.

Convention (docs/design.md section 1): the force is Re(F e^{j w t}) = F cos(w t) and x1's fundamental is
Re(X1 e^{j w t}); N = X1 / F (m/N) is the ratio of phasors. The fundamental is taken over an integer number
of forcing periods after a transient, by exact integration of the piecewise-analytic x1(t) (no sampling),
after removing the linear drift (x1(t_end) - x1(t_start)) / window, which is exact for a periodic motion
with drift. A least-squares line is not used: it correlates with the sine part of a periodic x1 and
biases N by about 0.6 / periods^2 relative.

Similarity law (paper's model only, no optional effects): with x = h xi and tau = w t the motion depends on
beta = F / (M2 h w^2), M1/M2 and eps only, so N(F, w) = h Xi1(beta) / F where Xi1 is the fundamental of xi1
computed with m2 = 1, h = 1, omega = 1, force = beta, m1 = M1/M2.
"""
from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from .. import _checks
from . import _core
from ._core import IMPACT_A, IMPACT_B
from .kernel import Trajectory, forced_motion, kernel_arrays
from .model import (DEFAULT_CHATTER_TOL, EventLimitError, ImpactParameters, default_max_events, effects_tuple,
                    event_limit_message, initial_state, run_periods)
from .limits import beta_lower_limit

__all__ = ["ImpactDF", "ImpactDFBatch", "describing_function_from_trajectory", "impact_describing_function",
           "impact_describing_function_batch"]

DEFAULT_TRANSIENT_PERIODS = 200
DEFAULT_PERIODS = 40
MAX_DETECTED_PERIOD = _core.MAX_PERIOD   # longest period looked for (forcing periods)
PERIODICITY_TOL = 1e-6  # relative mismatch of the stroboscopic state that still counts as periodic
_ROUNDING_MISMATCH = 1e-11   # stroboscopic mismatch at rounding level (x max(1, beta)): periodic whatever its trend
_MAX_CONTRACTION = 0.9995    # a candidate contracting slower than this per period is not extrapolated
_EXTRAPOLATE_BELOW = 1e-2    # ... nor one whose mismatch is still this large
_GROWTH = 4                  # adaptive transient: at most x4 per step, each step needing new evidence
MIN_TRANSIENT_PERIODS = 25   # first transient of the adaptive extraction
CHAOS_TRANSIENT_PERIODS = 160  # adaptive: a motion not contracting towards any period by then is irregular
DEFAULT_MAX_TRANSIENT_PERIODS = 4000


@dataclass(frozen=True, repr=False)
class ImpactDF:
    """Describing-function value from one run, with how much to trust it.

    Attributes
    ----------
    N : complex
        X1 / F (m/N), phasor ratio of x1's fundamental to the force.
    X1 : complex
        Phasor of x1's fundamental (m).
    periodicity : float
        Spread of the fundamental over consecutive blocks of ``period`` forcing periods (one period when
        irregular), max |X_block - X1| / |X1|; 0 when x1 never moves.
    period : int
        Detected period of the steady motion in forcing periods (1, 2, ...), 0 for none (irregular).
    regular : bool
        False when no period was detected: N is then an average over the window, not a periodic DF.
    impacts_per_period : float
        Impacts per forcing period in the window.
    max_run_A, max_run_B : int
        Longest run of consecutive impacts on side A / B (paper's Fig. 9, n_A and n_B).
    runs_A, runs_B : numpy.ndarray
        All run lengths on side A / B in the window (their distribution).
    stuck_fraction : float
        Fraction of the window spent stuck (masses moving as one body).
    periods_used : int
        Forcing periods integrated.
    n_impacts : int
        Impacts in the window.
    beta : float
        F / (M2 h w^2).
    below_wc : bool
        w below the paper's lower limit w_c of eq. (10), where the paper reports irregular motion. The exact
        kernel (with sticking) often finds periodic chatter-and-stick motion there: ``regular`` says which.
    transient_periods : int
        Forcing periods discarded before the window (chosen adaptively when the caller asked for it).
    orbit : numpy.ndarray
        Adaptive runs of the paper's model: the stroboscopic states (gap / h, u / v_scale, mode, with
        v_scale = max(h w, F / (M2 w))) of the detected periodic orbit, one row per forcing period of its
        cycle, followed by those of its mirror image (the motion half a period later reflected, x -> -x,
        gap -> h - gap: a motion too, with the same DF); empty when irregular or with effects. Pass it as
        ``attractor`` to recognise the same motion.
    settled : bool
        True when the run stopped because it settled on the ``attractor`` it was given (the same motion:
        N and the other fields are then NaN / 0 and the attractor's apply).
    restarts : int
        Adaptive runs of the paper's model: times the slowly contracting transient was cut short by restarting
        from the extrapolated fixed point of the stroboscopic map (the window is simulated from there).

    A window without impacts or sticking is free flight: x1 is exactly linear, N = 0 exactly, and the
    motion is labelled period 1 with ``n_impacts`` = 0 (no-impact motion), whatever the gap does.
    """

    N: complex
    X1: complex
    periodicity: float
    period: int
    impacts_per_period: float
    max_run_A: int
    max_run_B: int
    runs_A: np.ndarray
    runs_B: np.ndarray
    stuck_fraction: float
    periods_used: int
    n_impacts: int
    beta: float
    below_wc: bool
    transient_periods: int = 0
    orbit: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    settled: bool = False
    restarts: int = 0

    @property
    def regular(self) -> bool:
        """True when the steady motion was periodic (N is then a proper DF value)."""
        return self.period > 0

    def __repr__(self) -> str:
        if self.settled:
            return f"ImpactDF(settled on the given attractor (period {self.period}), beta={self.beta:.4g})"
        note = "" if self.regular else ", irregular: N is an average over the window"
        note += ", no impacts in the window" if self.n_impacts == 0 and self.stuck_fraction == 0 else ""
        note += ", below w_c of eq. (10)" if self.below_wc else ""
        return (f"ImpactDF(N={self.N:.6g}, |N|={abs(self.N):.4g}, period={self.period}, "
                f"periodicity={self.periodicity:.2e}, impacts_per_period={self.impacts_per_period:.3g}, "
                f"max_run_A={self.max_run_A}, max_run_B={self.max_run_B}, "
                f"stuck_fraction={self.stuck_fraction:.3g}, periods_used={self.periods_used}, "
                f"n_impacts={self.n_impacts}, transient_periods={self.transient_periods}, beta={self.beta:.4g}{note})")


def _run_lengths(sides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lengths of the runs of equal consecutive sides (0 = A, 1 = B)."""
    if sides.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    change = np.flatnonzero(np.diff(sides)) + 1
    starts = np.concatenate(([0], change))
    lengths = np.diff(np.concatenate((starts, [sides.size])))
    first = sides[starts]
    return lengths[first == 0], lengths[first == 1]


def _stroboscopic_states(traj: Trajectory, t_start: float, n_periods: int) -> np.ndarray:
    """Normalised state (v1, v2, gap) at the n_periods + 1 period boundaries from t_start."""
    p = traj.params
    tp = 2.0 * math.pi / p.omega
    t = t_start + tp * np.arange(n_periods + 1)
    t[-1] = min(t[-1], traj.t_end)
    st = traj.evaluate(t)
    v_scale = max(np.max(np.abs(st["v1"])), np.max(np.abs(st["v2"])), p.h * p.omega)
    return np.column_stack([st["v1"] / v_scale, st["v2"] / v_scale, st["gap"] / p.h])


def _assess_period(state: np.ndarray, tol: float = PERIODICITY_TOL, floor: float = _ROUNDING_MISMATCH
                   ) -> tuple[int, float]:
    """(period, extra_periods): the smallest converged period p, else 0 with the periods still needed.

    For a candidate p the mismatches m_j = |S_{j+p} - S_j| (max norm) over the window must stay below
    ``tol`` *and* the distance to the periodic orbit they imply must too: with the contraction rate r per
    period estimated from the two halves of the window, that distance is about m_end r / (1 - r) (a slowly
    converging motion has a small mismatch per period but is still far from its orbit). Mismatches at
    rounding level (below ``floor``, see :func:`_rounding_floor`) are accepted as they are. When no period has converged, ``extra_periods`` is the number
    of further periods after which the best candidate should meet the criterion if it keeps contracting at
    rate r (``inf`` when it does not clearly contract, see :func:`_extra_periods`, or its mismatch is still
    above 1e-2: irregular so far).
    """
    n = state.shape[0] - 1
    best = (math.inf, math.inf)       # (end mismatch, extra periods) of the best non-converged candidate
    for period in range(1, min(MAX_DETECTED_PERIOD, n // 3) + 1):
        m = np.max(np.abs(state[period:] - state[:-period]), axis=1)
        half = m.size // 2
        a, b = float(np.max(m[:half])), float(np.max(m[half:]))
        if b <= floor and a <= tol:
            return period, 0.0
        rate = (b / a) ** (1.0 / max(m.size - half, 1)) if a > 0 else 1.0
        if max(a, b) < tol and rate < 1.0 and b * rate / (1.0 - rate) < tol:
            return period, 0.0
        if b < best[0]:
            best = (b, _extra_periods(m, tol) if b < _EXTRAPOLATE_BELOW else math.inf)
    return 0, best[1]


def _rounding_floor(beta: float) -> float:
    """Stroboscopic mismatch of an exactly periodic motion in floating point: the gap h is computed from
    forcing terms of size ~ beta h, so rounding grows with beta (measured ~3e-13 beta in chattering motion)."""
    return _ROUNDING_MISMATCH * max(1.0, beta)


def _extra_periods(m: np.ndarray, tol: float) -> float:
    """Periods until the mismatch sequence m (one per period) falls to tol (1 - r) / 4, if it contracts.

    The contraction must be clear: a least-squares line through log m with slope log r < log 0.9995 and
    residuals below 0.5 (a factor 1.6); otherwise inf (an irregular motion's mismatch does not line up).
    """
    if m.size < 4 or np.any(m <= 0):
        return math.inf
    j = np.arange(m.size)
    y = np.log(m)
    slope, icept = np.polyfit(j, y, 1)
    if slope >= math.log(_MAX_CONTRACTION) or np.std(y - (slope * j + icept)) > 0.5:
        return math.inf
    rate = math.exp(slope)
    return max(math.log(tol * (1.0 - rate) / (4.0 * m[-1])) / slope, 0.0)


def describing_function_from_trajectory(traj: Trajectory, transient_periods: int, periods: int) -> ImpactDF:
    """DF of x1 from an existing trajectory over ``periods`` forcing periods after ``transient_periods``.

    Parameters
    ----------
    traj : Trajectory
        A run whose ``t_end`` covers at least transient_periods + periods forcing periods.
    transient_periods, periods : int
        Forcing periods discarded, then used (>= 1; detecting a period p needs periods >= 3 p).
    """
    transient_periods = int(_checks.nonnegative("transient_periods", transient_periods))
    periods = int(_checks.positive("periods", periods))
    p = traj.params
    w = p.omega
    tp = 2.0 * math.pi / w
    t_a = transient_periods * tp
    if t_a + periods * tp > traj.t_end * (1.0 + 1e-12):
        raise ValueError(f"periods: the trajectory ends at {traj.t_end:g} s, before the window end "
                         f"{t_a + periods * tp:g} s")
    period, _ = _assess_period(_stroboscopic_states(traj, t_a, periods), floor=_rounding_floor(p.beta))
    return _df_over_window(traj, t_a, periods, period)


def _no_impact(traj: Trajectory, t_a: float) -> bool:
    """True when the motion after t_a is free flight throughout (no impact, no stuck phase)."""
    first = np.searchsorted(traj.t0, t_a, side="right") - 1
    return bool(np.all(traj.mode[first:] == 0) and not np.any(traj.impact_mask[first + 1:]))


def _df_over_window(traj: Trajectory, t_a: float, periods: int, period: int) -> ImpactDF:
    """The DF of x1 over ``periods`` forcing periods from t_a, for a motion of the given period (0: none)."""
    p = traj.params
    w = p.omega
    tp = 2.0 * math.pi / w
    if _no_impact(traj, t_a):
        # free flight throughout: x1 is exactly linear in t, its fundamental exactly 0 (whatever the gap does)
        return ImpactDF(N=0j, X1=0j, periodicity=0.0, period=1, impacts_per_period=0.0, max_run_A=0,
                        max_run_B=0, runs_A=np.zeros(0, np.int64), runs_B=np.zeros(0, np.int64),
                        stuck_fraction=0.0, periods_used=periods, n_impacts=0, beta=p.beta,
                        below_wc=bool(p.beta > beta_lower_limit(p.restitution)))
    used = periods if period <= 1 else period * (periods // period)  # period <= periods // 3
    t_b = min(t_a + used * tp, traj.t_end)
    bounds = t_a + tp * np.arange(used + 1)
    bounds[-1] = t_b
    inside = traj.t0[(traj.t0 > t_a) & (traj.t0 < t_b)]
    cuts = np.union1d(bounds, inside)
    starts, ends = cuts[:-1], cuts[1:]
    four = traj.piece_integrals(starts, ends)
    length = t_b - t_a
    # drift: exact for periodic motion plus a constant drift (a least-squares line would bias the fundamental
    # of a periodic x1 by O(1/periods^2)); the mean does not touch the fundamental
    ends_x1 = traj.evaluate(np.array([t_a, t_b]))["x1"]
    slope = (ends_x1[1] - ends_x1[0]) / length
    block = max(period, 1)
    which = np.minimum((0.5 * (starts + ends) - t_a) / (block * tp), used // block - 1).astype(np.int64)
    block_four = np.bincount(which, weights=four.real) + 1j * np.bincount(which, weights=four.imag)
    # int over a block of (t - t_block) e^{-j w t} dt = j (block length) / w (integer periods from t_a)
    drift_four = slope * 1j * block * tp / w * np.exp(-1j * w * t_a)
    block_X = 2.0 / (block * tp) * (block_four - drift_four)
    X1 = complex(np.mean(block_X))
    spread = float(np.max(np.abs(block_X - X1)) / abs(X1)) if X1 != 0 else 0.0
    in_window = (traj.t0 >= t_a) & (traj.t0 < t_b)
    imp = in_window & ((traj.cause == IMPACT_A) | (traj.cause == IMPACT_B))
    sides = (traj.cause[imp] == IMPACT_B).astype(np.int64)
    runs_a, runs_b = _run_lengths(sides)
    seg_end = traj.segment_ends
    stuck = traj.mode != 0
    overlap = np.clip(np.minimum(seg_end, t_b) - np.maximum(traj.t0, t_a), 0.0, None)
    return ImpactDF(N=X1 / p.force, X1=X1, periodicity=spread, period=period,
                    impacts_per_period=sides.size / used,
                    max_run_A=int(runs_a.max(initial=0)), max_run_B=int(runs_b.max(initial=0)),
                    runs_A=runs_a, runs_B=runs_b, stuck_fraction=float(overlap[stuck].sum() / length),
                    periods_used=used, n_impacts=int(sides.size), beta=p.beta,
                    below_wc=bool(p.beta > beta_lower_limit(p.restitution)))


def impact_describing_function(m1: float, m2: float, h: float, restitution: float, force: float, omega: float,
                               *, effects=(), transient_periods: int | None = DEFAULT_TRANSIENT_PERIODS,
                               periods: int = DEFAULT_PERIODS, max_events: int | None = None,
                               chatter_tol: float = DEFAULT_CHATTER_TOL,
                               max_transient_periods: int = DEFAULT_MAX_TRANSIENT_PERIODS,
                               initial=None, attractor=None) -> ImpactDF:
    """N(F, w) = X1 / F (m/N) of the two-mass impact system driven by F cos(w t) on M2, output x1.

    Parameters
    ----------
    m1, m2 : float
        Masses (kg).
    h : float
        Clearance (m).
    restitution : float
        Coefficient of restitution in [0, 1].
    force, omega : float
        Force amplitude (N) and frequency (rad/s).
    effects : sequence, optional
        Optional effects (:mod:`dfloop.impact.effects`); they break the similarity law.
    transient_periods : int or None
        Forcing periods discarded before the window. None: adaptive. Paper's model: the run goes on period
        by period and stops as soon as the period detection has converged (:func:`dfloop.impact._core.
        assess_period` after every period: the stroboscopic state returns to itself after p periods, to
        1e-6 together with the distance to the orbit that its contraction implies, over a window of whole
        cycles of at least ``periods`` periods); the DF is integrated over that window. A motion without a
        clearly contracting candidate after ``CHAOS_TRANSIENT_PERIODS`` + ``periods`` periods is irregular;
        one still contracting is followed up to ``max_transient_periods`` + ``periods``. With effects: from
        ``MIN_TRANSIENT_PERIODS`` on, lengthened until the detection over the window of ``periods`` periods
        has converged (:func:`_assess_period`). The length discarded is returned as ``transient_periods``.
    periods : int
        Forcing periods integrated (a period-p motion uses a multiple of p).
    max_events : int, optional
        Bound on the events of the run (default :func:`dfloop.impact.model.default_max_events` for the
        longest run this call may make).
    chatter_tol : float
        See :func:`dfloop.impact.kernel.simulate`.
    max_transient_periods : int
        Bound of the adaptive transient (forcing periods).
    initial : (x1, v1, gap, u), optional
        Start state (m, m/s) instead of rest with a centred gap (paper's model only); used to look for
        coexisting periodic motions.
    attractor : numpy.ndarray, optional
        ``orbit`` of an earlier adaptive result at the same (F, w) (paper's model, adaptive transient only).
        When the motion comes within 1e-3 (normalised state) of its stroboscopic states, and closer, at
        three consecutive period boundaries it has settled on that motion: the run stops there and returns
        ``settled`` True.

    Returns
    -------
    ImpactDF

    Notes
    -----
    Without effects the motion is simulated in the similarity variables (h = M2 = w = 1, force = beta) and
    scaled back, N = h Xi1 / F, so extreme forces and clearances neither overflow nor lose precision as
    long as beta = F / (M2 h w^2) itself is a finite number.
    """
    transient = None if transient_periods is None else _checks.integer_at_least("transient_periods",
                                                                                 transient_periods, 0)
    periods = _checks.integer_at_least("periods", periods, 1)
    max_transient = _checks.integer_at_least("max_transient_periods", max_transient_periods, 1)
    run_periods("transient_periods + periods", (max_transient if transient is None else transient) + periods)
    chatter_tol = _checks.positive("chatter_tol", chatter_tol)
    effects = effects_tuple(effects)
    p = ImpactParameters(m1, m2, h, restitution, force, omega)
    longest = (max_transient if transient is None else transient) + periods
    if max_events is None:
        max_events = default_max_events(p.restitution, chatter_tol, longest)
    max_events = _checks.integer_at_least("max_events", max_events, 1)
    if effects and (initial is not None or attractor is not None):
        raise ValueError("initial, attractor: supported by the paper's model only (no effects)")
    if transient is None and not effects:
        return _adaptive_point(p, chatter_tol, initial, periods, max_transient, max_events, attractor)
    if attractor is not None:
        raise ValueError("attractor: supported with the adaptive transient only (transient_periods=None)")
    if effects:       # effects break the similarity law: the run is in SI units
        run = forced_motion(p, effects, chatter_tol)
        return _describe(p, partial(run.window, max_events=max_events), transient, periods, max_transient)
    scaled, initial = _similarity(p, initial)
    run = forced_motion(scaled, (), chatter_tol, initial)
    r = _describe(scaled, partial(run.window, max_events=max_events), transient, periods, max_transient)
    return replace(r, N=p.h * r.X1 / p.force, X1=p.h * r.X1)


def _similarity(p: ImpactParameters, initial):
    """The same motion in similarity units (h = M2 = w = 1, force beta) and its scaled start state."""
    log_beta = math.log(p.force) - math.log(p.m2) - math.log(p.h) - 2.0 * math.log(p.omega)
    if log_beta > math.log(1e300):
        raise ValueError(f"force: beta = F/(M2 h w^2) = exp({log_beta:.6g}) overflows (F = {p.force!r} N, "
                         f"h = {p.h!r} m, omega = {p.omega!r} rad/s); the masses then move as one body, "
                         f"N = -1/((M1 + M2) w^2)")
    beta = math.exp(log_beta) if log_beta > -690.0 else 1e-300
    scaled = ImpactParameters.trusted(p.m1 / p.m2, 1.0, 1.0, p.restitution, beta, 1.0)
    if initial is not None:
        x1, v1, gap, u = initial_state(initial, p.h)
        initial = (x1 / p.h, v1 / (p.h * p.omega), gap / p.h, u / (p.h * p.omega))
    return scaled, initial


_SETTLE_TOL = 1e-3            # an attractor is reached when the stroboscopic state is this close to it (and
                              # closer at each of _core._SETTLE_CHECKS consecutive period boundaries)
_FIRST_CAPACITY = 128         # periods recorded before the first growth of the per-period records
_NO_ORBIT = np.zeros((0, 3))
_NO_RUNS = np.zeros(0, np.int64)


def _adaptive_inputs(dim: ImpactParameters, chatter_tol: float, initial, periods: int, max_events: int):
    """(similarity parameters, kernel params, kernel state, control vector) of one adaptive run."""
    p, initial = _similarity(dim, initial)
    kparams, state = kernel_arrays(p, chatter_tol, initial)
    ctl = np.zeros(_core.N_CONTROL)
    ctl[_core.C_TOL], ctl[_core.C_FLOOR] = PERIODICITY_TOL, _rounding_floor(p.beta)
    ctl[_core.C_VSCALE] = max(p.h * p.omega, p.force / (p.m2 * p.omega))
    ctl[_core.C_WINDOW] = periods
    ctl[_core.C_CHAOS], ctl[_core.C_MAXEV] = CHAOS_TRANSIENT_PERIODS + periods, max_events
    ctl[_core.C_MATCH_TOL], ctl[_core.C_DIST] = _SETTLE_TOL, math.inf
    return p, kparams, state, ctl


def _attractor_array(attractor) -> np.ndarray:
    try:
        orbit = _NO_ORBIT if attractor is None else np.ascontiguousarray(attractor, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"attractor must be the (2 p, 3) orbit of an adaptive ImpactDF, got {attractor!r}") from None
    if orbit.ndim != 2 or orbit.shape[1] != 3 or orbit.shape[0] % 2 or orbit.shape[0] > 2 * _core.MAX_PERIOD:
        raise ValueError(f"attractor must be the (2 p, 3) orbit of an adaptive ImpactDF, got shape {orbit.shape}")
    if not np.all(np.isfinite(orbit)):
        raise ValueError("attractor must be finite (the orbit of a periodic ImpactDF), got NaN or inf entries")
    return orbit


def _adaptive_point(dim: ImpactParameters, chatter_tol: float, initial, periods: int, max_transient: int,
                    max_events: int, attractor) -> ImpactDF:
    """Adaptive DF of the paper's model at validated parameters ``dim`` (SI), simulated in similarity units.

    The compiled driver (:func:`dfloop.impact._core.run_periods`) stops as soon as the period detection has
    converged, the motion is irregular, or it has settled on ``attractor``; the DF and the diagnostics come
    from the Fourier integrals and impact records it accumulated per period (no trajectory is stored).
    """
    p, kparams, state, ctl = _adaptive_inputs(dim, chatter_tol, initial, periods, max_events)
    orbit = _attractor_array(attractor)
    k_max = max_transient + periods
    status, k, period, used, X1, spread, n_imp, run_a, run_b, stuck_time, orbit, sides, side_off = \
        _core.adaptive_run(kparams, state, ctl, orbit, k_max, _FIRST_CAPACITY)
    tp = p.period
    if status == _core.EVENT_LIMIT:
        raise EventLimitError(event_limit_message(max_events, k * tp, k_max * tp, tp))
    below_wc = bool(p.beta > beta_lower_limit(p.restitution))
    if status == _core.SETTLED:
        return ImpactDF(N=complex(np.nan, np.nan), X1=complex(np.nan, np.nan), periodicity=np.nan,
                        period=len(attractor) // 2, impacts_per_period=np.nan, max_run_A=0, max_run_B=0,
                        runs_A=_NO_RUNS, runs_B=_NO_RUNS, stuck_fraction=np.nan, periods_used=0, n_impacts=0,
                        beta=p.beta, below_wc=below_wc, transient_periods=k, settled=True)
    runs_a, runs_b = _run_lengths(sides[side_off[k - used]:side_off[k]].astype(np.int64))
    X1 = X1 * dim.h          # similarity units back to metres
    return ImpactDF(N=X1 / dim.force, X1=X1, periodicity=spread, period=period, impacts_per_period=n_imp / used,
                    max_run_A=int(run_a), max_run_B=int(run_b), runs_A=runs_a, runs_B=runs_b,
                    stuck_fraction=stuck_time / (used * tp), periods_used=used, n_impacts=int(n_imp), beta=p.beta,
                    below_wc=below_wc, transient_periods=k - used, orbit=orbit,
                    restarts=int(ctl[_core.C_RESTARTS]))


def _describe(p: ImpactParameters, window, transient: int | None, periods: int, max_transient: int) -> ImpactDF:
    """Fixed or adaptive transient; ``window(t_a, t_b)`` returns the motion covering [t_a, t_b]."""
    tp = p.period
    if transient is not None:
        traj = window(transient * tp, (transient + periods) * tp)
        return replace(describing_function_from_trajectory(traj, transient, periods), transient_periods=transient)
    t_skip = min(MIN_TRANSIENT_PERIODS, max_transient)
    for _ in range(max_transient // periods + 2):     # t_skip grows by >= periods every pass
        traj = window(t_skip * tp, (t_skip + periods) * tp)
        period, extra = _assess_period(_stroboscopic_states(traj, t_skip * tp, periods),
                                       floor=_rounding_floor(p.beta))
        if math.isfinite(extra):
            target = min(t_skip + periods + math.ceil(1.5 * extra), _GROWTH * t_skip + periods)
        elif t_skip < CHAOS_TRANSIENT_PERIODS:
            target = 2 * t_skip + periods
        else:
            target = None
        if period > 0 or t_skip >= max_transient or target is None or _no_impact(traj, t_skip * tp):
            return replace(_df_over_window(traj, t_skip * tp, periods, period), transient_periods=t_skip)
        t_skip = max(min(target, max_transient), t_skip + periods)
    raise AssertionError("unreachable: the adaptive transient grows by at least one window per pass")


@dataclass(frozen=True, repr=False)
class ImpactDFBatch:
    """Arrays of :class:`ImpactDF` fields over a broadcast grid of (force, omega).

    ``failure`` is "" where the run finished and the reason where it did not (with
    ``on_event_limit='record'``: the event bound was reached); there N is NaN and period 0. ``settled`` is
    True where the run stopped on the ``attractor`` it was given (N NaN there: the attractor's applies);
    ``orbit`` holds each point's :attr:`ImpactDF.orbit` (an object array).
    """

    N: np.ndarray
    periodicity: np.ndarray
    period: np.ndarray
    impacts_per_period: np.ndarray
    max_run_A: np.ndarray
    max_run_B: np.ndarray
    stuck_fraction: np.ndarray
    periods_used: np.ndarray
    n_impacts: np.ndarray
    beta: np.ndarray
    below_wc: np.ndarray
    transient_periods: np.ndarray
    failure: np.ndarray
    settled: np.ndarray
    orbit: np.ndarray

    @property
    def regular(self) -> np.ndarray:
        """True where a period was detected."""
        return self.period > 0

    def __repr__(self) -> str:
        failed = int(np.count_nonzero(self.failure != ""))
        note = f", failed={failed}" if failed else ""
        return (f"ImpactDFBatch(shape={self.N.shape}, regular={int(self.regular.sum())}/{self.N.size}, "
                f"max periodicity={float(np.nanmax(self.periodicity, initial=0.0)):.2e}{note})")


_BATCH_FIELDS = {"N": complex, "periodicity": float, "period": np.int64, "impacts_per_period": float,
                 "max_run_A": np.int64, "max_run_B": np.int64, "stuck_fraction": float, "periods_used": np.int64,
                 "n_impacts": np.int64, "beta": float, "below_wc": bool, "transient_periods": np.int64,
                 "settled": bool}
_FAILED = {"N": complex(np.nan, np.nan), "periodicity": np.nan, "period": 0, "impacts_per_period": np.nan,
           "max_run_A": 0, "max_run_B": 0, "stuck_fraction": np.nan, "periods_used": 0, "n_impacts": 0,
           "beta": np.nan, "below_wc": False, "transient_periods": 0, "settled": False}


def impact_describing_function_batch(m1: float, m2: float, h: float, restitution: float, force, omega, *,
                                     effects=(), transient_periods: int | None = DEFAULT_TRANSIENT_PERIODS,
                                     periods: int = DEFAULT_PERIODS, max_events: int | None = None,
                                     chatter_tol: float = DEFAULT_CHATTER_TOL,
                                     max_transient_periods: int = DEFAULT_MAX_TRANSIENT_PERIODS,
                                     initial=None, attractor=None, on_event_limit: str = "raise",
                                     workers: int | None = None, callback=None) -> ImpactDFBatch:
    """:func:`impact_describing_function` over broadcast arrays ``force`` and ``omega`` (N, rad/s).

    Runs in a thread pool of ``workers`` threads (default: the CPU count); the JIT kernel releases the GIL.
    ``on_event_limit``: 'raise' (default) lets an :class:`~dfloop.errors.EventLimitError` through;
    'record' marks that point failed (``failure`` holds the reason) and goes on. ``callback()``, if given,
    is called once per finished point (from the worker threads). ``initial`` is one start state for all
    points or a callable ``initial(force, omega)`` returning the start state of each point. ``attractor``
    (adaptive transient, paper's model) is None or an object array of the grid's shape holding, per point,
    a known orbit (:attr:`ImpactDF.orbit`) or None (see :func:`impact_describing_function`).
    """
    if on_event_limit not in ("raise", "record"):
        raise ValueError(f"on_event_limit must be 'raise' or 'record', got {on_event_limit!r}")
    f, w = np.broadcast_arrays(_checks.real_array(force, "force"), _checks.real_array(omega, "omega"))
    if callback is not None and not callable(callback):
        raise ValueError(f"callback must be callable (called after each point) or None, got {_checks.show(callback)}")
    if f.size == 0:
        raise ValueError("force, omega: empty grid")
    workers = (os.cpu_count() or 1) if workers is None else _checks.integer_at_least("workers", workers, 1)
    effects = effects_tuple(effects)

    if attractor is not None:
        attractor = np.asarray(attractor, dtype=object)
        if attractor.shape != f.shape:
            raise ValueError(f"attractor must have the grid's shape {f.shape}, got {attractor.shape}")
        attractor = attractor.ravel()
    no_orbit = np.zeros((0, 3))
    if not effects and transient_periods is None:
        return _adaptive_batch(ImpactParameters(m1, m2, h, restitution, 1.0, 1.0), f, w, chatter_tol, initial,
                               attractor, periods, max_transient_periods, max_events, on_event_limit, workers,
                               callback)

    def one(i_fw):
        i, fw = i_fw
        try:
            r = impact_describing_function(m1, m2, h, restitution, fw[0], fw[1], effects=effects,
                                           transient_periods=transient_periods, periods=periods,
                                           max_events=max_events, chatter_tol=chatter_tol,
                                           max_transient_periods=max_transient_periods,
                                           initial=initial(*fw) if callable(initial) else initial,
                                           attractor=None if attractor is None else attractor[i])
            out = ({k: getattr(r, k) for k in _BATCH_FIELDS}, "", r.orbit)
        except EventLimitError as exc:
            if on_event_limit == "raise":
                raise
            out = (_FAILED, f"event limit: {exc}", no_orbit)
        if callback is not None:
            callback()
        return out

    pairs = list(enumerate(zip(f.ravel().tolist(), w.ravel().tolist())))
    if workers == 1 or len(pairs) == 1:
        results = [one(fw) for fw in pairs]
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            results = list(pool.map(one, pairs))
    arrays = {k: np.array([r[0][k] for r in results], dtype=t).reshape(f.shape) for k, t in _BATCH_FIELDS.items()}
    failure = np.array([r[1] for r in results], dtype=str).reshape(f.shape)
    orbit = np.empty(len(results), dtype=object)
    orbit[:] = [r[2] for r in results]
    return ImpactDFBatch(**arrays, failure=failure, orbit=orbit.reshape(f.shape))


_POOLS: dict[int, ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def _pool(workers: int) -> ThreadPoolExecutor:
    """A persistent pool of ``workers`` threads for the compiled batches (threads are not started per call)."""
    with _POOLS_LOCK:
        if workers not in _POOLS:
            _POOLS[workers] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="dfloop-impact")
        return _POOLS[workers]


def _adaptive_batch(base: ImpactParameters, f: np.ndarray, w: np.ndarray, chatter_tol, initial, attractor,
                    periods, max_transient_periods, max_events, on_event_limit: str, workers: int,
                    callback) -> ImpactDFBatch:
    """The adaptive DF of the paper's model over a grid: validated once, every point in compiled code
    (:func:`dfloop.impact._core.adaptive_batch`), the points dealt out to ``workers`` threads."""
    for name, a in (("force", f), ("omega", w)):
        ok = np.isfinite(a) & (a > 0)
        if not np.all(ok):
            raise ValueError(f"{name} must be finite and > 0, got {a[~ok].ravel()[0]!r}")
    periods = _checks.integer_at_least("periods", periods, 1)
    max_transient = _checks.integer_at_least("max_transient_periods", max_transient_periods, 1)
    run_periods("max_transient_periods + periods", max_transient + periods)
    chatter_tol = _checks.positive("chatter_tol", chatter_tol)
    max_events = (default_max_events(base.restitution, chatter_tol, max_transient + periods) if max_events is None
                  else int(_checks.integer_at_least("max_events", max_events, 1)))
    fs, ws = f.ravel().tolist(), w.ravel().tolist()
    n = len(fs)
    kparams, states, ctls = np.empty((n, 7)), np.empty((n, 8)), np.empty((n, _core.N_CONTROL))
    orbits = np.zeros((n, 2 * _core.MAX_PERIOD, 3))
    orbit_rows = np.zeros(n, dtype=np.int64)
    scaled = []
    for i, (fi, wi) in enumerate(zip(fs, ws)):
        dim = ImpactParameters.trusted(base.m1, base.m2, base.h, base.restitution, fi, wi)
        p, kparams[i], states[i], ctls[i] = _adaptive_inputs(dim, chatter_tol, initial(fi, wi) if callable(initial)
                                                             else initial, periods, max_events)
        scaled.append(p)
        if attractor is not None and attractor[i] is not None:
            a = _attractor_array(attractor[i])
            orbits[i, :a.shape[0]], orbit_rows[i] = a, a.shape[0]
    k_max = max_transient + periods

    def run(idx):
        out = _core.adaptive_batch(kparams[idx], states[idx], ctls[idx], orbits[idx], orbit_rows[idx], k_max,
                                   _FIRST_CAPACITY)
        if callback is not None:
            for _ in range(idx.size):
                callback()
        return idx, out

    parts = [np.arange(j, n, workers) for j in range(min(workers, n))]
    fres, ires, out_orbits = np.empty((n, 4)), np.empty((n, 8), dtype=np.int64), np.empty((n, 2 * _core.MAX_PERIOD, 3))
    for idx, (fr, ir, orb) in (map(run, parts) if len(parts) == 1 else _pool(workers).map(run, parts)):
        fres[idx], ires[idx], out_orbits[idx] = fr, ir, orb
    status = ires[:, _core.R_STATUS]
    failed = status == _core.EVENT_LIMIT
    failure = np.full(n, "", dtype=object)
    for i in np.flatnonzero(failed):
        tp = scaled[i].period
        msg = event_limit_message(max_events, ires[i, _core.R_K] * tp, k_max * tp, tp)
        if on_event_limit == "raise":
            raise EventLimitError(msg)
        failure[i] = f"event limit: {msg}"
    settled = status == _core.SETTLED
    bad = failed | settled
    used = np.maximum(ires[:, _core.R_USED], 1)
    beta = np.array([p.force for p in scaled])
    # N = h X1 / F part by part, as the single-point call rounds it
    N = np.empty(n, dtype=complex)
    N.real, N.imag = fres[:, _core.R_X1_RE] * base.h / f.ravel(), fres[:, _core.R_X1_IM] * base.h / f.ravel()
    period = np.where(settled, orbit_rows // 2, np.where(failed, 0, ires[:, _core.R_PERIOD]))
    arrays = {"N": np.where(bad, complex(np.nan, np.nan), N),
              "periodicity": np.where(bad, np.nan, fres[:, _core.R_SPREAD]), "period": period,
              "impacts_per_period": np.where(bad, np.nan, ires[:, _core.R_IMPACTS] / used),
              "max_run_A": np.where(bad, 0, ires[:, _core.R_RUN_A]), "max_run_B": np.where(bad, 0, ires[:, _core.R_RUN_B]),
              "stuck_fraction": np.where(bad, np.nan, fres[:, _core.R_STUCK] / (used * 2.0 * math.pi)),
              "periods_used": np.where(bad, 0, ires[:, _core.R_USED]), "n_impacts": np.where(bad, 0, ires[:, _core.R_IMPACTS]),
              "beta": np.where(failed, np.nan, beta), "below_wc": ~failed & (beta > beta_lower_limit(base.restitution)),
              "transient_periods": np.where(bad, np.where(settled, ires[:, _core.R_K], 0),
                                            ires[:, _core.R_K] - ires[:, _core.R_USED]),
              "settled": settled}
    orbit = np.empty(n, dtype=object)
    orbit[:] = [out_orbits[i, :ires[i, _core.R_ORBIT]].copy() for i in range(n)]
    shape = f.shape
    return ImpactDFBatch(**{k: np.asarray(v, dtype=_BATCH_FIELDS[k]).reshape(shape) for k, v in arrays.items()},
                         failure=failure.astype(str).reshape(shape), orbit=orbit.reshape(shape))
