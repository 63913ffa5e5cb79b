"""The cheap confidence estimate brackets the true DF error (from exact_cycle) on loops of every element kind."""
import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.solve.confidence import BRACKET, cycle_confidence
from dfloop.exact import exact_cycle

LOOPS = {
    "relay": (ct.tf([1], [1, 3, 2, 0]), df.Relay()),
    "relay with hysteresis": (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.1)),
    "relay with dead zone": (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, dead_zone=0.1)),
    "saturation": (ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)),
    "backlash servo": (ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)),
    "dead zone (unstable cycle)": (ct.tf([12], [1, 3, 3, 1]), df.DeadZone(0.5)),
    "cubic stiffness": (ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0)),
}


@pytest.mark.parametrize("name", list(LOOPS))
def test_confidence_brackets_the_true_error(name):
    G, N = LOOPS[name]
    c = df.predict_limit_cycles(G, N)[-1]
    e = exact_cycle(G, N, c)
    assert e.success
    conf = cycle_confidence(G, N, c.amplitude, c.frequency)
    assert conf.reliable
    bA, bw = conf.bracket
    assert abs(e.amplitude_error) <= bA and abs(e.frequency_error) <= bw
    # the estimate is an estimate, not only a bound: same sign, at least half the true error
    for true, est in ((e.amplitude_error, conf.amplitude_error), (e.frequency_error, conf.frequency_error)):
        assert np.sign(true) == np.sign(est) and abs(est) >= abs(true) / BRACKET
    # the distortion at the element's input is the exact orbit's to within the neglected feedback of harmonics
    assert conf.distortion == pytest.approx(e.distortion, rel=0.2)


def test_confidence_is_unavailable_for_frequency_dependent_elements_and_rejects_bad_input():
    G = ct.tf([1], [1, 2, 1, 0])
    conf = cycle_confidence(G, df.MassBacklash(1.0, 1.0, 0.1), 1.0, 1.0)
    assert not conf.available and "frequency" in conf.note and conf.bracket is None
    assert "unavailable" in repr(conf)
    with pytest.raises(ValueError, match="amplitude"):
        cycle_confidence(G, df.Saturation(1.0), -1.0, 1.0)
    with pytest.raises(ValueError, match="frequency"):
        cycle_confidence(G, df.Saturation(1.0), 1.0, float("inf"))


def test_large_distortion_is_flagged_unreliable_where_the_df_is_far_off():
    """Open-loop-unstable plant: the DF is 23 % / 49 % off; the confidence says the prediction is unreliable."""
    G, N = ct.tf([30], [1, 4, 1, -6]), df.Saturation(1.0)
    c = df.predict_limit_cycles(G, N)[0]
    conf = cycle_confidence(G, N, c.amplitude, c.frequency)
    e = exact_cycle(G, N, c)
    assert e.success and abs(e.frequency_error) > 0.3
    assert not conf.reliable and conf.bracket is None and "unreliable" in repr(conf)
    assert conf.frequency_error > 0.1 and conf.amplitude_error < -0.05   # the estimate points the right way
