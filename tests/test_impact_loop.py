"""Closed loop around the dynamic backlash on the exact linear-mode engine (dfloop.hybrid.ImpactLoop): against an
independent event-located solve_ivp reference (with chatter and sticking), momentum bookkeeping, divergence, and
the periodic orbit exact_cycle finds with the one shooting routine: its period and harmonics against an FFT of a
long independent run, its Floquet multipliers against a finite-difference monodromy of the independent run, and
every validated option (tol, nodes, max_deviation, max_events) in use."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dfloop.describing.base import DescribingFunction
from dfloop.describing.time_model import Impact
from dfloop.exact import exact_cycle
from dfloop.hybrid import loop_model
from dfloop.impact import ViscousDamping
from dfloop.verify import simulate_loop

PD = ct.tf([33.028, 425.06], [1.11979e-4, 2.11640e-2, 1.0])   # models/dynamic_backlash_pd.toml
F0, W0 = 31.75, 31.5                                            # its design point
N_PD = -0.000848287 + 0.000507856j                              # the element's DF there (impact_describing_function)


class _Fixed(DescribingFunction):
    """A dynamic-backlash stand-in with a fixed N (the start state only needs N; no table is built); its time model
    is the impact element's."""

    frequency_dependent = True

    def __init__(self, eps, N, effects=(), chatter_tol=1e-9):
        self.m1, self.m2, self.h, self.restitution, self.effects, self._N = 1.0, 1.0, 0.1, eps, effects, N
        self.chatter_tol = chatter_tol

    def _evaluate(self, A, omega):
        return np.full(np.broadcast(A, omega).shape, complex(self._N))

    def time_model(self, amplitude):
        return Impact("stand-in", self.m1, self.m2, self.h, self.restitution, tuple(self.effects), self.chatter_tol)


def test_bad_input_is_named():
    element = _Fixed(0.5, 0.0)
    with pytest.raises(ValueError, match="amplitude"):
        simulate_loop(PD, element, -1.0, 20.0)
    with pytest.raises(ValueError, match="tf or ss"):
        simulate_loop(lambda w: 1.0 / (1j * w + 1), element, 10.0, 20.0)
    with pytest.raises(ValueError, match="periods"):
        simulate_loop(PD, element, 10.0, 20.0, periods=math.inf)
    with pytest.raises(ValueError, match="^N must be a dfloop DescribingFunction"):
        simulate_loop(PD, object(), 10.0, 20.0)
    with pytest.raises(ValueError, match="max_events"):
        exact_cycle(PD, element, (10.0, 20.0), max_events=0)


def test_loop_without_impacts_is_the_linear_loop_with_N_zero():
    """Below the no-impact limit N = 0: x1 stays 0 and nothing drives the plant; exact_cycle says the loop rests."""
    G = ct.tf([5.0], [1.0, 2.0])
    sim = simulate_loop(G, _Fixed(0.5, 0.0), 5.0, 40.0, periods=5)
    assert np.all(sim.y == 0.0) and np.all(sim.x == 0.0) and not sim.diverged
    e = exact_cycle(G, _Fixed(0.5, 0.0), (5.0, 40.0))
    assert not e.success and "rest" in e.message


def _reference(G, eps, z0, t_end, v_stick, full=False):
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

    def x(tt):                 # element input: the force on M2, -c
        out = np.empty(tt.size)
        for a, b, f in pieces:
            m = (tt >= a) & (tt <= b)
            if b > a and m.any():
                out[m] = force(f(tt[m]))
        return out

    if full:
        return np.array(events), x, y
    return np.array(events), x1


