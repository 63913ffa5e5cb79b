"""The closed loop of a strictly proper plant and a piecewise-linear element as an exact hybrid system.

Loop of the paper's Fig. 1: plant state s (s' = A s + B y, c = C s), element input x = -c, element output y
and element state e (the driven side of a backlash; none for static elements and relays). With the augmented
state z = [s, e, 1] every mode of the element (a :class:`~dfloop.describing.time_model.PiecewiseAffine`) is a linear ODE z' = A_m z,
solved exactly by the matrix exponential. Guards are linear rows r (r.z >= 0 in the mode). Events are
bracketed on steps of 1/32 of the fastest time scale of the mode (turning points inside a step found from
r.A z) and refined to rounding level on the Taylor series of exp(A s) z, with the compiled scan and refine
of the impact engine (:mod:`dfloop.impact._effects_core`).

:meth:`HybridLoop.flow` also returns the monodromy (the Jacobian of the flow map), including the saltation
matrix of every switch, S = R + (f+ - R f-) r^T / (r . f-) (R: Jacobian of the reset, f-/f+: the vector field
before/after), so Floquet multipliers are right for discontinuous elements (relays).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..describing.time_model import OUT_OF_RANGE, PiecewiseAffine
from ..impact._effects_core import BEYOND_LIMIT, admissible, propagate, rows_on_zero, scan_steps
from .realisation import conditioned

__all__ = ["LoopModel", "HybridLoop", "Flow", "HybridError", "plant_matrices", "plant_system", "saltation",
           "piecewise_fourier"]

STEPS_PER_SCALE = 32
_NEVER = -2                   # target of the dummy guard of a mode without guards (1 >= 0 always holds)
_GRAZING = 1e-10              # |r.f| below this fraction of |r||f| at a switch: a grazing contact


class HybridError(RuntimeError):
    """The hybrid flow cannot continue: sliding on a switching surface, grazing, range or event bound."""


_REALISED: dict = {}        # plant_system's results by the plant's coefficients (read-only arrays)
_REALISED_SIZE = 64


def _coefficients_key(G):
    """A key of a tf/ss plant's coefficients and sampling time (tf: numerator and denominator of the SISO pair)."""
    import control as ct

    if isinstance(G, ct.TransferFunction):
        if G.ninputs != 1 or G.noutputs != 1:
            return None
        parts = (np.asarray(G.num[0][0], float), np.asarray(G.den[0][0], float))
    else:
        parts = tuple(np.asarray(m, float) for m in (G.A, G.B, G.C, G.D))
    return (type(G).__name__, G.dt) + tuple((p.shape, p.tobytes()) for p in parts)


def plant_system(G, *, what: str = "the exact flow"):
    """(A, B, C, D) of a SISO continuous-time python-control tf/ss plant G (``ValueError`` naming G otherwise).

    The realisation (python-control's ``ss``, then balanced) is kept per set of coefficients (the arrays are
    read-only): a shooting, a sweep or a globalisation asks for the same plant many times, and ``ss`` of a
    transfer function costs 0.2-0.3 ms."""
    import control as ct

    G = getattr(G, "lti", G)     # a dfloop Plant carries its python-control system (or None)
    if not isinstance(G, (ct.TransferFunction, ct.StateSpace)):
        raise ValueError(f"G must be a python-control tf or ss system for {what}, got {type(G).__name__}")
    key = _coefficients_key(G)
    if key is not None and key in _REALISED:
        return _REALISED[key]
    out = _realise(G, what)
    if key is not None:
        if len(_REALISED) >= _REALISED_SIZE:
            _REALISED.pop(next(iter(_REALISED)))
        for a in out[:3]:
            a.flags.writeable = False
        _REALISED[key] = out
    return out


def _realise(G, what: str):
    import control as ct

    sys = ct.ss(G)
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise ValueError(f"G must be SISO for {what}, got {sys.ninputs} inputs and {sys.noutputs} outputs")
    if not sys.isctime():
        raise ValueError(f"G must be a continuous-time system for {what}, got dt = {sys.dt!r} (a digital loop is a "
                         "map: exact_cycle and dfloop.hybrid.discrete find its orbits)")
    return balanced(np.asarray(sys.A, float), np.asarray(sys.B, float)[:, 0], np.asarray(sys.C, float)[0]) + \
        (float(np.asarray(sys.D, float)[0, 0]),)


