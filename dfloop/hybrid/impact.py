"""The loop of a plant and the two-mass impact element (dynamic backlash) on the exact linear-mode engine.

Loop of the paper's Fig. 1: the element's input is the force on M2, x = -c, its output is x1, and the plant
closes the loop, c = G x1 (state s: s' = A s + B x1, c = C s + D x1; D is allowed: x1 is a state). Between
events the masses, the optional effects and the plant form one linear system of z = [x1, v1, d, u, s, 1] (d: gap,
u = v2 - v1), run by the compiled engine of :mod:`dfloop.impact._engine`: flows by matrix exponential, impacts
(eqs. 8a/8b), chatter cut into sticking and separation located to rounding, no integrator tolerance anywhere.

:class:`ImpactLoop` has the interface of every loop model of :mod:`dfloop.hybrid` (``start``, ``flow`` with the
monodromy, ``states``, ``signals``, ``fourier``, ``field``), so the one shooting routine and the one closed-loop
driver serve it. The state it exposes carries the absolute gap d in [0, h]; the engine's wall of reference (d
measured from the wall of the last impact, to keep a contact at exactly 0) is chosen per flow from d. The
monodromy multiplies the segment exponentials and the saltation matrix of every event (impact law, plastic
settle of a chatter, separation, friction stop/slip): S = J + (f+ - J f-) r^T / (r . f-).
"""
from __future__ import annotations

import math

import numpy as np

from ..describing.time_model import Impact
from ..impact import _effects_core as core
from ..impact import _engine
from ..impact._effects_core import D, IMPACT_A, IMPACT_B, SEPARATION, U, V1, X1
from ..impact.effects import effect_terms
from ..impact.kernel import EventLimitError
from .loop import Flow, HybridError, LoopModel, piecewise_fourier, saltation

__all__ = ["ImpactLoop"]


