"""Periodic orbits of a delayed loop with a static element with sloped pieces or a smooth one: a delay
differential equation, discretised.

Loop: s' = A s + B u(t), u(t) = f(x(t - T)), x = -C s (plant G e^{-sT}, static element y = f(x), e.g.
saturation, dead zone, cubic stiffness). The state of such a loop is a function (the history of x over a delay),
so the loop is discretised on a uniform grid t_k = k h, h = P / N over one period P:

- the plant is integrated exactly for a given input: s_{k+1} = e^{Ah} s_k + int_0^h e^{A(h - r)} B u(t_k + r) dr;
- the integral by 3-point Gauss-Legendre quadrature (exact matrices e^{A(h - r_q)} B);
- the delayed input u(t_k + r_q) = f(x(t_k + r_q - T)) from cubic (4-point Lagrange) interpolation of x at the
  grid nodes around t_k + r_q - T.

Both are 4th order in h for a smooth input (the quadrature is 6th order, the interpolation 4th), so the scheme is
a 4th-order method of steps when f is smooth; a kink of f (saturation, dead zone) crossed inside a step lowers
the local order there. ``benchmarks/bench_delay_exact.py`` measures the order on both kinds.

**Periodic orbit.** With h = P / N and the interpolation indices taken modulo N, the N steps of one period are a
set of equations in (s_0..s_{N-1}, P), all independent given the unknowns: a periodic boundary value problem,
solved by Newton with the exact Jacobian of the discrete equations (the period's column by a central
difference), with the phase condition that x's fundamental is a sine at t = 0 (the :class:`~dfloop.exact.ExactCycle`
time origin).

**Multipliers.** The same scheme run as a time-stepping map has a finite state: s_k and the node values of x over
the delay window (the nodes the interpolation can reach). Its Jacobian over N steps along the orbit is the
monodromy of the discretised history; its eigenvalues approximate the dominant Floquet multipliers of the delay
equation (the others cluster at 0). :func:`dde_orbit` computes them at N and at 2N and reports their change,
the convergence test.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from ..describing.time_model import PiecewiseAffine, Smooth
from .realisation import conditioned
from .run import LoopSimulation

__all__ = ["DDELoop", "DelayDDE", "dde_orbit", "dde_simulation", "periodic_orbit", "multipliers", "static_map"]

_GL_NODES = np.array([0.5 - math.sqrt(15) / 10, 0.5, 0.5 + math.sqrt(15) / 10])   # Gauss-Legendre on [0, 1]
_GL_WEIGHTS = np.array([5.0, 8.0, 5.0]) / 18.0


def static_map(tm):
    """(f, kinks) of a static element's time model, or (None, None): a :class:`Smooth` model is y = f(x) without
    kinks; a :class:`PiecewiseAffine` one is static when it has no state, every mode's output depends on x
    alone, every guard is a threshold on x, and the modes' intervals of x tile the line without overlap (no
    hysteresis): then f is its ``response`` and the kinks are the thresholds."""
    if isinstance(tm, Smooth):
        return tm.f, np.empty(0)
    if not isinstance(tm, PiecewiseAffine) or tm.n_states:
        return None, None
    intervals = []
    for m in tm.modes:
        if m.ge != 0.0 or m.de != 0.0:
            return None, None
        lo, hi = -math.inf, math.inf
        for g in m.guards:
            if g.cxd != 0.0 or g.ce != 0.0 or g.reset is not None or g.cx == 0.0:
                return None, None
            level = -g.c1 / g.cx
            if g.cx > 0:           # x >= level inside the mode
                lo = max(lo, level)
            else:                  # x <= level
                hi = min(hi, level)
        intervals.append((lo, hi))
    intervals.sort()
    if any(a[1] != b[0] for a, b in zip(intervals[:-1], intervals[1:])) or intervals[0][0] != -math.inf \
            or intervals[-1][1] != math.inf:
        return None, None            # overlapping (hysteretic) or gapped modes: not a static map
    kinks = np.array([lo for lo, _ in intervals[1:]], float)
    return (lambda x: np.asarray(tm.response(np.asarray(x, float)), float)), kinks


class DDELoop:
    """The loop of a plant (A, B, C) with a pure delay and a static element y = f(x) (kinks at ``kinks``): the
    loop model :func:`dfloop.hybrid.loop_model` builds for a delayed plant and a static element that is not
    piecewise constant (saturation, dead zone, cubic stiffness, ...). A delay differential equation: its orbit
    by :func:`dde_orbit`, its run by :func:`dde_simulation` (``delay`` > 0 tells the callers)."""

    exact = True            # a converged discretisation with an error estimate (not a flow to rounding level)
    settle_periods = 0.0
    method = ("delay differential equation (periodic method of steps: exact plant flow, Gauss-Legendre input split "
              "at the element's kinks, cubic history interpolation; 4th order)")

    def __init__(self, A, B, C, f, kinks, delay: float, name: str = ""):
        # the well-conditioned realisation of the exact flows (block-diagonal, balanced, from order 7): only x = -C s
        # leaves this model, so its states need not be the plant's as given
        self.A, self.B, self.C, _ = conditioned(*(np.asarray(a, float) for a in (A, B, C)))
        self.n = self.A.shape[0]
        self.f, self.kinks, self.delay, self.name = f, np.asarray(kinks, float), float(delay), name
        self.plant = (self.A, self.B)


class DelayDDE:
    """The discretised delayed loop of a plant (A, B, C), a static map f with kinks at ``kinks`` (x values where
    f' jumps; none for a smooth f), a delay T and a step h.

    Each step k integrates the plant over [t_k, t_k + h] with quadrature points tau_p (3-point Gauss-Legendre;
    in a step where the delayed x crosses a kink, 3 points on each side of the crossing, so the integrand is
    smooth on every piece and the order is kept). A point's delayed value is the 4-point Lagrange interpolant of
    the node values x_j around t_k + tau_p - T.
    """

    def __init__(self, A, B, C, f, delay: float, h: float, kinks=()):
        self.A, self.B, self.C = (np.asarray(a, float) for a in (A, B, C))
        self.n = self.A.shape[0]
        self.f, self.delay, self.h = f, float(delay), float(h)
        self.kinks = np.asarray(kinks, float)
        self.Phi = expm(self.A * h)
        # regular points: E_q = h w_q e^{A(h - r_q h)} B
        self.tau = _GL_NODES * h
        self.E = np.array([expm(self.A * (h - t)) @ self.B for t in self.tau]) * (h * _GL_WEIGHTS)[:, None]

    def slope(self, x: np.ndarray) -> np.ndarray:
        """df/dx by a central difference (never across a kink: the step shrinks to stay on one side)."""
        d = 1e-7 * (1.0 + np.abs(x))
        if self.kinks.size:
            gap = np.min(np.abs(np.asarray(x)[..., None] - self.kinks), axis=-1)
            d = np.where(gap > 0, np.minimum(d, 0.5 * gap), d)
        return (self.f(x + d) - self.f(x - d)) / (2 * d)

    def stencil(self, times: np.ndarray, N: int):
        """(node indices mod N (.., 4), Lagrange weights (.., 4)) of x at ``times`` (s, on the periodic grid)."""
        pos = np.asarray(times, float) / self.h
        o = np.floor(pos)
        th = pos - o
        w = np.stack([-th * (th - 1) * (th - 2) / 6, (th + 1) * (th - 1) * (th - 2) / 2,
                      -(th + 1) * th * (th - 2) / 2, (th + 1) * th * (th - 1) / 6], axis=-1)
        idx = (o.astype(int)[..., None] - 1 + np.arange(4)) % N
        return idx, w

    def crossings(self, x: np.ndarray) -> list:
        """The kinks the delayed x crosses inside a step: (step k, kink b, time r into the step), in the order of
        the kinks, then of the steps."""
        N = x.size
        k = np.arange(N)
        out = []
        if self.kinks.size:
            ends_i, ends_w = self.stencil(np.stack([k * self.h - self.delay, (k + 1) * self.h - self.delay], 1), N)
            xe = np.einsum("kej,kej->ke", x[ends_i], ends_w)
            for b in self.kinks:
                for kk in np.flatnonzero((xe[:, 0] - b) * (xe[:, 1] - b) < 0):
                    out.append((int(kk), float(b), self._crossing(x, kk, b)))
        return out

    def points(self, x: np.ndarray, crossings: list | None = None):
        """Quadrature points of the N steps: (step k, E_p (n,), node indices (4,), weights (4,)) as arrays.
        ``crossings``: :meth:`crossings` of x when already known."""
        N = x.size
        k = np.arange(N)
        times = k[:, None] * self.h + self.tau[None, :] - self.delay            # delayed times (N, 3)
        idx, w = self.stencil(times, N)
        ks, Es, idxs, ws = [np.repeat(k, 3)], [np.tile(self.E, (N, 1))], [idx.reshape(-1, 4)], [w.reshape(-1, 4)]
        crossings = self.crossings(x) if crossings is None else crossings
        if crossings:
            keep = np.ones(N * 3, bool)
            cuts: dict = {}
            for kk, _, r in crossings:
                cuts.setdefault(kk, []).append(r)
            for kk, rs in cuts.items():   # a step crossing several kinks (a steep saturation) is cut at each
                keep[3 * kk:3 * kk + 3] = False
                for tq, Eq in split_step(self.A, self.B, self.h, rs):
                    i2, w2 = self.stencil(kk * self.h + tq - self.delay, N)
                    ks.append(np.full(tq.size, kk))
                    Es.append(Eq)
                    idxs.append(i2)
                    ws.append(w2)
            ks[0], Es[0], idxs[0], ws[0] = ks[0][keep], Es[0][keep], idxs[0][keep], ws[0][keep]
        return np.concatenate(ks), np.concatenate(Es), np.concatenate(idxs), np.concatenate(ws)

    def jump_terms(self, x: np.ndarray, crossings: list) -> list:
        """The derivatives of the steps' states through the crossing times where f jumps (a relay part: Coulomb
        friction, a preload): (step k, node indices (4,), d s_{k+1} / d x at those nodes (n, 4)) per crossing.

        Where the delayed x crosses b at r into step k, the step's input integral changes with r by
        e^{A(h - r)} B (f before - f after), and r with the node values by dr/dx_j = -w_j(r) / xi'(r) (xi the
        Lagrange interpolant, w_j its weights). Zero where f is continuous (a kink of the slope only), so only
        the jumps are listed; without them Newton's Jacobian misses the switch's first-order effect and stalls on
        a relay-like element."""
        N, h, T = x.size, self.h, self.delay
        out = []
        for kk, b, r in crossings:
            lo, hi = (float(v) for v in self.f(np.array([np.nextafter(b, -np.inf), np.nextafter(b, np.inf)])))
            if abs(hi - lo) <= 1e-9 * (abs(lo) + abs(hi)):
                continue                                                # continuous: a kink of the slope only
            idx, w = (a[0] for a in self.stencil(np.array([kk * h + r - T]), N))
            pos = (kk * h + r - T) / h
            th = pos - math.floor(pos)
            dw = np.array([-(3 * th * th - 6 * th + 2) / 6, (3 * th * th - 4 * th - 1) / 2,
                           -(3 * th * th - 2 * th - 2) / 2, (3 * th * th - 1) / 6]) / h     # d w / d r
            slope = float(dw @ x[idx])                                  # xi'(r)
            if slope == 0.0:
                continue
            before, after = (lo, hi) if slope > 0 else (hi, lo)
            kernel = expm(self.A * (h - r)) @ self.B
            out.append((kk, idx, np.outer(kernel * (before - after), -w / slope)))
        return out

    def _crossing(self, x, k, b):
        """Time into step k where the interpolated delayed x crosses b (bisection to rounding level, on the
        Lagrange cubic written out in floats)."""
        N, h, T = x.size, self.h, self.delay

        def g(r):
            pos = (k * h + r - T) / h
            o = math.floor(pos)
            th = pos - o
            w = (-th * (th - 1) * (th - 2) / 6, (th + 1) * (th - 1) * (th - 2) / 2,
                 -(th + 1) * th * (th - 2) / 2, (th + 1) * th * (th - 1) / 6)
            return sum(wi * float(x[(o - 1 + i) % N]) for i, wi in enumerate(w)) - b

        lo, hi = 0.0, h
        glo = g(lo)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if (g(mid) > 0) == (glo > 0):
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)


def split_step(A, B, h: float, cuts) -> list:
    """The quadrature of a step [0, h] cut at the times ``cuts`` (where the delayed x crosses kinks of f): per
    piece between consecutive cuts, its 3 Gauss-Legendre times tq and the matrices E_q = w_q e^{A(h - tq)} B
    times the piece's length (so the integrand is smooth on every piece and the order is kept)."""
    ends = [0.0, *sorted(cuts), h]
    out = []
    for a0, a1 in zip(ends[:-1], ends[1:]):
        tq = a0 + _GL_NODES * (a1 - a0)
        out.append((tq, np.array([expm(A * (h - t)) @ B for t in tq]) * ((a1 - a0) * _GL_WEIGHTS)[:, None]))
    return out


