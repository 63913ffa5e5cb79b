"""The exact forced response of a loop with a pure delay and a static element: the delay equation at the forcing
period.

Loop: s' = A s + B f(x(t - T)), x = R sin(w t) - C s (plant G e^{-sT}, static element y = f(x) with sloped pieces
or smooth, driven by r = R sin(w t) at the summing junction). Its response at the forcing period P = 2 pi / w is a
periodic boundary value problem of the delay equation, discretised exactly as the autonomous orbit of
:mod:`dfloop.hybrid.dde` (exact plant flow over each step, Gauss-Legendre quadrature split where the delayed x
crosses a kink, cubic interpolation of the history, 4th order), with two differences: the period is fixed (no
phase condition, no period unknown), and the node equations carry the forcing, x_k + C s_k = R sin(w t_k).
Newton solves them at N, 2N, ... nodes until the fundamental amplitude changes by less than 1e-8 (the change is
the stated error). The Floquet multipliers are those of the discretised history along the orbit
(:func:`dfloop.hybrid.dde.multipliers`: the forcing does not enter the linearisation); a forced orbit has no
trivial multiplier, so the orbit is stable when all of them lie inside the unit circle.
"""
from __future__ import annotations

import math

import numpy as np

from .dde import DDELoop, DelayDDE, balanced_states, multipliers, node_jacobian, node_states

__all__ = ["forced_dde_orbit", "TARGET", "MAX_NODES"]

TARGET = 1e-8          # change of the fundamental amplitude between the last two resolutions (relative)
MAX_NODES = 4096


def _equations(dde: DelayDDE, x: np.ndarray, s0: np.ndarray, r: np.ndarray):
    """(residual, node states S (N + 1, n), quadrature data) of the forced periodic equations."""
    S, data = node_states(dde, x, s0)
    return np.concatenate([x + S[:-1] @ dde.C - r, S[-1] - s0]), S, data


def _newton(A, B, C, f, kinks, T, P, x, s0, R, tol, max_iterations):
    """Newton with a backtracking line search on the forced equations at x.size nodes. Returns (S (N, n), residual,
    iterations) or raises RuntimeError with the reason."""
    N, n = x.size, s0.size
    dde = DelayDDE(A, B, C, f, T, P / N, kinks)
    r = R * np.sin(2 * math.pi * np.arange(N) / N)
    scale = max(float(np.max(np.abs(r))), 1e-300)
    res_prev = math.inf
    for it in range(1, max_iterations + 1):
        Rv, S, data = _equations(dde, x, s0, r)
        res = float(np.max(np.abs(Rv))) / scale
        if res <= tol or (res <= 1e-9 and res > 0.5 * res_prev):
            return S[:-1], res, it
        res_prev = res
        J = node_jacobian(dde, x, data)[:N + n]          # without the phase row
        try:
            d = np.linalg.solve(J, -Rv)
        except np.linalg.LinAlgError:
            raise RuntimeError(f"singular Jacobian at iteration {it} (a fold of the forced response)") from None
        step = 1.0
        for _ in range(12):
            x_try, s_try = x + step * d[:N], s0 + step * d[N:]
            if float(np.max(np.abs(_equations(dde, x_try, s_try, r)[0]))) < float(np.max(np.abs(Rv))) * (1 - 1e-4 * step):
                break
            step *= 0.5
        else:
            if res <= 1e-9:
                return S[:-1], res, it
            raise RuntimeError(f"Newton iteration {it}: no step reduces the residual {res:.2e}")
        x, s0 = x_try, s_try
    raise RuntimeError(f"Newton did not converge in max_iterations = {max_iterations} (residual {res:.2e}); "
                       "raise max_iterations")


