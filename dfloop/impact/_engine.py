"""The exact linear-mode engine of the two-mass clearance system: mode matrices, runs and trajectories.

Between events the masses, the optional effects (:mod:`dfloop.impact.effects`) and the ``extra`` states (the
forcing oscillator of the open-loop runs, or the plant of a closed loop, :mod:`dfloop.hybrid.impact`) obey one
linear ODE z' = A z per mode, z = [x1, v1, d, u, extra..., 1] (d: gap from the wall of the last impact, u =
v2 - v1). :class:`LinearModeSystem` builds the matrices of every mode (contact free / stuck on side A or B x
the ground mode of a friction mass) from the forces, their constraint rows and step exponentials; :func:`run`
drives the compiled event loop of :mod:`dfloop.impact._effects_core` with buffers that grow geometrically up to
``max_events``; :class:`EngineRun` holds the recorded segments and evaluates them exactly.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import EventLimitError
from . import _effects_core as core
from ._effects_core import D, FREE, N_SLOTS, STUCK_A, STUCK_B, U, V1, X1

STEPS_PER_SCALE = 16
_INITIAL_CAPACITY = 256


class EngineError(RuntimeError):
    """No admissible mode exists at a state (an inconsistent model, e.g. contradictory constraints)."""


class LinearModeSystem:
    """Mode matrices, constraint rows and step exponentials of the clearance system with ``n_extra`` states.

    Parameters
    ----------
    m1, m2, h, restitution : float
        Masses (kg), clearance (m), coefficient of restitution.
    force2 : (n,) array
        Force on M2 (N) as a row over z (e.g. F cos wt, or -c of a closed loop).
    extra_dynamics : (n_extra, n) array
        Rows of A for the extra states (z[4:4+n_extra]' = extra_dynamics @ z).
    damping, stiffness : float
        Viscous damping c (N s/m) and spring k (N/m) from M1 to ground.
    friction : (force, mass index) or None
        Coulomb friction level (N) on M1 (0) or M2 (1).
    extra_scales : sequence of float
        Further time scales (s) the step must resolve (e.g. the forcing period).
    """

    def __init__(self, m1, m2, h, restitution, force2, extra_dynamics, *, damping=0.0, stiffness=0.0,
                 friction=None, extra_scales=()):
        self.m1, self.m2, self.h, self.eps = float(m1), float(m2), float(h), float(restitution)
        self.n_extra = extra_dynamics.shape[0]
        n = self.n = 5 + self.n_extra
        self.one = n - 1
        self.friction = friction
        f1 = np.zeros(n)
        f1[X1], f1[V1] = -stiffness, -damping
        self._f1, self._f2, self._extra = f1, np.asarray(force2, float), np.asarray(extra_dynamics, float)
        self.valid = np.zeros(N_SLOTS, dtype=np.bool_)
        self.mats = np.zeros((N_SLOTS, n, n))
        self.contact_force = np.zeros((N_SLOTS, n))   # contact force on M2 from M1 (N), stuck modes
        self.ground_force = np.zeros((N_SLOTS, n))    # ground reaction on the grounded friction mass (N)
        grounds = [0] if friction is None else [0, 1, 2]
        for contact in (FREE, STUCK_A, STUCK_B):
            for g in grounds:
                self._build(3 * contact + g, contact, g)
        self.dt = self._step(extra_scales)
        self.exps = np.array([core.expm_taylor(A * self.dt) if ok else np.zeros((n, n))
                              for A, ok in zip(self.mats, self.valid)])
        self.rows, self.kinds, self.nrows = self._constraints()
        self.rows_a = np.einsum("srjk,skl->srjl", self.rows, self.mats)
        self.rows_aa = np.einsum("srjk,skl->srjl", self.rows_a, self.mats)

    def _unit(self, i):
        e = np.zeros(self.n)
        e[i] = 1.0
        return e

    def _build(self, slot, contact, g):
        """Accelerations of both masses (and the contact and ground forces) solved as rows over z."""
        grounded = self.friction is not None and g == 0
        f1, f2 = self._f1.copy(), self._f2.copy()
        if self.friction is not None and not grounded:
            sign = 1.0 if g == 1 else -1.0
            (f1 if self.friction[1] == 0 else f2)[self.one] -= self.friction[0] * sign
        names = ["a1", "a2"] + (["P"] if contact != FREE else []) + (["R"] if grounded else [])
        idx = {name: i for i, name in enumerate(names)}
        lhs, rhs = [], []

        def eq(coeffs, r):
            row = np.zeros(len(names))
            for name, v in coeffs.items():
                row[idx[name]] = v
            lhs.append(row)
            rhs.append(r)

        c1, c2 = {"a1": self.m1}, {"a2": self.m2}
        if "P" in idx:
            c1["P"], c2["P"] = 1.0, -1.0
        if "R" in idx:
            (c1 if self.friction[1] == 0 else c2)["R"] = -1.0
        eq(c1, f1)
        eq(c2, f2)
        zero = np.zeros(self.n)
        if "P" in idx:
            eq({"a1": 1.0, "a2": -1.0}, zero)
        if "R" in idx:
            eq({("a1" if self.friction[1] == 0 else "a2"): 1.0}, zero)
        sol = np.linalg.solve(np.array(lhs), np.array(rhs))
        A = np.zeros((self.n, self.n))
        A[X1, V1] = 1.0
        A[D, U] = 1.0
        A[V1] = sol[idx["a1"]]
        A[U] = sol[idx["a2"]] - sol[idx["a1"]]
        A[4:4 + self.n_extra] = self._extra
        if contact != FREE:
            A[U] = 0.0        # exactly: the pair moves as one body
            self.contact_force[slot] = sol[idx["P"]]
        if grounded:
            self.ground_force[slot] = sol[idx["R"]]
        self.mats[slot] = A
        self.valid[slot] = True

    def _step(self, extra_scales):
        """1/STEPS_PER_SCALE of the fastest time scale: 2 pi/|lambda| (oscillatory) or 1/|lambda| (decaying) of
        every mode's eigenvalues lambda (all modes in one batched call)."""
        scales = [float(s) for s in extra_scales]
        for lam in np.linalg.eigvals(self.mats[self.valid]).ravel():
            size = abs(lam)
            if size > 1e-12:
                scales.append(2.0 * math.pi / size if abs(lam.imag) >= abs(lam.real) else 1.0 / size)
        if not scales:
            raise ValueError("the system has no time scale (no force, no dynamics)")
        return min(scales) / STEPS_PER_SCALE

    def _constraints(self):
        """Rows r (r.z >= 0 in the mode) per slot and reference wall, their kinds and counts."""
        n, h, one = self.n, self.h, self.one
        rows = np.zeros((N_SLOTS, 2, 4, n))
        kinds = np.zeros((N_SLOTS, 4), dtype=np.int64)
        nrows = np.zeros(N_SLOTS, dtype=np.int64)
        ed, e1 = self._unit(D), self._unit(one)
        gap_rows = [[(ed + wall * e1, core.HIT_A), ((h - wall) * e1 - ed, core.HIT_B)] for wall in (0.0, h)]
        if self.friction is not None:
            v = self._unit(V1) + (self._unit(U) if self.friction[1] == 1 else 0.0)
            f_e1 = self.friction[0] * e1
        for slot in np.flatnonzero(self.valid):
            contact, g = divmod(int(slot), 3)
            out = []                  # rows of the slot that do not depend on the reference wall
            if contact != FREE:
                P = self.contact_force[slot]
                out += [(P if contact == STUCK_A else -P, core.SEPARATE)]
            if self.friction is not None:
                if g == 0:
                    R = self.ground_force[slot]
                    out += [(f_e1 - R, core.SLIP), (f_e1 + R, core.SLIP)]
                else:
                    out += [((1.0 if g == 1 else -1.0) * v, core.STOP)]
            for ref in (0, 1):
                both = (gap_rows[ref] if contact == FREE else []) + out
                for j, (r, kind) in enumerate(both):
                    rows[slot, ref, j] = r
                    kinds[slot, j] = kind
            nrows[slot] = len(both)
        return rows, kinds, nrows

    def parameters(self, v_stick, limit=np.inf):
        """Float and int parameter arrays of :func:`dfloop.impact._effects_core.run_engine`."""
        fpar = np.array([self.m1, self.m2, self.eps, self.h, v_stick, self.dt, limit])
        ipar = np.array([self.friction is not None, 0 if self.friction is None else self.friction[1]],
                        dtype=np.int64)
        return fpar, ipar

    def first_slot(self, z, ref, v_stick):
        """The admissible mode at a start state (raises EngineError when there is none)."""
        fpar, ipar = self.parameters(v_stick)
        slot = core.choose_mode(self.mats, self.rows, self.nrows, self.valid, ipar, fpar, z, ref)
        if slot < 0:
            raise EngineError(f"no admissible contact/friction mode at state {z[:4]}")
        return int(slot)


class EngineRun:
    """Recorded segments of one run: segment k starts at ``t0[k]`` in state ``z0[k]`` and mode ``slot[k]``."""

    def __init__(self, system, t_end, t0, z0, slot, ref, cause, vel, n_events, diverged=False, z_end=None,
                 ref_end=0):
        self.system, self.t_end, self.diverged = system, t_end, diverged
        self.t0, self.z0, self.slot, self.ref, self.cause, self.vel = t0, z0, slot, ref, cause, vel
        self.n_events = n_events
        self.z_end, self.ref_end = z_end, ref_end    # state at t_end (d relative to wall ref_end): continue here

    def then(self, later: "EngineRun") -> "EngineRun":
        """This run followed by ``later``, a run continued from this one's end (one record list)."""
        cat = [np.concatenate([a, b]) for a, b in zip((self.t0, self.z0, self.slot, self.ref, self.cause, self.vel),
                                                      (later.t0, later.z0, later.slot, later.ref, later.cause,
                                                       later.vel))]
        return EngineRun(self.system, later.t_end, *cat, self.n_events + later.n_events, later.diverged,
                         later.z_end, later.ref_end)

    @property
    def contact(self) -> np.ndarray:
        return self.slot // 3

    def states(self, t) -> np.ndarray:
        """State vectors at times t (s, within [t0[0], t_end]), one row per time; d is made absolute (gap)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if np.any(~np.isfinite(t)) or np.any(t < self.t0[0]) or np.any(t > self.t_end):
            raise ValueError(f"t must lie in [{self.t0[0]}, t_end = {self.t_end}]")
        k = np.searchsorted(self.t0, t, side="right") - 1
        z = self.z0[k].copy()              # exact at segment starts
        sysm = self.system
        inside = np.flatnonzero(t != self.t0[k])
        order = inside[np.argsort(k[inside], kind="stable")]
        bounds = np.flatnonzero(np.diff(k[order])) + 1
        for group in np.split(order, bounds) if order.size else ():
            seg = k[group[0]]
            s = self.slot[seg]
            z[group] = core.propagate(sysm.mats[s], sysm.exps[s], self.z0[seg], t[group] - self.t0[seg], sysm.dt)
        z[:, D] += self.ref[k] * sysm.h
        return z

    def fourier_integrals(self, starts, ends, w: float, component: int) -> np.ndarray:
        """Exact integrals of z[component](t) e^{-j w t} dt over pieces [starts, ends] inside segments.

        y = e^{-j w s} z obeys y' = (A - j w) y and its integral Y' = y: over a whole step dt the integral is
        e^{-j w s_i} g.z(s_i) with g a row of the Van Loan block exponential (one per mode), z stepped by the
        real exp(A dt); over each remainder (shorter than dt) the Taylor series of its integral, compiled
        (:func:`_effects_core.van_loan_pieces`).
        """
        starts = np.asarray(starts, dtype=float)
        ends = np.asarray(ends, dtype=float)
        sysm = self.system
        n, dt = sysm.n, sysm.dt
        zs = self.states(starts)
        zs[:, D] -= self.ref[np.searchsorted(self.t0, starts, side="right") - 1] * sysm.h  # back to the mode's d
        seg = np.searchsorted(self.t0, starts, side="right") - 1
        slots = self.slot[seg]
        out = np.empty(starts.size, complex)
        for slot in np.unique(slots):
            m = np.flatnonzero(slots == slot)
            big = np.zeros((2 * n, 2 * n), complex)
            big[:n, :n] = sysm.mats[slot] - 1j * w * np.eye(n)
            big[n:, :n] = np.eye(n)
            g = core.expm_taylor(big * dt)[n + component, :n].copy()
            total = core.van_loan_pieces(sysm.exps[slot], g, sysm.mats[slot], np.ascontiguousarray(zs[m]),
                                         ends[m] - starts[m], dt, float(w), component)
            out[m] = np.exp(-1j * w * starts[m]) * total
        return out


def run(system: LinearModeSystem, z: np.ndarray, t_end: float, v_stick: float, max_events: int, *,
        ref: int = 0, t_start: float = 0.0, record_from: float = 0.0, limit: float = np.inf,
        capacity: int = _INITIAL_CAPACITY, what: str = "simulation") -> EngineRun:
    """Run the compiled event loop from state ``z`` (d relative to wall ``ref``) over [t_start, t_end].

    Records before ``record_from`` (s) are dropped except the segment running at that time (bounded memory).
    A state component beyond ``limit`` ends the run early (``diverged``; ``t_end`` is then the time reached).
    ``capacity``: initial record buffers (they double as needed, up to ``max_events`` + 2).
    Raises :class:`dfloop.errors.EventLimitError` past ``max_events`` events, naming how to raise it.
    """
    z = np.array(z, dtype=float)
    slot = system.first_slot(z, ref, v_stick)
    fpar, ipar = system.parameters(v_stick, limit)
    fst = np.array([t_start, t_end, record_from])
    ist = np.array([slot, ref, 0, max_events, 1], dtype=np.int64)
    capacity = int(min(max_events + 1, max(capacity, 16))) + 1
    bufs = _buffers(capacity, system.n)
    bufs[0][0], bufs[1][0], bufs[2][0], bufs[3][0], bufs[4][0] = t_start, z, slot, ref, core.START
    bufs[5][0] = [z[V1], z[V1] + z[U], z[V1], z[V1] + z[U]]
    diverged = False
    while True:
        status = core.run_engine(system.mats, system.exps, system.rows, system.rows_a, system.rows_aa,
                                 system.kinds, system.nrows, system.valid, fpar, ipar, z, fst, ist, *bufs)
        if status == core.DONE:
            break
        if status == core.DIVERGED:
            diverged, t_end = True, float(fst[0])
            break
        if status == core.EVENT_LIMIT:
            rate = ist[2] / max(fst[0] - t_start, 1e-300)
            raise EventLimitError(
                f"max_events = {max_events} reached at t = {fst[0]:.6g} s of the {what} (t_end = {t_end:g} s; "
                f"{rate:.3g} events/s so far): pass a larger max_events (about "
                f"{int(rate * (t_end - t_start) * 1.5) + 1000} for this run) or a shorter run")
        if status == core.NO_MODE:
            raise EngineError(f"no admissible contact/friction mode at t = {fst[0]:.6g} s, state {z[:4]}")
        new_capacity = int(min(2 * capacity, max_events + 2))
        new = _buffers(new_capacity, system.n)
        for old, nb in zip(bufs, new):
            nb[:capacity] = old
        bufs, capacity = new, new_capacity
    n = int(ist[4])
    t0, z0, sl, rf, cause, vel = (b[:n].copy() for b in bufs)
    return EngineRun(system, t_end, t0, z0, sl, rf, cause, vel, int(ist[2]), diverged, z, int(ist[1]))


def _buffers(capacity, n):
    return (np.empty(capacity), np.empty((capacity, n)), np.empty(capacity, dtype=np.int64),
            np.empty(capacity, dtype=np.int64), np.empty(capacity, dtype=np.int64), np.empty((capacity, 4)))