def node_states(dde: DelayDDE, x: np.ndarray, s0: np.ndarray):
    """(S (N + 1, n), (points, xi, crossings)): the plant states at the N + 1 nodes of one period driven by the
    delayed element output of the node values x, by the steps' recursion s_{k+1} = Phi s_k + sum_p E_p f(xi_p)
    from s0."""
    N = x.size
    crossings = dde.crossings(x)
    pts = dde.points(x, crossings)
    k, E, idx, w = pts
    xi = np.einsum("pj,pj->p", x[idx], w)
    F = np.zeros((N, dde.n))
    np.add.at(F, k, E * dde.f(xi)[:, None])
    S = np.empty((N + 1, dde.n))
    S[0] = s0
    for j in range(N):
        S[j + 1] = dde.Phi @ S[j] + F[j]
    return S, (pts, xi, crossings)


def _equations(A, B, C, f, delay, kinks, s0: np.ndarray, x: np.ndarray, P: float):
    """The periodic equations in (node values x, plant state s_0, P): x_k + C s_k (s_k from s_0 by the steps'
    recursion s_{k+1} = Phi s_k + sum_p E_p f(xi_p)), s_N - s_0, and the phase. Returns (R, S (N+1, n), dde,
    (points, xi))."""
    dde = DelayDDE(A, B, C, f, delay, P / x.size, kinks)
    S, data = node_states(dde, x, s0)
    R = np.concatenate([x + S[:-1] @ dde.C, S[-1] - s0, [_phase(x)]])
    return R, S, dde, data


