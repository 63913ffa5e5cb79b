"""Period-k orbits: a loop that settles on an orbit repeating only after several oscillations (past a period
doubling) is shot over its whole period. The test loop is Chua's circuit in Lur'e form (a third-order plant
around a saturation) at alpha = 8.2, past its first period doubling: checked against an independent
event-located solve_ivp run of the circuit's own equations."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import dfloop as df
from dfloop.exact import exact_cycle

BETA, M0, M1 = 14.286, -8 / 7, -5 / 7


def chua_loop(alpha):
    """x' = alpha (y - x - f(x)), y' = x - y + z, z' = -beta y with f(x) = m1 x + (m0 - m1) sat(x): the linear part
    is the plant (output -x, so the loop's x is the circuit's x) and (m1 - m0) sat(x) the element."""
    A = [[-alpha * (1 + M1), alpha, 0], [1, -1, 1], [0, -BETA, 0]]
    return ct.ss(A, [[alpha], [0], [0]], [[-1, 0, 0]], 0), df.Saturation(1.0, k=M1 - M0)


def chua_field(alpha):
    def f(x):
        return M1 * x + 0.5 * (M0 - M1) * (abs(x + 1) - abs(x - 1))
    return lambda t, s: [alpha * (s[1] - s[0] - f(s[0])), s[0] - s[1] + s[2], -BETA * s[1]]


def _maxima(alpha, s0, t_end):
    """Event-located maxima of x (x' = 0 downwards) of the circuit run from s0 (rtol 1e-12)."""
    field = chua_field(alpha)

    def top(t, s):
        return field(t, s)[0]
    top.direction = -1
    sol = solve_ivp(field, (0, t_end), s0, method="DOP853", rtol=1e-12, atol=1e-12, events=top)
    return np.reshape(sol.y_events[0], (-1, 3))[:, 0], sol


def test_period_two_orbit_of_chua_circuit_is_found_whole():
    alpha = 8.2
    G, N = chua_loop(alpha)
    e = exact_cycle(G, N, (3.2, 2.65), settle_periods=40, max_deviation=3.0)
    assert e.success and e.extra["returns"] == 2, e.message
    assert "period-2" in e.message and e.stable
    s0 = e.extra["plant_state"]
    # independent: the circuit's own flow returns to the start after the period, not after half of it
    _, whole = _maxima(alpha, s0, e.period)
    _, half = _maxima(alpha, s0, 0.5 * e.period)
    scale = np.max(np.abs(s0))
    assert np.max(np.abs(whole.y[:, -1] - s0)) < 1e-8 * scale
    assert np.max(np.abs(half.y[:, -1] - s0)) > 1e-2 * scale
    # the circuit started elsewhere (on the orbit's side: the circuit is odd, each orbit has a mirror image)
    # settles on it: its alternating maxima are the orbit's two maxima
    tops, _ = _maxima(alpha, [math.copysign(0.1, np.mean(e.x)), 0.0, 0.0], 400.0)
    orbit_tops, _ = _maxima(alpha, s0, e.period * (1 - 1e-9))
    assert orbit_tops.size == 2 and abs(orbit_tops[0] - orbit_tops[1]) > 0.03
    for top in orbit_tops:
        assert np.min(np.abs(tops[-6:] - top)) < 1e-6
    # the errors are those of the predicted oscillation, the orbit's second harmonic
    assert e.frequency_error == pytest.approx((2.65 - 2 * e.frequency) / (2 * e.frequency))
    assert e.amplitude_error == pytest.approx((3.2 - abs(e.harmonics[1])) / abs(e.harmonics[1]))


def test_period_one_orbit_stays_period_one():
    """Before the doubling (alpha = 7.5) the settled single-scroll orbit is shot as a period-1 orbit, and it is
    the circuit's: its one maximum is where the independent run's maxima settle."""
    alpha = 7.5
    G, N = chua_loop(alpha)
    e = exact_cycle(G, N, (3.2, 2.65), settle_periods=40, max_deviation=3.0)
    assert e.success and e.extra["returns"] == 1, e.message
    tops, _ = _maxima(alpha, [math.copysign(0.1, np.mean(e.x)), 0.0, 0.0], 300.0)
    orbit_tops, _ = _maxima(alpha, e.extra["plant_state"], e.period * (1 - 1e-9))
    assert orbit_tops.size == 1 and np.max(np.abs(tops[-4:] - orbit_tops[0])) < 1e-6
