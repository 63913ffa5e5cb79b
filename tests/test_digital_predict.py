"""Discrete-time plants in predict_limit_cycles (dfloop.solve.sampled): G(e^{jw dt}) on (0, pi/dt]."""
import math

import control as ct
import numpy as np
import pytest

from dfloop import Quantizer, Relay, predict_limit_cycles
from dfloop import cycle_confidence
from dfloop.solve.plant import as_plant


def _stable(cycles):
    return [c for c in cycles if c.stability == "stable"][0]


def test_response_is_g_of_z_on_the_unit_circle():
    G = ct.sample_system(ct.tf([2.0, 1.0], [1.0, 0.4, 3.0]), 0.05)
    plant = as_plant(G)
    w = np.linspace(0.1, math.pi / 0.05 * 0.999, 37)
    direct = np.array([complex(G(np.exp(1j * x * 0.05))) for x in w])   # python-control's own evaluation
    assert np.allclose(plant(w), direct, rtol=1e-12)
    assert plant.domain == (0.0, math.pi / 0.05)
    assert plant.default_window[1] < math.pi / 0.05


@pytest.mark.parametrize("seed", range(6))
def test_variation_bound_holds_against_dense_sampling(seed):
    """The bilinear-image bound is >= the true change of ln G(e^{jw dt}) (dense samples, unwrapped phase)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 5))
    poles = rng.uniform(0.2, 0.98, n) * np.exp(1j * rng.uniform(-3, 3, n))
    zeros = rng.uniform(0.1, 1.5, n - 1) * np.exp(1j * rng.uniform(-3, 3, n - 1))
    den, num = np.real(np.poly(np.concatenate([poles, poles.conj()]))), np.real(np.poly(np.concatenate([zeros, zeros.conj()])))
    dt = float(rng.uniform(0.01, 1.0))
    plant = as_plant(ct.tf(num, den, dt))
    w_nyq = math.pi / dt
    for _ in range(20):
        w0, w1 = np.sort(rng.uniform(1e-3, 0.999, 2)) * w_nyq
        ws = np.linspace(w0, w1, 4001)
        g = plant(ws)
        lg = np.log(np.abs(g)) + 1j * np.unwrap(np.angle(g))
        true = np.max(np.abs(lg - lg[0]))
        assert plant.log_variation(np.array([w0]), np.array([w1]))[0] >= true * (1 - 1e-9) - 1e-12


def test_log_slope_matches_finite_difference():
    plant = as_plant(ct.tf([1.0, -0.3], [1.0, -1.2, 0.5], 0.2))
    w = np.array([0.3, 2.0, 9.0, 15.0])
    h = 1e-6
    fd = (np.log(plant(w * math.exp(h))) - np.log(plant(w * math.exp(-h)))) / (2 * h)
    assert np.allclose(plant.log_slope(w), fd, rtol=1e-6, atol=1e-8)


def test_continuous_limit_rates():
    """As dt -> 0 the ZOH loop's prediction tends to the continuous one at rate dt (the hold's half-sample lag),
    and to the prediction for G(s) exp(-s dt/2) at rate dt^2."""
    G = ct.tf([1.0], [1.0, 3.0, 3.0, 1.0])
    N = Relay(1.0, dead_zone=0.05)
    w_c = _stable(predict_limit_cycles(G, N)).frequency
    assert w_c == pytest.approx(math.sqrt(3.0), rel=1e-9)     # arg G = -pi at w = sqrt(3)
    err_c, err_h = [], []
    for dt in (0.1, 0.05, 0.025):
        c = _stable(predict_limit_cycles(ct.sample_system(G, dt), N))
        h = _stable(predict_limit_cycles(lambda w, dt=dt: np.exp(-0.5j * w * dt) / (1j * w + 1) ** 3, N,
                                         omega=(0.01, math.pi / dt)))
        err_c.append(abs(c.frequency - w_c))
        err_h.append(abs(c.frequency - h.frequency) + abs(c.amplitude - h.amplitude))
    for k in range(2):
        assert 1.7 < err_c[k] / err_c[k + 1] < 2.3
        assert 3.4 < err_h[k] / err_h[k + 1] < 4.6


def test_few_samples_per_period_flagged_in_confidence():
    G = ct.tf([1.4], [1.0, 0.5, 0.3], 1.0)
    cycles = predict_limit_cycles(G, Quantizer(1.0), amplitude=(0.5, 20))
    assert len(cycles) == 1
    conf = cycles[0].confidence
    assert conf.samples_per_period == round(2 * math.pi / cycles[0].frequency) == 3
    assert conf.sampled_spread > 0.5 and not conf.reliable
    assert "questionable" in repr(conf)
    # many samples per period: the sampled DF tends to N (spread small)
    fine = cycle_confidence(ct.tf([1.0], [1.0, -0.9], 0.001), Relay(1.0, dead_zone=0.1), 1.0, 2 * math.pi / 0.2)
    assert fine.samples_per_period == 200 and fine.sampled_spread < 0.02


def test_sampling_period_must_be_numeric():
    with pytest.raises(ValueError, match="dt"):
        predict_limit_cycles(ct.tf([1.0], [1.0, -0.5], True), Relay(1.0))
