"""A scene's [sweep] runs the continuation and writes every branch at every swept value to CSV."""
import csv

import numpy as np

from dfloop.scene import load_scene, run_scene


def test_shipped_gain_sweep_writes_both_branches_at_every_value_beyond_the_fold(tmp_path):
    scene = load_scene("backlash_servo_gain")
    report = run_scene(scene, tmp_path, log=lambda _line: None)
    rows = list(csv.DictReader(open(tmp_path / "backlash_servo_gain_sweep.csv")))
    folds = [float(r["gain K"]) for r in rows if r["point"] == "fold"]
    assert len(folds) == 2 and folds[0] == folds[1]          # one fold, where the two branches meet
    K_fold = folds[0]
    values = scene.sweep_values
    beyond = values[values > K_fold]
    at_values = [r for r in rows if r["point"] in ("value", "sweep end")]
    assert len(at_values) == 2 * beyond.size                   # both cycles exist at every value past the fold
    for branch in ("0", "1"):
        got = np.sort([float(r["gain K"]) for r in at_values if r["branch"] == branch])
        np.testing.assert_allclose(got, beyond, rtol=1e-12)
    # every point of a branch solves the DF equation: N(A) = -1/G(jw) for backlash h = 1 around K/(s(s+1))
    import dfloop as df

    N = df.Backlash(1.0)
    for r in rows:
        K, A, w = float(r["gain K"]), float(r["amplitude X [m]"]), float(r["frequency [rad/s]"])
        G = K / (1j * w * (1j * w + 1))
        assert abs(1 + G * N(A)) <= 1e-8 * (1 + abs(G * N(A)))
    assert (tmp_path / "backlash_servo_gain_sweep.png").exists()
    assert report.sweep is not None
