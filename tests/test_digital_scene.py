"""Scenes with a sampling period: a digital controller and a continuous plant behind a zero-order hold."""
import math
from pathlib import Path

import control as ct
import numpy as np
import pytest

from dfloop import Quantizer, SceneError, exact_cycle, load_scene, predict_limit_cycles

ROOT = Path(__file__).resolve().parents[1]

SCENE = """[plant]
num = [1.0]
den = [1.0, 3.0, 3.0, 1.0]
[controller]
num = [5.6]
den = [1.0]
dt = 0.2
discrete = true
[element]
type = "Quantizer"
step = 0.05
[analysis]
amplitude = [0.026, 1.0]
plots = []
"""


def test_digital_controller_samples_the_plant_behind_a_hold(tmp_path):
    path = tmp_path / "digital.toml"
    path.write_text(SCENE)
    scene = load_scene(path)
    assert scene.plant.dt == 0.2
    direct = 5.6 * ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), 0.2, "zoh")
    w = np.linspace(0.1, math.pi / 0.2 * 0.99, 50)
    assert np.allclose(scene.plant(np.exp(1j * w * 0.2)), direct(np.exp(1j * w * 0.2)), rtol=1e-10)
    got = predict_limit_cycles(scene.plant, scene.element, amplitude=(0.026, 1.0))
    ref = predict_limit_cycles(direct, Quantizer(0.05), amplitude=(0.026, 1.0))
    assert np.allclose([(c.amplitude, c.frequency) for c in got], [(c.amplitude, c.frequency) for c in ref],
                       rtol=1e-9)
    assert len(got) == 2


def test_sampled_plant_and_errors(tmp_path):
    path = tmp_path / "zoh.toml"
    path.write_text(SCENE.replace("[controller]\nnum = [5.6]\nden = [1.0]\ndt = 0.2\ndiscrete = true\n", "")
                    .replace('den = [1.0, 3.0, 3.0, 1.0]', 'den = [1.0, 3.0, 3.0, 1.0]\ndt = 0.1'))
    scene = load_scene(path)
    assert scene.plant.dt == 0.1
    assert np.allclose(ct.ss(scene.plant).A, ct.ss(ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), 0.1)).A)
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.replace("dt = 0.2\n", ""))
    with pytest.raises(SceneError, match="dt"):
        load_scene(bad)


def test_shipped_digital_scene_exact_orbit():
    scene = load_scene(ROOT / "models" / "digital_quantizer.toml")
    cycles = predict_limit_cycles(scene.plant, scene.element, amplitude=(0.026, 1.0))
    stable = [c for c in cycles if c.stability == "stable"][0]
    ex = exact_cycle(scene.plant, scene.element, stable)
    assert ex.success and ex.extra["map"] and ex.stable
    # the orbit's outputs are multiples of the step, and its inputs quantize to them (the element's own rule)
    assert np.allclose(ex.y / 0.05, np.round(ex.y / 0.05))
    assert np.array_equal(Quantizer(0.05).output(ex.x), ex.y)


def test_nyquist_draws_the_discrete_time_curve():
    import matplotlib
    matplotlib.use("Agg")
    from dfloop import plot_nyquist

    G = ct.sample_system(ct.tf([5.6], [1.0, 3.0, 3.0, 1.0]), 0.2)
    cycles = predict_limit_cycles(G, Quantizer(0.05), amplitude=(0.026, 1.0))
    cp = plot_nyquist(cycles)
    line = cp.lines[0][0]
    assert "e^{jωΔt}" in line.get_label()
    z = line.get_xdata() + 1j * line.get_ydata()
    # every drawn point is G(z) at some z on the upper unit half-circle: compare with python-control's G on a dense grid
    w = np.geomspace(1e-3, math.pi / 0.2, 40_001)
    g = G(np.exp(1j * w * 0.2))
    dist = np.min(np.abs(z[::50, None] - g[None, :]), axis=1)
    assert np.max(dist / np.abs(z[::50])) < 1e-3