def node_jacobian(dde: DelayDDE, x: np.ndarray, data) -> np.ndarray:
    """d R / d (x, s_0) ((N + n + 1) x (N + n)): the tangent of the steps' recursion, ds_k/dx and ds_k/ds_0,
    carried along the period, at fixed quadrature points, plus the moving crossing times where f jumps
    (:meth:`DelayDDE.jump_terms`)."""
    (k, E, idx, w), xi, crossings = data
    N, n, C = x.size, dde.n, dde.C
    fp = dde.slope(xi)
    order = np.argsort(k, kind="stable")
    bounds = np.searchsorted(k[order], np.arange(N + 1))
    jumps: dict = {}
    for kk, j_idx, term in dde.jump_terms(x, crossings):
        jumps.setdefault(kk, []).append((j_idx, term))
    J = np.zeros((N + n + 1, N + n))
    D = np.zeros((n, N))                 # ds_k / dx
    Pk = np.eye(n)                       # ds_k / ds_0
    for j in range(N):
        J[j, :N] = C @ D
        J[j, j] += 1.0
        J[j, N:] = C @ Pk
        D = dde.Phi @ D
        for p in order[bounds[j]:bounds[j + 1]]:
            D[:, idx[p]] += np.outer(E[p] * fp[p], w[p])
        for j_idx, term in jumps.get(j, ()):
            np.add.at(D.T, j_idx, term.T)
        Pk = dde.Phi @ Pk
    J[N:N + n, :N] = D
    J[N:N + n, N:] = Pk - np.eye(n)
    J[N + n, :N] = np.cos(2 * np.pi * np.arange(N) / N) * 2.0 / N
    return J


