"""The scene's [autotune] stage: the shipped scene's report holds the experiment and the tunings, equal to the
library's results; a recording in [autotune] is fitted and drawn; a non-relay element is refused."""
import pytest

from dfloop.autotune import ProcessModel, relay_experiment, tune
from dfloop.autotune.record import write_relay_record
from dfloop.autotune.synthetic import synthetic_record
from dfloop.scene import load_scene, run_scene


def test_shipped_autotune_scene_reports_the_experiment_and_the_tunings(tmp_path):
    import control as ct

    import dfloop as df

    report = run_scene(load_scene("relay_autotune"), tmp_path, log=lambda m: None)
    exp = relay_experiment(ct.tf([2.0], [4.0, 5.0, 1.0]), df.Relay(1.0, hysteresis=0.05), delay=1.0, bias=0.2)
    assert report.autotune.experiment.Ku_experiment == pytest.approx(exp.Ku_experiment, rel=1e-12)
    assert report.autotune.experiment.static_gain == pytest.approx(2.0, rel=1e-8)
    amigo = tune("amigo-pid", model=ProcessModel(2.0, (4.0, 1.0), 1.0))
    got = next(t for t in report.autotune.tunings if t.rule == "amigo-pid")
    assert (got.Kp, got.Ti, got.Td) == pytest.approx((amigo.Kp, amigo.Ti, amigo.Td))
    text = (tmp_path / "relay_autotune_report.md").read_text()
    assert "## Relay experiment and tuning" in text and "| amigo-pid | plant model |" in text
    assert "Relay experiment and tuning" in (tmp_path / "relay_autotune_report.html").read_text()


def test_autotune_scene_fits_a_recording_and_refuses_other_elements(tmp_path):
    rec = synthetic_record(ProcessModel(1.0, (2.0,), 0.5), hysteresis=0.05, cycles=6, noise=0.01, seed=3)
    write_relay_record(tmp_path / "rec.csv", rec)
    scene = tmp_path / "s.toml"
    scene.write_text("[plant]\nnum = [1.0]\nden = [2.0, 1.0]\ndelay = 0.5\n[element]\ntype = 'Relay'\nM = 1.0\n"
                     "hysteresis = 0.05\n[analysis]\nplots = []\n[autotune]\nrules = ['zn-pi', 'simc-pi']\n"
                     "record = 'rec.csv'\n")
    report = run_scene(load_scene(scene), tmp_path / "out", log=lambda m: None)
    fit = report.autotune.fit
    for k, v in zip(fit.names, (1.0, 2.0, 0.5)):
        assert fit.intervals[k][0] <= v <= fit.intervals[k][1]
    assert report.autotune.sources == ["FOPDT fit", "FOPDT fit"]
    assert (tmp_path / "out" / "s_relay_fit.png").stat().st_size > 10_000
    scene.write_text(scene.read_text().replace("type = 'Relay'\nM = 1.0\nhysteresis = 0.05", "type = 'Saturation'\n"
                                               "limit = 1.0"))
    with pytest.raises(ValueError, match="needs the element to be a Relay"):
        load_scene(scene)
