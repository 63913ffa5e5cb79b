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
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .. import _checks
from ._core import IMPACT_A, IMPACT_B
from .kernel import DEFAULT_CHATTER_TOL, DEFAULT_MAX_EVENTS, Trajectory, simulate
from .limits import lower_limit_frequency

__all__ = ["ImpactDF", "ImpactDFBatch", "describing_function_from_trajectory", "impact_describing_function",
           "impact_describing_function_batch"]

DEFAULT_TRANSIENT_PERIODS = 200
DEFAULT_PERIODS = 40
MAX_DETECTED_PERIOD = 12
PERIODICITY_TOL = 1e-6  # relative mismatch of the stroboscopic state that still counts as periodic


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

    @property
    def regular(self) -> bool:
        """True when the steady motion was periodic (N is then a proper DF value)."""
        return self.period > 0

    def __repr__(self) -> str:
        note = "" if self.regular else ", irregular: N is an average over the window"
        note += ", below w_c of eq. (10)" if self.below_wc else ""
        return (f"ImpactDF(N={self.N:.6g}, |N|={abs(self.N):.4g}, period={self.period}, "
                f"periodicity={self.periodicity:.2e}, impacts_per_period={self.impacts_per_period:.3g}, "
                f"max_run_A={self.max_run_A}, max_run_B={self.max_run_B}, "
                f"stuck_fraction={self.stuck_fraction:.3g}, periods_used={self.periods_used}, "
                f"n_impacts={self.n_impacts}, beta={self.beta:.4g}{note})")


def _run_lengths(sides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lengths of the runs of equal consecutive sides (0 = A, 1 = B)."""
    if sides.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    change = np.flatnonzero(np.diff(sides)) + 1
    starts = np.concatenate(([0], change))
    lengths = np.diff(np.concatenate((starts, [sides.size])))
    first = sides[starts]
    return lengths[first == 0], lengths[first == 1]


def _detect_period(traj: Trajectory, t_start: float, n_periods: int) -> int:
    """Smallest p such that the state at period boundaries repeats after p periods (0 if none)."""
    p = traj.params
    tp = 2.0 * math.pi / p.omega
    t = t_start + tp * np.arange(n_periods + 1)
    t[-1] = min(t[-1], traj.t_end)
    st = traj.evaluate(t)
    v_scale = max(np.max(np.abs(st["v1"])), np.max(np.abs(st["v2"])), p.h * p.omega)
    state = np.column_stack([st["v1"] / v_scale, st["v2"] / v_scale, st["gap"] / p.h])
    for period in range(1, min(MAX_DETECTED_PERIOD, n_periods // 3) + 1):
        if np.max(np.abs(state[period:] - state[:-period])) < PERIODICITY_TOL:
            return period
    return 0


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
    period = _detect_period(traj, t_a, periods)
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
                    below_wc=bool(w < lower_limit_frequency(p.force, p.m2, p.h, p.restitution)))


def impact_describing_function(m1: float, m2: float, h: float, restitution: float, force: float, omega: float,
                               *, effects=(), transient_periods: int = DEFAULT_TRANSIENT_PERIODS,
                               periods: int = DEFAULT_PERIODS, max_events: int = DEFAULT_MAX_EVENTS,
                               chatter_tol: float = DEFAULT_CHATTER_TOL) -> ImpactDF:
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
    transient_periods, periods : int
        Forcing periods discarded, then integrated (a period-p motion uses a multiple of p).
    max_events, chatter_tol
        Passed to :func:`dfloop.impact.kernel.simulate`.

    Returns
    -------
    ImpactDF
    """
    transient_periods = int(_checks.nonnegative("transient_periods", transient_periods))
    periods = int(_checks.positive("periods", periods))
    omega_checked = _checks.positive("omega", omega)
    t_end = (transient_periods + periods) * 2.0 * math.pi / omega_checked
    traj = simulate(m1, m2, h, restitution, force, omega, t_end, effects=effects, max_events=max_events,
                    chatter_tol=chatter_tol)
    return describing_function_from_trajectory(traj, transient_periods, periods)


@dataclass(frozen=True, repr=False)
class ImpactDFBatch:
    """Arrays of :class:`ImpactDF` fields over a broadcast grid of (force, omega)."""

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

    @property
    def regular(self) -> np.ndarray:
        """True where a period was detected."""
        return self.period > 0

    def __repr__(self) -> str:
        return (f"ImpactDFBatch(shape={self.N.shape}, regular={int(self.regular.sum())}/{self.N.size}, "
                f"max periodicity={float(np.max(self.periodicity, initial=0.0)):.2e})")


def impact_describing_function_batch(m1: float, m2: float, h: float, restitution: float, force, omega, *,
                                     effects=(), transient_periods: int = DEFAULT_TRANSIENT_PERIODS,
                                     periods: int = DEFAULT_PERIODS, max_events: int = DEFAULT_MAX_EVENTS,
                                     chatter_tol: float = DEFAULT_CHATTER_TOL,
                                     workers: int | None = None) -> ImpactDFBatch:
    """:func:`impact_describing_function` over broadcast arrays ``force`` and ``omega`` (N, rad/s).

    Runs in a thread pool of ``workers`` threads (default: the CPU count); the JIT kernel releases the GIL.
    """
    f, w = np.broadcast_arrays(np.asarray(force, dtype=float), np.asarray(omega, dtype=float))
    if f.size == 0:
        raise ValueError("force, omega: empty grid")
    workers = int(workers or os.cpu_count() or 1)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")

    def one(fw):
        return impact_describing_function(m1, m2, h, restitution, fw[0], fw[1], effects=effects,
                                          transient_periods=transient_periods, periods=periods,
                                          max_events=max_events, chatter_tol=chatter_tol)

    pairs = list(zip(f.ravel().tolist(), w.ravel().tolist()))
    if workers == 1:
        results = [one(fw) for fw in pairs]
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            results = list(pool.map(one, pairs))

    def field_array(name, dtype):
        return np.array([getattr(r, name) for r in results], dtype=dtype).reshape(f.shape)

    return ImpactDFBatch(N=field_array("N", complex), periodicity=field_array("periodicity", float),
                         period=field_array("period", np.int64),
                         impacts_per_period=field_array("impacts_per_period", float),
                         max_run_A=field_array("max_run_A", np.int64), max_run_B=field_array("max_run_B", np.int64),
                         stuck_fraction=field_array("stuck_fraction", float),
                         periods_used=field_array("periods_used", np.int64),
                         n_impacts=field_array("n_impacts", np.int64), beta=field_array("beta", float),
                         below_wc=field_array("below_wc", bool))
