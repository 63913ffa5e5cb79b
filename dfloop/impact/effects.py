"""Optional physical effects for the impact system, simulated by the exact linear-mode engine.

The paper's model is clearance + restitution impacts (+ the sticking that comes with them). The effects below
add physics that the paper leaves out. Each adds a time or a length scale, so **none of them keeps the
similarity law** (``keeps_similarity`` is False): with any of them N(F, w) is a genuinely two-dimensional table.

- :class:`ViscousDamping` ``c`` (N s/m, >= 0): force -c v1 on M1 (to ground).
- :class:`LoadSpring` ``k`` (N/m, >= 0): force -k x1 on M1 (to ground, relaxed at x1 = 0).
- :class:`CoulombFriction` ``force`` (N, > 0) on ``mass`` "m1" or "m2": -force sign(v) while slipping; the mass
  sticks to the ground while the other forces on it stay within ``force`` (stick-slip).

Engine (:mod:`dfloop.impact._engine`): in every mode (free / stuck together on side A or B) x (friction mass
slipping +, slipping -, stuck) the motion is a linear ODE z' = A z of z = [x1, v1, d, u, cos wt, sin wt, 1]
(d: gap from the wall of the last impact, u = v2 - v1), solved exactly by the matrix exponential. Events
(impacts, separation, stop, stick-slip) are roots of linear functionals r.z(s), bracketed on steps of 1/16 of
the fastest time scale and refined to rounding level on the Taylor series of exp(A s) over the step. The whole
event loop (step scan, root refinement, impact law, chatter cut, mode selection, records) is compiled
(:mod:`dfloop.impact._effects_core`); its cost per impact is measured against the closed-form JIT kernel of the
paper's model in ``benchmarks/bench_effects.py``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _checks
from . import _engine
from ._effects_core import GROUND_EVENT  # noqa: F401  (segment cause of stick-slip events, re-exported)
from ._effects_core import D, FREE, STUCK_B, U, V1, X1
from .model import ForcedRun, ImpactEvents, initial_state

__all__ = ["ViscousDamping", "LoadSpring", "CoulombFriction", "EffectsTrajectory", "EffectsRun"]

C, S = 4, 5   # forcing oscillator slots of the open-loop state


@dataclass(frozen=True)
class ViscousDamping:
    """Viscous damper of coefficient ``c`` (N s/m, >= 0; 0 is the undamped model) from M1 to ground.

    Breaks the similarity law: at fixed beta the motion depends on c / (M2 w), a power 1 of 1/w
    (``frequency_power``).
    """

    c: float
    keeps_similarity = False
    frequency_power = 1
    acts_on = "m1"

    def __post_init__(self):
        object.__setattr__(self, "c", _checks.nonnegative("c", self.c))


@dataclass(frozen=True)
class LoadSpring:
    """Linear spring of stiffness ``k`` (N/m, >= 0; 0 is no spring) from M1 to ground, relaxed at x1 = 0.

    Breaks the similarity law: at fixed beta the motion depends on k / (M2 w^2) (``frequency_power`` 2).
    """

    k: float
    keeps_similarity = False
    frequency_power = 2
    acts_on = "m1"

    def __post_init__(self):
        object.__setattr__(self, "k", _checks.nonnegative("k", self.k))


@dataclass(frozen=True)
class CoulombFriction:
    """Coulomb friction of level ``force`` (N) between ``mass`` ("m1" or "m2") and ground.

    Static and kinetic levels are equal. Breaks the similarity law: at fixed beta the motion depends on
    force / (M2 h w^2) (``frequency_power`` 2).
    """

    force: float
    mass: str = "m2"
    keeps_similarity = False
    frequency_power = 2

    def __post_init__(self):
        object.__setattr__(self, "force", _checks.positive("force", self.force))
        if self.mass not in ("m1", "m2"):
            raise ValueError(f"mass must be 'm1' or 'm2', got {self.mass!r}")

    @property
    def acts_on(self) -> str:
        """The mass the effect acts on ("m1" or "m2")."""
        return self.mass



def effect_terms(effects) -> tuple:
    """Validated effect set as (damping c, stiffness k, friction (force, mass index) or None)."""
    for e in effects:
        if not isinstance(e, (ViscousDamping, LoadSpring, CoulombFriction)):
            raise ValueError(f"effects: unknown effect {e!r} (use ViscousDamping, LoadSpring, CoulombFriction)")
    frictions = [e for e in effects if isinstance(e, CoulombFriction)]
    if len(frictions) > 1:
        raise ValueError("effects: at most one CoulombFriction is supported")
    c = sum(e.c for e in effects if isinstance(e, ViscousDamping))
    k = sum(e.k for e in effects if isinstance(e, LoadSpring))
    friction = (frictions[0].force, 0 if frictions[0].mass == "m1" else 1) if frictions else None
    return float(c), float(k), friction


class EffectsTrajectory(ImpactEvents):
    """Trajectory of the engine with effects; same interface as :class:`dfloop.impact.kernel.Trajectory`.

    Segment k starts at ``t0[k]`` (s) in contact ``mode[k]`` (0 free, 1/2 stuck on side A/B) with the friction
    mass's ground mode ``ground[k]`` (0 grounded or no friction, +1/-1 slipping) and ``cause[k]`` (0 start, 1/2
    impact on side A/B, 3 separation, 4 stick-slip event). ``pre``/``post``: (v1, v2) before/after the event
    (m/s). A run with ``record_from`` > 0 starts its records at the segment running at that time: it can be
    evaluated on [t0[0], t_end] only.
    """

    def __init__(self, params, effects, run: _engine.EngineRun):
        self.params, self.effects, self._run = params, effects, run
        self.t_end = run.t_end
        self.t0 = run.t0
        self.mode = run.contact
        self.ground = np.where(run.slot % 3 == 0, 0, np.where(run.slot % 3 == 1, 1, -1))
        self.cause = run.cause
        self.pre = run.vel[:, :2]
        self.post = run.vel[:, 2:]
        self.step = run.system.dt

    @property
    def n_events(self) -> int:
        """Events simulated (recorded or not)."""
        return self._run.n_events

    @property
    def phase0(self) -> np.ndarray:
        """Forcing phase w t0 mod 2 pi at every segment start."""
        z0 = self._run.z0
        return np.arctan2(z0[:, S], z0[:, C]) % (2.0 * math.pi)

    def _segment_velocities(self):
        return self.pre[:, 0], self.pre[:, 1], self.post[:, 0], self.post[:, 1]

    @property
    def segment_ends(self) -> np.ndarray:
        """End time of every segment (s)."""
        return np.append(self.t0[1:], self.t_end)

    @property
    def stuck_intervals(self) -> np.ndarray:
        """(n, 3) array of [start, end, side] of the phases stuck together (side 0 = A, 1 = B)."""
        ends = self.segment_ends
        m = self.mode != FREE
        return np.column_stack([self.t0[m], ends[m], (self.mode[m] == STUCK_B).astype(float)])

    def evaluate(self, t) -> dict:
        """x1, v1, x2, v2 (m, m/s) and the gap at times ``t`` (s, within [t0[0], t_end])."""
        shape = np.shape(t)
        z = self._run.states(t)
        gap = z[:, D]
        out = {"x1": z[:, X1], "v1": z[:, V1], "x2": z[:, X1] + gap, "v2": z[:, V1] + z[:, U], "gap": gap}
        return {k: v.reshape(shape) for k, v in out.items()}

    def piece_integrals(self, starts, ends) -> np.ndarray:
        """Exact integrals of x1(t) e^{-j w t} dt over pieces inside segments (Van Loan block exponential)."""
        return self._run.fourier_integrals(starts, ends, self.params.omega, X1)

    def __repr__(self) -> str:
        p = self.params
        return (f"EffectsTrajectory(m1={p.m1:g}, m2={p.m2:g}, h={p.h:g}, eps={p.restitution:g}, F={p.force:g}, "
                f"omega={p.omega:g}, effects={self.effects}, t_end={self.t_end:g}, segments={self.t0.size}, "
                f"impacts={self.n_impacts})")


def open_loop_system(p, effects) -> _engine.LinearModeSystem:
    """The engine's modes for the forced two-mass system: z = [x1, v1, d, u, cos wt, sin wt, 1]."""
    c, k, friction = effect_terms(effects)
    n = 7
    force2 = np.zeros(n)
    force2[C] = p.force
    osc = np.zeros((2, n))
    osc[0, S], osc[1, C] = -p.omega, p.omega
    return _engine.LinearModeSystem(p.m1, p.m2, p.h, p.restitution, force2, osc, damping=c, stiffness=k,
                                    friction=friction, extra_scales=(2.0 * math.pi / p.omega,))


