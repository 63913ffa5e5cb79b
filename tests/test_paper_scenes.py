"""The paper's figure scenes and the scene ``[figure]`` stage, checked against independent computations."""
import math

import numpy as np
import pytest

from dfloop.impact.limits import lower_limit_frequency
from dfloop.impact.reference import simulate_solve_ivp
from dfloop.scene import SceneError, load_scene, shipped_scenes
from dfloop.scene.figure import figure_data, figure_spec

PAPER = sorted(name for name in shipped_scenes() if name.startswith("paper_"))
PLANT = "[plant]\nnum = [1.0]\nden = [1.0]\n"
IMPACT = ("[element]\ntype = 'DynamicBacklash'\nm1 = 1.0\nm2 = 1.0\nh = 0.1\nrestitution = 0.5\n"
          "[analysis]\npredict = false\nplots = []\n")


def scene(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return load_scene(path)


def test_every_paper_figure_has_a_scene_that_loads():
    figures = {int(name.removeprefix("paper_fig")) for name in PAPER}
    assert figures == {3, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14}
    for name in PAPER:
        s = load_scene(name)
        spec = figure_spec(s)
        assert spec is not None and s.data["analysis"]["predict"] is False
        if spec.kind == "time_response":  # Figs. 10-14: one frequency each, the paper's three eps
            assert spec.values == [0.2, 0.5, 0.8] and len(spec.frequencies) == 1


def test_nyquist_stage_matches_a_brute_force_describing_function(tmp_path):
    """-1/N of backlash (h = 1) against the fundamental of an independently coded play operator."""
    s = scene(tmp_path, PLANT + "[element]\ntype = 'Backlash'\nh = 1.0\n[analysis]\npredict = false\nplots = []\n"
              "[figure]\nkind = 'nyquist'\namplitudes = [0.8, 2.0]\nomega = [1.0, 10.0]\npoints = 12\n")
    data = figure_data(s)
    assert [c.amplitude for c in data.curves] == [0.8, 2.0]
    n = 200_000
    theta = 2 * math.pi * np.arange(2 * n) / n
    for curve in data.curves:
        x = curve.amplitude * np.sin(theta)
        y, c = np.empty_like(x), 0.0
        for i, xi in enumerate(x):  # play operator: the output follows x at distance h/2 once engaged
            c = min(max(c, xi - 0.5), xi + 0.5)
            y[i] = c
        fundamental = 2 / n * np.sum(y[n:] * np.exp(-1j * theta[n:]))  # phasor of Re(Y e^{j theta}) ...
        N = 1j * fundamental / curve.amplitude  # ... against x = A sin(theta) = Re(-j A e^{j theta})
        assert curve.x.size == 12 and curve.ok.all()
        np.testing.assert_allclose(curve.y, -1 / N, rtol=1e-4)


def test_time_response_stage_matches_solve_ivp_and_marks_the_lower_limit(tmp_path):
    # w = 35 rad/s: alternate impacts without sticking (the solve_ivp reference cannot stick), above eq. (10)'s
    # w_c (13.3 rad/s at eps = 0.5, 4.23 at 0.8); w = 4 rad/s is below both, so only those panels are marked
    s = scene(tmp_path, PLANT + IMPACT + "[figure]\nkind = 'time_response'\namplitudes = [50.0]\n"
              "parameter = 'element.restitution'\nvalues = [0.5, 0.8]\nfrequencies = [35.0, 4.0]\nperiods = 3\n")
    data = figure_data(s)
    assert [(c.value, c.omega) for c in data.curves] == [(0.5, 35.0), (0.8, 35.0), (0.5, 4.0), (0.8, 4.0)]
    for curve in data.curves:
        below = curve.omega < lower_limit_frequency(50.0, 1.0, 0.1, curve.value)
        assert ("not applicable" in curve.note) == below
        assert below == (curve.omega == 4.0)
    for curve in data.curves[:2]:
        ref = simulate_solve_ivp(1.0, 1.0, 0.1, curve.value, 50.0, curve.omega, curve.x[-1])
        assert ref["t"].size > 2
        t = curve.x[5:-5:7]  # impacts are instantaneous jumps of v1: compare away from them
        keep = np.min(np.abs(t[:, None] - ref["t"][None, :]), axis=1) > 1e-6
        np.testing.assert_allclose(curve.y[5:-5:7][keep], ref["sol"](t[keep])[1], atol=1e-7)


def test_collisions_stage_counts_no_impacts_above_w_L_and_alternate_impacts_in_the_regular_band(tmp_path):
    # eq. (11) is exact: no impact from rest for w > 2 sqrt(F/(h M2)) = 44.7 rad/s (F = 50 N); just below it
    # (beta ~ 0.3..0.6) the motion is one impact on each side per period (the paper's regular band)
    s = scene(tmp_path, PLANT + IMPACT + "[figure]\nkind = 'collisions'\namplitudes = [50.0]\n"
              "omega = [30.0, 60.0]\npoints = 10\ntransient_periods = 50\nperiods = 10\n")
    (curve,) = figure_data(s).curves
    w_L = 2 * math.sqrt(50.0 / 0.1)
    assert np.all(curve.y[curve.x > w_L] == 0)
    beta = 50.0 / (0.1 * curve.x ** 2)
    band = (beta > 0.3) & (beta < 0.6)
    assert band.any() and np.all(curve.y[band] == 1) and curve.ok[band].all()


@pytest.mark.parametrize("figure, key, message", [
    ("kind = 'nyquist'\namplitudes = [1.0]\n", "figure", "needs omega"),
    ("kind = 'time_response'\namplitudes = [1.0]\n", "figure", "needs frequencies"),
    ("kind = 'nyquist'\namplitudes = [1.0]\nomega = [1.0, 2.0]\nparameter = 'element.h'\n", "figure",
     "parameter and values go together"),
    ("kind = 'nyquist'\namplitudes = [-1.0]\nomega = [1.0, 2.0]\n", "figure", "amplitudes must all be > 0"),
    ("kind = 'nyqist'\namplitudes = [1.0]\nomega = [1.0, 2.0]\n", "figure.kind", "unknown value"),
    ("kind = 'nyquist'\namplitudes = [1.0]\nomega = [1.0, 2.0]\npoint = 10\n", "figure.point", "unknown key"),
])
def test_figure_mistakes_are_named(tmp_path, figure, key, message):
    with pytest.raises(SceneError) as info:
        scene(tmp_path, PLANT + "[element]\ntype = 'Backlash'\nh = 1.0\n[figure]\n" + figure)
    assert any(p.key == key and message in p.message for p in info.value.problems), info.value


def test_predict_false_refuses_stages_that_need_cycles(tmp_path):
    with pytest.raises(SceneError, match="predict = true"):
        scene(tmp_path, PLANT + "[element]\ntype = 'Backlash'\nh = 1.0\n[analysis]\npredict = false\n"
                                "verify = true\n")


def test_impact_kinds_need_dynamic_backlash_and_a_real_parameter(tmp_path):
    s = scene(tmp_path, PLANT + "[element]\ntype = 'Backlash'\nh = 1.0\n[figure]\nkind = 'time_response'\n"
                                "amplitudes = [1.0]\nfrequencies = [2.0]\n")
    with pytest.raises(SceneError, match=r"must carry its parameters .*Backlash has no m1, m2, restitution, effects"):
        figure_data(s)
    s = scene(tmp_path, PLANT + "[element]\ntype = 'Backlash'\nh = 1.0\n[figure]\nkind = 'nyquist'\n"
                                "amplitudes = [1.0]\nomega = [1.0, 2.0]\nparameter = 'element.hh'\nvalues = [1.0]\n")
    with pytest.raises(SceneError) as info:
        figure_data(s)
    assert info.value.problems[0].key == "figure.parameter" and info.value.problems[0].suggestion == "h"