@pytest.mark.parametrize("eps,F,w,chatter", [(0.8, F0, W0, False), (0.2, 60.0, 14.0, True)])
def test_closed_loop_engine_matches_event_located_solve_ivp(eps, F, w, chatter):
    G = ct.ss(PD)
    loop = loop_model(G, _Fixed(eps, 0.0, chatter_tol=1e-4), F, w)
    z0 = np.zeros(loop.size)
    z0[2], z0[-1] = 0.05, 1.0
    z0[4:-1] = [0.002, -0.004]               # the plant starts away from rest: the loop is driven by its state
    t_end = 0.8
    fl = loop.flow(z0, 0, t_end, max_events=100_000)
    ref_events, ref_x1 = _reference(G, eps, z0[:-1], t_end, loop.v_stick)
    ours = np.array(fl.events, dtype=float)
    assert ours.shape[0] == ref_events.shape[0] >= 8
    assert np.array_equal(ours[:, 1], ref_events[:, 1])
    assert np.max(np.abs(ours[:, 0] - ref_events[:, 0])) < 1e-8
    if chatter:
        assert np.count_nonzero(fl.run.contact != 0) >= 2   # chatter settled into stuck phases, then separated
    t = np.linspace(0, t_end, 801)
    ref = ref_x1(t)      # the reference's own error (rtol 1e-12 over dozens of restarts) sets the bound
    assert np.max(np.abs(loop.states(fl, t)[:, 0] - ref)) < 1e-7 * np.max(np.abs(ref))


def test_momentum_changes_only_by_the_impulse_of_the_control_force():
    """d/dt (M1 v1 + M2 v2) = -c; impacts and sticking conserve momentum: p(t) - p(0) = -int c dt exactly."""
    loop = loop_model(ct.ss(PD), _Fixed(0.3, 0.0, chatter_tol=1e-6), F0, W0)
    z0 = np.zeros(loop.size)
    z0[2], z0[-1], z0[4:-1] = 0.05, 1.0, [0.002, -0.004]
    fl = loop.flow(z0, 0, 0.6, max_events=100_000)
    assert fl.t0.size > 20
    nodes, weights = np.polynomial.legendre.leggauss(20)
    impulse = 0.0
    ends = np.append(fl.t0[1:], 0.6)
    for a, b in zip(fl.t0, ends):
        if b > a:
            tt = 0.5 * (b - a) * nodes + 0.5 * (a + b)
            impulse += 0.5 * (b - a) * weights @ loop.signals(fl, tt)[0]
    zt = loop.states(fl, 0.6)[0]
    momentum = zt[1] + (zt[1] + zt[3])
    assert abs(momentum - impulse) < 1e-10 * max(1.0, abs(impulse))


def test_diverging_loop_is_flagged_and_stops():
    G = ct.tf([300.0], [1.0, -5.0])
    sim = simulate_loop(G, _Fixed(0.5, 0.001 + 0.0j), 30.0, 30.0, periods=200)
    assert sim.diverged and sim.t[-1] < 200 * 2 * math.pi / 30.0
    e = exact_cycle(G, _Fixed(0.5, 0.001 + 0.0j), (30.0, 30.0))
    assert not e.success and "diverged" in e.message and "not found" in repr(e)


def test_event_bound_names_how_to_raise_it():
    e = exact_cycle(PD, _Fixed(0.5, N_PD), (F0, W0), max_events=1)   # two impacts per period
    assert not e.success and "max_events = 1" in e.message


def test_zero_damping_effect_is_the_undamped_loop():
    a = simulate_loop(PD, _Fixed(0.5, 0.003), F0, W0, periods=10)
    b = simulate_loop(PD, _Fixed(0.5, 0.003, (ViscousDamping(0.0),)), F0, W0, periods=10)
    assert np.array_equal(a.x, b.x) and np.max(np.abs(a.x)) > 10.0


# ------------------------------------------------------------------------------ the orbit exact_cycle finds


@pytest.fixture(scope="module")
def pd_orbit():
    return exact_cycle(PD, _Fixed(0.5, N_PD), (F0, W0))


def _period_map(z, T, t_end=None):
    """The independent reference from state z over t_end (default T): (events, x1 function, state at the end)."""
    return _reference(ct.ss(PD), 0.5, z[:-1], T if t_end is None else t_end, 0.0, full=True)


