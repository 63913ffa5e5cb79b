"""Sampled (zero-order-hold) elements behind a plant with a pure delay, against truths written here.

The truth is a brute-force continuous-time run: the plant propagated with scipy.linalg.expm from event to event,
the events being the sample instants t_k (x read, the element's output computed and queued) and the arrivals
t_k + T (the plant's input jumps). Against it: the exact sampled map (``sample_delayed``: its orbits, x samples and
multipliers with the pending values), its limits (T -> 0 is the plain hold, T = k dt is z^-k) and the fixed-step
loop of an operator-only element with the exact delay line (``DelaySampledLoop``, T = 0 is ``SampledLoop``).
"""
from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm

import dfloop as df
from dfloop.hybrid import loop_model
from dfloop.hybrid.delay import delay_orbit
from dfloop.hybrid.delay_sampled import DelaySampledLoop
from dfloop.hybrid.discrete import discrete_cycle, sample_delayed, shoot_discrete
from dfloop.hybrid.sampled import SampledLoop
from dfloop.solve.delay import delayed

G0 = ct.tf([1.0], [1.0, 2.0, 1.0])
DT = 0.1


def _abc(G):
    s = ct.ss(G)
    return np.asarray(s.A, float), np.asarray(s.B, float)[:, 0], np.asarray(s.C, float)[0]


def brute(G, T, dt, element, s0, u0, pending, samples):
    """Event-by-event run: returns x at the samples t_0..t_{samples-1} and the final (s, u, pending values).

    ``element(x)`` gives the held output of the sample; ``pending``: values queued before t = 0, arriving at
    T - dt * (len(pending) - i) (the oldest first); ``u0`` the plant's input at t = 0-."""
    A, B, C = _abc(G)
    n = A.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n] = A, B
    queue = [[T - dt * (len(pending) - i), float(v)] for i, v in enumerate(pending)]
    s, u, t = np.array(s0, float), float(u0), 0.0
    tol = 1e-9 * dt
    xs = []
    k = 0
    while True:
        if k == samples and t >= samples * dt - tol:      # the end: the state z_samples, before its arrivals
            break
        while queue and queue[0][0] <= t + tol:           # arrivals due now
            u = queue.pop(0)[1]
        if k < samples and abs(t - k * dt) <= tol:          # a sample
            x = -float(C @ s)
            xs.append(x)
            queue.append([k * dt + T, float(element(x))])
            k += 1
            while queue and queue[0][0] <= t + tol:       # T = 0: the held value reaches the plant now
                u = queue.pop(0)[1]
        t_next = min(k * dt, queue[0][0]) if queue else k * dt
        if t_next > t + tol:
            E = expm(aug * (t_next - t))
            s = E[:n, :n] @ s + E[:n, n] * u
        t = max(t, t_next)
    return np.array(xs), s, u, [v for _, v in queue]


@pytest.mark.parametrize("k", [0, 3])
def test_a_whole_number_of_samples_is_z_to_the_minus_k(k):
    Gd = sample_delayed(delayed(G0, k * DT), DT)
    ref = ct.sample_system(G0, DT, method="zoh")
    theta = np.linspace(0.05, 3.0, 9)
    z = np.exp(1j * theta)
    assert np.max(np.abs(Gd(z) - ref(z) * z ** (-k))) < 1e-12
    # T -> 0 from above: continuous in T
    small = sample_delayed(delayed(G0, 1e-9), DT)
    assert np.max(np.abs(small(z) - ref(z))) < 1e-8


def test_digital_relay_orbit_with_a_fractional_delay_is_the_brute_force_orbit():
    T = 0.25                                           # 2.5 samples: changes of the plant input between samples
    Gd = sample_delayed(delayed(G0, T), DT)
    N = df.Relay(M=1.0)
    lc = df.predict_limit_cycles(delayed(G0, T + DT / 2), N)   # the hold's half-sample lag on top of T
    o, note = discrete_cycle(Gd, N, lc[0].amplitude, lc[0].frequency)
    assert o is not None, note
    assert o.state.size == 2 + 3                       # plant state and 3 pending held values
    relay = lambda x: 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)   # noqa: E731
    m = o.state.size - 2
    xs, *_ = brute(G0, T, DT, relay, o.state[:2], o.state[2], o.state[3:], 3 * o.period)
    assert np.max(np.abs(xs - np.tile(o.x, 3))) < 1e-12
    # settled from rest with a kick: the run reaches the same orbit (the same output sequence up to a shift)
    xs, *_ = brute(G0, T, DT, relay, [0.0, 0.05], 0.0, [0.0] * m, 80 * o.period)
    tail = np.array([relay(x) for x in xs[-2 * o.period:]])
    assert np.array_equal(tail[:o.period], tail[o.period:])
    rolled = [np.roll(o.y, j) for j in range(o.period)]
    assert any(np.array_equal(tail[:o.period], r) for r in rolled)
    assert abs(np.ptp(xs[-o.period:]) / np.ptp(o.x) - 1) < 1e-9


