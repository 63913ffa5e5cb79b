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
then refined (Newton + bisection) on the Taylor series of exp(A s) over the step (to rounding level).
Slower than the closed-form JIT kernel of the paper's model, which is used whenever no effect is given.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .. import _checks

__all__ = ["ViscousDamping", "LoadSpring", "CoulombFriction", "simulate_with_effects", "EffectsTrajectory"]

X1, V1, X2, V2, C, S, ONE = range(7)
FREE, STUCK_A, STUCK_B = 0, 1, 2
SLIP_POS, SLIP_NEG, GROUNDED = 1, -1, 0
START, IMPACT_A, IMPACT_B, SEPARATION, GROUND_EVENT = 0, 1, 2, 3, 4
STEPS_PER_SCALE = 32
TAYLOR_TERMS = 30


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


def _taylor(A, z, n=TAYLOR_TERMS):
    """Vectors A^k z / k! for k < n (Taylor coefficients of exp(A s) z)."""
    terms = [z]
    for k in range(1, n):
        terms.append(A @ terms[-1] / k)
    return np.array(terms)


def _poly(terms, s):
    """exp(A s) z from Taylor coefficients (Horner)."""
    out = terms[-1].copy()
    for k in range(terms.shape[0] - 2, -1, -1):
        out = out * s + terms[k]
    return out


def _propagate(A, z0, s, step):
    """exp(A s) z0 for an array of s >= 0: exact steps exp(A step) to the chunk starts, Taylor inside."""
    chunk = np.floor(s / step).astype(np.int64)
    e_step = expm(A * step)
    starts = [z0]
    for _ in range(int(chunk.max(initial=0))):
        starts.append(e_step @ starts[-1])
    starts = np.array(starts)
    powers = [np.eye(7)]
    for k in range(1, TAYLOR_TERMS):
        powers.append(powers[-1] @ A / k)
    terms = np.einsum("kij,nj->nki", np.array(powers), starts)   # (chunk, k, 7)
    r = (s - chunk * step)[:, None]
    out = terms[chunk, -1]
    for k in range(TAYLOR_TERMS - 2, -1, -1):
        out = out * r + terms[chunk, k]
    return out


