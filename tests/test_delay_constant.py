"""A constant input (reference r0, load) on loops with a pure delay, against truths written here.

- Relay with hysteresis around G e^{-sT}, r0 and load: the asymmetric orbit's closed conditions (the periodic
  response of the plant to the delayed rectangular wave plus the load, from matrix exponentials over its pieces;
  x = r0 - c crosses +a at the switch up and -a at the switch down), solved by fsolve.
- Saturation and backlash (delay differential equations): a long method-of-steps run written here (exact plant
  flow for an input linear between the grid nodes, the element on the node samples, the delay a whole number of
  steps), settled, against the orbit's period, amplitude and mean.
"""
from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import fsolve

import dfloop as df
from dfloop.hybrid import loop_model
from dfloop.hybrid.delay import delay_orbit, delay_simulation
from dfloop.solve.delay import delayed

R0, LOAD = 0.2, 0.1


def _ss(G):
    s = ct.ss(G)
    return np.asarray(s.A, float), np.asarray(s.B, float)[:, 0], np.asarray(s.C, float)[0]


def _periodic_state(A, B, pieces, P):
    """Plant state at t = 0 of the periodic response to a piecewise-constant input [(start, level)] on [0, P)."""
    n = A.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n] = A, B
    Phi, F = np.eye(n), np.zeros(n)
    bounds = [p[0] for p in pieces] + [P]
    for (t0, u), t1 in zip(pieces, bounds[1:]):
        E = expm(aug * (t1 - t0))
        F = E[:n, :n] @ F + E[:n, n] * u
        Phi = E[:n, :n] @ Phi
    return np.linalg.solve(np.eye(n) - Phi, F)


def _relay_orbit(A, B, C, M, a, T, r0, load, guess):
    """(time at +M, time at -M) of the relay's orbit with x(0) = +a rising (switch up), x(d1) = -a (down)."""

    def x_at(d1, d2, t):
        P = d1 + d2
        ups = [(0.0 + T) % P, (d1 + T) % P]                   # the plant sees y's switches T later
        levels = [M + load, -M + load]
        order = np.argsort(ups)
        pieces = [(ups[i], levels[i]) for i in order]
        pieces = [(0.0, pieces[-1][1])] + pieces if pieces[0][0] > 0 else pieces
        s0 = _periodic_state(A, B, pieces, P)
        n = A.shape[0]
        aug = np.zeros((n + 1, n + 1))
        aug[:n, :n], aug[:n, n] = A, B
        s, tc = s0, 0.0
        for (t0, u), t1 in zip(pieces, [p[0] for p in pieces[1:]] + [P]):
            if t <= t1:
                E = expm(aug * (t - t0))
                return r0 - C @ (E[:n, :n] @ s + E[:n, n] * u)
            E = expm(aug * (t1 - t0))
            s = E[:n, :n] @ s + E[:n, n] * u
        return r0 - C @ s

    def eqs(v):
        d1, d2 = v
        return [x_at(d1, d2, 0.0) - a, x_at(d1, d2, d1) + a]

    d1, d2 = fsolve(eqs, guess, xtol=1e-14)
    return d1, d2, x_at


def test_biased_relay_with_delay_matches_the_closed_conditions():
    T, M, a = 0.4, 1.0, 0.05
    G0 = ct.tf([1.0], [1.0, 2.0, 1.0])
    N = df.Relay(M=M, hysteresis=a)
    loop = loop_model(delayed(G0, T), N, 0.27, 1.9, r0=R0, load=LOAD)
    assert loop.r0 == R0 and loop.load == LOAD
    out = delay_orbit(loop, 0.27, 1.9, bias=0.03)
    assert out["success"], out["message"]
    A, B, C = _ss(G0)
    P = out["period"]
    sw = np.sort(out["switching_times"])
    ups = [t for t in sw if np.interp(t + 1e-9 * P, out["t"], out["y"], period=P) > 0]
    d1 = (sw[(np.searchsorted(sw, ups[0]) + 1) % sw.size] - ups[0]) % P
    d1_true, d2_true, x_at = _relay_orbit(A, B, C, M, a, T, R0, LOAD, [d1, P - d1])
    assert abs(d1_true + d2_true - P) < 1e-9 * P
    assert abs(d1_true - d1) < 1e-9 * P
    assert d1_true / (d1_true + d2_true) != pytest.approx(0.5, abs=1e-3)   # the load makes it asymmetric
    # the orbit's x (read back in the loop's signals) is the closed form's, and so is its mean
    tt = np.linspace(0.0, P, 401)[:-1]
    xs = np.array([x_at(d1_true, d2_true, t) for t in tt])
    assert abs(out["mean"] - xs.mean()) < 1e-6
    assert abs(out["x"].max() - xs.max()) < 1e-6 and abs(out["x"].min() - xs.min()) < 1e-6
    assert set(np.round(out["y"], 12)) == {M, -M}


