"""Closed loop around the dynamic backlash on the exact linear-mode engine: against an independent event-located
solve_ivp reference (with chatter and sticking), momentum bookkeeping, divergence, the periodic orbit found by
shooting against a long run, and its Floquet multipliers against a finite-difference monodromy."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dfloop.errors import EventLimitError
from dfloop.impact import DynamicBacklash, ViscousDamping
from dfloop.impact import _engine
from dfloop.impact.loop import _ImpactMap, _Loop, impact_loop_orbit, simulate_impact_loop

PD = ct.tf([33.028, 425.06], [1.11979e-4, 2.11640e-2, 1.0])   # models/dynamic_backlash_pd.toml
F0, W0 = 31.75, 31.5                                            # its design point


class _Fixed:
    """A DynamicBacklash stand-in with a fixed N (the start state only needs N; no table is built)."""

    def __init__(self, eps, N, effects=()):
        self.m1, self.m2, self.h, self.restitution, self.effects, self._N = 1.0, 1.0, 0.1, eps, effects, N

    def __call__(self, A, w):
        return self._N


def test_bad_input_is_named():
    element = _Fixed(0.5, 0.0)
    with pytest.raises(ValueError, match="amplitude"):
        simulate_impact_loop(PD, element, -1.0, 20.0)
    with pytest.raises(ValueError, match="tf or ss"):
        simulate_impact_loop(lambda w: 1.0 / (1j * w + 1), element, 10.0, 20.0)
    with pytest.raises(ValueError, match="periods"):
        simulate_impact_loop(PD, element, 10.0, 20.0, periods=math.inf)
    with pytest.raises(ValueError, match="element"):
        simulate_impact_loop(PD, object(), 10.0, 20.0)
    with pytest.raises(ValueError, match="max_period_multiple"):
        impact_loop_orbit(PD, element, 10.0, 20.0, max_period_multiple=0)


def test_loop_without_impacts_is_the_linear_loop_with_N_zero():
    """Below the no-impact limit N = 0: x1 stays 0 and nothing drives the plant."""
    sim = simulate_impact_loop(ct.tf([5.0], [1.0, 2.0]), _Fixed(0.5, 0.0), 5.0, 40.0, periods=5)
    assert np.all(sim.y == 0.0) and np.all(sim.x == 0.0) and not sim.diverged


def _reference(G, eps, z0, t_end, v_stick):
    """Independent reference: solve_ivp (DOP853, rtol 1e-12) on y = [x1, v1, gap, v2 - v1, s], restarted at every
    impact (law 8a/8b); chatter below v_stick settled plastically, stuck phases integrated as one body until the
    contact force changes sign."""
    A, B, C, D = (np.asarray(m, float) for m in (G.A, G.B[:, 0], G.C[0], G.D[0, 0]))
    m1 = m2 = 1.0
    M, h = m1 + m2, 0.1

    def force(y):              # force on M2 = -c
        return -(C @ y[4:] + D * y[0])

    def free(t, y):
        return np.concatenate([[y[1], 0.0, y[3], force(y) / m2], A @ y[4:] + B * y[0]])

    def stuck(t, y):
        return np.concatenate([[y[1], force(y) / M, 0.0, 0.0], A @ y[4:] + B * y[0]])

    start = [0.0]   # restart time: a wall just left is not an event again at the restart (rounding)

    def hit_a(t, y):
        return y[2] + (h if t - start[0] < 1e-12 and side == 0 else 0.0)

    def hit_b(t, y):
        return y[2] - h - (h if t - start[0] < 1e-12 and side == 1 else 0.0)

    def contact(t, y):         # force on M2 from M1 while stuck: m2 a - force
        return m2 * force(y) / M - force(y)

    hit_a.terminal = hit_b.terminal = contact.terminal = True
    hit_a.direction, hit_b.direction = -1, 1
    y = z0.copy()
    t, side, mode = 0.0, None, "free"
    events, pieces = [], []
    while t < t_end and len(events) < 5000:
        start[0] = t
        if mode == "free":
            sol = solve_ivp(free, (t, t_end), y, events=(hit_a, hit_b), rtol=1e-12, atol=1e-16,
                            method="DOP853", dense_output=True)
        else:
            contact.direction = -1 if side == 0 else 1
            sol = solve_ivp(stuck, (t, t_end), y, events=(contact,), rtol=1e-12, atol=1e-16,
                            method="DOP853", dense_output=True)
        pieces.append((t, sol.t[-1], sol.sol))
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            break
        if mode == "stuck":
            events.append((t, 3))
            mode = "free"
            continue
        side = 0 if sol.t_events[0].size else 1
        y[2] = 0.0 if side == 0 else h
        u = y[3]
        y[1] += (1 + eps) * m2 * u / M
        y[3] = -eps * u
        if abs(y[3]) <= v_stick:
            y[1] += m2 * y[3] / M
            y[3] = 0.0
            mode = "stuck"
        events.append((t, 1 + side))

    def x1(tt):
        out = np.empty(tt.size)
        for a, b, f in pieces:
            m = (tt >= a) & (tt <= b)
            if b > a and m.any():
                out[m] = f(tt[m])[0]
        return out

    return np.array(events), x1


@pytest.mark.parametrize("eps,F,w,chatter", [(0.8, F0, W0, False), (0.2, 60.0, 14.0, True)])
def test_closed_loop_engine_matches_event_located_solve_ivp(eps, F, w, chatter):
    G = ct.ss(PD)
    chatter_tol = 1e-4
    loop = _Loop(G, _Fixed(eps, 0.0), chatter_tol, F, w)
    z0 = np.zeros(loop.n)
    z0[2], z0[-1] = 0.05, 1.0
    z0[4:-1] = [0.002, -0.004]               # the plant starts away from rest: the loop is driven by its state
    t_end = 0.8
    run = _engine.run(loop.system, z0, t_end, loop.v_stick, 100_000)
    ref_events, ref_x1 = _reference(G, eps, z0[:-1], t_end, loop.v_stick)
    ours = np.column_stack([run.t0[1:], run.cause[1:]])
    assert ours.shape[0] == ref_events.shape[0] >= 8
    assert np.array_equal(ours[:, 1], ref_events[:, 1])
    assert np.max(np.abs(ours[:, 0] - ref_events[:, 0])) < 1e-8
    if chatter:
        assert np.count_nonzero(run.contact != 0) >= 2   # chatter settled into stuck phases, then separated
    t = np.linspace(0, t_end, 801)
    ref = ref_x1(t)      # the reference's own error (rtol 1e-12 over dozens of restarts) sets the bound
    assert np.max(np.abs(run.states(t)[:, 0] - ref)) < 1e-7 * np.max(np.abs(ref))


def test_momentum_changes_only_by_the_impulse_of_the_control_force():
    """d/dt (M1 v1 + M2 v2) = -c; impacts and sticking conserve momentum: p(t) - p(0) = -int c dt exactly."""
    G = ct.ss(PD)
    loop = _Loop(G, _Fixed(0.3, 0.0), 1e-6, F0, W0)
    z0 = np.zeros(loop.n)
    z0[2], z0[-1], z0[4:-1] = 0.05, 1.0, [0.002, -0.004]
    run = _engine.run(loop.system, z0, 0.6, loop.v_stick, 100_000)
    assert run.t0.size > 20
    nodes, weights = np.polynomial.legendre.leggauss(20)
    impulse = 0.0
    ends = np.append(run.t0[1:], run.t_end)
    for a, b in zip(run.t0, ends):
        if b > a:
            tt = 0.5 * (b - a) * nodes + 0.5 * (a + b)
            impulse += 0.5 * (b - a) * weights @ (run.states(tt) @ loop.x_row)
    zt = run.states(np.array([run.t_end]))[0]
    momentum = zt[1] + (zt[1] + zt[3])
    assert abs(momentum - impulse) < 1e-10 * max(1.0, abs(impulse))


def test_diverging_loop_is_flagged_and_stops():
    sim = simulate_impact_loop(ct.tf([300.0], [1.0, -5.0]), _Fixed(0.5, 0.001 + 0.0j), 30.0, 30.0, periods=200)
    assert sim.diverged and sim.t[-1] < 200 * 2 * math.pi / 30.0
    orbit = impact_loop_orbit(ct.tf([300.0], [1.0, -5.0]), _Fixed(0.5, 0.001 + 0.0j), 30.0, 30.0)
    assert not orbit.success and "diverges" in orbit.message and "failed" in repr(orbit)


def test_event_bound_names_how_to_raise_it():
    with pytest.raises(EventLimitError, match="max_events"):
        simulate_impact_loop(PD, _Fixed(0.5, 0.003), F0, W0, periods=20, max_events=5)


def test_zero_damping_effect_is_the_undamped_loop():
    a = simulate_impact_loop(PD, _Fixed(0.5, 0.003), F0, W0, periods=10)
    b = simulate_impact_loop(PD, _Fixed(0.5, 0.003, (ViscousDamping(0.0),)), F0, W0, periods=10)
    assert np.array_equal(a.x, b.x) and np.max(np.abs(a.x)) > 10.0


@pytest.fixture(scope="module")
def pd_orbit():
    element = DynamicBacklash(1.0, 1.0, 0.1, 0.5, cache=False)
    return element, impact_loop_orbit(PD, element, F0, W0)


def test_pd_loop_orbit_agrees_with_a_long_run(pd_orbit):
    element, orbit = pd_orbit
    assert orbit.success and orbit.period_multiple == 1 and orbit.stable, orbit
    assert abs(orbit.frequency / W0 - 1) < 0.05          # near the prediction, not on it (the DF's error)
    # a long run of the engine from the prediction's start settles on the orbit
    loop = _Loop(PD, element, 1e-9, F0, W0)
    z = loop.start_state(F0, W0)
    t_end = 400 * 2 * math.pi / W0
    run = _engine.run(loop.system, z, t_end, loop.v_stick, 10 ** 6, record_from=0.9 * t_end)
    pm = _ImpactMap(loop, orbit.section_side, orbit.period, 10 ** 6, np.inf)
    idx = pm.section_indices(run)
    assert abs(np.diff(run.t0[idx])[-1] - orbit.period) < 1e-9 * orbit.period
    t_sec = run.t0[idx[-2]]
    x_run = run.states(t_sec + orbit.t) @ loop.x_row
    assert np.max(np.abs(x_run - orbit.x)) < 1e-7 * np.max(np.abs(orbit.x))


def test_orbit_multipliers_match_finite_difference_monodromy(pd_orbit):
    element, orbit = pd_orbit
    loop = _Loop(PD, element, 1e-9, F0, W0)
    pm = _ImpactMap(loop, orbit.section_side, orbit.period, 10 ** 6, np.inf)
    xi = orbit.section_state
    p0, J, *_ = pm.map_and_jacobian(xi, 1)
    fd = np.empty_like(J)
    for j in range(xi.size):
        d = 1e-6 * max(abs(xi[j]), 1e-3)
        e = np.zeros(xi.size)
        e[j] = d
        fd[:, j] = (pm.map_and_jacobian(xi + e, 1)[0] - pm.map_and_jacobian(xi - e, 1)[0]) / (2 * d)
    scale = np.max(np.abs(fd))
    assert np.max(np.abs(fd - J)) < 1e-5 * scale
    mu_fd = np.sort(np.abs(np.linalg.eigvals(fd)))[::-1]
    assert np.allclose(np.sort(np.abs(orbit.multipliers))[::-1][:2], mu_fd[:2], rtol=1e-4)


def test_orbit_reports_failure_without_impacts():
    orbit = impact_loop_orbit(ct.tf([5.0], [1.0, 2.0]), _Fixed(0.5, 0.0), 5.0, 40.0)
    assert not orbit.success and "impacts" in orbit.message and np.isnan(orbit.period)