def _refine(fun, lo, hi, flo):
    """Root of a scalar function with a sign change on [lo, hi] (bisection with secant steps)."""
    fhi = fun(hi)
    for _ in range(200):
        if hi - lo <= 4e-16 * max(hi, 1e-300):
            break
        s = hi - fhi * (hi - lo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        if not (lo < s < hi) or (hi - lo) < 1e-3 * abs(s - 0.5 * (lo + hi)):
            s = 0.5 * (lo + hi)
        fs = fun(s)
        if fs == 0.0:
            return s
        if (fs > 0) == (flo > 0):
            lo, flo = s, fs
        else:
            hi, fhi = s, fs
        # force a bisection every other step to guarantee progress
        m = 0.5 * (lo + hi)
        fm = fun(m)
        if fm == 0.0:
            return m
        if (fm > 0) == (flo > 0):
            lo, flo = m, fm
        else:
            hi, fhi = m, fm
    return hi


def _first_violation(terms, A, r, leaving, dt):
    """First s in (0, dt] where r.z(s) < 0 given r.z >= 0 before (None if none in the step).

    ``leaving``: the step starts on r.z = 0 and moves away; values within rounding of 0 are then not events.
    One turning point per step is resolved (the step is 1/32 of the fastest time scale).
    """
    def f(s):
        return r @ _poly(terms, s)

    def df(s):
        return r @ (A @ _poly(terms, s))

    tol = 1e-12 * float(np.abs(r) @ np.abs(terms[0])) if leaving else 0.0
    fa, fb = f(0.0), f(dt)
    da, db = df(0.0), df(dt)
    turn = _refine(df, 0.0, dt, da) if (da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0) else None
    if fb < -tol:
        if turn is not None and da > 0.0:  # rises to a maximum, then falls through zero
            ft = f(turn)
            return _refine(f, turn, dt, ft) if ft > 0.0 else turn
        return _refine(f, 0.0, dt, fa) if fa > 0.0 else 0.0
    if turn is not None and da < 0.0:      # dips to a minimum inside the step
        ft = f(turn)
        if ft < -tol:
            return _refine(f, 0.0, turn, fa) if fa > 0.0 else 0.0
    return None


@dataclass(frozen=True, repr=False)
class EffectsTrajectory:
    """Trajectory of the engine with effects; same interface as :class:`dfloop.impact.kernel.Trajectory`.

    Segment k starts at ``t0[k]`` with state ``z0[k]`` = [x1, v1, x2, v2, cos wt, sin wt, 1] and evolves by
    exp(A s) with ``A = matrices[mode_key[k]]``. ``ground`` holds the friction mass's ground mode.
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
    mode_key: np.ndarray
    step: float

    @property
    def phase0(self) -> np.ndarray:
        """Forcing phase w t0 mod 2 pi at every segment start."""
        return np.arctan2(self.z0[:, S], self.z0[:, C]) % (2.0 * math.pi)

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
        return {"t": self.t0[m], "side": (self.cause[m] == IMPACT_B).astype(np.int8),
                "v1_pre": self.pre[m, 0], "v2_pre": self.pre[m, 1],
                "v1_post": self.post[m, 0], "v2_post": self.post[m, 1]}

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
            z[m] = _propagate(self.matrices[self.mode_key[seg]], self.z0[seg], t[m] - self.t0[seg], self.step)
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
    keys, mats = {}, []

    def key_of(contact, ground):
        kk = (contact, ground)
        if kk not in keys:
            keys[kk] = len(mats)
            mats.append(model.mode(contact, ground)[0])
        return keys[kk]

    rec = {"t0": [0.0], "z0": [z.copy()], "mode": [contact], "ground": [0 if ground is None else ground],
           "cause": [START], "pre": [(0.0, 0.0)], "post": [(0.0, 0.0)], "key": [key_of(contact, ground)]}
    leaving = set()
    n_events = 0
    while t < t_end:
        A, P, R, E = model.mode(contact, ground)
        cons = model.constraints(contact, ground)
        dt = min(model.dt, t_end - t)
        Edt = E if dt == model.dt else expm(A * dt)
        z_next = Edt @ z
        rows = np.array([r for r, _ in cons])
        fb = rows @ z_next
        da, db = rows @ (A @ z), rows @ (A @ z_next)
        # cheap screen: a constraint needs the exact search only if it ends violated, turns, or starts on 0
        suspect = [j for j in range(len(cons)) if fb[j] < 0.0 or da[j] * db[j] < 0.0 or j in leaving]
        hits = []
        if suspect:
            terms = _taylor(A, z)
            for j in suspect:
                s = _first_violation(terms, A, cons[j][0], j in leaving, dt)
                if s is not None:
                    hits.append((s, j, cons[j][1]))
        if not hits:
            z = z_next
            t += dt
            leaving = set()
            continue
        s, j, kind = min(hits)
        z = _poly(terms, s)
        t += s
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
        leaving = set(j for j, (r, _) in enumerate(model.constraints(contact, ground))
                      if abs(r @ z) <= 1e-12 * (np.abs(r) @ np.abs(z) + 1e-300))
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
                             matrices=tuple(mats), mode_key=np.array(rec["key"]), step=model.dt)


def _admissible(model, z, contact, ground) -> bool:
    """All constraints of the mode hold at z, ties broken by the first non-negligible time derivative."""
    A = model.mode(contact, ground)[0]
    derivs, sizes = [z], [np.abs(z)]   # sizes bound the terms summed in each derivative (rounding scale)
    for _ in range(3):
        derivs.append(A @ derivs[-1])
        sizes.append(np.abs(A) @ sizes[-1])
    for r, _ in model.constraints(contact, ground):
        for d, size in zip(derivs, sizes):
            val = r @ d
            tol = 1e-12 * (np.abs(r) @ size)
            if val > tol:
                break
            if val < -tol:
                return False
    return True


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
            if _admissible(model, z, contact, ground):
                return contact, ground
    raise RuntimeError(f"no admissible contact/friction mode at state {z[:4]}")