def test_pd_orbit_fields_are_real(pd_orbit):
    e = pd_orbit
    assert e.success and e.stable, e
    assert abs(e.frequency / W0 - 1) < 0.05          # near the prediction, not on it (the DF's error)
    assert 1 <= e.iterations <= 40 and 0 <= e.residual <= 1e-11
    assert e.harmonics.size == 15 and e.distortion > 0.05           # an impact orbit is far from a sinusoid
    assert e.distortion == pytest.approx(np.sqrt(np.sum(np.abs(e.harmonics[1:]) ** 2)) / e.amplitude, rel=1e-14)
    assert e.switching_times.size >= 2 and np.all(np.diff(e.switching_times) > 0)
    assert np.min(np.abs(e.multipliers - 1)) < 1e-6      # the trivial multiplier of the autonomous loop


def test_pd_orbit_harmonics_match_an_fft_of_a_long_independent_run(pd_orbit):
    """The reference (event-located DOP853) starts 1 % off the orbit and runs 30 periods (multipliers ~0.31 shrink
    the offset below 1e-14); its period (impact to impact on one wall) and the FFT of x over its last period give
    the period and the harmonics."""
    e = pd_orbit
    z = e.extra["z0"].copy()
    z[:-1] *= 1.01
    z[2] = min(max(z[2], 0.0), 0.1)
    events, x_of, _ = _period_map(z, e.period, 30 * e.period)
    side = events[-1, 1]
    same = events[events[:, 1] == side, 0]
    assert same[-1] - same[-2] == pytest.approx(e.period, rel=1e-9)
    t = same[-2] + np.arange(4096) * (e.period / 4096)
    X = 2j * np.fft.fft(x_of(t))[1:16] / t.size                       # x ~ Im(X_k e^{jk w (t - t_start)})
    X = X * np.exp(-1j * np.arange(1, 16) * np.angle(X[0]))          # time origin where x's fundamental is A sin
    assert abs(X[0]) == pytest.approx(e.amplitude, rel=1e-7)
    np.testing.assert_allclose(X, e.harmonics, atol=1e-6 * e.amplitude)
    distortion = np.sqrt(np.sum(np.abs(X[1:]) ** 2)) / abs(X[0])
    assert distortion == pytest.approx(e.distortion, rel=1e-5)


def test_pd_orbit_multipliers_match_a_finite_difference_monodromy_of_the_independent_run(pd_orbit):
    e = pd_orbit
    z0 = e.extra["z0"]
    nx = z0.size - 1
    fd = np.empty((nx, nx))
    for j in range(nx):
        h = 1e-6 * max(abs(z0[j]), 1e-3)
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        fd[:, j] = (_period_map(zp, e.period)[2] - _period_map(zm, e.period)[2]) / (2 * h)
    mu_fd = np.sort(np.abs(np.linalg.eigvals(fd)))[::-1]
    mu = np.sort(np.abs(e.multipliers))[::-1]
    np.testing.assert_allclose(mu[:3], mu_fd[:3], rtol=1e-4)
    assert mu_fd[0] == pytest.approx(1.0, abs=1e-5) and e.largest_multiplier < 1


def test_every_option_is_used_on_the_impact_loop(pd_orbit):
    e = pd_orbit
    single = exact_cycle(PD, _Fixed(0.5, N_PD), (F0, W0), nodes=1)
    assert single.success and single.frequency == pytest.approx(e.frequency, rel=1e-10)
    assert single.amplitude == pytest.approx(e.amplitude, rel=1e-9)
    loose = exact_cycle(PD, _Fixed(0.5, N_PD), (F0, W0), tol=1e-4)
    assert loose.success and loose.residual <= 1e-4 and loose.iterations <= e.iterations
    short = exact_cycle(PD, _Fixed(0.5, N_PD), (F0, W0), harmonics=3, samples=64)
    assert short.harmonics.size == 3 and short.x.size == 64
    far = exact_cycle(PD, _Fixed(0.5, N_PD), (F0, W0), max_deviation=0.001)   # the orbit is 2 % away
    assert not far.success and "max_deviation" in far.message


