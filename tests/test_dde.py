"""A static element with sloped pieces and a pure delay: the loop is a delay differential equation, solved by
dfloop.hybrid.dde (4th-order method of steps on a periodic grid). Checks: the measured order of convergence, the
agreement with the exact hybrid engine on Padé chains of rising order (an independent discretisation of the
delay), and the multipliers of the discretised history (trivial one at 1, the others converged)."""
import math

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.hybrid import loop_model
from dfloop.hybrid.dde import dde_orbit
from dfloop.solve.delay import delayed

G0 = ct.tf([12.0], [1.0, 1.0]) * ct.tf([1.0], [0.5, 1.0])
T = 0.4
N = df.Saturation(1.0)
PRED = (3.3392759240180117, 2.57610328612914)


@pytest.fixture(scope="module")
def orbits():
    loop = loop_model(delayed(G0, T), N, *PRED)        # the dispatcher: a DDELoop for a delayed static element
    return {n: dde_orbit(loop, *PRED, nodes=n) for n in (32, 64, 128, 256)}


def test_saturation_delay_orbit_converges_at_fourth_order(orbits):
    ref = orbits[256]                       # 512 nodes
    assert ref["success"]
    for key in ("amplitude", "frequency"):
        e = [abs(orbits[n][key] / ref[key] - 1) for n in (32, 64, 128)]   # 64, 128, 256 nodes
        order = [math.log2(e[0] / e[1]), math.log2(e[1] / e[2])]
        assert min(order) > 3.0, (key, e, order)
    # the reported error estimate (change between the two resolutions) bounds the true error of the finer one
    est = orbits[64]["extra"]["error_estimate"]
    assert abs(orbits[64]["amplitude"] / ref["amplitude"] - 1) <= est[0]
    assert abs(orbits[64]["frequency"] / ref["frequency"] - 1) <= est[1]


def test_pade_chains_on_the_exact_hybrid_engine_converge_to_the_delay_equation_orbit(orbits):
    ref = orbits[256]
    prev = None
    gaps = []
    for order in (5, 6, 7):
        num, den = ct.pade(T, order)
        e = df.exact_cycle(G0 * ct.tf(num, den), N, PRED, nodes=1)
        assert e.success, e.message
        gaps.append(max(abs(e.amplitude / ref["amplitude"] - 1), abs(e.frequency / ref["frequency"] - 1)))
        if prev is not None:
            # the Pade chain's own change bounds its distance to the delay equation's orbit
            step = max(abs(e.amplitude / prev.amplitude - 1), abs(e.frequency / prev.frequency - 1))
            assert gaps[-1] <= step
        prev = e
    assert gaps[0] > gaps[1] > gaps[2] and gaps[2] < 2e-6


def test_delay_equation_multipliers_and_exact_cycle_dispatch(orbits):
    coarse, fine = orbits[32]["multipliers"], orbits[128]["multipliers"]     # 64 and 256 nodes
    assert abs(fine[0] - 1) < 1e-6                      # the trivial multiplier of the autonomous orbit
    assert abs(fine[1] - coarse[1]) < 1e-4 * abs(fine[1]) and abs(fine[1]) < 1   # converged, inside: stable
    e = df.exact_cycle(delayed(G0, T), N, PRED)
    assert e.success and e.stable and "delay equation" in e.method
    assert e.amplitude == pytest.approx(orbits[128]["amplitude"], rel=1e-12)   # the default: 128 and 256 nodes
    assert e.largest_multiplier == pytest.approx(abs(fine[1]), rel=1e-9)
    np.testing.assert_allclose(np.max(np.abs(e.x)) / e.amplitude, 1.0, atol=0.1)   # a near-sinusoidal wave


def test_time_simulation_of_the_delay_equation_settles_on_the_orbit(orbits):
    # verify_cycle / simulate_loop run the same scheme as a time-stepping method of steps from the prediction
    from dfloop.harmonics import steady_state
    from dfloop.verify import simulate_loop

    G = delayed(G0, T)
    sim = simulate_loop(G, N, *PRED, periods=50, steps_per_period=200)
    assert "method of steps" in sim.method and not sim.diverged
    st = steady_state(sim.t, sim.x, 10)
    ref = orbits[128]
    assert st.frequency == pytest.approx(ref["frequency"], rel=1e-7)
    assert st.amplitude == pytest.approx(ref["amplitude"], rel=1e-6)
    v = df.verify_cycle(G, N, PRED, periods=40, steps_per_period=100)
    assert v.verdict == "stable"


def test_the_dispatcher_picks_the_delay_engine_from_the_time_model():
    # loop_model reads the element's time model only: a static map (checked against the element's own output and
    # breakpoints) -> the delay equation; piecewise constant -> the exact delay flow; memory -> the delay equation with
    # the element's state in the history; impacts -> ValueError naming N
    from dfloop.hybrid import DDELoop, DelayLoop
    from dfloop.hybrid.dde import static_map

    G = delayed(G0, T)
    x = np.linspace(-4.0, 4.0, 2001)
    for el in (df.Saturation(1.0, k=2.0), df.DeadZone(0.5), df.CubicStiffness(1.0, 0.3), df.PreloadedSpring(1.0, 0.3)):
        loop = loop_model(G, el, 2.0, 2.0)
        assert isinstance(loop, DDELoop) and loop.delay == T
        np.testing.assert_allclose(loop.f(x), el.output(x), rtol=1e-13, atol=1e-13)
        bp = el.breakpoints(64 * 2.0)
        expected = np.unique(np.concatenate([-np.asarray(bp, float), np.asarray(bp, float)])) if bp is not None \
            else np.empty(0)
        np.testing.assert_array_equal(np.sort(loop.kinks), expected)
    for el in (df.Relay(1.0), df.Relay(1.0, hysteresis=0.1, dead_zone=0.2), df.Quantizer(0.5)):
        assert isinstance(loop_model(G, el, 2.0, 2.0), DelayLoop)
    assert static_map(df.Relay(1.0, hysteresis=0.1).time_model(2.0)) == (None, None)   # hysteretic: not a map
    from dfloop.hybrid.dde_memory import MemoryDDELoop

    assert isinstance(loop_model(G, df.Backlash(h=0.5), 2.0, 2.0), MemoryDDELoop)   # memory: its state in history
    from dfloop.hybrid.delay_impact import DelayImpactLoop                           # impacts: steps on the engine

    assert isinstance(loop_model(G, df.DynamicBacklash(1.0, 1.0, 0.1, 0.5), 2.0, 2.0), DelayImpactLoop)


def test_multipliers_with_a_delay_longer_than_the_period():
    # the history window then wraps the periodic node indices more than once (an IndexError before); the
    # multipliers still converge with the resolution, and the 2.74 rad/s cycle (period 2.29 s < T = 3 s) is
    # unstable through a complex pair
    G, N = delayed(ct.tf([4.0], [1.0, 1.0]), 3.0), df.Saturation(1.0)
    c = sorted(df.predict_limit_cycles(G, N), key=lambda c: c.frequency)[1]
    loop = loop_model(G, N, c.amplitude, c.frequency)
    mu = [dde_orbit(loop, c.amplitude, c.frequency, nodes=n)["multipliers"] for n in (64, 128)]
    assert abs(mu[1][0] - mu[0][0]) < 1e-4 * abs(mu[1][0]) and abs(mu[1][0]) > 1.2
    assert abs(mu[1][0].imag) > 1.0 and np.min(np.abs(mu[1] - 1)) < 1e-4     # the pair, and the trivial one