def _phase(x: np.ndarray) -> float:
    """Cosine part of x's fundamental over the period (0: x's fundamental is a sine at t = 0)."""
    N = x.size
    return float(np.cos(2 * np.pi * np.arange(N) / N) @ x) * 2.0 / N


def periodic_orbit(A, B, C, f, delay, s0: np.ndarray, x0: np.ndarray, P0: float, *, kinks=(), tol: float = 1e-12,
                   max_iterations: int = 40):
    """Newton on the discrete periodic equations in (x at the N nodes, s_0, P) (N + n + 1 unknowns: the plant
    order enters only through the recursion's tangent). Returns (S (N, n) the node states, P, residual,
    iterations) or raises RuntimeError."""
    x, s0, P = np.array(x0, float), np.array(s0, float), float(P0)
    N, n = x.size, s0.size
    res_prev = math.inf
    for it in range(1, max_iterations + 1):
        R, S, dde, data = _equations(A, B, C, f, delay, kinks, s0, x, P)
        scale = max(float(np.abs(x).max()), 1e-300)
        res = float(np.abs(R).max()) / scale
        if res <= tol or (res <= 1e-9 and res > 0.5 * res_prev):
            return S[:-1], P, res, it
        res_prev = res
        J = np.zeros((N + n + 1, N + n + 1))
        J[:, :N + n] = node_jacobian(dde, x, data)
        dP = 1e-7 * P
        Rp = _equations(A, B, C, f, delay, kinks, s0, x, P + dP)[0]
        Rm = _equations(A, B, C, f, delay, kinks, s0, x, P - dP)[0]
        J[:, -1] = (Rp - Rm) / (2 * dP)
        try:
            d = np.linalg.solve(J, -R)
        except np.linalg.LinAlgError:
            raise RuntimeError(f"singular Jacobian at iteration {it} (a marginal orbit)") from None
        step = 1.0
        for _ in range(12):
            x_try, s_try, P_try = x + step * d[:N], s0 + step * d[N:N + n], P + step * d[-1]
            if P_try > 0:
                R_try = _equations(A, B, C, f, delay, kinks, s_try, x_try, P_try)[0]
                if float(np.abs(R_try).max()) < float(np.abs(R).max()) * (1 - 1e-4 * step):
                    break
            step *= 0.5
        else:
            if res <= 1e-9:
                return S[:-1], P, res, it
            raise RuntimeError(f"Newton iteration {it}: no step reduces the residual {res:.2e}")
        x, s0, P = x_try, s_try, P_try
    raise RuntimeError(f"Newton did not converge in max_iterations = {max_iterations} (residual {res:.2e}); "
                       "raise max_iterations")