class ImpactLoop(LoopModel):
    """Exact model of the loop of plant (A, B, C, D) and an :class:`~dfloop.describing.time_model.Impact` element.

    Parameters
    ----------
    A, B, C, D : ndarray, ndarray, ndarray, float
        The plant from x1 (m) to c (N).
    model : Impact
        Masses, clearance, restitution, effects, chatter tolerance.
    force_scale, frequency : float
        Amplitude (N) and frequency (rad/s) of the motion: they set the sticking speed and the step.
    """

    method = ("exact linear-mode impact engine (matrix exponentials, impacts and sticking located to rounding); "
              "monodromy with saltation matrices")
    exact = True
    settle_periods = 200.0   # the masses' state is not set by the predicted sinusoid: settle before shooting

    def __init__(self, A, B, C, D_, model: Impact, force_scale: float, frequency: float):
        self.model = model
        self.plant = (A, B)
        self.nc = nc = A.shape[0]
        n = 5 + nc
        force2 = np.zeros(n)                      # force on M2 = -c = -(C s + D x1)
        force2[X1] = -D_
        force2[4:4 + nc] = -C
        extra = np.zeros((nc, n))
        extra[:, X1] = B
        extra[:, 4:4 + nc] = A
        c, k, friction = effect_terms(model.effects)
        self.system = _engine.LinearModeSystem(model.m1, model.m2, model.h, model.restitution, force2, extra,
                                               damping=c, stiffness=k, friction=friction,
                                               extra_scales=(2.0 * math.pi / frequency,))
        self.v_stick = model.chatter_tol * max(model.h * frequency, force_scale / (model.m2 * frequency))
        self.x_row = force2                       # element input x (N) as a row over z
        self.size = self.n = n

    # ----------------------------------------------------------------------------------------- helpers

    def x(self, z) -> np.ndarray:
        """Element input x = -c (N) for state(s) z (last axis)."""
        return np.asarray(z) @ self.x_row

    def start(self, s0: np.ndarray, x_history=None) -> tuple[np.ndarray, int]:
        """Masses at rest with the gap centred, plant in state s0 (the model's initial state)."""
        z = np.concatenate([[0.0, 0.0, 0.5 * self.model.h, 0.0], s0, [1.0]])
        return z, 0

    def admissible_mode(self, z, mode: int = 0):
        """The contact mode is chosen by the engine from the state itself: (z, 0)."""
        return np.array(z, dtype=float), 0

    def _relative(self, z):
        """The engine's state (d from the nearer wall) and that wall (0: A at d = 0, 1: B at d = h)."""
        zr = np.array(z, dtype=float)
        ref = 0 if zr[D] <= 0.5 * self.model.h else 1
        zr[D] -= ref * self.model.h
        return zr, ref

    def field(self, z, mode: int = 0) -> np.ndarray:
        """Vector field at z in the mode the engine would choose there."""
        zr, ref = self._relative(z)
        try:
            slot = self.system.first_slot(zr, ref, self.v_stick)
        except _engine.EngineError as exc:
            raise HybridError(str(exc)) from None
        return self.system.mats[slot] @ zr

    # -------------------------------------------------------------------------------------------- flow

    def flow(self, z0, mode0: int, t_end: float, *, monodromy: bool = False, max_events: int = 10_000) -> Flow:
        """Flow from z0 over [0, t_end] (s); events located to rounding level.

        Raises
        ------
        HybridError
            More than ``max_events`` events (impacts, separations; raise the bound for long runs), or no
            admissible contact mode.
        """
        zr, ref = self._relative(z0)
        try:
            run = _engine.run(self.system, zr, t_end, self.v_stick, max_events, ref=ref,
                              what="loop flow (max_events)")
        except (EventLimitError, _engine.EngineError) as exc:
            raise HybridError(str(exc)) from None
        z = run.z_end.copy()
        z[D] += run.ref_end * self.model.h
        z0s = run.z0.copy()
        z0s[:, D] += run.ref * self.model.h
        M = self._monodromy(run) if monodromy else None
        events = [(float(run.t0[i]), int(run.cause[i])) for i in range(1, run.t0.size)]
        return Flow(z, 0, M, run.t0.copy(), z0s, np.zeros(run.t0.size, dtype=int), events, run=run)

    def states(self, flow: Flow, t) -> np.ndarray:
        """States z (absolute gap) at times t within the flow's span, one row per time."""
        t = np.clip(np.atleast_1d(np.asarray(t, float)), flow.run.t0[0], flow.run.t_end)
        return flow.run.states(t)

    def signals(self, flow: Flow, t) -> tuple[np.ndarray, np.ndarray]:
        """Element input x (N) and output x1 (m) at times t."""
        z = self.states(flow, t)
        return self.x(z), z[:, X1]

    def fourier(self, flow: Flow, t_end: float, omega: float, harmonics: int) -> np.ndarray:
        """Exact (1/T) int_0^T x(t) e^{-j k w t} dt, k = 1..harmonics, T = t_end (Van Loan per segment)."""
        run = flow.run
        ends = np.append(flow.t0[1:], t_end)
        pieces = ((self.system.mats[s], z0, t0, t1) for t0, z0, s, t1 in zip(flow.t0, flow.z0, run.slot, ends))
        return piecewise_fourier(pieces, t_end, omega, harmonics, self.x_row)

    # -------------------------------------------------------------------------------------- monodromy

    def _reset_matrix(self, run, i: int) -> np.ndarray:
        """Jacobian of the state jump at the event that starts segment i (impact law, chatter settle, stop)."""
        sysm = self.system
        J = np.eye(self.n)
        c = run.cause[i]
        M = sysm.m1 + sysm.m2
        if c in (IMPACT_A, IMPACT_B):
            if run.z0[i, U] == 0.0 and run.vel[i, 0] != run.vel[i, 1]:   # plastic settle of a converged chatter
                J[V1, U] = sysm.m2 / M
                J[U, U] = 0.0
            else:
                J[V1, U] = (1.0 + sysm.eps) * sysm.m2 / M
                J[U, U] = -sysm.eps
        elif c == core.GROUND_EVENT and sysm.friction is not None:
            pre_v = run.vel[i, 0] if sysm.friction[1] == 0 else run.vel[i, 1]
            post_v = run.vel[i, 2] if sysm.friction[1] == 0 else run.vel[i, 3]
            if pre_v != 0.0 and post_v == 0.0:      # the friction mass stopped: its speed is reset to 0
                if run.slot[i] // 3 != 0:
                    J[V1, :], J[U, :] = 0.0, 0.0
                elif sysm.friction[1] == 0:
                    J[U, V1], J[V1, :] = 1.0, 0.0
                else:
                    J[U, :] = 0.0
                    J[U, V1] = -1.0
        return J

    def _segment_end_state(self, run, i: int) -> np.ndarray:
        """State at the end of segment i, before the event (in the segment's own wall reference)."""
        sysm = self.system
        s = run.slot[i]
        tau = np.array([run.t0[i + 1] - run.t0[i]])
        return core.propagate(sysm.mats[s], sysm.exps[s], run.z0[i], tau, sysm.dt)[0]

    def _event_row(self, run, i: int) -> np.ndarray:
        """The constraint row whose zero crossing ended segment i (the event surface's normal)."""
        sysm = self.system
        s, ref = run.slot[i], run.ref[i]
        c = run.cause[i + 1]
        kinds = sysm.kinds[s, :sysm.nrows[s]]
        want = {IMPACT_A: core.HIT_A, IMPACT_B: core.HIT_B, SEPARATION: core.SEPARATE}.get(int(c))
        if want is None:   # ground event: the stop or slip row closest to zero at the segment end
            z_end = self._segment_end_state(run, i)
            vals = np.abs(sysm.rows[s, ref, :sysm.nrows[s]] @ z_end)
            cand = [j for j in range(kinds.size) if kinds[j] in (core.STOP, core.SLIP)]
            j = min(cand, key=lambda jj: vals[jj]) if cand else int(np.argmin(vals))
        else:
            j = int(np.flatnonzero(kinds == want)[0])
        return sysm.rows[s, ref, j]

    def _monodromy(self, run) -> np.ndarray:
        """d z(t_end) / d z(0) along the run: exp(A tau) of every segment and the saltation matrix of every event."""
        sysm = self.system
        Phi = np.eye(self.n)
        last = run.t0.size - 1
        for i in range(last):
            A = sysm.mats[run.slot[i]]
            Phi = core.expm_taylor(A * (run.t0[i + 1] - run.t0[i])) @ Phi
            f_minus = A @ self._segment_end_state(run, i)
            J = self._reset_matrix(run, i + 1)
            f_plus = sysm.mats[run.slot[i + 1]] @ run.z0[i + 1]
            S = saltation(J, f_minus, f_plus, self._event_row(run, i), grazing=0.0)
            Phi = (J if S is None else S) @ Phi     # r . f- = 0 exactly: a reset without a moving surface
        return core.expm_taylor(sysm.mats[run.slot[last]] * (run.t_end - run.t0[last])) @ Phi
