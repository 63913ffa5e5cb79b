"""Optional physical effects for the impact system, and the exact linear-mode engine that simulates them.

The paper's model is clearance + restitution impacts (+ the sticking that comes with them). The effects below
add physics that the paper leaves out. Each adds a time or a length scale, so **none of them keeps the
similarity law** (``keeps_similarity`` is False): with any of them N(F, w) is a genuinely two-dimensional table.

- :class:`ViscousDamping` ``c`` (N s/m): force -c v1 on M1 (to ground).
- :class:`LoadSpring` ``k`` (N/m): force -k x1 on M1 (to ground, relaxed at x1 = 0).
- :class:`CoulombFriction` ``force`` (N) on ``mass`` "m1" or "m2": -force sign(v) while slipping; the mass
  sticks to the ground while the other forces on it stay within ``force`` (stick-slip).

Engine: in every mode (free / stuck together on side A or B) x (friction mass slipping +, slipping -, stuck)
the motion is a linear ODE z' = A z of z = [x1, v1, x2, v2, cos wt, sin wt, 1], solved exactly by the
matrix exponential. Events (impacts, separation, stop, stick-slip) are roots of linear functionals r.z(s):
bracketed on steps of 1/32 of the fastest time scale (turning points inside a step found from r.A z),
then refined (secant + bisection) on the Taylor series of exp(A s) over the step (to rounding level).
The step loop and the event search run as numba functions (:mod:`dfloop.impact._effects_core`) on the
mode matrices and their step exponentials exp(A dt), computed once per mode; the event transitions stay here.
Still slower than the closed-form JIT kernel of the paper's model, which is used whenever no effect is given.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .. import _checks
from ._effects_core import admissible, propagate, rows_on_zero, scan_steps
from .kernel import ImpactEvents

__all__ = ["ViscousDamping", "LoadSpring", "CoulombFriction", "simulate_with_effects", "EffectsTrajectory"]

X1, V1, X2, V2, C, S, ONE = range(7)
FREE, STUCK_A, STUCK_B = 0, 1, 2
SLIP_POS, SLIP_NEG, GROUNDED = 1, -1, 0
START, IMPACT_A, IMPACT_B, SEPARATION, GROUND_EVENT = 0, 1, 2, 3, 4
STEPS_PER_SCALE = 32


@dataclass(frozen=True)
class ViscousDamping:
    """Viscous damper of coefficient ``c`` (N s/m) from M1 to ground. Breaks the similarity law."""

    c: float
    keeps_similarity = False

    def __post_init__(self):
        object.__setattr__(self, "c", _checks.positive("c", self.c))


@dataclass(frozen=True)
class LoadSpring:
    """Linear spring of stiffness ``k`` (N/m) from M1 to ground, relaxed at x1 = 0. Breaks the similarity law."""

    k: float
    keeps_similarity = False

    def __post_init__(self):
        object.__setattr__(self, "k", _checks.positive("k", self.k))


@dataclass(frozen=True)
class CoulombFriction:
    """Coulomb friction of level ``force`` (N) between ``mass`` ("m1" or "m2") and ground.

    Static and kinetic levels are equal. Breaks the similarity law.
    """

    force: float
    mass: str = "m2"
    keeps_similarity = False

    def __post_init__(self):
        object.__setattr__(self, "force", _checks.positive("force", self.force))
        if self.mass not in ("m1", "m2"):
            raise ValueError(f"mass must be 'm1' or 'm2', got {self.mass!r}")


def _unit(i: int) -> np.ndarray:
    e = np.zeros(7)
    e[i] = 1.0
    return e


class _Model:
    """Mode matrices and event rows for one parameter set and effect set."""

    def __init__(self, p, effects, v_stick: float):
        self.p = p
        self.v_stick = v_stick  # relative speed below which a wall contact may stick
        self.c = sum(e.c for e in effects if isinstance(e, ViscousDamping))
        self.k = sum(e.k for e in effects if isinstance(e, LoadSpring))
        frictions = [e for e in effects if isinstance(e, CoulombFriction)]
        for e in effects:
            if not isinstance(e, (ViscousDamping, LoadSpring, CoulombFriction)):
                raise ValueError(f"effects: unknown effect {e!r}")
        if len(frictions) > 1:
            raise ValueError("effects: at most one CoulombFriction is supported")
        self.friction = frictions[0] if frictions else None
        self.fmass = None if self.friction is None else (0 if self.friction.mass == "m1" else 1)
        self._cache = {}
        M = p.m1 + p.m2
        scales = [2.0 * math.pi / p.omega]
        if self.k > 0:
            scales += [2.0 * math.pi * math.sqrt(p.m1 / self.k), 2.0 * math.pi * math.sqrt(M / self.k)]
        if self.c > 0:
            scales += [p.m1 / self.c]
        self.dt = min(scales) / STEPS_PER_SCALE

    def mode(self, contact, ground):
        """(A, P row, R row, exp(A dt)) for a contact mode and a ground mode of the friction mass.

        P row: contact force on M2 from M1 (N) as a row over z (None when free); R row: ground reaction on the
        friction mass (None unless it is stuck to the ground).
        """
        key = (contact, ground)
        if key in self._cache:
            return self._cache[key]
        p = self.p
        f1 = -self.k * _unit(X1) - self.c * _unit(V1)
        f2 = p.force * _unit(C)
        grounded = self.friction is not None and ground == GROUNDED
        if self.friction is not None and not grounded:
            (f1 if self.fmass == 0 else f2)[ONE] -= self.friction.force * ground
        # unknowns a1, a2, P (contact force on M2 from M1), R (ground reaction on the friction mass)
        rows, rhs = [], []
        names = ["a1", "a2"] + (["P"] if contact != FREE else []) + (["R"] if grounded else [])
        idx = {n: i for i, n in enumerate(names)}

        def eq(coeffs, r):
            row = np.zeros(len(names))
            for n, v in coeffs.items():
                row[idx[n]] = v
            rows.append(row)
            rhs.append(r)

        c1 = {"a1": p.m1}
        c2 = {"a2": p.m2}
        if "P" in idx:
            c1["P"], c2["P"] = 1.0, -1.0
        if "R" in idx:
            (c1 if self.fmass == 0 else c2)["R"] = -1.0
        eq(c1, f1)
        eq(c2, f2)
        if "P" in idx:
            eq({"a1": 1.0, "a2": -1.0}, np.zeros(7))
        if "R" in idx:
            eq({("a1" if self.fmass == 0 else "a2"): 1.0}, np.zeros(7))
        sol = np.linalg.solve(np.array(rows), np.array(rhs))
        A = np.zeros((7, 7))
        A[X1, V1] = 1.0
        A[X2, V2] = 1.0
        A[V1] = sol[idx["a1"]]
        A[V2] = sol[idx["a2"]]
        A[C, S] = -p.omega
        A[S, C] = p.omega
        P = sol[idx["P"]] if "P" in idx else None
        R = sol[idx["R"]] if "R" in idx else None
        out = (A, P, R, expm(A * self.dt))
        self._cache[key] = out
        return out

    def constraint_rows(self, contact, ground):
        """The rows of :meth:`constraints` stacked as an (n, 7) array, and the list of their kinds (cached)."""
        key = ("rows", contact, ground)
        if key not in self._cache:
            cons = self.constraints(contact, ground)
            self._cache[key] = (np.array([r for r, _ in cons]), [kind for _, kind in cons])
        return self._cache[key]

    def constraints(self, contact, ground):
        """Rows r with r.z >= 0 in the mode, and their kind (for the transition)."""
        A, P, R, _ = self.mode(contact, ground)
        h = self.p.h
        gap = _unit(X2) - _unit(X1)
        out = []
        if contact == FREE:
            out += [(gap, "hit_A"), (h * _unit(ONE) - gap, "hit_B")]
        else:
            out += [(P if contact == STUCK_A else -P, "separate")]
        if self.friction is not None:
            v = _unit(V1 if self.fmass == 0 else V2)
            if ground == GROUNDED:
                ff = self.friction.force * _unit(ONE)
                out += [(ff - R, "slip"), (ff + R, "slip")]
            else:
                out += [(ground * v, "stop")]
        return out


@dataclass(frozen=True, repr=False)
class EffectsTrajectory(ImpactEvents):
    """Trajectory of the engine with effects; same interface as :class:`dfloop.impact.kernel.Trajectory`.

    Segment k starts at ``t0[k]`` with state ``z0[k]`` = [x1, v1, x2, v2, cos wt, sin wt, 1] and evolves by
    exp(A s) with ``A = matrices[mode_key[k]]`` (``exponentials``: exp(A step) of the same modes).
    ``ground`` holds the friction mass's ground mode.
    """

    params: object
    t_end: float
    effects: tuple
    t0: np.ndarray
    z0: np.ndarray
    mode: np.ndarray
    ground: np.ndarray
    cause: np.ndarray
    pre: np.ndarray      # (n, 2) v1, v2 before the impact that starts the segment
    post: np.ndarray     # (n, 2) v1, v2 after it (Newton's law)
    matrices: tuple
    exponentials: tuple
    mode_key: np.ndarray
    step: float

    @property
    def phase0(self) -> np.ndarray:
        """Forcing phase w t0 mod 2 pi at every segment start."""
        return np.arctan2(self.z0[:, S], self.z0[:, C]) % (2.0 * math.pi)

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

    def _states(self, t):
        """State vectors z at times t (validated), one row per time."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if np.any(~np.isfinite(t)) or np.any(t < 0.0) or np.any(t > self.t_end):
            raise ValueError(f"t must lie in [0, t_end = {self.t_end}]")
        k = np.searchsorted(self.t0, t, side="right") - 1
        z = np.empty((t.size, 7))
        for seg in np.unique(k):
            m = k == seg
            key = self.mode_key[seg]
            z[m] = propagate(self.matrices[key], self.exponentials[key], self.z0[seg], t[m] - self.t0[seg],
                             self.step)
        return z

    def evaluate(self, t) -> dict:
        """x1, v1, x2, v2 and the gap at times ``t`` (s)."""
        shape = np.shape(t)
        z = self._states(t)
        out = {"x1": z[:, X1], "v1": z[:, V1], "x2": z[:, X2], "v2": z[:, V2], "gap": z[:, X2] - z[:, X1]}
        return {k: v.reshape(shape) for k, v in out.items()}

    def piece_integrals(self, starts, ends) -> np.ndarray:
        """Exact integrals of x1(t) e^{-j w t} dt over pieces inside segments (Van Loan block exponential)."""
        starts = np.asarray(starts, dtype=float)
        ends = np.asarray(ends, dtype=float)
        w = self.params.omega
        zs = self._states(starts)
        k = np.searchsorted(self.t0, starts, side="right") - 1
        four = np.empty(starts.size, complex)
        eye = np.eye(7)
        big = np.zeros((14, 14), complex)
        big[7:, :7] = eye
        for i in range(starts.size):
            # y = e^{-j w s} z obeys y' = (A - j w) y; the lower block accumulates its integral
            big[:7, :7] = self.matrices[self.mode_key[k[i]]] - 1j * w * eye
            y = expm(big * (ends[i] - starts[i])) @ np.concatenate([zs[i], np.zeros(7)])
            four[i] = np.exp(-1j * w * starts[i]) * y[7 + X1]
        return four

    def __repr__(self) -> str:
        p = self.params
        return (f"EffectsTrajectory(m1={p.m1:g}, m2={p.m2:g}, h={p.h:g}, eps={p.restitution:g}, F={p.force:g}, "
                f"omega={p.omega:g}, effects={self.effects}, t_end={self.t_end:g}, segments={self.t0.size}, "
                f"impacts={self.n_impacts})")


