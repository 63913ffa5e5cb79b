"""End to end: the console script runs a scene, runs only the stages it names, and writes its files."""
from pathlib import Path

import numpy as np

import pytest

from dfloop.cli import main
from dfloop.scene import load_scene, run_scene

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_every_shipped_scene_loads():
    scenes = sorted(MODELS.glob("*.toml"))
    assert len(scenes) >= 4
    for path in scenes:
        scene = load_scene(path)
        assert scene.element is not None and scene.plant is not None


def test_cli_runs_a_scene_and_writes_its_files(tmp_path):
    assert main(["run", str(MODELS / "relay_hysteresis.toml"), "--out", str(tmp_path)]) == 0
    report = (tmp_path / "relay_hysteresis_report.md").read_text()
    assert "Closed-loop verification" in report
    assert (tmp_path / "relay_hysteresis_nyquist.png").stat().st_size > 10_000


def test_scene_runs_only_the_stages_it_names(tmp_path):
    scene = load_scene(MODELS / "relay_delay.toml")
    assert not scene.verify
    report = run_scene(scene, tmp_path, log=lambda message: None)
    names = [name for name, _ in report.stages]
    assert names == ["predict limit cycles", "plot nyquist"]
    assert len(report.cycles) >= 5  # a delay gives many cycles
    assert not report.verifications


def test_main_study_predicts_two_cycles_that_simulation_confirms(tmp_path):
    report = run_scene(load_scene(MODELS / "backlash_servo.toml"), tmp_path, log=lambda message: None)
    assert [c.stable for c in report.cycles] == [False, True]
    assert [v.stable for v in report.verifications] == [False, True]
    assert (tmp_path / "backlash_servo_residual.png").stat().st_size > 10_000


def test_cli_reports_bad_scene_without_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[plant]\nnum=[1.0]\nden=[1.0, 1.0]\n[element]\ntype='Backlash'\nh=-1.0\n")
    assert main(["run", str(bad), "--out", str(tmp_path)]) == 1
    assert "h" in capsys.readouterr().err


def test_cli_without_command_prints_help(capsys):
    assert main([]) == 2
    assert "run" in capsys.readouterr().out


def test_dynamic_scene_tabulates_only_its_window_and_second_run_simulates_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "cache"))
    first = run_scene(load_scene(MODELS / "dynamic_backlash_pd.toml"), tmp_path, log=lambda message: None)
    element = first.scene.element
    assert element.n_simulations > 0
    # the run's note is written after every stage: it counts the motions simulated, not "0 ... from the cache"
    (note,) = [n for n in first.notes if "motions simulated in this run" in n]
    assert f"for {element.n_simulations} table samples (tables built and cached)" in note
    assert int(note.split(": ")[1].split()[0]) >= element.n_simulations   # each sample simulates >= 1 motion
    # the solver's window (F, w in [5, 60]) reaches beta = F/(M2 h w^2) <= 60/(0.1 * 25) = 24 only
    assert np.exp(element.table.hi) <= 2 * 24.0
    assert [c.stable for c in first.cycles] == [True] and all(c.valid for c in first.cycles)
    # the closed-loop impact simulation settles on the predicted cycle within the DF's few-percent error
    (check,) = first.verifications
    assert check.stable
    assert abs(check.inside.frequency / first.cycles[0].frequency - 1) < 0.05
    assert abs(check.inside.amplitude / first.cycles[0].amplitude - 1) < 0.05
    second = run_scene(load_scene(MODELS / "dynamic_backlash_pd.toml"), tmp_path, log=lambda message: None)
    assert second.scene.element.n_simulations == 0
    assert second.cycles[0].amplitude == first.cycles[0].amplitude
    assert any("served from the cache" in note for note in second.notes)