def multipliers(A, B, C, f, delay, S: np.ndarray, P: float, kinks=(), count: int = 6,
                x: np.ndarray | None = None) -> np.ndarray:
    """The ``count`` largest eigenvalues of the monodromy of the discretised history along the orbit S: the
    time-stepping form of the same scheme (state: s_k and the node values of x the interpolation can reach).
    ``x``: the node values of x when they are not -C s (a forcing added at the summing junction)."""
    N, n = S.shape
    dde = DelayDDE(A, B, C, f, delay, P / N, kinks)
    x = -(S @ dde.C) if x is None else np.asarray(x, float)
    crossings = dde.crossings(x)
    k, E, idx, w = dde.points(x, crossings)
    xi = np.einsum("pj,pj->p", x[idx], w)
    fp = dde.slope(xi)
    # node offsets relative to the step (<= 0): congruent to idx - k modulo N, within the 5-node window around
    # -T / h (a delay longer than half the period, or than the period, wraps the periodic indices)
    r_lo = -int(math.ceil(delay / dde.h)) - 3
    rel = (idx - k[:, None] - r_lo) % N + r_lo
    jumps: dict = {}
    for kk, j_idx, term in dde.jump_terms(x, crossings):   # the crossing times where f jumps, as node offsets
        jumps.setdefault(kk, []).append(((j_idx - kk - r_lo) % N + r_lo, term))
    lo = int(min([rel.min()] + [int(j_rel.min()) for terms in jumps.values() for j_rel, _ in terms]))
    H = -lo + 1                                              # history slots: x_{k+lo} .. x_k
    D = n + H
    M = np.eye(D)
    order = np.argsort(k, kind="stable")
    k, E, rel, w, fp = k[order], E[order], rel[order], w[order], fp[order]
    bounds = np.searchsorted(k, np.arange(N + 1))
    for step_k in range(N):
        step = np.zeros((D, D))
        step[:n, :n] = dde.Phi
        for p in range(bounds[step_k], bounds[step_k + 1]):
            for i in range(4):
                step[:n, n + rel[p, i] - lo] += fp[p] * w[p, i] * E[p]
        for j_rel, term in jumps.get(step_k, ()):
            for i in range(4):
                step[:n, n + j_rel[i] - lo] += term[:, i]
        step[n:n + H - 1, n + 1:n + H] = np.eye(H - 1)
        step[n + H - 1, :] = -dde.C @ step[:n, :]
        M = step @ M
    mu = np.linalg.eigvals(M)
    return mu[np.argsort(-np.abs(mu))][:count]


def _start(A, B, C, f, delay, A0, w0, N):
    """Node states of the DF's sinusoidal orbit x = A0 sin(w0 t) (plant driven by the delayed fundamental)."""
    theta = 2 * np.pi * np.arange(256) / 256
    y = f(A0 * np.sin(theta))
    Y1 = complex(2 * np.mean(y * np.sin(theta)) + 2j * np.mean(y * np.cos(theta)))
    t = np.arange(N) * (2 * np.pi / w0) / N
    X = np.linalg.solve(1j * w0 * np.eye(A.shape[0]) - A, B) * Y1
    return (X[None, :] * np.exp(1j * w0 * (t[:, None] - delay))).imag


def balanced_states(A, B, C, S):
    """The plant in states scaled to the size of x on the start orbit S (node states, rows): s = D s' with D the
    diagonal of each state's largest value over the size of x. An exact change of coordinates (x = -C s and the
    multipliers are unchanged) that puts the periodicity equations s_N - s_0 in the units of x: with integrators
    or slow poles the companion states of an orbit reach 1e8 times x, and Newton's residual was then the states'
    rounding. Returns (A', B', C', S')."""
    size = max(float(np.max(np.abs(S @ C))), 1e-300)
    d = np.max(np.abs(S), axis=0) / size
    d = np.where(d > 0, d, 1.0)
    return A * d[None, :] / d[:, None], B / d, C * d, S / d


SETTLE_PERIODS = 80    # periods of the prediction run before the second start (when Newton from the sinusoid fails)
_SETTLED = 1e-4        # the last two periods of that run agree to this (relative): a start for Newton


