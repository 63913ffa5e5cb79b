"""The dynamic backlash behind a plant with a pure delay, against truths written here.

The truth is an event-located solve_ivp run (DOP853, rtol 1e-12) of the delay equation with impacts: restarted at
every impact (law 8a/8b, chatter below the sticking speed settled plastically, stuck phases run as one body), at
every T (so the delayed x1 is always in the recorded past, read from the dense outputs) and at every delayed
impact (x1's kink reaching the plant). Started on the orbit dfloop finds, it stays there; its period and the
fundamental of x agree with the orbit to the discretisation's stated error. And T -> 0: the orbit approaches the
undelayed loop's exact orbit linearly in T.
"""
from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dfloop.describing.base import DescribingFunction
from dfloop.describing.time_model import Impact
from dfloop.exact import exact_cycle
from dfloop.hybrid import loop_model
from dfloop.hybrid.delay import delay_orbit
from dfloop.hybrid.delay_impact import DelayImpactLoop
from dfloop.solve.delay import delayed
from dfloop.verify import verify_cycle

PD = ct.tf([33.028, 425.06], [1.11979e-4, 2.11640e-2, 1.0])   # models/dynamic_backlash_pd.toml
F0, W0 = 31.75, 31.5
N_PD = -0.000848287 + 0.000507856j                              # the element's DF there
EPS = 0.5


class _Fixed(DescribingFunction):
    """The paper's dynamic backlash (1 kg, 1 kg, 0.1 m, eps 0.5) with a fixed N (no table is built)."""

    frequency_dependent = True

    def _evaluate(self, A, omega):
        return np.full(np.broadcast(A, omega).shape, complex(N_PD))

    def time_model(self, amplitude):
        return Impact("stand-in", 1.0, 1.0, 0.1, EPS, (), 1e-9)


def reference(G, T, z0, history, t_end, v_stick):
    """Event-located run of the delayed loop from state z0 = [x1, v1, gap, v2 - v1, s] at t = 0 with x1 = history(t)
    for t < 0: (impact times on wall B, x(t) as a function)."""
    A, B, C, D = (np.asarray(m, float) for m in (G.A, G.B[:, 0], G.C[0], G.D[0, 0]))
    m1 = m2 = 1.0
    M, h = m1 + m2, 0.1
    pieces = []                                   # (t0, t1, dense solution) of the run so far

    def x1_at(t):
        if t <= 0:
            return float(history(t))
        for a, b, f in reversed(pieces):
            if a <= t <= b:
                return float(f(t)[0])
        raise AssertionError(f"x1 at {t} is not in the recorded past")

    def force(t, y):              # force on M2 = -c, c = C s + D x1(t - T)
        return -(C @ y[4:] + D * x1_at(t - T))

    def free(t, y):
        return np.concatenate([[y[1], 0.0, y[3], force(t, y) / m2], A @ y[4:] + B * x1_at(t - T)])

    def stuck(t, y):
        return np.concatenate([[y[1], force(t, y) / M, 0.0, 0.0], A @ y[4:] + B * x1_at(t - T)])

    start = [0.0]

    def hit_a(t, y):
        return y[2] + (h if t - start[0] < 1e-12 and side == 0 else 0.0)

    def hit_b(t, y):
        return y[2] - h - (h if t - start[0] < 1e-12 and side == 1 else 0.0)

    def contact(t, y):            # force on M2 from M1 while stuck
        return m2 * force(t, y) / M - force(t, y)

    hit_a.terminal = hit_b.terminal = contact.terminal = True
    hit_a.direction, hit_b.direction = -1, 1
    y = np.array(z0, float)
    t, side, mode = 0.0, None, "free"
    kinks, hits_b = [], []
    while t < t_end - 1e-12:
        start[0] = t
        later = [k + T for k in kinks if k + T > t + 1e-12]
        t_stop = min([t_end, t + T] + later)
        if mode == "free":
            sol = solve_ivp(free, (t, t_stop), y, events=(hit_a, hit_b), rtol=1e-12, atol=1e-15,
                            method="DOP853", dense_output=True)
        else:
            contact.direction = -1 if side == 0 else 1
            sol = solve_ivp(stuck, (t, t_stop), y, events=(contact,), rtol=1e-12, atol=1e-15,
                            method="DOP853", dense_output=True)
        pieces.append((t, sol.t[-1], sol.sol))
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            continue                              # a restart point (T or a delayed kink): same mode
        if mode == "stuck":
            mode = "free"
            continue
        side = 0 if sol.t_events[0].size else 1
        y[2] = 0.0 if side == 0 else h
        u = y[3]
        y[1] += (1 + EPS) * m2 * u / M
        y[3] = -EPS * u
        if abs(y[3]) <= v_stick:
            y[1] += m2 * y[3] / M
            y[3] = 0.0
            mode = "stuck"
        kinks.append(t)
        if side == 1:
            hits_b.append(t)
        assert len(kinks) < 20_000

    def x(tt):
        return np.array([force(ti, np.concatenate([[0, 0, 0, 0], _s(ti)])) for ti in tt])

    def _s(ti):
        for a, b, f in reversed(pieces):
            if a <= ti <= b:
                return f(ti)[4:]
        raise AssertionError

    return np.array(hits_b), x