_IMBALANCE = 1e4            # ||A|| over the balanced ||D^-1 A D|| beyond which a realisation is rebalanced


def balanced(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C) unchanged, or by the diagonal similarity D^-1 A D, D^-1 B, C D (D powers of 2: no rounding) when
    that shrinks ||A|| by more than ``_IMBALANCE``: the companion form python-control gives a high-order tf (a
    Pade chain of order 10 has entries up to 1e15) loses the flow's accuracy to rounding (1e-7 on its trivial
    multiplier); balanced, the same plant keeps it (the element sees x = -C s, the same in both)."""
    from scipy.linalg import matrix_balance

    if A.size == 0:
        return A, B, C
    Ab, (d, _) = matrix_balance(A, permute=False, separate=True)
    if np.linalg.norm(A, 1) <= _IMBALANCE * np.linalg.norm(Ab, 1):
        return A, B, C
    return Ab, B / d, C * d


def plant_matrices(G, *, what: str = "the exact flow"):
    """(A, B, C) of a strictly proper SISO tf/ss plant G (``ValueError`` naming G otherwise)."""
    A, B, C, D = plant_system(G, what=what)
    if D != 0:
        raise ValueError(f"G must be strictly proper (D = 0) for {what} (a direct feedthrough closes an "
                         f"algebraic loop through the element); got D = {D!r}")
    return A, B, C


REAL_STEP = 0.5              # |lambda| dt for a fast real mode (its curvature changes by e^0.5 < 2 in a step)


def mode_step(Am: np.ndarray, time_scale: float) -> float:
    """The scan step (s) of a mode: ``time_scale`` / 32, and per eigenvalue lambda of A_m: 1 / (32 |lambda|) for an
    oscillating one (32 steps per radian), ``REAL_STEP`` / |lambda| for a real one. A real mode's contribution is
    monotone with a curvature of one sign that changes by at most e^0.5 within such a step, which is all the scan's
    dip test assumes (the bracketing of events stays complete), and its Taylor refinement is accurate there: a
    stiff plant (fast real poles 1e4 times the period's rate) is then scanned 16 times faster than at 32 steps per
    fast time constant, with the same events."""
    lam = np.linalg.eigvals(Am)
    size = np.abs(lam)
    keep = size > 1e-12 * max(float(size.max(initial=0.0)), 1e-300)
    lam, size = lam[keep], size[keep]
    dt = time_scale / STEPS_PER_SCALE
    if lam.size:
        real = np.abs(lam.imag) <= 1e-9 * size
        per = np.where(real, REAL_STEP / size, 1.0 / (STEPS_PER_SCALE * size))
        dt = min(dt, float(per.min()))
    return dt


def saltation(R: np.ndarray, f_minus: np.ndarray, f_plus: np.ndarray, r: np.ndarray,
              grazing: float = _GRAZING) -> np.ndarray | None:
    """Saltation matrix S = R + (f+ - R f-) r^T / (r . f-) of a switch on the surface r . z = 0.

    R is the Jacobian of the reset, f-/f+ the vector fields before and after. None when the flow grazes the
    surface (|r . f-| <= ``grazing`` |r| |f-|): the jump of the flow map's derivative is then undefined.
    """
    denom = float(r @ f_minus)
    if abs(denom) <= grazing * np.linalg.norm(r) * np.linalg.norm(f_minus):
        return None
    return R + np.outer(f_plus - R @ f_minus, r) / denom


def piecewise_fourier(pieces, t_end: float, omega: float, harmonics: int, row: np.ndarray) -> np.ndarray:
    """Exact (1/T) int_0^T (row . z(t)) e^{-j k w t} dt, k = 1..harmonics, T = ``t_end``, of a piecewise-linear
    trajectory: ``pieces`` yields (A, z0, t0, t1), z' = A z on [t0, t1) from z(t0) = z0.

    Each piece's integral is one block exponential (Van Loan) per harmonic: for y = e^{-jkw s} z and Y' = y,
    exp([[A - jkw I, 0], [I, 0]] tau) [z0, 0] = [y(tau), Y(tau)].
    """
    out = np.zeros(harmonics, complex)
    big = None
    for A, z0, t0, t1 in pieces:
        if t1 <= t0:
            continue
        N = A.shape[0]
        if big is None or big.shape[0] != 2 * N:
            big = np.zeros((2 * N, 2 * N), complex)
            big[N:, :N] = np.eye(N)
        start = np.concatenate([z0, np.zeros(N)])
        for k in range(1, harmonics + 1):
            big[:N, :N] = A - 1j * k * omega * np.eye(N)
            out[k - 1] += np.exp(-1j * k * omega * t0) * (row @ (expm(big * (t1 - t0)) @ start)[N:])
    return out / t_end


@dataclass
class Flow:
    """Result of :meth:`HybridLoop.flow` over [0, t_end].

    ``z`` / ``mode``: end state and mode; ``monodromy``: d z(t_end) / d z(0) (augmented, or None);
    ``t0, z0, modes``: start time, state and mode of every segment; ``events``: (time, guard index, from mode,
    to mode) of every switch.
    """

    z: np.ndarray
    mode: int
    monodromy: np.ndarray | None
    t0: np.ndarray
    z0: np.ndarray
    modes: np.ndarray
    events: list
    dense: object = None     # dense output of an integrator (smooth loops only)
    run: object = None       # the impact engine's run (impact loops only)
    stopped: float | None = None   # time (s) where the flow stopped at its divergence bound (``limit``), else None
    span: float | None = None      # the flow's length t_end (s)

    @property
    def event_times(self) -> np.ndarray:
        """Times (s) of the switches / impacts of the flow."""
        return np.array([e[0] for e in self.events], dtype=float)


class LoopModel:
    """What every loop model shares: the flows of several nodes and the flow of a whole period from them.

    Subclasses define ``flow``; a model whose nodes can run together (one integration) overrides
    :meth:`flow_many` and sets ``batched``; one whose node flows compose into the period's flow overrides
    :meth:`join`.
    """

    batched = False        # flow_many does more than one flow per node
    bounded = False        # flow accepts ``limit`` (stops where |x| may pass it: a diverging loop)
    delay = 0.0            # the plant's pure delay (s): only a DelayLoop (dfloop.hybrid.delay) has one
    switching = True       # flows switch modes (the shooting keeps its first node away from switches)

    def flow_many(self, zs, modes, t_end, *, monodromy: bool = False, max_events: int = 10_000) -> list:
        """The flows from every (zs[i], modes[i]) over [0, t_end] (a float, or one per node)."""
        ends = np.broadcast_to(np.asarray(t_end, float), (len(zs),))
        return [self.flow(z, mo, te, monodromy=monodromy, max_events=max_events)
                for z, mo, te in zip(zs, modes, ends)]

    def join(self, flows: list, period: float, *, max_events: int = 10_000) -> "Flow":
        """The flow (with its monodromy) over one period from the first node of converged node flows."""
        return self.flow(flows[0].z0[0], flows[0].modes[0], period, monodromy=True, max_events=max_events)


class HybridLoop(LoopModel):
    """Exact hybrid model of the loop of plant (A, B, C) and a piecewise-linear element model.

    Parameters
    ----------
    A, B, C : ndarray
        Strictly proper plant (see :func:`plant_matrices`). The flow runs in the well-conditioned realisation
        :func:`dfloop.hybrid.realisation.conditioned` makes of it (block-diagonal, balanced): states z hold
        s' with s = ``basis`` @ s' (``plant`` is that realisation's (A', B')).
    element : PiecewiseAffine
        The element's time model (:meth:`dfloop.describing.base.DescribingFunction.time_model`).
    time_scale : float
        Longest step allowed (s) times 32, e.g. the expected period; steps are also bounded by the fastest
        time constant of every mode.
    r0, load : float
        Constant input: the element's input is x = r0 - C s (a reference at the summing junction) and the plant
        is driven by y + load (a load at the element's output). Both ride on the constant last component of z,
        so every mode stays linear and the flow exact.
    """

    method = "exact (matrix exponential between switches, switches located to rounding level)"
    bounded = True
    exact = True           # flows carry a monodromy: periodic orbits can be shot
    settle_periods = 0.0   # the predicted sinusoid sets the element's state: no transient needed before shooting

    def __init__(self, A, B, C, element: PiecewiseAffine, time_scale: float, *, r0: float = 0.0,
                 load: float = 0.0):
        A, B, C, self.basis = conditioned(A, B, C)   # the flow's own realisation: s (as given) = basis @ s'
        self.plant = (A, B)
        self.r0, self.load = float(r0), float(load)
        n = A.shape[0]
        self.n, self.element = n, element
        self.size = n + element.n_states + 1
        N = self.size
        self.x_row = np.zeros(N)
        self.x_row[:n] = -C
        self.x_row[-1] = self.r0
        self.x_scale = max(float(np.max(np.abs(C), initial=0.0)), 1e-300)   # |x| <~ n x_scale max|s_i|
        one = np.zeros(N)
        one[-1] = 1.0
        e_unit = np.zeros(N)
        if element.n_states:
            e_unit[n] = 1.0
        self.matrices, self.rows, self.targets, self.resets, self.steps, self.exps = [], [], [], [], [], []
        self.y_rows = []
        self._sample_exps = {}
        for mode in element.modes:
            y_row = mode.gx * self.x_row + mode.ge * e_unit + mode.g1 * one
            Am = np.zeros((N, N))
            Am[:n, :n] = A
            Am[:n] += np.outer(B, y_row + self.load * one)
            xd_row = self.x_row @ Am
            if element.n_states:
                Am[n] = mode.de * xd_row
            rows, targets, resets = [], [], []
            for g in mode.guards:
                rows.append(g.cx * self.x_row + g.cxd * xd_row + g.ce * e_unit + g.c1 * one)
                targets.append(g.target)
                R = np.eye(N)
                if g.reset is not None:
                    R[n] = g.reset[0] * self.x_row + g.reset[1] * one
                resets.append(R)
            if not rows:
                rows, targets, resets = [one.copy()], [_NEVER], [np.eye(N)]
            dt = mode_step(Am, time_scale)
            self.matrices.append(Am)
            self.y_rows.append(y_row)
            self.rows.append(np.array(rows))
            self.targets.append(targets)
            self.resets.append(resets)
            self.steps.append(dt)
            self.exps.append(expm(Am * dt))

    @property
    def growth_rate(self) -> float:
        """The fastest growth rate (1/s) of a perturbation in any mode: the largest real part among the
        eigenvalues of the modes' matrices (plant and element states; the constant component left out)."""
        nx = self.size - 1
        return max(float(np.max(np.linalg.eigvals(Am[:nx, :nx]).real, initial=0.0)) for Am in self.matrices)

    def join(self, flows: list, period: float, *, max_events: int = 10_000) -> Flow:
        """The flow over one period composed of the converged node flows (segments, events and the monodromy
        M_{m-1} ... M_0), not re-flowed: a strongly unstable orbit's one-period flow would leave it."""
        t0s, z0s, modes, events = [], [], [], []
        M = np.eye(self.size)
        offset = 0.0
        for fl in flows:
            t0s.append(offset + fl.t0)
            z0s.append(fl.z0)
            modes.append(fl.modes)
            events.extend((offset + e[0],) + tuple(e[1:]) for e in fl.events)
            M = fl.monodromy @ M
            offset += fl.span
        return Flow(flows[-1].z, flows[-1].mode, M, np.concatenate(t0s), np.concatenate(z0s),
                    np.concatenate(modes), events)

    # ----------------------------------------------------------------------------------------- helpers

    def x(self, z) -> np.ndarray:
        """Element input x = -C s for state(s) z (last axis)."""
        return np.asarray(z) @ self.x_row

    def output(self, z, mode) -> np.ndarray:
        """Element output y for state(s) z in mode(s) ``mode`` (broadcast)."""
        z = np.atleast_2d(z)
        return np.einsum("ij,ij->i", z, np.array(self.y_rows)[np.broadcast_to(mode, z.shape[:1])])

    def signals(self, flow: Flow, t) -> tuple[np.ndarray, np.ndarray]:
        """Element input x and output y at times t within the flow's span."""
        t = np.atleast_1d(np.asarray(t, float))
        z = self.states(flow, t)
        seg = np.clip(np.searchsorted(flow.t0, t, side="right") - 1, 0, flow.t0.size - 1)
        return self.x(z), self.output(z, flow.modes[seg])

    def field(self, z, mode: int) -> np.ndarray:
        """Vector field z' = A_mode z."""
        return self.matrices[mode] @ z

    def start(self, s0: np.ndarray, x_history: np.ndarray) -> tuple[np.ndarray, int]:
        """Augmented state and mode from a plant state and the element input's recent history."""
        z = np.zeros(self.size)
        z[:self.n] = s0
        z[-1] = 1.0
        # x' does not depend on the mode through e when CB = 0; use any mode for the rate
        xdot = float(self.x_row @ (self.matrices[0] @ z))
        mode, e = self.element.initial(np.append(x_history, self.x(z)), xdot)
        if self.element.n_states:
            z[self.n] = e
        return self.admissible_mode(z, mode)   # on a switching surface and leaving it: switch now

    def admissible_mode(self, z: np.ndarray, mode: int) -> tuple[np.ndarray, int]:
        """(z, mode) unchanged when z satisfies the mode's guards; otherwise the switches a guard violated at
        z calls for are taken at once (at most one per mode; ``HybridError`` when none settles)."""
        z = np.array(z, dtype=float)
        for _ in range(len(self.matrices) + 1):
            A, rows = self.matrices[mode], self.rows[mode]
            if admissible(A, rows, z):
                return z, mode
            j = int(np.argmin(rows @ z))
            target = self.targets[mode][j]
            if target < 0:
                break
            z = self.resets[mode][j] @ z
            mode = target
        raise HybridError(f"no admissible mode of the {self.element.name} model at x = {self.x(z):.6g}")

    def states(self, flow: Flow, t) -> np.ndarray:
        """States z at times t (within the flow's span), one row per time."""
        t = np.atleast_1d(np.asarray(t, float))
        k = np.clip(np.searchsorted(flow.t0, t, side="right") - 1, 0, flow.t0.size - 1)
        out = np.empty((t.size, self.size))
        for seg in np.unique(k):
            m = k == seg
            mode = flow.modes[seg]
            s = t[m] - flow.t0[seg]
            gaps = np.diff(s) if s.size > 1 else np.zeros(1)
            if s[0] >= 0.0 and np.all(np.abs(gaps - gaps[0]) <= 1e-12 * max(gaps[0], s[-1])):
                out[m] = self._uniform(mode, flow.z0[seg], s[0], gaps[0], s.size)
            else:
                out[m] = propagate(self.matrices[mode], self.exps[mode], flow.z0[seg], s, self.steps[mode])
        return out

    def _uniform(self, mode: int, z0: np.ndarray, first: float, gap: float, count: int) -> np.ndarray:
        """exp(A (first + j gap)) z0, j < count: one exponential to the first sample, then exact steps
        exp(A gap) (cached per mode and gap). :func:`propagate` would step from the segment's start across every
        scan step, which dominated the sampling of long runs on high-order loops."""
        A = self.matrices[mode]
        key = (mode, gap)
        E = self._sample_exps.get(key)
        if E is None:
            if len(self._sample_exps) >= 64:
                self._sample_exps.clear()
            E = self._sample_exps[key] = expm(A * gap)
        out = np.empty((count, z0.size))
        out[0] = expm(A * first) @ z0 if first > 0.0 else z0
        for j in range(1, count):
            out[j] = E @ out[j - 1]
        return out

    def fourier(self, flow: Flow, t_end: float, omega: float, harmonics: int) -> np.ndarray:
        """Exact (1/T) int_0^T x(t) e^{-j k w t} dt for k = 1..harmonics, T = t_end (complex, (K,))."""
        ends = np.append(flow.t0[1:], t_end)
        pieces = ((self.matrices[mode], z0, t0, t1) for t0, z0, mode, t1 in zip(flow.t0, flow.z0, flow.modes, ends))
        return piecewise_fourier(pieces, t_end, omega, harmonics, self.x_row)

    # -------------------------------------------------------------------------------------------- flow

    def flow(self, z0: np.ndarray, mode0: int, t_end: float, *, monodromy: bool = False,
             max_events: int = 10_000, limit: float = math.inf) -> Flow:
        """Flow from (z0, mode0) over [0, t_end] (s), switches located to rounding level.

        ``limit``: a bound on |x|; the flow stops (``Flow.stopped``: the time) where a state component passes
        ``limit`` / max|C'| (x may then have passed it), so a strongly diverging motion ends before its
        switching surfaces drown in rounding.

        Raises
        ------
        HybridError
            Sliding motion or an inadmissible mode after a switch, a grazing switch (monodromy undefined),
            the input leaving the modelled range, or more than ``max_events`` switches (raise the bound for
            long runs).
        """
        z = np.array(z0, dtype=float)
        mode = int(mode0)
        pending = []
        if not admissible(self.matrices[mode], self.rows[mode], z):
            # a switch due at t = 0 (the previous flow of a run ended on it, within rounding): take it now; a flow
            # with a monodromy (shooting) never starts on a switch, so there it is an error
            far = (self.rows[mode] @ z < 0) & ~rows_on_zero(self.rows[mode], z)   # violated beyond rounding
            if monodromy or np.any(far):
                raise HybridError(f"the start state violates a guard of mode {self.element.modes[mode].label!r}")
            from_mode = mode
            z, mode = self.admissible_mode(z, mode)
            pending.append((0.0, -1, from_mode, mode))
        if t_end == 0.0:
            return Flow(z, mode, np.eye(self.size) if monodromy else None, np.array([0.0]), z[None, :].copy(),
                        np.array([mode]), [], span=0.0)
        t = 0.0
        M = np.eye(self.size) if monodromy else None
        t0s, z0s, modes, events = [0.0], [z.copy()], [mode], pending
        seg_t = 0.0
        leaving = rows_on_zero(self.rows[mode], z)
        state_limit = limit / self.x_scale
        stopped = None
        while t < t_end:
            A, E, dt, rows = self.matrices[mode], self.exps[mode], self.steps[mode], self.rows[mode]
            rows_a = rows @ A
            t, j = scan_steps(A, E, dt, rows, rows_a, rows_a @ A, leaving, z, t, t_end,  # to t_end, or an event
                              state_limit)
            if j == BEYOND_LIMIT:
                stopped = t
                break
            if j < 0:
                leaving[:] = False
                continue
            target = self.targets[mode][j]
            if target == OUT_OF_RANGE:
                raise HybridError(f"at t = {t:.6g} s the input x = {self.x(z):.6g} left the range the "
                                  f"{self.element.name} model covers")
            if len(events) >= max_events:
                raise HybridError(f"max_events = {max_events} switches reached at t = {t:.6g} s of {t_end:.6g} s "
                                  "(raise max_events for longer runs; many switches in a short time mean a "
                                  "sliding or chattering motion)")
            r, R = rows[j], self.resets[mode][j]
            f_minus = A @ z
            z_plus = R @ z
            A_new = self.matrices[target]
            f_plus = A_new @ z_plus
            if M is not None:
                S = saltation(R, f_minus, f_plus, r)
                if S is None:
                    raise HybridError(f"grazing switch at t = {t:.6g} s (the guard is tangent to the flow): "
                                      "the monodromy is undefined there")
                M = S @ (expm(A * (t - seg_t)) @ M)
            z = z_plus
            if not admissible(A_new, self.rows[target], z):
                raise HybridError(f"no admissible mode after the switch at t = {t:.6g} s, x = {self.x(z):.6g}: "
                                  "the motion slides on the switching surface (sliding / chattering motion is "
                                  "not modelled)")
            events.append((t, j, mode, target))
            mode = target
            seg_t = t
            t0s.append(t)
            z0s.append(z.copy())
            modes.append(mode)
            leaving = rows_on_zero(self.rows[mode], z)
        if M is not None:
            M = expm(self.matrices[mode] * (t - seg_t)) @ M
        return Flow(z, mode, M, np.array(t0s), np.array(z0s), np.array(modes, dtype=int), events, stopped=stopped,
                    span=t_end)
