"""Limit frequencies of the paper's dynamic backlash (eqs. 10, 11, 12) and their measured counterparts.

Eq. (5), the upper limit of the static (geometric) backlash model, belongs to that element:
:meth:`dfloop.describing.composition.MassBacklash.limit_frequency`.

With the similarity variable beta = F / (M2 h w^2) the dynamic-backlash limits are fixed values of beta:
eq. (11) w_L is beta = 1/4 (exact no-impact limit from rest with a centred gap), eq. (12) w_J is
beta ~ 1, eq. (10) w_c is beta = 1 / (2 (1 - eps)^(5/2)). The ``measured_*`` functions read the same
limits off the model itself (the exact impact simulation, through a :class:`DynamicBacklash` table).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import in_closed_interval, positive, real_array
from ..errors import DfloopError

__all__ = ["lower_limit_frequency", "no_impact_frequency", "jump_frequency",
           "beta_of", "omega_of", "beta_lower_limit", "BETA_NO_IMPACT", "BETA_JUMP",
           "x2_peak_excursion", "MeasuredLimits", "measured_limits"]

BETA_NO_IMPACT = 0.25   # eq. (11)
BETA_JUMP = 1.0         # eq. (12), approximate


def _arr(name, value):
    a = real_array(value, name)
    bad = ~np.isfinite(a) | (a <= 0)
    if np.any(bad):
        raise DfloopError(f"{name} must be finite and > 0, got {float(a[bad].ravel()[0])!r}")
    return a


def beta_of(F, omega, m2: float, h: float):
    """Similarity variable beta = F / (M2 h w^2) (dimensionless); F in N, omega in rad/s."""
    m2, h = positive("m2", m2), positive("h", h)
    return _arr("F", F) / (m2 * h * _arr("omega", omega) ** 2)


def omega_of(beta, F, m2: float, h: float):
    """Frequency (rad/s) at which force amplitude F gives similarity variable beta."""
    m2, h = positive("m2", m2), positive("h", h)
    return np.sqrt(_arr("F", F) / (m2 * h * _arr("beta", beta)))


def beta_lower_limit(restitution: float) -> float:
    """beta at the paper's lower-limit frequency (eq. 10): 1 / (2 (1 - eps)^(5/2)); inf for eps = 1."""
    eps = in_closed_interval("restitution", restitution, 0.0, 1.0)
    return math.inf if eps == 1.0 else 0.5 / (1.0 - eps) ** 2.5


def lower_limit_frequency(F, m2: float, h: float, restitution: float):
    """Eq. (10): w_c ~ [(2 F / (M2 h))^2 (1 - eps)^5]^(1/4), below which the motion is irregular."""
    m2, h = positive("m2", m2), positive("h", h)
    eps = in_closed_interval("restitution", restitution, 0.0, 1.0)
    # written as sqrt(F) sqrt(2/(M2 h)) (1 - eps)^(5/4): no intermediate square of F to overflow
    return np.sqrt(_arr("F", F)) * math.sqrt(2.0 / (m2 * h)) * (1.0 - eps) ** 1.25


def no_impact_frequency(F, m2: float, h: float):
    """Eq. (11): w_L = 2 sqrt(F / (h M2)); for w >= w_L the masses never collide (N = 0)."""
    m2, h = positive("m2", m2), positive("h", h)
    return 2.0 * np.sqrt(_arr("F", F)) / math.sqrt(h * m2)


def jump_frequency(F, m2: float, h: float):
    """Eq. (12): w_J ~ sqrt(F / (h M2)), the approximate frequency of the jump phenomenon."""
    m2, h = positive("m2", m2), positive("h", h)
    return np.sqrt(_arr("F", F)) / math.sqrt(h * m2)


def x2_peak_excursion(F, omega, m2: float):
    """Peak of x2(t) - x2(0) for M2 driven by F cos(w t) from rest, without impacts: 2 F / (M2 w^2) (m)."""
    m2 = positive("m2", m2)
    return 2 * _arr("F", F) / (m2 * _arr("omega", omega) ** 2)