class EffectsRun(ForcedRun):
    """A continuable forced motion on the linear-mode engine (any effects, or none): the :class:`ForcedRun`
    protocol. ``advance(t)`` moves the motion on to time t (s), ``forget()`` drops the stored segments,
    ``trajectory()`` is the motion since the last forget; every period is simulated once.

    Parameters
    ----------
    params : ImpactParameters
    effects : tuple
        Effect objects of this module (empty: the paper's model on the general engine).
    chatter_tol : float
        Relative post-impact speed (of max(h w, F/(M2 w))) below which a converging chatter sticks.
    initial : (x1, v1, gap, u), optional
        Free-flight state at t = 0 (m, m/s); default rest with a centred gap.
    """

    def __init__(self, params, effects, chatter_tol: float, initial=None):
        self.params, self.effects = params, tuple(effects)
        self._system = open_loop_system(params, self.effects)
        self._v_stick = chatter_tol * max(params.h * params.omega, params.force / (params.m2 * params.omega))
        x1, v1, gap, u = (0.0, 0.0, 0.5 * params.h, 0.0) if initial is None else initial_state(initial, params.h)
        self._z = np.array([x1, v1, gap, u, 1.0, 0.0, 1.0])   # at t = 0: cos wt = 1, sin wt = 0
        self._ref = 0
        self._run = None            # segments since the last forget
        self.n_events = 0           # events since t = 0
        self.t = 0.0                # time reached (s)

    def advance(self, t_end: float, max_events: int, keep: bool = True) -> None:
        """Run on to ``t_end`` (s); raises EventLimitError when the events since t = 0 would exceed max_events.

        ``keep=False`` stores only the segment running at ``t_end`` (memory bounded for long transients).
        """
        if t_end <= self.t:
            return
        p = self.params
        periods = (t_end - self.t) / p.period if keep else 0.0
        run = _engine.run(self._system, self._z, t_end, self._v_stick, max(int(max_events) - self.n_events, 0),
                          ref=self._ref, t_start=self.t, record_from=self.t if keep else t_end,
                          capacity=int(4 * periods) + 16,
                          what=f"forced motion F = {p.force:g} N, w = {p.omega:g} rad/s")
        self.n_events += run.n_events
        self._z, self._ref, self.t = run.z_end, run.ref_end, float(t_end)
        self._run = run if (self._run is None or not keep) else self._run.then(run)

    def forget(self) -> None:
        """Drop the stored segments; the next :meth:`advance` records from the time reached."""
        self._run = None

    def trajectory(self) -> EffectsTrajectory:
        """The motion since the last :meth:`forget` (or since t = 0)."""
        if self._run is None:
            raise ValueError("no motion stored since the last forget(): advance first")
        return EffectsTrajectory(self.params, self.effects, self._run)
