"""Closed-loop simulation around the dynamic backlash: scope checks (its agreement with the DF prediction is
tested end to end in test_cli.py on the dynamic-backlash scene)."""
import control as ct
import numpy as np
import pytest

from dfloop.impact import DynamicBacklash, ViscousDamping
from dfloop.impact.loop import simulate_impact_loop


def test_effects_are_rejected_by_name():
    element = DynamicBacklash(1.0, 1.0, 0.1, 0.5, effects=(ViscousDamping(1.0),), cache=False)
    with pytest.raises(ValueError, match="effects"):
        simulate_impact_loop(ct.tf([1.0], [1.0, 1.0]), element, 10.0, 20.0)


def test_bad_amplitude_and_plant_are_named():
    element = DynamicBacklash(1.0, 1.0, 0.1, 0.5, cache=False)
    with pytest.raises(ValueError, match="amplitude"):
        simulate_impact_loop(ct.tf([1.0], [1.0, 1.0]), element, -1.0, 20.0)
    with pytest.raises(ValueError, match="tf or ss"):
        simulate_impact_loop(lambda w: 1.0 / (1j * w + 1), element, 10.0, 20.0)


def test_loop_without_impacts_is_the_linear_loop_with_N_zero():
    """Below the no-impact limit (beta < 1/4) the masses never touch, x1 stays 0 and the plant decays freely:
    c(t) = C exp(A t) s0 exactly, which the simulation must reproduce."""
    element = DynamicBacklash(1.0, 1.0, 0.1, 0.5, cache=False)
    G = ct.tf([5.0], [1.0, 2.0])
    F, w = 5.0, 40.0                      # beta = 5 / (0.1 * 1600) = 0.03 < 1/4: N = 0
    sim = simulate_impact_loop(G, element, F, w, periods=5)
    assert np.all(sim.y == 0.0)
    assert np.allclose(sim.x, 0.0)        # s0 = 0 because N = 0: nothing drives the plant