def test_multipliers_of_the_sampled_map_include_the_pending_values():
    T, N = 0.25, df.Saturation(0.01, 100.0)     # a steep saturation: the sampled loop locks on a periodic orbit
    Gd = sample_delayed(delayed(G0, T), DT)
    lc = df.predict_limit_cycles(delayed(G0, T + DT / 2), N)
    c = lc[0]
    P0 = 2 * math.pi / (c.frequency * DT)
    found = [o for P in range(int(P0) - 2, int(P0) + 4)
             if (o := shoot_discrete(Gd, N, P, c.amplitude, c.frequency)) is not None and o.amplitude > 1e-6]
    assert found
    o = found[0]
    sat = lambda x: 100.0 * min(max(x, -0.01), 0.01)      # noqa: E731

    def period_map(z):
        _, s, u, pend = brute(G0, T, DT, sat, z[:2], z[2], z[3:], o.period)
        return np.concatenate([s, [u], pend])

    z0 = o.state
    assert np.max(np.abs(period_map(z0) - z0)) < 1e-10 * np.max(np.abs(z0))     # a fixed point of the period
    h = 1e-7 * max(np.max(np.abs(z0)), 1.0)
    J = np.column_stack([(period_map(z0 + h * e) - period_map(z0 - h * e)) / (2 * h) for e in np.eye(z0.size)])
    mu = np.linalg.eigvals(J)
    mu = mu[np.argsort(-np.abs(mu))]
    k = 3
    assert np.max(np.abs(np.abs(mu[:k]) - np.abs(o.multipliers[:k]))) < 1e-6
    assert o.stable == bool(np.all(np.abs(mu) < 1))


class Hysteron:            # a user's element known only through an operator: a relay of +/- 1, band +/- 0.2
    def __init__(self):
        self.state = -1.0

    def __call__(self, x):
        self.state = 1.0 if x > 0.2 else (-1.0 if x < -0.2 else self.state)
        return self.state


def test_operator_loop_with_a_delay_steps_like_sampled_loop_and_the_brute_force_run():
    N = df.NumericDF(Hysteron(), hysteretic=True)
    A, B, C = _abc(G0)
    loop0 = loop_model(delayed(G0, 0.0), N, 0.5, 2.0, steps_per_period=200)
    ref = loop_model(G0, N, 0.5, 2.0, steps_per_period=200)
    assert isinstance(ref, SampledLoop)
    assert not isinstance(loop0, DelaySampledLoop)            # T = 0 is no delay at all
    zero = DelaySampledLoop(A, B, C, N.time_model(0.5), 0.0, ref.dt, 200)
    s0 = np.array([0.1, -0.2])
    op = N.time_model(0.5).make_operator()
    xs, ys, *_ = zero.run(np.append(s0, 0.0), op, 0.0, 500)
    fl = ref.flow(np.append(s0, 1.0), (N.time_model(0.5).make_operator(), 0.0), 500 * ref.dt)
    assert np.max(np.abs(xs - fl.dense[1])) < 1e-12 and np.array_equal(ys, fl.dense[2])
    # a fractional delay: the loop's steps are the brute-force run's with the same midpoint-extrapolated input
    T = 0.37
    loop = loop_model(delayed(G0, T), N, 0.5, 2.0, steps_per_period=200)
    assert isinstance(loop, DelaySampledLoop)
    z, op, x_prev = loop.start(0.5, 2.0)
    xs, ys, *_ = loop.run(z, op, x_prev, 600)
    op2, last = loop.start(0.5, 2.0)[1], [x_prev]

    def element(x):
        y = op2(1.5 * x - 0.5 * last[0])
        last[0] = x
        return y
    xb, *_ = brute(G0, T, loop.dt, element, z[:2], z[2], z[3:], 600)
    assert np.max(np.abs(xs - xb)) < 1e-11


def test_verify_cycle_runs_an_operator_element_behind_a_delay_towards_the_exact_relay_orbit():
    T = 0.4
    N = df.NumericDF(Hysteron(), hysteretic=True)
    exact_loop = loop_model(delayed(G0, T), df.Relay(M=1.0, hysteresis=0.2), 0.5, 1.5)
    exact = delay_orbit(exact_loop, 0.5, 1.5)
    assert exact["success"], exact["message"]
    v = df.verify_cycle(delayed(G0, T), N, (exact["amplitude"], exact["frequency"]), periods=40,
                        steps_per_period=400)
    assert v.verdict == "stable", v.message
    assert "delay" in v.method
    # the step is the exact period / 400, and the relay's fixed-step loop locks on it: measured 2e-8 in A
    assert abs(v.inside.amplitude / exact["amplitude"] - 1) < 1e-6
    assert abs(v.inside.frequency / exact["frequency"] - 1) < 1e-9
    with pytest.raises(ValueError, match="^N: .*sampled operator"):
        df.exact_cycle(delayed(G0, T), N, (exact["amplitude"], exact["frequency"]))
