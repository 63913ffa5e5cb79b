"""The exact forced response of a delayed loop (dfloop.hybrid.forced_delay: the delay equation at the forcing
period) against an independent truth written here: a method of steps with DOP853 (rtol 1e-12), pieces of one
delay, the delayed input read from the previous piece's dense output, started at rest and run until the
stroboscopic samples repeat. Its amplitude must equal the exact point's to 1e-8, and the rate at which its
samples converge must be the largest Floquet multiplier's modulus."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import dfloop as df
from dfloop.hybrid.forced import exact_forced_point
from dfloop.solve.delay import delayed
from dfloop.solve.forced import forced_response

G0 = ct.tf([1.0], [1.0, 0.2, 1.0])
T, R = 0.1, 0.3
K1, K3 = 1.0, 0.5


def _strobed_run(w, periods=120, settle=1e-11):
    """(|X1| of x over the last forcing period, the stroboscopic samples) of the forced delayed loop."""
    ss = ct.ss(G0)
    A, B, C = ss.A, ss.B.ravel(), ss.C.ravel()
    P = 2 * math.pi / w

    def x_of(t, s):
        return R * math.sin(w * t) - float(C @ s)

    s, prev, t, strobe, pieces = np.zeros(2), None, 0.0, [], []
    while t < periods * P:
        def rhs(tt, ss_, prev=prev):
            if prev is None or tt - T < prev[0]:
                return A @ ss_
            xd = x_of(tt - T, prev[1](tt - T))
            return A @ ss_ + B * (K1 * xd + K3 * xd ** 3)
        sol = solve_ivp(rhs, (t, t + T), s, method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True)
        prev = (t, sol.sol)
        pieces.append((t, t + T, sol.sol))
        s, t = sol.y[:, -1], t + T
        while (len(strobe) + 1) * P <= t:
            strobe.append(sol.sol((len(strobe) + 1) * P))
        if len(strobe) > 3 and np.max(np.abs(strobe[-1] - strobe[-2])) < settle * np.max(np.abs(strobe[-1])):
            a = len(strobe) * P - P
            tq = a + P * (np.arange(2048) + 0.5) / 2048
            xs = np.array([x_of(tt, next(so for t0, t1, so in reversed(pieces) if t0 <= tt <= t1)(tt)) for tt in tq])
            return abs(2 / 2048 * np.sum(xs * np.exp(-1j * w * (tq - a)))), np.array(strobe)
    raise AssertionError("the reference run did not settle")


def test_forced_response_of_a_delayed_cubic_loop_equals_an_exact_delay_run():
    N = df.CubicStiffness(K1, K3)
    G = delayed(G0, T)
    w = 0.6
    p = forced_response(G, N, R, np.array([w, 2 * w]), amplitude=(1e-3, 20.0)).solutions[0][0]
    e = exact_forced_point(G, N, R, w, p.amplitude)
    assert e.periodic and e.stable, e
    assert e.extra["target_met"] and e.extra["error_estimate"] <= 1e-8
    amp, strobe = _strobed_run(w)
    assert abs(e.amplitude / amp - 1) < 1e-8
    # the DF is close here but not equal: the comparison is not trivial
    assert abs(p.amplitude / amp - 1) > 1e-6
    # the samples converge geometrically at the largest multiplier's modulus (a complex pair here: the fitted
    # slope of log|change| over 20 periods, read where the changes are still far above the run's rounding)
    d = np.linalg.norm(np.diff(strobe, axis=0), axis=1)[2:22]
    rate = math.exp(np.polyfit(np.arange(d.size), np.log(d), 1)[0])
    assert abs(rate / np.max(np.abs(e.multipliers)) - 1) < 0.03, (rate, e.multipliers)


def test_a_delayed_relay_in_the_exact_forced_response_is_refused_by_name():
    with pytest.raises(ValueError, match="G: a pure delay in the exact forced response"):
        exact_forced_point(delayed(G0, T), df.Relay(1.0, hysteresis=0.1), R, 1.0, 0.5)