def settled_start(loop: DDELoop, A0: float, w0: float, N: int, plant: tuple, periods: int = SETTLE_PERIODS):
    """A start for Newton from the motion itself, when the DF's sinusoid is too far from the orbit (a strongly
    distorted orbit, e.g. a dead zone barely exceeded): run the loop ``periods`` periods of the prediction
    (:func:`dde_simulation`, same scheme), and when its last two periods (between upward crossings of x's
    mean) agree to 1e-4, sample the last one at N nodes with x's fundamental a sine at t = 0 (the phase
    condition; more nodes when the period is longer than predicted, so that the step stays below a third of the
    delay); the plant state at the first node is the least-squares fit of the discrete recursion to those
    samples. ``plant``: (A, B, C) in the coordinates Newton uses. Returns (x, s0, P) or None (the run diverged,
    came to rest or did not settle)."""
    A, B, C = plant
    T = loop.delay
    try:
        sim = dde_simulation(loop, A0, w0, periods, N)
    except ValueError:
        return None
    if sim.diverged or sim.x.size < 4 * N:
        return None
    h = float(sim.t[1] - sim.t[0])
    tail = sim.x[-3 * N:]
    mean = float(np.mean(tail))
    if float(np.max(np.abs(tail - mean))) <= 1e-9 * A0:
        return None                                                  # at rest
    d = sim.x - mean
    k = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0))
    if k.size < 3:
        return None
    ups = sim.t[k] + h * d[k] / (d[k] - d[k + 1])                   # upward crossings (linear between samples)
    p1, p2 = ups[-1] - ups[-2], ups[-2] - ups[-3]
    if abs(p1 / p2 - 1) > _SETTLED:
        return None
    P = float(p1)
    N = max(N, int(math.ceil(3 * P / T)) + 1)                         # at least 3 steps per delay
    tq = ups[-2] + P * np.arange(N) / N                               # the last period at N nodes (cubic)
    pos = tq / h
    o = np.clip(np.floor(pos).astype(int), 1, sim.x.size - 3)
    th = pos - o
    wts = np.stack([-th * (th - 1) * (th - 2) / 6, (th + 1) * (th - 1) * (th - 2) / 2,
                    -(th + 1) * th * (th - 2) / 2, (th + 1) * th * (th - 1) / 6], axis=-1)
    x = np.einsum("pj,pj->p", sim.x[o[:, None] - 1 + np.arange(4)], wts)
    c = np.fft.rfft(x)
    shift = np.angle(1j * c[1])                                      # fundamental turned to a sine at t = 0
    x = np.fft.irfft(c * np.exp(-1j * np.arange(c.size) * shift), n=N)
    # plant state at node 0: s_k = Phi^k s0 + g_k (g_k the response to the delayed input from s0 = 0), fitted to
    # x_k = -C s_k and to the periodicity s_N = s_0 together (a fast mode barely seen in x is fixed by the latter)
    n = A.shape[0]
    _, G0, dde, _ = _equations(A, B, C, loop.f, loop.delay, loop.kinks, np.zeros(n), x, P)
    M = np.empty((N, n))
    Pk = np.eye(n)
    for j in range(N):
        M[j] = C @ Pk
        Pk = dde.Phi @ Pk
    lhs = np.vstack([-M, Pk - np.eye(n)])
    rhs = np.concatenate([x + G0[:-1] @ C, -G0[-1]])
    s0 = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return x, s0, P


TARGET = 1e-8          # the change of A and w between the last two resolutions must fall below this (relative)
MAX_NODES = 4096       # the finest resolution dde_orbit tries (nodes per period)