@dataclass(frozen=True)
class MeasuredLimits:
    """Limits read off the simulated model, as beta values (convert with :meth:`omegas`).

    beta_no_impact : smallest beta at which a motion from rest collides (eq. 11 says exactly 1/4).
    beta_regular_end : end of the regular band that starts at the no-impact limit (the paper's w_J,
        eq. 12, beta ~ 1: below it in beta, one alternate collision on each side).
    beta_irregular_end : largest beta with irregular motion (the observed lower limit of the model's
        regular range, the paper's w_c of eq. 10); nan if no irregular motion up to the table's end.
    beta_jumps, jump_sizes : jumps in N between two regular impacting regimes (N != 0 on both sides), located
        by bisection, and |dD|.
    """

    beta_no_impact: float
    beta_regular_end: float
    beta_irregular_end: float
    beta_jumps: np.ndarray
    jump_sizes: np.ndarray

    def omegas(self, F, m2: float, h: float) -> dict:
        """The same limits as frequencies (rad/s) for force amplitude F (N)."""
        conv = lambda b: float(omega_of(b, F, m2, h)) if np.isfinite(b) else math.nan
        return {"omega_L": conv(self.beta_no_impact), "omega_J": conv(self.beta_regular_end),
                "omega_c": conv(self.beta_irregular_end)}

    def __repr__(self) -> str:
        return (f"MeasuredLimits(beta_no_impact={self.beta_no_impact:.7g}, beta_regular_end="
                f"{self.beta_regular_end:.4g}, beta_irregular_end={self.beta_irregular_end:.4g}, "
                f"jumps={np.round(self.beta_jumps, 4).tolist()})")


def measured_limits(backlash, beta_max: float = 100.0, rel_tol: float = 1e-9) -> MeasuredLimits:
    """Measure the limit betas of a similarity-law :class:`DynamicBacklash` from its kernel and table.

    The no-impact limit is bisected on whether a simulation from rest collides within its first two
    forcing periods (to relative width ``rel_tol``); the other limits come from the table over
    1/4 < beta <= ``beta_max`` (built on demand, or read from the cache).
    """
    beta_max = positive("beta_max", beta_max)
    rel_tol = positive("rel_tol", rel_tol)
    lo, hi = 0.05, 1.0
    if backlash.sampler.collides(np.array([lo]))[0] or not backlash.sampler.collides(np.array([hi]))[0]:
        raise RuntimeError("no-impact limit not bracketed in beta in [0.05, 1]")
    for _ in range(200):
        if hi - lo <= rel_tol * hi:
            break
        mid = 0.5 * (lo + hi)
        if backlash.sampler.collides(np.array([mid]))[0]:
            hi = mid
        else:
            lo = mid
    else:
        raise RuntimeError("bisection bound of 200 steps reached")
    table = backlash.similarity_table(beta_max)
    beta = np.exp(table.x)
    jump = table.jumps()
    # impacting periodic motion: regular with N != 0 (just above beta = 1/4 the motion from rest may graze and
    # settle into free flight, N = 0 exactly, or wander irregularly: neither starts the regular band)
    impacting = table.regular & (table.value != 0)
    start = int(np.argmax(impacting))
    breaks = np.flatnonzero(jump[start:]) + start
    beta_regular_end = float(beta[breaks[0]]) if breaks.size else float(beta[-1])
    irregular = np.flatnonzero(~table.regular)
    beta_irregular_end = float(beta[irregular[-1]]) if irregular.size else math.nan
    sharp = np.flatnonzero(jump & impacting[:-1] & impacting[1:])
    sizes = np.abs(table.value[sharp + 1] - table.value[sharp])
    return MeasuredLimits(0.5 * (lo + hi), beta_regular_end, beta_irregular_end,
                          np.sqrt(beta[sharp] * beta[sharp + 1]), sizes)
