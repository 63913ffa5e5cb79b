"""[chart] in scenes: the shipped delay chart traces the closed-form birth curve, names its axes, writes its
files and prints the design point's limit-cycle margin; bad paths are reported with their key.

Reference: saturation (limit 1) around K e^{-sT}/(s(s+1)) is born at K_c(T) = w sqrt(1 + w^2), atan w + wT = pi/2.
"""
import csv
import math

import matplotlib

matplotlib.use("Agg")
import pytest  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

from dfloop.scene import SceneError, load_scene, run_scene  # noqa: E402


def critical_gain(T):
    w = brentq(lambda w: math.atan(w) + w * T - math.pi / 2, 1e-9, 1e3, xtol=1e-15, rtol=1e-15)
    return w * math.sqrt(1 + w * w)


def test_shipped_delay_chart(tmp_path):
    report = run_scene(load_scene("saturation_delay_chart"), tmp_path, log=lambda s: None, progress=False)
    (b,) = report.chart.boundaries
    assert b.kind == "linear range"
    assert max(abs(K / critical_gain(T) - 1) for K, T in zip(b.x, b.y)) < 1e-10
    (m,) = report.margins
    assert abs(m.x_above - (critical_gain(0.5) - 1.0)) < 1e-8  # nominal K = 1 (num), T = 0.5 (delay)
    text = (tmp_path / "saturation_delay_chart_report.md").read_text()
    assert "## Limit-cycle margins" in text and "gain K up: boundary at 2.1496704" in text
    assert f"({20 * math.log10(critical_gain(0.5)):+.3g} dB)" in text
    with open(tmp_path / "saturation_delay_chart_chart.csv") as fh:
        assert next(csv.reader(fh))[2:4] == ["gain K", "delay T [s]"]
    assert (tmp_path / "saturation_delay_chart_chart.png").stat().st_size > 10_000


def test_chart_paths_are_checked(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[plant]\nnum = [1.0]\nden = [1.0, 1.0, 0.0]\n[element]\ntype = 'Saturation'\nlimit = 1.0\n"
                    "[chart]\nx_axis = { parameter = 'plant.num.0', start = 1.0, stop = 2.0 }\n"
                    "y_axis = { parameter = 'element.limt', start = 1.0, stop = 2.0 }\n")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    (problem,) = info.value.problems
    assert problem.key == "chart.y_axis.parameter" and problem.suggestion == "limit"
