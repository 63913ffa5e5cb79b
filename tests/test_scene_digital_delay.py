"""A scene with a delayed plant and a digital controller: the delayed plant is sampled exactly behind the hold
(``sample_delayed``), and the exact orbit of the scene is checked against the continuous plant driven by the held
outputs T later (matrix exponentials over one period, written here)."""
from __future__ import annotations

from pathlib import Path

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm

from dfloop import Quantizer, SceneError, exact_cycle, load_scene, predict_limit_cycles, run_scene

ROOT = Path(__file__).resolve().parents[1]
K, T, DT, STEP = 4.9, 0.07, 0.2, 0.05


def _periodic_samples(y: np.ndarray) -> np.ndarray:
    """x_k = -K c(t_k) of 1/(s+1)^3 in its periodic regime when the held output y_k acts on [t_k + T, t_{k+1} + T)."""
    sys = ct.ss(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]))
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    n = A.shape[0]

    def step(u, tau):
        big = np.zeros((n + 1, n + 1))
        big[:n, :n], big[:n, n] = A, B * u
        E = expm(big * tau)
        return E[:n, :n], E[:n, n]

    P = y.size
    # over [t_k, t_{k+1}): y_{k-1} until t_k + T, then y_k (T < DT)
    maps = []
    for k in range(P):
        F1, g1 = step(y[k - 1], T)
        F2, g2 = step(y[k], DT - T)
        maps.append((F2 @ F1, F2 @ g1 + g2))
    F, g = np.eye(n), np.zeros(n)
    for Fk, gk in maps:
        F, g = Fk @ F, Fk @ g + gk
    s = np.linalg.solve(np.eye(n) - F, g)
    xs = np.empty(P)
    for k, (Fk, gk) in enumerate(maps):
        xs[k] = -K * (C @ s)
        s = Fk @ s + gk
    return xs


def test_scene_with_delay_and_digital_controller_runs_end_to_end(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scene = load_scene(ROOT / "models" / "digital_quantizer_delay.toml")
    assert scene.plant.dt == DT
    report = run_scene(scene)
    cycles = report.cycles
    assert [c.stability for c in cycles] == ["unstable", "stable"]
    stable = cycles[1]
    ex = stable.exact if getattr(stable, "exact", None) is not None else exact_cycle(scene.plant, scene.element, stable)
    assert ex.success and ex.stable and ex.extra["map"]
    # the orbit's outputs are quantized inputs, and its inputs are the continuous delayed plant's periodic response
    assert np.array_equal(Quantizer(STEP).output(ex.x), ex.y)
    assert np.max(np.abs(_periodic_samples(ex.y) - ex.x)) < 1e-12
    # verification runs the exact map: the run from inside the stable cycle settles on a periodic sequence whose
    # samples are again the continuous delayed plant's periodic response to its held outputs
    (v_unstable, v_stable) = report.verifications
    assert v_stable.verdict == "stable" and v_unstable.verdict != "stable"
    run = v_stable.runs[0]
    tail_x, tail_y = run.x[-5 * ex.y.size:], run.y[-5 * ex.y.size:]
    period = next(p for p in range(1, 200) if np.array_equal(tail_y[p:], tail_y[:-p]))
    assert np.max(np.abs(_periodic_samples(tail_y[-period:]) - tail_x[-period:])) < 1e-12
    assert np.array_equal(run.t[:3], [0.0, DT, 2 * DT])
    # the delay made the cycles: without it (same gain, |C G| = 0.79 at -180 deg, below 1 / 1.27) there are none
    G0 = K * ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), DT, "zoh")
    assert len(predict_limit_cycles(G0, Quantizer(STEP), amplitude=(0.026, 1.0))) == 0


def test_delay_in_a_plant_given_in_z_is_refused(tmp_path):
    text = (ROOT / "models" / "digital_quantizer_delay.toml").read_text()
    path = tmp_path / "z.toml"
    path.write_text(text.replace("delay = 0.07", "delay = 0.07\ndt = 0.2\ndiscrete = true"))
    with pytest.raises(SceneError, match="z\\^-k"):
        load_scene(path)


def test_plant_with_its_own_dt_and_a_delay_is_the_exact_sampled_map(tmp_path):
    text = (ROOT / "models" / "digital_quantizer_delay.toml").read_text()
    path = tmp_path / "own_dt.toml"
    path.write_text(text.replace("delay = 0.07", "delay = 0.07\ndt = 0.2"))
    scene = load_scene(path)
    w = np.linspace(0.1, 0.99 * np.pi / DT, 7)
    z = np.exp(1j * w * DT)
    ref = load_scene(ROOT / "models" / "digital_quantizer_delay.toml").plant
    assert np.allclose(scene.plant(z), ref(z), rtol=1e-12)


def test_digital_run_refuses_memory_and_constant_input():
    from dfloop import Relay, simulate_loop

    G = K * ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), DT, "zoh")
    with pytest.raises(ValueError, match="N: Relay is not a static element"):
        simulate_loop(G, Relay(1.0, hysteresis=0.1), 0.5, 1.0)
    with pytest.raises(ValueError, match="r0 must be 0"):
        simulate_loop(G, Quantizer(STEP), 0.05, 1.4, r0=0.1)