def simulate_with_effects(p, t_end: float, effects: tuple, max_events: int, chatter_tol: float):
    """Event-driven simulation with optional effects (called by :func:`dfloop.impact.kernel.simulate`)."""
    v_stick = chatter_tol * max(p.h * p.omega, p.force / (p.m2 * p.omega))
    model = _Model(p, effects, v_stick)
    z = np.array([0.0, 0.0, 0.5 * p.h, 0.0, 1.0, 0.0, 1.0])
    t = 0.0
    contact, ground = _choose_mode(model, z)
    keys, mats, exps = {}, [], []

    def key_of(contact, ground):
        kk = (contact, ground)
        if kk not in keys:
            keys[kk] = len(mats)
            A, _, _, E = model.mode(contact, ground)
            mats.append(A)
            exps.append(E)
        return keys[kk]

    rec = {"t0": [0.0], "z0": [z.copy()], "mode": [contact], "ground": [0 if ground is None else ground],
           "cause": [START], "pre": [(0.0, 0.0)], "post": [(0.0, 0.0)], "key": [key_of(contact, ground)]}
    leaving = np.zeros(len(model.constraint_rows(contact, ground)[1]), dtype=np.bool_)  # rows starting on 0
    n_events = 0
    while t < t_end:
        A, P, R, E = model.mode(contact, ground)
        rows, kinds = model.constraint_rows(contact, ground)
        t_scan = t
        t, j = scan_steps(A, E, model.dt, rows, leaving, z, t, t_end)
        if j < 0 and t < t_end:   # the last, shorter step before t_end
            if t != t_scan:
                leaving[:] = False
            dt = t_end - t
            t, j = scan_steps(A, expm(A * dt), dt, rows, leaving, z, t, t_end)
        if j < 0:
            leaving[:] = False
            continue
        kind = kinds[j]
        n_events += 1
        if n_events > max_events:
            from .kernel import EventLimitError
            raise EventLimitError(f"max_events = {max_events} reached at t = {t:.6g} s (t_end = {t_end:g} s)")
        pre = post = (z[V1], z[V2])
        if kind in ("hit_A", "hit_B"):
            side = 0 if kind == "hit_A" else 1
            z[X2] = z[X1] + (0.0 if side == 0 else p.h)
            pre = (z[V1], z[V2])
            M = p.m1 + p.m2
            eps = p.restitution
            v1 = (z[V1] * (p.m1 - eps * p.m2) + z[V2] * (1 + eps) * p.m2) / M
            v2 = (z[V1] * (1 + eps) * p.m1 + z[V2] * (p.m2 - eps * p.m1)) / M
            post = (v1, v2)
            z[V1], z[V2] = v1, v2
            if abs(v2 - v1) <= v_stick:  # converged chatter: plastic settle (momentum kept)
                z[V1] = z[V2] = (p.m1 * v1 + p.m2 * v2) / M
            cause = IMPACT_A if side == 0 else IMPACT_B
        elif kind == "separate":
            cause = SEPARATION
        elif kind == "stop":
            cause = GROUND_EVENT
            z[V1 if model.fmass == 0 else V2] = 0.0
            if contact != FREE:
                z[V1] = z[V2] = 0.0
        else:  # slip
            cause = GROUND_EVENT
        contact, ground = _choose_mode(model, z)
        leaving = rows_on_zero(model.constraint_rows(contact, ground)[0], z)
        rec["t0"].append(t)
        rec["z0"].append(z.copy())
        rec["mode"].append(contact)
        rec["ground"].append(0 if ground is None else ground)
        rec["cause"].append(cause)
        rec["pre"].append(pre)
        rec["post"].append(post)
        rec["key"].append(key_of(contact, ground))
    return EffectsTrajectory(params=p, t_end=t_end, effects=effects, t0=np.array(rec["t0"]),
                             z0=np.array(rec["z0"]), mode=np.array(rec["mode"]), ground=np.array(rec["ground"]),
                             cause=np.array(rec["cause"]), pre=np.array(rec["pre"]), post=np.array(rec["post"]),
                             matrices=tuple(mats), exponentials=tuple(exps), mode_key=np.array(rec["key"]), step=model.dt)


def _choose_mode(model, z):
    """The first admissible (contact, ground) mode at z among those the state allows.

    Contact is a candidate when the gap sits on a wall with no relative velocity (stuck preferred over free);
    a friction mass at rest may stay on the ground (preferred) or slip either way.
    """
    gap = z[X2] - z[X1]
    h = model.p.h
    contacts = [FREE]
    if abs(z[V2] - z[V1]) <= model.v_stick and min(abs(gap), abs(gap - h)) <= 1e-12 * h:
        contacts = [STUCK_A if abs(gap) < 0.5 * h else STUCK_B, FREE]
    if model.friction is None:
        grounds = [None]
    else:
        v = z[V1 if model.fmass == 0 else V2]
        grounds = [GROUNDED, SLIP_POS, SLIP_NEG] if v == 0.0 else [SLIP_POS if v > 0 else SLIP_NEG]
    for contact in contacts:
        for ground in grounds:
            if admissible(model.mode(contact, ground)[0], model.constraint_rows(contact, ground)[0], z):
                return contact, ground
    raise RuntimeError(f"no admissible contact/friction mode at state {z[:4]}")
