"""The two-mass clearance system's parameters, event and run bounds, run-setting checks, impact bookkeeping and
the protocol of a forced run (no simulation).

The lowest module of :mod:`dfloop.impact`: the exact event engine (the linear-mode engine,
:mod:`dfloop.impact.effects`, with its closed-form fast path for the paper's model, :mod:`dfloop.impact.kernel`)
and the DF extraction (:mod:`dfloop.impact.extract`) build on it; it imports neither of them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _checks
from ..errors import EventLimitError
from ._core import IMPACT_A, IMPACT_B

__all__ = ["ImpactParameters", "ImpactEvents", "EventLimitError", "default_max_events", "event_limit_message",
           "DEFAULT_MAX_EVENTS", "DEFAULT_CHATTER_TOL", "MAX_RUN_PERIODS", "run_periods", "effects_tuple",
           "initial_state", "ForcedRun"]

DEFAULT_MAX_EVENTS = 5_000_000      # floor of the default event bound
DEFAULT_CHATTER_TOL = 1e-9
MAX_RUN_PERIODS = 10**7  # forcing periods of one run (the kernel steps through each: ~1 microsecond or more)
_FREE_IMPACTS_PER_PERIOD = 64       # impacts per forcing period outside chatter sequences, in the default bound


def default_max_events(restitution: float, chatter_tol: float, periods: float) -> int:
    """Default bound on the number of events of a run of ``periods`` forcing periods.

    A converging chatter (impacts whose relative speed shrinks by eps each time) reaches the cut speed
    ``chatter_tol`` after about ln(chatter_tol) / ln(eps) impacts; a period holds at most two such sequences
    (one per side) plus a few free impacts. The bound is that count per period times ``periods``, and never
    less than ``DEFAULT_MAX_EVENTS``.
    """
    eps = min(max(float(restitution), 1e-3), 1.0 - 1e-3)
    chatter = math.ceil(math.log(chatter_tol) / math.log(eps)) + 2
    per_period = 2 * chatter + _FREE_IMPACTS_PER_PERIOD
    return int(max(DEFAULT_MAX_EVENTS, math.ceil(per_period * max(float(periods), 1.0))))


def event_limit_message(max_events: int, t: float, t_end: float, period: float) -> str:
    """Message of the :class:`EventLimitError` of a forced run stopped at time ``t`` (s) of ``t_end`` (s)."""
    return (f"max_events = {max_events} reached at t = {t:.6g} s (t_end = {t_end:g} s, "
            f"{t / period:.6g} of {t_end / period:.6g} forcing periods): pass a larger max_events "
            f"(e.g. max_events={2 * max_events}) to simulate further")


def run_periods(name: str, periods: float) -> float:
    """``periods`` (forcing periods of one run) if at most ``MAX_RUN_PERIODS``; else a ValueError naming ``name``."""
    if not periods <= MAX_RUN_PERIODS:
        raise ValueError(f"{name} spans {periods:.3g} forcing periods, above the bound of {MAX_RUN_PERIODS:.0e} "
                         "for one run (the kernel steps through every period); shorten the run")
    return periods


def effects_tuple(effects) -> tuple:
    """Validated effects: a sequence of effect objects (each with a ``keeps_similarity`` attribute)."""
    if isinstance(effects, (str, bytes)) or not hasattr(effects, "__iter__"):
        raise ValueError(f"effects must be a sequence of effect objects (dfloop.impact.effects), got {effects!r}")
    effects = tuple(effects)
    for e in effects:
        if not isinstance(getattr(e, "keeps_similarity", None), bool):
            raise ValueError(f"effects: {e!r} is not an effect object (e.g. dfloop.impact.ViscousDamping(c=...)); "
                             f"got effects={effects!r}")
    return effects


def initial_state(initial, h: float) -> tuple[float, float, float, float]:
    """``initial`` (x1, v1, gap, u) in m, m/s as four finite floats with the gap in [0, h]; else a ValueError."""
    try:
        x1, v1, gap, u = (float(v) for v in initial)
    except (TypeError, ValueError):
        raise ValueError(f"initial must be four numbers (x1, v1, gap, u), got {initial!r}") from None
    if not all(math.isfinite(v) for v in (x1, v1, gap, u)):
        raise ValueError(f"initial must be finite, got {initial!r}")
    if not 0.0 <= gap <= h:
        raise ValueError(f"initial gap must lie in [0, h = {h:g}], got {gap!r}")
    return x1, v1, gap, u


@dataclass(frozen=True)
class ImpactParameters:
    """Validated physical parameters (SI units: kg, m, N, rad/s).

    Attributes
    ----------
    m1, m2 : float
        Masses (kg); the force acts on ``m2``, the output is x1.
    h : float
        Total clearance (m).
    restitution : float
        Coefficient of restitution eps in [0, 1].
    force : float
        Force amplitude F (N) of F cos(w t).
    omega : float
        Forcing frequency w (rad/s).
    """

    m1: float
    m2: float
    h: float
    restitution: float
    force: float
    omega: float

    def __post_init__(self):
        for name in ("m1", "m2", "h", "force", "omega"):
            object.__setattr__(self, name, _checks.positive(name, getattr(self, name)))
        object.__setattr__(self, "restitution", _checks.in_closed_interval("restitution",
                                                                           self.restitution, 0.0, 1.0))

    @classmethod
    def trusted(cls, m1: float, m2: float, h: float, restitution: float, force: float,
                omega: float) -> "ImpactParameters":
        """Parameters derived from already validated ones (hot paths): no checks."""
        self = object.__new__(cls)
        for name, v in zip(("m1", "m2", "h", "restitution", "force", "omega"),
                           (m1, m2, h, restitution, force, omega)):
            object.__setattr__(self, name, float(v))
        return self

    @property
    def beta(self) -> float:
        """Similarity parameter F / (M2 h w^2) (dimensionless)."""
        return self.force / (self.m2 * self.h * self.omega ** 2)

    @property
    def period(self) -> float:
        """Forcing period 2 pi / w (s)."""
        return 2.0 * math.pi / self.omega


class ImpactEvents:
    """Impact bookkeeping shared by the kernel's :class:`Trajectory` and the effects engine's trajectory.

    Subclasses hold per-segment ``t0`` (s) and ``cause`` (1/2: the segment starts with an impact on side
    A/B) and implement ``_segment_velocities()`` -> (v1_pre, v2_pre, v1_post, v2_post) per segment (m/s).
    """

    @property
    def impact_mask(self) -> np.ndarray:
        """Boolean mask over segments that start with an impact."""
        return (self.cause == IMPACT_A) | (self.cause == IMPACT_B)

    @property
    def n_impacts(self) -> int:
        """Number of impacts."""
        return int(np.count_nonzero(self.impact_mask))

    @property
    def impacts(self) -> dict:
        """Impact times (s), sides (0 = A, 1 = B), and pre/post velocities v1, v2 (m/s)."""
        m = self.impact_mask
        v1_pre, v2_pre, v1_post, v2_post = self._segment_velocities()
        return {"t": self.t0[m], "side": (self.cause[m] == IMPACT_B).astype(np.int8),
                "v1_pre": v1_pre[m], "v2_pre": v2_pre[m], "v1_post": v1_post[m], "v2_post": v2_post[m]}


class ForcedRun:
    """Protocol of a continuable forced motion (the one interface of the exact event engine's open-loop runs).

    ``advance(t_end, max_events, keep=True)`` moves the motion on to time ``t_end`` (s), raising
    :class:`EventLimitError` when the events since t = 0 would exceed ``max_events``; ``keep=False`` keeps only
    the segment running at ``t_end`` (bounded memory). ``forget()`` drops the stored segments; ``trajectory()``
    is the motion since the last forget (an :class:`ImpactEvents` with ``evaluate`` and ``piece_integrals``).
    Implemented by :class:`dfloop.impact.kernel.KernelRun` (closed-form free flight, the paper's model) and
    :class:`dfloop.impact.effects.EffectsRun` (the linear-mode engine, any effects);
    :func:`dfloop.impact.kernel.forced_motion` chooses.
    """

    params: ImpactParameters
    n_events: int
    t: float

    def advance(self, t_end: float, max_events: int, keep: bool = True) -> None:  # pragma: no cover - protocol
        raise NotImplementedError

    def forget(self) -> None:  # pragma: no cover - protocol
        raise NotImplementedError

    def trajectory(self) -> ImpactEvents:  # pragma: no cover - protocol
        raise NotImplementedError

    def window(self, t_a: float, t_b: float, max_events: int) -> ImpactEvents:
        """The motion over [t_a, t_b] (s): every period up to ``t_a`` simulated once and dropped, then kept.

        Windows must be asked for in increasing time (``t_a`` at or after the time reached).
        """
        self.advance(t_a, max_events, keep=False)
        self.forget()
        self.advance(t_b, max_events)
        return self.trajectory()
