"""Names, units and limit-cycle margins of swept parameters, in the sweep's report, CSV and axes.

Reference: G(s) = K / (s (s + 1) (s + 2)) with a saturation of limit 1 has a stable cycle exactly for K > 6
(the linear loop's critical gain: G(j sqrt 2) = -K/6), so from the nominal K = 4 the stable-cycle margin is
+2 in K and 20 log10(6/4) = +3.52 dB; nothing happens below.
"""
import csv
import math

import matplotlib

matplotlib.use("Agg")
import control as ct  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.continuation import sweep  # noqa: E402
from dfloop.scene import load_scene, run_scene  # noqa: E402
from dfloop.scene.parameters import parameter_label  # noqa: E402

SAT = """
[plant]
num = [4.0]
den = [1.0, 3.0, 2.0, 0.0]
[element]
type = "Saturation"
limit = 1.0
[analysis]
plots = []
[sweep]
parameter = "plant.num.0"
values = { start = 2.0, stop = 10.0, num = 5 }
"""


def test_scene_sweep_names_the_gain_and_reports_its_margin(tmp_path):
    path = tmp_path / "sat.toml"
    path.write_text(SAT)
    report = run_scene(load_scene(path), out_dir=tmp_path, log=lambda s: None, progress=False)
    with open(tmp_path / "sat_sweep.csv") as fh:
        header = next(csv.reader(fh))
    assert header[1] == "gain K"
    (m,) = report.margins
    d, exact = m.distance("above")
    assert exact and abs(d - 2.0) < 1e-12 and abs(m.decibels(d) - 20 * math.log10(1.5)) < 1e-10
    assert m.stable_below is None and m.any_below is None
    text = (tmp_path / "sat_report.md").read_text()
    assert "limit-cycle margin of gain K from the nominal 4" in text and "+3.52 dB" in text
    assert "plant.num.0" not in text.split("## Stages run")[0]


def test_sweep_plot_and_csv_use_name_and_unit(tmp_path):
    G0 = ct.tf([1], [1, 3, 2, 0])
    res = sweep(lambda h: (5 * G0, df.Backlash(h)), np.linspace(0.1, 0.3, 3), parameter="clearance h", unit="m",
                progress=False)
    ax_a, ax_w = res.plot().axes[:, 0]
    assert ax_w.get_xlabel() == "clearance h [m]" and ax_a.get_ylabel() == "Amplitude X [m]"
    res.to_csv(tmp_path / "s.csv")
    assert (tmp_path / "s.csv").read_text().splitlines()[0].startswith("branch,clearance h [m],amplitude X [m]")
    assert "sweep of clearance h [m]" in repr(res)


@pytest.mark.parametrize("path, name, unit, gain", [
    ("plant.num.0", "gain K", "", True), ("plant.delay", "delay T", "s", False),
    ("element.h", "clearance h", "m", False), ("plant.den.1", "plant.den.1", "", False)])
def test_derived_labels(path, name, unit, gain):
    data = {"plant": {"num": [2.0], "den": [1.0, 1.0, 0.0]}, "element": {"type": "Backlash", "h": 1.0}}
    label = parameter_label(data, path)
    assert (label.name, label.unit, label.gain) == (name, unit, gain)
    assert parameter_label(data, path, "my p", "rad").axis == "my p [rad]"


def test_margin_rejects_a_nominal_outside_the_range():
    G0 = ct.tf([1], [1, 3, 2, 0])
    res = sweep(lambda K: (K * G0, df.Saturation(1.0)), [2.0, 4.0], parameter="gain K", progress=False)
    with pytest.raises(ValueError, match="nominal"):
        res.margin(5.0)
