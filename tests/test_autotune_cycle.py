"""Exact relay orbits of FOPDT/SOPDT models (symmetric and biased) against closed forms, an independent simulation
and dfloop's exact engine; relay_experiment with dead time and bias; the tuning rules by hand and by their design
robustness."""
import math

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm

import dfloop as df
from dfloop.autotune import (ProcessModel, closed_loop_check, fopdt_biased_relay_cycle, fopdt_relay_cycle,
                             relay_cycle, relay_experiment, tune)


@pytest.mark.parametrize("K, T, L, a", [(2.0, 3.0, 1.0, 0.0), (1.0, 1.0, 0.5, 0.1), (0.5, 0.5, 2.0, 0.05)])
def test_fopdt_orbits_equal_the_closed_forms(K, T, L, a):
    m = ProcessModel(K, (T,), L)
    peak, period = fopdt_relay_cycle(K, T, L, 1.0, a)
    cyc = relay_cycle(m, 1.0, hysteresis=a)
    assert cyc.period == pytest.approx(period, rel=1e-12) and cyc.amplitude == pytest.approx(peak, rel=1e-12)
    c_hi, c_lo, h1, h2 = fopdt_biased_relay_cycle(K, T, L, 1.3, -0.7, a)
    cyc = relay_cycle(m, 1.3, -0.7, hysteresis=a)
    assert (cyc.h1, cyc.h2) == pytest.approx((h1, h2), rel=1e-12)
    assert cyc.extremes() == pytest.approx((c_hi, c_lo), rel=1e-12)
    # the static-gain identity: the mean of a periodic response is G(0) times the mean input
    assert cyc.mean_output == pytest.approx(K * cyc.mean_input, rel=1e-12)


def _sopdt_run(m, high, low, a, t_end, h):
    """The relay loop of K e^{-Ls}/((T1 s + 1)(T2 s + 1)) on a grid of step h (L / h an integer): the state advanced
    by the matrix exponential of python-control's realisation for the held input, the input read from a delay
    line, the relay (with hysteresis) evaluated at every step. Returns t, c, u."""
    sys = ct.ss(m.tf())
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    n = A.shape[0]
    E = expm(np.block([[A, B[:, None]], [np.zeros((1, n + 1))]]) * h)
    Phi, Gam = E[:n, :n], E[:n, n]
    d = int(round(m.L / h))
    steps = int(t_end / h)
    line = [low] * d
    x, u_relay = np.zeros(n), low
    cs, us = np.empty(steps), np.empty(steps)
    for k in range(steps):
        c = float(C @ x)
        if c < -a:
            u_relay = high
        elif c > a:
            u_relay = low
        line.append(u_relay)
        x = Phi @ x + Gam * line[k]
        cs[k], us[k] = c, u_relay
    return np.arange(steps) * h, cs, us


def test_sopdt_biased_orbit_matches_an_independent_simulation():
    m = ProcessModel(2.0, (4.0, 1.0), 1.0)
    cyc = relay_cycle(m, 1.2, -0.8, hysteresis=0.05)
    t, c, u = _sopdt_run(m, 1.2, -0.8, 0.05, 20 * cyc.period, 2e-3)
    tail = t > 10 * cyc.period
    rises = t[1:][(u[1:] > u[:-1]) & tail[1:]]
    falls = t[1:][(u[1:] < u[:-1]) & tail[1:]]
    assert float(np.mean(np.diff(rises))) == pytest.approx(cyc.period, rel=1e-3)
    assert float(np.mean(falls[falls > rises[0]][:3] - rises[:3])) == pytest.approx(cyc.h1, abs=4e-3)
    hi, lo = cyc.extremes()
    assert c[tail].max() == pytest.approx(hi, abs=2e-3) and c[tail].min() == pytest.approx(lo, abs=2e-3)
    # the orbit's waveform, aligned on a relay rise of the run
    k = np.flatnonzero(tail & (t >= rises[2]) & (t < rises[3]))
    assert np.max(np.abs(c[k] - cyc.output(t[k] - rises[2]))) < 5e-3


def test_delay_free_sopdt_orbit_equals_dfloops_exact_engine():
    m = ProcessModel(1.0, (1.0, 0.5), 0.0)
    cyc = relay_cycle(m, 1.0, hysteresis=0.05)
    ex = df.exact_cycle(m.tf(), df.Relay(1.0, hysteresis=0.05), (0.1, 2 * math.pi / cyc.period))
    assert ex.success and 2 * math.pi / ex.frequency == pytest.approx(cyc.period, rel=1e-8)
    assert 0.5 * (ex.x.max() - ex.x.min()) == pytest.approx(cyc.amplitude, rel=1e-4)   # ex.x: 512 samples


