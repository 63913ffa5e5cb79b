"""Biased cycles (dual-input DF) of loops with a pure delay: G(jw) e^{-jwT} in the harmonic balance, G(0) in the bias
equation, and the exact biased orbit on the delay flow against an event-located simulation with an exact delay."""
from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from dfloop import Relay
from dfloop.biased import biased_cycles
from dfloop.solve.bias import predict_biased_cycles, static_gain
from dfloop.solve.delay import delayed

M, H, T, R0 = 1.0, 0.1, 0.4, 0.3
G0 = ct.tf([1.0], [1.0, 2.0, 1.0])


def test_static_gain_of_a_delayed_plant_is_the_rational_parts():
    assert static_gain(delayed(3 * G0, 0.7)) == pytest.approx(3.0, rel=1e-14)
    assert static_gain(delayed(ct.tf([1.0], [1.0, 1.0, 0.0]), 0.2)) == math.inf


def _relay_dual_input(B, A):
    """Closed form of the hysteresis relay (+M from e rising through +H, -M from e falling through -H) driven by
    e = B + A sin(theta), |B| < A - H: mean output and fundamental gain b1 + j a1 over A."""
    th1 = math.asin((H - B) / A)                   # rising through +H
    th2 = math.pi - math.asin((-H - B) / A)        # falling through -H
    mean = M * ((th2 - th1) / math.pi - 1.0)
    b1 = 2 * M / math.pi * (math.cos(th1) - math.cos(th2))
    a1 = 2 * M / math.pi * (math.sin(th2) - math.sin(th1))
    return mean, (b1 + 1j * a1) / A


def test_delayed_balance_against_the_closed_form():
    """The delay turns G(jw) by -wT in the first harmonic and leaves the bias equation B + G(0) m = r0 alone. The
    amplitude window reaches below the hysteresis, where the relay holds one output and the mean output jumps from
    -M to +M across B: that sign change is no root (it used to stop the bias bisection)."""
    cycles = predict_biased_cycles(delayed(G0, T), Relay(M, hysteresis=H), r0=R0, amplitude=(0.05, 5.0))
    (c,) = cycles
    assert cycles.dc_gain == 1.0 and cycles.gaps   # the gap: where the relay stops switching (A ~ H)
    mean, NA = _relay_dual_input(c.bias, c.amplitude)
    assert c.bias + 1.0 * mean == pytest.approx(R0, abs=1e-12)
    w = c.frequency
    assert abs(1 + 1 / (1j * w + 1) ** 2 * np.exp(-1j * w * T) * NA) < 1e-9
    # the undelayed loop's cycle is elsewhere: the delay did enter
    (c0,) = predict_biased_cycles(G0, Relay(M, hysteresis=H), r0=R0, amplitude=(0.05, 5.0))
    assert c0.frequency > 1.4 * w


def _simulate_delayed_relay(periods: int):
    """Event-located run written here: between events the plant input u is constant and the flow is the exponential
    of [[A, B u], [C, 0]] (the last state integrates y); the relay switches where e = r0 - y crosses +-H (bracketed
    on a 0.01 s grid, then Brent to 1e-15 s), and the plant sees each switch T later. Returns (period, mean e) of the
    last period between two rising switches."""
    sys = ct.ss(G0)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    n = A.shape[0]

    def flow(z, u, t):
        big = np.zeros((n + 2, n + 2))
        big[:n, :n], big[:n, n], big[n + 1, :n] = A, B * u, C
        return expm(big * t) @ np.concatenate([z[:n], [1.0], z[n + 1:]])

    z = np.zeros(n + 2)                      # x, the constant 1, the integral of y
    t, y_rel, u = 0.0, M, M
    pending, rises = [], []
    step = 0.01
    while len(rises) < periods + 1:
        horizon = pending[0][0] if pending else t + 1.0
        level, sign = (-H, -1) if y_rel == M else (H, 1)

        def gap(tau):
            return sign * ((R0 - C @ flow(z, u, tau)[:n]) - level)

        tau, hit = 0.0, None
        while tau < horizon - t:
            nxt = min(tau + step, horizon - t)
            if gap(tau) < 0 <= gap(nxt):
                hit = brentq(gap, tau, nxt, xtol=1e-15, rtol=1e-15)
                break
            tau = nxt
        if hit is None:                      # the plant input changes first
            z, t = flow(z, u, horizon - t), horizon
            if pending and pending[0][0] == t:
                u = pending.pop(0)[1]
            continue
        z, t = flow(z, u, hit), t + hit
        y_rel = -y_rel
        pending.append((t + T, y_rel))
        if y_rel == M:
            rises.append((t, z[n + 1]))
    (t0, i0), (t1, i1) = rises[-2], rises[-1]
    return t1 - t0, R0 - (i1 - i0) / (t1 - t0)


def test_exact_biased_orbit_with_delay_against_an_event_located_run():
    (c,) = biased_cycles(delayed(G0, T), Relay(M, hysteresis=H), r0=R0, amplitude=(0.15, 5.0))
    ex = c.exact
    assert ex.success, ex.message
    period, mean_e = _simulate_delayed_relay(periods=25)
    assert ex.period == pytest.approx(period, rel=1e-9)
    assert ex.mean == pytest.approx(mean_e, abs=1e-9)
    assert ex.stable
    # the DF's error on this loop (measured: w 1.729 against 1.662 rad/s, bias 0.091 against 0.080)
    assert abs(c.frequency - ex.frequency) < 0.05 * ex.frequency
    assert abs(c.bias - ex.mean) < 0.05 * c.amplitude


def test_autotune_entry_points_take_a_delayed_plant():
    """closed_loop_check and process_model read the delay of ``delayed(G, L)`` (they used to fail in python-control's
    margins). Truth: the phase margin of 2 e^{-Ls} / (s + 1) in closed form, crossover at w = sqrt(3)."""
    from dfloop.autotune.experiment import process_model
    from dfloop.autotune.rules import closed_loop_check

    L = 0.3
    Gd = delayed(ct.tf([2.0], [1.0, 1.0]), L)
    check = closed_loop_check(ct.tf([1.0], [1.0]), Gd)
    w = math.sqrt(3.0)
    assert check["phase_margin"] == pytest.approx(180.0 - math.degrees(math.atan(w) + w * L), abs=1e-6)
    assert check["stable"] and check["final_value"] == pytest.approx(2.0 / 3.0, rel=1e-3)
    model = process_model(delayed(ct.tf([2.0], [0.5, 1.0]), L), delay=0.1)
    assert (model.K, model.T, model.L) == (pytest.approx(2.0), (pytest.approx(0.5),), pytest.approx(L + 0.1))


def test_run_from_inside_a_dead_zone_with_a_delay_rests_at_the_reference():
    """A start whose predicted input never leaves the dead zone used to stop the delay flow ('never switches');
    the run now starts at the plant's equilibrium under the held output: with the output 0 the plant's output is
    0, so x = r0 for all time (closed form)."""
    from dfloop import simulate_loop

    G = delayed(ct.tf([22.0], [1.0, 6.0, 11.0, 6.0]), 0.2)
    sim = simulate_loop(G, Relay(1.0, dead_zone=0.2), 0.1, 2.3, periods=5, r0=0.15, bias=0.01)
    assert not sim.diverged and sim.t[-1] > 4 * 2 * math.pi / 2.3
    assert np.max(np.abs(sim.x - 0.15)) < 1e-12 and np.all(sim.y == 0.0)
