"""Scenes with a constant input ([loop]) and a forced stage ([forced]): what the report holds, and bad scenes."""
import pytest

from dfloop.scene import load_scene, run_scene
from dfloop.scene.errors import SceneError

FORCED = """
[plant]
num = [1.0]
den = [1.0, 0.2, 1.0]

[element]
type = "CubicStiffness"
k1 = 1.0
k3 = 0.5

[analysis]
predict = false
plots = []

[forced]
forcing = 0.3
omega = [1.5, 2.1]
num = 13
amplitude = [0.001, 20.0]
every = 3
region = [0.2, 0.3]
"""


def test_forced_stage_reports_the_jumps_the_exact_orbits_and_the_region(tmp_path):
    path = tmp_path / "forced.toml"
    path.write_text(FORCED)
    report = run_scene(load_scene(path), tmp_path / "out", log=lambda s: None, progress=False)
    response, exact, region = report.forced
    assert len(response.jumps) == 2 and response.R == 0.3
    assert exact is not None and all(p.periodic for p in exact.flat()) and exact.disagreements() == []
    assert region.band(0) is None and region.band(1) == pytest.approx((response.jumps[0].omega,
                                                                        response.jumps[1].omega), rel=1e-12)
    names = {p.name for p in report.files}
    assert {"forced_forced.png", "forced_region.png", "forced_report.md", "forced_report.html"} <= names
    md = (tmp_path / "out" / "forced_report.md").read_text()
    assert "## Forced response" in md and "Jump-resonance region" in md and "Jump(omega=" in md
    assert "Forced response" in (tmp_path / "out" / "forced_report.html").read_text()


def test_shipped_biased_scene_predicts_and_verifies_both_biased_cycles(tmp_path):
    scene = load_scene("relay_dead_zone_bias")
    assert scene.reference == 0.15 and scene.biased
    report = run_scene(scene, tmp_path, log=lambda s: None, progress=False)
    assert report.cycles is None and len(report.biased) == 2
    stab = sorted((c.amplitude, c.exact.stable, v.verdict) for c, v in zip(report.biased, report.verifications))
    assert [s[1:] for s in stab] == [(False, "unstable"), (True, "stable")]
    assert "## Biased limit cycles" in (tmp_path / "relay_dead_zone_bias_report.md").read_text()


def test_constant_input_needs_an_amplitude_window(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(FORCED.replace("predict = false\nplots = []", "") + "\n[loop]\nreference = 0.2\n")
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert any(p.key == "analysis.amplitude" for p in err.value.problems)
    path.write_text(FORCED.replace("forcing = 0.3", "forcing = -0.3"))
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert any(p.key == "forced.forcing" for p in err.value.problems)