@pytest.mark.parametrize("eps,N", [(0.0, -5.2597e-06 + 6.4157e-04j), (0.2, -4.1141e-04 + 7.3077e-04j)])
def test_orbits_at_other_restitutions_match_the_independent_run(eps, N):
    """Plastic impacts with sticking (eps = 0) and low restitution with chatter (the former impact-map finder
    stopped on an event-bound error at eps = 0.2): the shot orbit's period and fundamental against the independent
    event-located run started 0.1 % off it."""
    e = exact_cycle(PD, _Fixed(eps, N), (F0, W0))
    assert e.success, e.message
    z = e.extra["z0"].copy()
    z[:-1] *= 1.001
    z[2] = min(max(z[2], 0.0), 0.1)
    T = e.period
    events, x_of, _ = _reference(ct.ss(PD), eps, z[:-1], 25 * T, 0.0, full=True)
    assert events.shape[0] >= 40
    t = 23 * T + np.arange(4096) * (T / 4096)
    x = x_of(t)
    assert np.max(np.abs(x_of(t + T) - x)) < 1e-7 * np.max(np.abs(x))     # settled, and periodic with T
    assert abs(2j * np.mean(x * np.exp(-2j * np.pi * t / T))) == pytest.approx(e.amplitude, rel=1e-6)


@pytest.mark.parametrize("eps,gain", [(0.3, 1.5), (0.9, 1.5)])
def test_orbits_of_stronger_loops_are_periodic_in_the_independent_run(eps, gain):
    """Gain 1.5 on the PD loop: at eps = 0.3 an unstable orbit (a complex multiplier pair just outside the unit
    circle, the settled motion turns around it), found with the nodes kept away from the impacts; at eps = 0.9 a
    stable orbit at twice the predicted frequency (found with the period detected on the settled motion; beyond
    the default max_deviation, which says so). Both return to their start after one period of the independent
    event-located run."""
    G = PD * gain
    e = exact_cycle(G, _Fixed(eps, N_PD), (F0, W0), max_deviation=1.0)
    assert e.success, e.message
    z0 = e.extra["z0"]
    _, _, z_end = _reference(ct.ss(G), eps, z0[:-1], e.period, 0.0, full=True)
    assert np.max(np.abs(z_end - z0[:-1])) < 1e-7 * np.max(np.abs(z0[:-1]))
    if eps == 0.3:
        assert not e.stable and 1.0 < e.largest_multiplier < 1.2
    else:
        assert e.stable and e.frequency > 1.8 * W0
        far = exact_cycle(G, _Fixed(eps, N_PD), (F0, W0))
        assert not far.success and "max_deviation" in far.message


def test_sampled_python_control_loop_converges_to_the_exact_orbit():
    """dfloop.control_loop(G, dynamic backlash, dt): the sampled-data loop (the masses' exact motion over each
    sample with the force held, the plant discretised with a hold on x1) run by python-control converges to the
    exact orbit at first order in dt: halving dt halves the error of amplitude and frequency, and the
    Richardson-extrapolated values are the exact orbit's within 0.5 %."""
    from dfloop.describing.interop import control_loop
    from dfloop.harmonics import steady_state
    from dfloop.impact.sampled_model import SampledImpactModel

    class Sampled(_Fixed):
        def sampled_model(self, dt):
            return SampledImpactModel(self.m1, self.m2, self.h, self.restitution, tuple(self.effects),
                                      self.chatter_tol, dt)

    element = Sampled(0.5, N_PD)
    e = exact_cycle(PD, element, (F0, W0))
    assert e.success, e.message
    errors = []
    for k in (100, 200):
        dt = e.period / k
        loop = control_loop(PD, element, dt=dt)
        assert loop.isdtime() and loop.nstates == 2 + 4
        t = np.arange(100 * k) * dt
        x = ct.input_output_response(loop, t, 0.0, loop.initial_state((F0, W0))).outputs[0]
        tail = t > 70 * e.period
        ss = steady_state(t[tail] - t[tail][0], x[tail], periods=20)
        errors.append(np.array([ss.amplitude / e.amplitude - 1, ss.frequency / e.frequency - 1]))
    coarse, fine = errors
    assert np.all(np.abs(fine) < np.abs(coarse)) and np.all(np.abs(coarse / fine - 2) < 0.3)
    assert np.all(np.abs(2 * fine - coarse) < 5e-3)
