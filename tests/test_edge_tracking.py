"""Edge tracking (issue 16, never a false "no orbit"): the motion on the boundary between the basins of the starts
around a prediction. Truths: an independent event-located DOP853 shooting (scipy, its own realisation of the
plant) for an unstable orbit, and event-located DOP853 runs of a backlash loop for a boundary that is rest."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

import dfloop as df
from dfloop.hybrid import loop_model
from dfloop.hybrid.edge import edge_track
from dfloop.solve.verdict import exact_kind

RTOL = 1e-13


def _companion(num: float, den: list):
    """c''' ... from num / den (den monic) in controllable canonical form: s = [c, c', ...]."""
    n = len(den) - 1
    A = np.zeros((n, n))
    A[:-1, 1:] = np.eye(n - 1)
    A[-1] = -np.asarray(den[::-1][:-1], float)
    B = np.zeros(n)
    B[-1] = num
    return A, B


def _dead_zone_flow(A, B, d, s0, tau, w=None):
    """phi_tau(s0) of s' = A s + B dz(x), x = -c, integrated piece by piece between the kinks |x| = d (located
    by DOP853's events), so every piece is smooth. With ``w`` two more states integrate x sin(w t), x cos(w t)."""
    n = len(s0)

    def rhs(t, z):
        x = -z[0]
        ds = A @ z[:n] + B * (np.sign(x) * max(abs(x) - d, 0.0))
        return ds if w is None else np.concatenate([ds, [x * np.sin(w * t), x * np.cos(w * t)]])

    def kink(sign):
        ev = lambda t, z: -z[0] - sign * d   # noqa: E731
        ev.terminal = True
        return ev

    t, z = 0.0, np.concatenate([s0, [] if w is None else [0.0, 0.0]])
    for _ in range(50):
        sol = solve_ivp(rhs, (t, tau), z, method="DOP853", rtol=RTOL, atol=1e-15, events=[kink(1), kink(-1)])
        z = sol.y[:, -1]
        if sol.status == 0:
            return z
        t = sol.t[-1]
        z = z + 1e-15 * rhs(t, z)      # off the kink, in the flow's direction (one rounding step)
    raise AssertionError("more than 50 kinks in half a period")


def test_edge_tracking_finds_the_unstable_dead_zone_orbit_to_1e8():
    """3/(s(s+1)^2) with a dead zone 0.5: inside the DF's unstable cycle the motions come to rest in the dead band,
    outside they diverge. Edge tracking between starts at 0.8 and 1.2 times the prediction follows the boundary
    until it is periodic and shoots from there: the unstable orbit. Truth: the odd symmetric orbit solved
    independently, phi_{T/2}(s0) = -s0 on x = 0, by scipy's fsolve on an event-located DOP853 flow."""
    G, N = ct.tf([3.0], [1.0, 2.0, 1.0, 0.0]), df.DeadZone(0.5)
    c = df.predict_limit_cycles(G, N)[0]
    loop = loop_model(G, N, c.amplitude, c.frequency)
    e = edge_track(loop, N, c.amplitude, c.frequency, 0.8, 1.2, periods=60)
    assert e.outcome == "orbit", e
    assert (e.inside, e.outside) == ("rest", "divergence")
    T = e.orbit.period
    w = 2 * math.pi / T
    amplitude = abs(2 * loop.fourier(e.orbit.flow, T, w, 1)[0])
    mu = np.abs(np.linalg.eigvals(e.orbit.flow.monodromy[:loop.size - 1, :loop.size - 1]))
    assert mu.max() > 1.5           # unstable: a simulation never settles on it

    # independent truth
    A, B = _companion(3.0, [1.0, 2.0, 1.0, 0.0])
    v = c.amplitude * complex(N(c.amplitude))
    s_hb = np.imag(np.linalg.solve(1j * c.frequency * np.eye(3) - A, B) * v)     # x = A sin(w t) at t = 0
    s_hb[0] = 0.0

    def F(u):
        s0 = np.array([0.0, u[0], u[1]])
        return _dead_zone_flow(A, B, 0.5, s0, u[2]) + s0

    u, _, ok, msg = fsolve(F, [s_hb[1], s_hb[2], math.pi / c.frequency], full_output=True, xtol=1e-14)
    assert ok == 1 and np.max(np.abs(F(u))) < 1e-11, msg
    T_true = 2 * u[2]
    # the fundamental of x over one period (odd symmetric: twice the half period's integral)
    q = _dead_zone_flow(A, B, 0.5, np.array([0.0, u[0], u[1]]), u[2], w=2 * math.pi / T_true)[3:]
    A_true = float(np.hypot(*q)) * 2 * 2 / T_true
    assert w == pytest.approx(2 * math.pi / T_true, rel=1e-8)
    assert amplitude == pytest.approx(A_true, rel=1e-8)


def _backlash_run(A, B, h, s0, y0, t_end):
    """An event-located DOP853 run of the backlash loop s' = A s + B y, x = -s[0] (free: y' = 0; in contact:
    y = x -+ h/2 while x moves away from the play); returns (t, x) samples."""
    C_dot = lambda s: -(A @ s)[0]   # noqa: E731   x' (independent of y: B[0] = 0)
    ts, xs = [], []
    t, s, y, mode = 0.0, np.array(s0, float), float(y0), 0   # mode 0 free, +1 upper contact, -1 lower
    while t < t_end:
        if mode == 0:
            def rhs(_, z):
                return np.append(A @ z[:-1] + B * z[-1], 0.0)
            up = lambda _, z: -z[0] - h / 2 - z[-1]        # noqa: E731  x reaches y + h/2
            down = lambda _, z: -z[0] + h / 2 - z[-1]      # noqa: E731  x reaches y - h/2
            up.terminal = down.terminal = True
            up.direction, down.direction = 1, -1
            events = [up, down]
        else:
            def rhs(_, z):
                y_c = -z[0] - mode * h / 2
                return np.append(A @ z[:-1] + B * y_c, 0.0)
            turn = lambda _, z: C_dot(z[:-1])              # noqa: E731  x' = 0: contact lost
            turn.terminal = True
            turn.direction = -mode
            events = [turn]
        sol = solve_ivp(rhs, (t, t_end), np.append(s, y), method="DOP853", rtol=1e-10, atol=1e-13,
                        events=events, max_step=0.05)
        ts.append(sol.t)
        xs.append(-sol.y[0])
        t, s = sol.t[-1], sol.y[:-1, -1]
        y = sol.y[-1, -1] if mode == 0 else -s[0] - mode * h / 2
        if sol.status == 1:
            if mode == 0:
                mode = 1 if sol.t_events[0].size else -1
            else:
                mode = 0
            s = s + 1e-12 * np.append((A @ s + B * y)[:], [])   # off the surface, along the flow
    return np.concatenate(ts), np.concatenate(xs)


def test_backlash_servo_inner_prediction_is_an_artefact_the_boundary_is_rest():
    """5/(s(s+1)) with a backlash h = 1 (models/backlash_servo.toml): the DF's unstable inner cycle (A = 0.528) is
    not an orbit. Starts inside go to rest, outside to the outer cycle; edge tracking puts the boundary between
    them at the start amplitude h/2 (where the predicted sinusoid no longer leaves the play: below it the start
    is at rest) and finds no oscillation on it. Truth: event-located DOP853 runs of the loop (own model of the
    backlash): a start at 1.03 h/2, between the boundary and the prediction, leaves rest for the outer cycle."""
    G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)
    inner, outer = df.predict_limit_cycles(G, N)
    hit = df.exact_cycle(G, N, outer)
    miss = df.exact_cycle(G, N, inner)
    assert not miss.success and miss.extra["outcome"] == "edge rest" and exact_kind(miss) == "artefact"
    edge = miss.extra["edge"]
    assert edge["outcome"] == "slow" and "the boundary runs through rest" in miss.message
    assert edge["boundary"] * inner.amplitude == pytest.approx(0.5, rel=1e-6)   # h/2
    assert abs(edge["x_rest"]) < 1e-6
    # truth: a start on the predicted sinusoid of amplitude 1.03 h/2 (< the prediction, 1.056 h/2) is not at rest
    # and ends on the outer cycle
    A, B = _companion(5.0, [1.0, 1.0, 0.0])
    a = 1.03 * 0.5
    s0 = np.imag(np.linalg.solve(1j * inner.frequency * np.eye(2) - A, B) * a * complex(N(a)))
    y0 = -a + 0.5                   # after the sinusoid's last trough (x = -a), free since: y = -a + h/2
    t, x = _backlash_run(A, B, 1.0, s0, y0, 400.0)
    tail = x[t > 340.0]
    assert 0.5 * np.ptp(tail) == pytest.approx(hit.amplitude, rel=2e-2)      # x's peak ~ the fundamental (0.54 %)


def test_rest_point_is_the_element_input_itself_with_a_constant_input():
    """With a reference r0 the motion that comes to rest is reported where x rests (x = r0 - c), not as its
    deviation from the run's mean (which is 0 by construction)."""
    from dfloop.hybrid.globalise import _motion

    G, N = ct.tf([3.0], [1.0, 2.0, 1.0, 0.0]), df.DeadZone(0.5)
    c = df.predict_limit_cycles(G, N)[0]
    m = _motion(G, N, 0.85 * c.amplitude, c.frequency, 0.7, {"r0": 0.3, "load": 0.0, "bias": 0.0})
    assert m["outcome"] == "rest"
    # at rest the integrator's input is 0: the element output is 0, x inside the dead band, and not at 0
    assert m["y_end"] == pytest.approx(0.0, abs=1e-9)
    assert abs(m["x_end"]) <= 0.5 and abs(m["x_end"]) > 1e-3