@pytest.fixture(scope="module")
def orbit():
    T = 0.004                                    # 2 % of the period
    loop = loop_model(delayed(PD, T), _Fixed(), F0, W0)
    out = delay_orbit(loop, F0, W0)
    return T, loop, out


def test_delayed_impact_orbit_is_the_event_located_run(orbit):
    T, loop, o = orbit
    assert isinstance(loop, DelayImpactLoop)
    assert o["success"], o["message"]
    err_A, err_w = o["extra"]["error_estimate"]
    assert err_A < 1e-3 and err_w < 1e-3
    mu_err = o["extra"]["multiplier_error"]
    assert mu_err < 0.05                                       # the trivial multiplier, measured 1.023
    assert np.min(np.abs(o["multipliers"] - 1)) == pytest.approx(mu_err)
    assert o["stable"] and np.sort(np.abs(o["multipliers"]))[-2] < 1 - 5 * mu_err   # 0.135: clearly stable
    P = o["period"]
    zm, H = o["extra"]["zm0"], o["extra"]["history0"]
    Nn = o["extra"]["nodes"]
    tn = P / Nn * np.arange(-H.size, 1)
    vals = np.append(H, zm[0])
    history = lambda t: np.interp(t, tn, vals)    # noqa: E731
    periods = 12
    hits, x = reference(ct.ss(PD), T, zm, history, periods * P, loop.step_loop.v_stick)
    # one impact on wall B per period once settled: the spacing of the last ones is the period
    late = hits[hits > (periods - 5) * P]
    spacing = np.diff(late)
    assert spacing.size >= 3 and np.ptp(spacing) < 1e-7 * P            # settled, periodic
    P_ref = float(np.mean(spacing))
    # the stated error bounds the true one (measured: P 6.0e-6 for an estimate of 1.3e-5, A 3.0e-5 for 6.7e-5)
    assert abs(P_ref / P - 1) < err_w
    t = late[-2] + P_ref * np.arange(512) / 512
    X1 = 2 * np.mean(x(t) * np.exp(-2j * math.pi * np.arange(512) / 512))
    assert abs(abs(X1) / o["amplitude"] - 1) < err_A


def test_public_verification_runs_the_delayed_impact_loop(orbit):
    T, _, o = orbit
    v = verify_cycle(delayed(PD, T), _Fixed(), (o["amplitude"], o["frequency"]), periods=20, steps_per_period=160)
    assert "impacts" in v.method
    assert v.verdict == "stable", v.message
    assert abs(v.inside.frequency / o["frequency"] - 1) < 1e-3


def test_delayed_impact_orbit_tends_to_the_undelayed_one(orbit):
    T, _, o = orbit
    e0 = exact_cycle(PD, _Fixed(), (F0, W0))
    assert e0.success
    T2 = T / 2
    o2 = delay_orbit(loop_model(delayed(PD, T2), _Fixed(), F0, W0), F0, W0)
    assert o2["success"], o2["message"]
    d1 = abs(o["frequency"] / e0.frequency - 1)
    d2 = abs(o2["frequency"] / e0.frequency - 1)
    assert d1 > 0.05                                            # the delay matters: 14 % in w at T = 4 ms
    assert 1.7 < d1 / d2 < 2.3                                  # linear in T (measured 1.91)
    a1, a2 = abs(o["amplitude"] / e0.amplitude - 1), abs(o2["amplitude"] / e0.amplitude - 1)
    # first order with a second-order part still visible at these T (measured 2.50 here, 2.23 from 2 to 1 ms)
    assert 1.7 < a1 / a2 < 3.0