def test_sopdt_relay_experiment_against_python_control_margins_and_the_static_gain():
    G = ct.tf([2.0], [4.0, 5.0, 1.0])          # 2 / ((4 s + 1)(s + 1))
    res = relay_experiment(G, df.Relay(1.0, hysteresis=0.05), delay=1.0, bias=0.2)
    num, den = ct.pade(1.0, 12)
    gm, _, _, w180, _, _ = ct.stability_margins(G * ct.tf(num, den))
    assert res.Ku == pytest.approx(gm, rel=1e-6) and res.Tu == pytest.approx(2 * math.pi / w180, rel=1e-6)
    assert res.static_gain == pytest.approx(2.0, rel=1e-8)
    assert res.cycle.high == 1.2 and res.cycle.low == pytest.approx(-0.8)
    assert res.errors["Ku_experiment"] < -0.1 and res.errors["Tu_experiment"] > 0.05
    assert "static gain" in repr(res) and res.to_dict()["static_gain"] == res.static_gain
    with pytest.raises(ValueError, match="bias"):
        relay_experiment(G, df.Relay(1.0), delay=1.0, bias=1.5)
    with pytest.raises(ValueError, match="first or second order"):
        relay_experiment(ct.tf([1.0, 1.0], [1.0, 3.0, 2.0]), delay=1.0)


def test_amigo_and_simc_pid_by_hand_and_amigo_robustness():
    """AMIGO PI is designed for a peak sensitivity Ms = 1.4 on FOPDT processes; python-control's frequency response
    of the loop (Pade delay) shows it lands between 1.2 and 1.6 from delay- to lag-dominant processes."""
    K, T, L = 2.0, 3.0, 1.0
    t = tune("amigo-pi", model=(K, T, L))
    assert t.Kp == pytest.approx(0.15 / K + (0.35 - L * T / (L + T) ** 2) * T / (K * L))
    assert t.Ti == pytest.approx(0.35 * L + 13 * L * T ** 2 / (T ** 2 + 12 * L * T + 7 * L ** 2))
    t = tune("amigo-pid", model=(K, T, L))
    assert (t.Kp, t.Ti, t.Td) == pytest.approx(((0.2 + 0.45 * T / L) / K, (0.4 * L + 0.8 * T) / (L + 0.1 * T) * L,
                                                0.5 * L * T / (0.3 * L + T)))
    for T_over_L in (0.2, 1.0, 5.0):
        m = ProcessModel(1.0, (T_over_L,), 1.0)
        check = closed_loop_check(tune("amigo-pi", model=m).controller, m, t_end=60.0)
        assert check["stable"] and 1.2 < check["Ms"] < 1.6 and check["final_value"] == pytest.approx(1.0, abs=2e-3)
    # SIMC PID on a SOPDT: series Kc (1 + 1/(Ti s))(1 + T2 s) with Kc = T1/(K 2L), Ti = min(T1, 8L)
    t = tune("simc-pid", model=(2.0, 4.0, 1.0, 1.0), derivative_filter=1e9)
    kc, ti, td = 4.0 / (2.0 * 2.0), 4.0, 1.0
    for w in (0.1, 1.0):
        s = 1j * w
        assert complex(t.controller(s)) == pytest.approx(kc * (1 + 1 / (ti * s)) * (1 + td * s), rel=1e-6)
    with pytest.raises(ValueError, match="model"):
        tune("amigo-pi", model=(1.0, -1.0, 1.0))


def test_biased_experiment_predicts_the_biased_df_cycle():
    """With an output offset b the DF prediction is the dual-input DF's biased cycle. For an ideal relay around a
    FOPDT it satisfies the closed forms of the balance: the relay input's mean B solves B + K (m + b) = 0 with the
    relay's mean output m = (2M/pi) asin(B/A); the oscillation sits at the phase crossover w180 of
    K e^{-jwL}/(jwT + 1); and (4M/(pi A)) sqrt(1 - (B/A)^2) |G(j w180)| = 1."""
    import math

    K, T, L, M, b = 2.0, 4.0, 1.0, 1.0, 0.2
    res = relay_experiment(ct.tf([K], [T, 1.0]), df.Relay(M), delay=L, bias=b)
    c = res.prediction
    B, A, w = c.bias, c.amplitude, c.frequency
    assert c.stability == "stable" and B != 0.0
    assert B + K * (2 * M / math.pi * math.asin(B / A) + b) == pytest.approx(0.0, abs=1e-9)
    assert math.atan(w * T) + w * L == pytest.approx(math.pi, rel=1e-9)
    gain = K / math.sqrt(1 + (w * T) ** 2)
    assert 4 * M / (math.pi * A) * math.sqrt(1 - (B / A) ** 2) * gain == pytest.approx(1.0, rel=1e-9)
    assert res.Ku_df == pytest.approx(4 * M / (math.pi * A), rel=1e-12)
