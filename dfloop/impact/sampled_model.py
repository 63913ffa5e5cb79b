"""The two masses as a sampled system: the exact motion over one sample with the force held (zero-order hold).

This is how the dynamic backlash enters python-control (:func:`dfloop.to_control` with ``dt``): impacts are
velocity jumps, which a continuous-time ``nlsys`` cannot carry, but the map from the state at one sample to the
state at the next, under a force held over the sample, is exact on the linear-mode event engine
(:mod:`dfloop.impact._engine`: impacts with restitution, chatter settled into sticking, separation, and the
optional effects).
"""
from __future__ import annotations

import numpy as np

from .. import _checks
from . import _engine
from .effects import effect_terms

__all__ = ["SampledImpactModel"]

_F = 4           # slot of the held force in the engine state [x1, v1, d, u, F, 1]


class SampledImpactModel:
    """Sample-to-sample map of the two-mass clearance system under a held force on M2.

    State s = [x1, v1, gap, u] (m, m/s; gap = x2 - x1 in [0, h], u = v2 - v1); input the force F on M2 (N),
    held over each sample; output x1 (m), the element's output in the loop.

    Parameters
    ----------
    m1, m2, h, restitution : float
        Masses (kg), clearance (m), coefficient of restitution.
    effects : tuple
        Effect objects of :mod:`dfloop.impact.effects`.
    chatter_tol : float
        A chatter is settled into sticking when the relative speed falls below chatter_tol h / dt.
    dt : float
        Sampling period (s).
    max_events : int
        Bound on the events (impacts, separations) within one sample; reaching it raises EventLimitError.
    """

    nstates = 4
    needs_rate = False

    def __init__(self, m1: float, m2: float, h: float, restitution: float, effects: tuple, chatter_tol: float,
                 dt: float, max_events: int = 100_000):
        self.dt = _checks.positive("dt", dt)
        self.h = float(h)
        self.max_events = _checks.integer_at_least("max_events", max_events, 1)
        c, k, friction = effect_terms(effects)
        force2 = np.zeros(6)
        force2[_F] = 1.0
        self.system = _engine.LinearModeSystem(m1, m2, h, restitution, force2, np.zeros((1, 6)), damping=c,
                                               stiffness=k, friction=friction, extra_scales=(self.dt,))
        self.v_stick = float(chatter_tol) * self.h / self.dt

    def initial(self) -> np.ndarray:
        """At rest with the gap centred."""
        return np.array([0.0, 0.0, 0.5 * self.h, 0.0])

    def output(self, s) -> float:
        """x1 (m) at the sample."""
        return float(s[0])

    def step(self, s, force: float) -> np.ndarray:
        """The state one sample later, the force ``force`` (N) held over the sample."""
        x1, v1, gap, u = (float(v) for v in s)
        if not 0.0 <= gap <= self.h:
            raise ValueError(f"s: the gap {gap!r} must lie in [0, h = {self.h}] m")
        ref = 1 if gap > 0.5 * self.h else 0          # measure the gap from the nearer wall (full precision)
        z = np.array([x1, v1, gap - ref * self.h, u, float(force), 1.0])
        run = _engine.run(self.system, z, self.dt, self.v_stick, self.max_events, ref=ref, record_from=self.dt,
                          what=f"sample of {self.dt:g} s under a force of {force:g} N")
        ze = run.z_end
        return np.array([ze[0], ze[1], min(max(ze[2] + run.ref_end * self.h, 0.0), self.h), ze[3]])