def _start(loop: DDELoop, N_of, R: float, w: float, A0: float, N: int):
    """Node values of x and plant states of the DF's forced solution x = Im(E e^{jwt}), E = R / (1 + G(jw)
    e^{-jwT} N(A0)), the plant driven by the delayed fundamental of N's output."""
    A, B, C, T = loop.A, loop.B, loop.C, loop.delay
    n = A.shape[0]
    nv = complex(N_of(A0))
    v = np.linalg.solve(1j * w * np.eye(n) - A, B)               # G(jw) = C v (c = C s, x = r - c)
    Gw = complex(C @ v) * np.exp(-1j * w * T)
    E = R / (1 + Gw * nv)
    t = np.arange(N) * (2 * math.pi / w) / N
    X = v * (nv * E * np.exp(-1j * w * T))
    S = (X[None, :] * np.exp(1j * w * t[:, None])).imag
    return (E * np.exp(1j * w * t)).imag, S


def forced_dde_orbit(loop: DDELoop, N_of, R: float, w: float, A0: float, *, nodes: int = 128,
                     target: float = TARGET, max_nodes: int = MAX_NODES, tol: float = 1e-12,
                     max_iterations: int = 40) -> dict:
    """The periodic response at the forcing period of a delayed loop with a static element (module notes).

    Parameters
    ----------
    loop : DDELoop
        From :func:`dfloop.hybrid.loop_model` for a delayed plant and a static element.
    N_of : callable
        A -> N(A), the element's describing function (the start's gain).
    R, w : float
        Forcing amplitude (element input units) and frequency (rad/s).
    A0 : float
        The DF's amplitude of x at w (the start).
    nodes, target, max_nodes, tol, max_iterations
        First resolution (at least 3 nodes per delay), the change of A between resolutions to reach, the finest
        resolution, Newton's tolerance and bound.

    Returns
    -------
    dict
        ``success``; with an orbit: ``X1`` (complex fundamental of x, x ~ Im(X1 e^{jwt})), ``multipliers``
        (largest first), ``stable``, ``residual``, ``iterations``, ``nodes``, ``error_estimate`` (the last change
        of |X1|), ``target_met``, ``message``; without: ``message`` (the reason).
    """
    A, B, C, f, kinks, T = loop.A, loop.B, loop.C, loop.f, loop.kinks, loop.delay
    P = 2 * math.pi / w
    if T < 3 * P / max_nodes:
        raise ValueError(f"G: the delay {T:g} s is below 3/{max_nodes} of the forcing period {P:g} s; the delay "
                         "equation solver needs at least 3 grid steps per delay (use the plant without the delay)")
    Nn = max(int(nodes), int(math.ceil(3 * P / T)) + 1)
    x, S = _start(loop, N_of, R, w, A0, Nn)
    A, B, C, S = balanced_states(A, B, C, S)
    s0 = S[0]
    levels, mus = [], []
    while True:
        try:
            S, res, it = _newton(A, B, C, f, kinks, T, P, x, s0, R, tol, max_iterations)
        except RuntimeError as exc:
            return dict(success=False, message=f"{Nn} nodes: {exc}")
        x = -(S @ C) + R * np.sin(2 * math.pi * np.arange(Nn) / Nn)
        X1 = 2j * complex(np.fft.rfft(x)[1]) / Nn
        levels.append((Nn, X1, res, it))
        if len(mus) < 2:
            mus.append(multipliers(A, B, C, f, T, S, P, kinks, x=x))
        if len(levels) >= 2:
            err = abs(abs(levels[-1][1]) / abs(levels[-2][1]) - 1)
            if err <= target or 2 * Nn > max_nodes:
                break
        x = np.fft.irfft(np.fft.rfft(x), n=2 * Nn) * 2.0
        s0 = S[0]
        Nn *= 2
    Nn, X1, res, it = levels[-1]
    mu = mus[-1]
    met = err <= target
    msg = (f"delay equation at the forcing period: converged in {it} Newton iteration(s), residual {res:.1e}; "
           f"change from {levels[-2][0]} to {Nn} nodes: A {err:.1e}")
    if not met:
        msg += f" - above the target {target:g}; raise max_nodes (now {max_nodes}) for a smaller error"
    return dict(success=True, X1=X1, multipliers=mu, stable=bool(np.all(np.abs(mu) < 1.0)), residual=res,
                iterations=it, nodes=Nn, error_estimate=err, target_met=met, message=msg,
                multipliers_coarse=mus[0])
