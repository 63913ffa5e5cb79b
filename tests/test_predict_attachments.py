"""predict_limit_cycles attaches a confidence to every cycle and, on request, the exact orbit; both equal what
the stand-alone functions give for the same (A, w)."""
import pickle

import control as ct
import numpy as np
import pytest

import dfloop as df

G_RELAY = ct.tf([1.0], [1.0, 3.0, 2.0, 0.0])   # 1/(s(s+1)(s+2)): ideal relay, exact cycle in closed form


def test_every_cycle_carries_the_confidence_cycle_confidence_gives():
    cycles = df.predict_limit_cycles(ct.tf([8.0], [1.0, 2.0, 2.0, 1.0]), df.Saturation(1.0))
    assert len(cycles) == 1
    c = cycles[0]
    direct = df.cycle_confidence(ct.tf([8.0], [1.0, 2.0, 2.0, 1.0]), df.Saturation(1.0), c.amplitude, c.frequency)
    assert c.confidence.distortion == pytest.approx(direct.distortion, rel=1e-12)
    assert c.confidence.amplitude_error == pytest.approx(direct.amplitude_error, rel=1e-12)
    assert pickle.loads(pickle.dumps(c)).confidence.distortion == pytest.approx(direct.distortion, rel=1e-12)
    assert "distortion" in repr(cycles)


def test_exact_true_attaches_the_orbit_exact_cycle_finds():
    cycles = df.predict_limit_cycles(G_RELAY, df.Relay(1.0), exact=True)
    ex = cycles[0].exact
    direct = df.exact_cycle(G_RELAY, df.Relay(1.0), cycles[0])
    assert ex.success and direct.success
    assert ex.frequency == pytest.approx(direct.frequency, rel=1e-12)
    assert ex.amplitude == pytest.approx(direct.amplitude, rel=1e-12)
    # the DF's error is what the prediction and the orbit say it is
    assert ex.frequency < cycles[0].frequency
    assert df.predict_limit_cycles(G_RELAY, df.Relay(1.0))[0].exact is None


def test_python_control_nonlinearity_gives_the_same_cycle_as_the_dfloop_element():
    G = ct.tf([8.0], [1.0, 2.0, 2.0, 1.0])
    a = df.predict_limit_cycles(G, ct.saturation_nonlinearity(1.0))[0]
    b = df.predict_limit_cycles(G, df.Saturation(1.0))[0]
    assert a.amplitude == pytest.approx(b.amplitude, rel=1e-12)
    assert a.frequency == pytest.approx(np.sqrt(2.0), rel=1e-12)


@pytest.mark.parametrize("bad", ["yes", 1, None])
def test_exact_must_be_a_bool(bad):
    with pytest.raises(ValueError, match="exact must be True or False"):
        df.predict_limit_cycles(G_RELAY, df.Relay(1.0), exact=bad)


def test_dynamic_backlash_exact_cycle_is_where_a_long_run_of_the_engine_settles():
    from dfloop.harmonics import fundamental

    G = ct.tf([33.028, 425.06], [1.11979e-4, 2.11640e-2, 1.0])      # PD + roll-off of models/dynamic_backlash_pd
    N = df.DynamicBacklash(m1=1.0, m2=1.0, h=0.1, restitution=0.5)
    ex = df.exact_cycle(G, N, (31.75, 31.5))                         # a pair: no table is needed
    assert ex.success, ex.message
    assert ex.largest_multiplier < 1 and ex.stable
    assert np.min(np.abs(ex.multipliers - 1)) < 1e-6                 # the trivial multiplier of the autonomous loop
    run = df.simulate_loop(G, N, 31.75, 31.5, periods=300, steps_per_period=400)
    T = ex.period
    last = run.t >= run.t[-1] - 40 * T                               # 40 periods of the exact period, settled
    t, x = run.t[last], run.x[last]
    n = int((t[-1] - t[0]) / T)
    keep = t <= t[0] + n * T
    A_run = abs(fundamental(t[keep], x[keep], ex.frequency))
    assert A_run == pytest.approx(ex.amplitude, rel=2e-3)            # sampled run: rectangle-rule fundamental
    # the settled run repeats with the exact period, to the error of linear interpolation between its samples
    # (dt^2 / 8 |x''| <= (2 pi / 400)^2 / 8 * max|x| * (1 + harmonics) ~ 1e-4 max|x|)
    inside = t[keep] + T <= run.t[-1]
    shifted = np.interp(t[keep][inside] + T, run.t, run.x)
    assert np.max(np.abs(shifted - x[keep][inside])) < 1e-3 * np.max(np.abs(x))
