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