def dde_orbit(loop: DDELoop, A0: float, w0: float, *, nodes: int = 128, target: float = TARGET,
              max_nodes: int = MAX_NODES, tol: float = 1e-12, harmonics: int = 15, samples: int = 512,
              settle_periods: float = 0.0) -> dict:
    """The periodic orbit of a delayed loop with a static element, by the discretised DDE (module notes).

    Solves at ``nodes``, 2 ``nodes``, 4 ``nodes``, ... points per period (at least 3 P / T + 1, so the step
    stays below a third of the delay), each from the previous orbit, until the change of A and of w between the
    last two resolutions is below ``target`` (relative) or the next would exceed ``max_nodes``. The orbit is the
    finest one; ``extra["error_estimate"]`` is the last change, a bound on its error as long as the error at
    least halves per doubling (the scheme is 4th order, measured in ``benchmarks/bench_dde_order.py``: the
    error is then about 1/15 of the change). When the target is not met within ``max_nodes`` the orbit is still
    returned, with ``extra["target_met"]`` False and the message saying so. The multipliers are those of the
    discretised history at the first two resolutions (``multipliers`` the finer, ``extra["multipliers_coarse"]``
    the coarser: their change is the convergence test). ``settle_periods`` > 0: Newton starts from the motion
    settled after that many periods of the prediction (:func:`settled_start`; from the sinusoid when it does not
    settle, said in the message), as it does anyway when Newton from the sinusoid fails. Returns a dict of
    :class:`dfloop.exact.ExactCycle` fields (``success`` False with the reason when Newton fails).
    """
    A, B, C, f, kinks, T = loop.A, loop.B, loop.C, loop.f, loop.kinks, loop.delay
    P0 = 2 * math.pi / w0
    if T < 3 * P0 / 4096:
        raise ValueError(f"G: the delay {T:g} s is below 3/4096 of the period {P0:g} s; the delay equation solver "
                         "needs at least 3 grid steps per delay (use the plant without the delay)")
    nodes = max(int(nodes), int(math.ceil(3 * P0 / T)) + 1)       # h <= T / 3: the history is in the past
    max_nodes = max(int(max_nodes), 2 * nodes)
    S = _start(A, B, C, f, T, A0, w0, nodes)
    A, B, C, S = balanced_states(A, B, C, S)
    x, s0, P = -(S @ C), S[0], P0
    levels = []                     # (nodes, A, w, S, P, residual, iterations, X)
    mus = []
    Nn = nodes
    note = ""
    if settle_periods > 0:          # the caller's choice: start from the settled motion
        start = settled_start(loop, A0, w0, Nn, (A, B, C), periods=settle_periods)
        if start is None:
            note = f"; the motion did not settle in {settle_periods:g} periods: Newton started on the prediction"
        else:
            x, s0, P = start
            Nn = x.size
    while True:
        try:
            S, P, res, it = periodic_orbit(A, B, C, f, T, s0, x, P, kinks=kinks, tol=tol)
        except RuntimeError as exc:
            start = settled_start(loop, A0, w0, Nn, (A, B, C)) if not levels else None
            if start is None:
                return dict(success=False, message=f"{Nn} nodes: {exc}", method=_method(levels, Nn))
            x, s0, P = start          # Newton from the sinusoid failed: once more from the settled motion
            Nn = x.size
            try:
                S, P, res, it = periodic_orbit(A, B, C, f, T, s0, x, P, kinks=kinks, tol=tol)
            except RuntimeError as exc2:
                return dict(success=False, message=f"{Nn} nodes: from the prediction: {exc}; from the motion "
                                                   f"settled after {SETTLE_PERIODS} periods: {exc2}",
                            method=_method(levels, Nn))
        x = -(S @ C)
        if P / Nn > T / 3:            # the period grew past 3 steps per delay: solve again on a finer grid
            fine = int(math.ceil(3 * P / T)) + 1
            x, s0 = np.fft.irfft(np.fft.rfft(x), n=fine) * (fine / Nn), S[0]
            Nn = fine
            continue
        X = 2j * np.fft.rfft(x)[1:harmonics + 1] / Nn
        levels.append((Nn, abs(X[0]), 2 * math.pi / P, S, P, res, it, X))
        if len(mus) < 2:
            mus.append(multipliers(A, B, C, f, T, S, P, kinks))
        if len(levels) >= 2:
            err = (abs(levels[-1][1] / levels[-2][1] - 1), abs(levels[-1][2] / levels[-2][2] - 1))
            if max(err) <= target or 2 * Nn > max_nodes:
                break
        x = np.fft.irfft(np.fft.rfft(x), n=2 * Nn) * 2.0      # the orbit on the finer grid (spectral)
        s0 = S[0]
        Nn *= 2
    Nn, A2, w2, S, P, res, it, X = levels[-1]
    mu1, mu2 = mus
    met = max(err) <= target
    # the trivial multiplier is the one closest to 1; the verdict uses the others
    nontrivial = np.delete(mu2, int(np.argmin(np.abs(mu2 - 1.0))))
    stable = bool(np.all(np.abs(nontrivial) < 1.0))
    t_new = np.arange(samples) * (P / samples)
    phase = float(np.angle(X[0]))
    c = np.fft.rfft(-(S @ C))
    c = c * np.exp(-1j * np.arange(c.size) * phase)               # time origin: x's fundamental a sine at 0
    spec = np.zeros(samples // 2 + 1, complex)
    m = min(c.size, spec.size)
    spec[:m] = c[:m]
    x_s = np.fft.irfft(spec, n=samples) * (samples / S.shape[0])
    k = np.arange(1, X.size + 1)
    X = X * np.exp(-1j * k * phase)
    msg = (f"converged in {it} Newton iteration(s), residual {res:.1e}; change from {levels[-2][0]} to {Nn} "
           f"nodes: A {err[0]:.1e}, w {err[1]:.1e}")
    if not met:
        msg += (f" - above the target {target:g}: the finest resolution allowed is max_nodes = {max_nodes}; "
                "raise max_nodes for a smaller error")
    msg += note
    return dict(success=True, message=msg, method=_method(levels, Nn), amplitude=float(abs(X[0])),
                frequency=2 * math.pi / P, period=P, t=t_new, x=x_s, y=f(x_s),
                switching_times=np.empty(0), harmonics=X, multipliers=mu2, stable=stable, residual=res,
                iterations=it, extra={"error_estimate": err, "target": target, "target_met": met,
                                      "multipliers_coarse": mu1, "nodes": Nn,
                                      "multiplier_nodes": (levels[0][0], levels[1][0])})


def _method(levels, Nn) -> str:
    used = [lv[0] for lv in levels] or [Nn]
    return (f"delay equation discretised ({', '.join(map(str, used))} nodes per period: exact plant flow, "
            "Gauss-Legendre input split at the kinks, cubic history interpolation; 4th order, refined until "
            "the change of A and w is below the target; error estimate in extra)")


def dde_simulation(loop: DDELoop, amplitude: float, frequency: float, periods: float, steps_per_period: int,
                   diverge: float = 1e6) -> LoopSimulation:
    """Run the delayed loop with a static element by the same scheme as a time-stepping method of steps.

    Start: the plant in the state the predicted sinusoid's fundamental drives it to, x's history over the
    delay the sinusoid A sin(w t), t <= 0. Step h = P / max(steps_per_period, 3 P / T) (every delayed point in
    the past); the quadrature is split where the delayed x crosses a kink of f, as in :class:`DelayDDE`.

    Returns the :class:`~dfloop.hybrid.run.LoopSimulation`, x and y at the grid times; stops early when |x|
    exceeds ``diverge`` times the amplitude.
    """
    A, B, C, f, kinks, T = loop.A, loop.B, loop.C, loop.f, loop.kinks, loop.delay
    P = 2 * math.pi / frequency
    if T < 3 * P / 4096:
        raise ValueError(f"G: the delay {T:g} s is below 3/4096 of the period {P:g} s; use the plant without it")
    steps = max(int(steps_per_period), int(math.ceil(3 * P / T)) + 1)
    h = P / steps
    dde = DelayDDE(A, B, C, f, T, h, ())
    H = int(math.ceil(T / h)) + 3                              # history nodes before t = 0
    n_steps = int(math.ceil(periods * steps))
    x = np.empty(H + n_steps + 1)
    x[:H + 1] = amplitude * np.sin(frequency * h * np.arange(-H, 1))
    s = _start(A, B, C, f, T, amplitude, frequency, 1)[0]
    x[H] = float(-C @ s)

    def interp(times):                                        # times (s, absolute, <= current) -> x values
        pos = times / h + H
        o = np.floor(pos).astype(int)
        th = pos - o
        w = np.stack([-th * (th - 1) * (th - 2) / 6, (th + 1) * (th - 1) * (th - 2) / 2,
                      -(th + 1) * th * (th - 2) / 2, (th + 1) * th * (th - 1) / 6], axis=-1)
        return np.einsum("pj,pj->p", x[o[:, None] - 1 + np.arange(4)], w)

    diverged = False
    k_done = 0
    for k in range(n_steps):
        t0 = k * h
        u_int = dde.E.T @ f(interp(t0 + dde.tau - T))
        if kinks.size:
            ends = interp(np.array([t0 - T, t0 + h - T]))
            cuts = []
            for b in kinks:
                if (ends[0] - b) * (ends[1] - b) < 0:
                    lo, hi = 0.0, h
                    g0 = ends[0] - b
                    for _ in range(60):
                        mid = 0.5 * (lo + hi)
                        if (interp(np.array([t0 + mid - T]))[0] - b > 0) == (g0 > 0):
                            lo = mid
                        else:
                            hi = mid
                    cuts.append(0.5 * (lo + hi))
            if cuts:   # cut at every kink crossed in the step
                u_int = sum(Eq.T @ f(interp(t0 + tq - T)) for tq, Eq in split_step(dde.A, dde.B, h, cuts))
        s = dde.Phi @ s + u_int
        x[H + k + 1] = float(-C @ s)
        k_done = k + 1
        if not math.isfinite(x[H + k + 1]) or abs(x[H + k + 1]) > diverge * amplitude:
            diverged = True
            break
    xs = x[H:H + k_done + 1]
    t = np.arange(xs.size) * h
    method = (f"delay equation, method of steps ({steps} steps per period: exact plant flow, Gauss-Legendre input "
              "split at the kinks, cubic history interpolation; 4th order)")
    return LoopSimulation(t, xs, f(xs), diverged, method)