def _reference_run(A, B, C, element, T, r0, load, x_hist, h, steps):
    """Method of steps written here: the plant flows exactly for u linear between the grid nodes (an augmented
    exponential), u_k = element(x_{k-d}) + load with T = d h, x = r0 - C s; returns x at the nodes."""
    n = A.shape[0]
    d = int(round(T / h))
    assert abs(d * h - T) < 1e-12 * T
    M = np.zeros((n + 2, n + 2))
    M[:n, :n], M[:n, n], M[n, n + 1] = A, B, 1.0 / h
    E = expm(M * h)
    Phi, g0, g1 = E[:n, :n], E[:n, n] - E[:n, n + 1], E[:n, n + 1]
    xs = list(x_hist)                                     # x at t_{-d} .. t_0 (the last one is the start's)
    us = [element(x) + load for x in xs]
    s = np.linalg.lstsq(C[None, :], [r0 - xs[-1]], rcond=None)[0]
    out = np.empty(steps)
    for k in range(steps):
        s = Phi @ s + g0 * us[-d - 1] + g1 * us[-d]
        x = r0 - C @ s
        xs.append(x)
        us.append(element(x) + load)
        out[k] = x
    return np.array(out)


def _settled(x, h, periods_tail):
    """(period, amplitude of the fundamental, mean) of the tail of a uniformly sampled x."""
    m = np.mean(x[-periods_tail:])
    v = x - m
    up = np.flatnonzero((v[:-1] < 0) & (v[1:] >= 0))
    up = up[up > x.size // 2]
    tc = (up - v[up] / (v[up + 1] - v[up])) * h
    P = float(np.mean(np.diff(tc)[-10:]))
    i0 = int(round(tc[-11] / h))
    seg = x[i0:int(round(tc[-1] / h))]
    t = np.arange(seg.size) * h
    w = 2 * math.pi / P
    c = 2 * np.mean(seg * np.exp(-1j * w * t))
    return P, abs(c), float(np.mean(seg))


@pytest.mark.parametrize("case", ["saturation", "backlash"])
def test_delay_equation_with_constant_input_matches_a_method_of_steps(case):
    if case == "saturation":
        G0, T, N = ct.tf([1.0], [1.0, 2.0, 1.0]), 0.4, df.Saturation(0.2, 10.0)
        lim, k = 0.2, 10.0
        element = lambda x: k * min(max(x, -lim), lim)            # noqa: E731
        start, bias = (0.437, 2.14), 0.0
    else:
        G0, T, N = ct.tf([3.0], [1.0, 1.0, 0.0]), 0.2, df.Backlash(h=0.5)
        state = {"c": 0.0}

        def element(x):
            if x - state["c"] > 0.25:
                state["c"] = x - 0.25
            elif x - state["c"] < -0.25:
                state["c"] = x + 0.25
            return state["c"]
        start, bias = (0.8245, 1.3876), -LOAD     # the integrator holds the output's mean at -load
    loop = loop_model(delayed(G0, T), N, *start, r0=R0, load=LOAD)
    out = delay_orbit(loop, *start, bias=bias)
    assert out["success"], out["message"]
    A, B, C = _ss(G0)
    P0 = 2 * math.pi / start[1]
    d = 200 if case == "saturation" else 150
    h = T / d                                         # about 1400-3700 steps per period
    hist = R0 + start[0] * np.sin(start[1] * h * np.arange(-d, 1))
    steps = int(60 * P0 / h)
    x = _reference_run(A, B, C, element, T, R0, LOAD, hist, h, steps)
    P, amp, mean = _settled(x, h, int(10 * P0 / h))
    # the reference is 2nd order (input linear between nodes): measured 1e-7..5e-7 in P, 4e-6..2e-5 in A
    assert abs(P / out["period"] - 1) < 2e-6
    assert abs(amp / out["amplitude"] - 1) < 1e-4
    assert abs(mean - out["mean"]) < 1e-5 * out["amplitude"]
    assert abs(out["mean"] - R0) > 1e-1 * out["amplitude"]      # the orbit's bias is not r0 alone
    # the run the verification uses reads back the same signals: its settled mean is the orbit's
    sim = delay_simulation(loop, *start, 40, 256)
    tail = sim.t > sim.t[-1] - 10 * out["period"]
    assert abs(np.mean(sim.x[tail]) - out["mean"]) < 2e-2 * out["amplitude"]


def test_public_exact_and_verify_take_a_constant_input_with_a_delay():
    G = delayed(ct.tf([1.0], [1.0, 2.0, 1.0]), 0.4)
    N = df.Relay(M=1.0, hysteresis=0.05)
    e = df.exact_cycle(G, N, (0.27, 1.9), r0=R0, load=LOAD, bias=0.03)
    assert e.success, e.message
    assert e.mean is not None and abs(e.mean - float(np.mean(e.x))) < 1e-12
    v = df.verify_cycle(G, N, (e.amplitude, e.frequency), r0=R0, load=LOAD, bias=e.mean, periods=40)
    assert v.verdict == "stable", v.message
    with pytest.raises(ValueError, match="r0"):
        loop_model(delayed(ct.tf([1.0], [1.0, 1.0]), 0.3), df.DynamicBacklash(m1=1.0, m2=1.0, h=0.1, restitution=0.5), 1.0, 1.0,
                   r0=0.1)
