"""[sweep] in scenes: the swept parameter is replaced in the rebuilt loop, values and paths are checked."""
import pickle

import numpy as np
import pytest

from dfloop.scene import SceneError, load_scene

BASE = """
[controller]
num = [2.0, 1.0]
den = [1.0]
[plant]
num = [5.0]
den = [1.0, 1.0, 0.0]
delay = 0.1
[element]
type = "Backlash"
h = 1.0
"""
DYNAMIC = """
[plant]
num = [1.0]
den = [1.0]
[element]
type = "DynamicBacklash"
m1 = 1.0
m2 = 2.0
h = 0.1
restitution = 0.5
effects = [{ type = "ViscousDamping", c = 5.0 }]
"""


def scene(tmp_path, base, parameter, values):
    path = tmp_path / "sweep.toml"
    path.write_text(base + f"[sweep]\nparameter = {parameter!r}\nvalues = {values}\n")
    return load_scene(path)


def loop(num0, delay=0.1):
    """Closed form of BASE's loop: (2 s + 1) num0 / (s^2 + s) e^{-s delay} at s = jw."""
    def G(w):
        s = 1j * np.asarray(w)
        return (2 * s + 1) * num0 / (s * s + s) * np.exp(-s * delay)
    return G


W = np.array([0.3, 1.0, 7.0])  # rad/s; the scene's delayed plant is evaluated at s = jW


def test_element_parameter_is_replaced_and_plant_kept(tmp_path):
    s = scene(tmp_path, BASE, "element.h", "[0.5, 2.0]")
    assert np.array_equal(s.sweep_values, [0.5, 2.0])
    for value in s.sweep_values:
        G, N = s.loop_at(value)
        assert N.h == value and N.k == 1.0
        assert np.allclose(G(1j * W), loop(5.0)(W), rtol=1e-13)


def test_plant_coefficient_is_replaced(tmp_path):
    s = scene(tmp_path, BASE, "plant.num.0", "{ start = 1.0, stop = 4.0, num = 4 }")
    assert np.allclose(s.sweep_values, [1.0, 2.0, 3.0, 4.0], rtol=0, atol=1e-15)
    for value in s.sweep_values:
        G, N = s.loop_at(value)
        assert np.allclose(G(1j * W), loop(value)(W), rtol=1e-13)
        assert N.h == 1.0


def test_delay_and_defaulted_parameter_can_be_swept(tmp_path):
    G, _ = scene(tmp_path, BASE, "plant.delay", "[0.0, 0.3]").loop_at(0.3)
    assert np.allclose(G(1j * W), loop(5.0, delay=0.3)(W), rtol=1e-13)
    G, _ = scene(tmp_path, BASE, "controller.delay", "[0.0, 0.2]").loop_at(0.2)  # not in the file: default 0
    assert np.allclose(G(1j * W), loop(5.0, delay=0.3)(W), rtol=1e-13)  # delays of controller and plant add up
    _, N = scene(tmp_path, BASE, "element.k", "[0.5, 2.0]").loop_at(2.0)  # k is not in the file: its default
    assert N.k == 2.0 and N.h == 1.0


def test_log_range_is_geometric(tmp_path):
    values = scene(tmp_path, BASE, "element.h", "{ start = 0.01, stop = 100.0, num = 5, scale = 'log' }")
    assert np.allclose(values.sweep_values, [0.01, 0.1, 1.0, 10.0, 100.0], rtol=1e-13)


def test_dynamic_backlash_restitution_and_effect_parameter(tmp_path):
    G, N = scene(tmp_path, DYNAMIC, "element.restitution", "[0.2, 0.8]").loop_at(0.8)
    assert N.restitution == 0.8 and (N.m1, N.m2, N.h) == (1.0, 2.0, 0.1)
    _, N = scene(tmp_path, DYNAMIC, "element.effects.0.c", "[1.0, 9.0]").loop_at(9.0)
    (effect,) = N.effects
    assert effect.c == 9.0 and N.restitution == 0.5
    _, N = scene(tmp_path, DYNAMIC, "element.periods", "[10.0, 30.0]").loop_at(30.0)
    assert N.periods == 30 and isinstance(N.periods, int)


def test_loop_at_pickles_for_executors(tmp_path):
    s = scene(tmp_path, BASE, "plant.num.0", "[1.0, 3.0]")
    clone = pickle.loads(pickle.dumps(s.loop_at))
    (G1, N1), (G2, N2) = s.loop_at(3.0), clone(3.0)
    assert np.array_equal(G1(W), G2(W))
    A = np.array([0.6, 1.0, 5.0])
    assert np.array_equal(N1(A), N2(A))


@pytest.mark.parametrize("parameter, values, key, message, suggestion", [
    ("element.hh", "[1.0, 2.0]", "sweep.parameter", "no key 'hh'", "h"),
    ("plantt.num.0", "[1.0, 2.0]", "sweep.parameter", "does not start with", "plant"),
    ("plant.num.1", "[1.0, 2.0]", "sweep.parameter", "not an index", None),
    ("element.type", "[1.0, 2.0]", "sweep.parameter", "not a number", None),
    ("element.h", "[1.0, -2.0]", "sweep.values", "element.h = -2", None),
    ("element.h", "{ start = -1.0, stop = 1.0, num = 3, scale = 'log' }", "sweep.values", "start > 0", None),
    ("element.h", "[1.0]", "sweep.values", "at least 2", None),
])
def test_bad_sweeps_are_named(tmp_path, parameter, values, key, message, suggestion):
    with pytest.raises(SceneError) as info:
        scene(tmp_path, BASE, parameter, values)
    (problem,) = info.value.problems
    assert problem.key == key and message in str(problem) and problem.suggestion == suggestion
