"""The relay experiment (dfloop.autotune) against closed forms and an independent event-located simulation."""
import math

import control as ct
import dfloop as df
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dfloop import Relay, Saturation
from dfloop.autotune import relay_experiment

G3 = ct.tf([1.0], [1.0, 3.0, 3.0, 1.0])


def _relay_run(G, M, periods=40):
    """Ideal relay y = M sign(x), x = -c, run with solve_ivp between located switches (each switch waits for the
    crossing opposite to the previous one); (peak |x|, period) of the settled oscillation."""
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    s = np.zeros(A.shape[0])
    s[-1] = 0.1
    c0 = float(C @ s)
    y = -M * math.copysign(1.0, c0)
    direction = 1.0 if c0 < 0 else -1.0      # c must cross zero upward first when it starts negative
    t0, switches, peak = 0.0, [], 0.0
    for i in range(2 * periods):
        def ev(t, z):
            return C @ z
        ev.terminal, ev.direction = True, direction
        sol = solve_ivp(lambda t, z: A @ z + B * y, (t0, t0 + 100.0), s, events=ev, rtol=1e-11, atol=1e-13,
                        dense_output=True)
        t1 = float(sol.t_events[0][0])
        if i >= periods:
            tt = np.linspace(t0, t1, 400)
            peak = max(peak, float(np.max(np.abs(C @ sol.sol(tt)))))
        switches.append(t1)
        t0, s, y, direction = t1, sol.y_events[0][0], -y, -direction
    T = 2.0 * float(np.mean(np.diff(switches[-20:])))
    return peak, T


def test_ideal_relay_df_estimate_is_the_ultimate_point():
    """1/(s+1)^3: arg G = -180 deg at w = sqrt(3), |G| = 1/8 there, so Ku = 8, Tu = 2 pi / sqrt(3); the DF of an
    ideal relay solves exactly arg G = -180 deg, |G| = pi A / (4 M): its estimate is the ultimate point."""
    res = relay_experiment(G3, Relay(1.0), exact=False)
    assert res.Ku == pytest.approx(8.0, rel=1e-9) and res.Tu == pytest.approx(2 * math.pi / math.sqrt(3), rel=1e-9)
    assert res.Ku_df == pytest.approx(8.0, rel=1e-8) and res.Tu_df == pytest.approx(res.Tu, rel=1e-8)
    assert res.exact is None and "Ku_experiment" not in res.errors


def test_experiment_estimates_match_an_independent_relay_simulation():
    res = relay_experiment(G3, Relay(1.0))
    peak, T = _relay_run(G3, 1.0)
    assert res.amplitude_exact == pytest.approx(peak, rel=1e-4)
    assert res.Tu_experiment == pytest.approx(T, rel=1e-6)
    assert res.Ku_experiment == pytest.approx(4 / (math.pi * peak), rel=1e-4)
    # the experiment's error is what a tuning inherits: a few percent here, of known sign
    assert -0.05 < res.errors["Ku_experiment"] < -0.01 and 0.005 < res.errors["Tu_experiment"] < 0.03


def test_digital_relay_experiment_and_bad_input():
    Gd = ct.sample_system(G3, 0.1)
    res = relay_experiment(Gd)
    assert res.exact.extra["map"] and res.Ku_df == pytest.approx(res.Ku, rel=1e-5)
    with pytest.raises(ValueError, match="relay must be a dfloop Relay"):
        relay_experiment(G3, Saturation(1.0))
    with pytest.raises(ValueError, match="ultimate point"):
        relay_experiment(ct.tf([1.0], [1.0, 1.0]))


def _fopdt_run(K, T, L, M, a, t_end=60.0, steps_per_delay=2000):
    """FOPDT relay loop on a fixed grid (step L / steps_per_delay): the plant updated exactly for the held input,
    the input read from a delay line, the relay with hysteresis; (peak |c|, period) over the last third."""
    h = L / steps_per_delay
    n = int(t_end / h)
    decay = math.exp(-h / T)
    line = [M] * steps_per_delay          # relay output history over the delay
    c, u_state, cs = 0.3, M, np.empty(n)
    for k in range(n):
        x = -c
        if x > a:
            u_state = M
        elif x < -a:
            u_state = -M
        line.append(u_state)
        u = line[k]                       # the input applied now left the relay L ago
        c = K * u + (c - K * u) * decay
        cs[k] = c
    tail = cs[2 * n // 3:]
    up = np.flatnonzero((tail[:-1] < 0) & (tail[1:] >= 0))
    return float(np.max(np.abs(tail))), float(np.mean(np.diff(up))) * h


@pytest.mark.parametrize("K, T, L, a", [(2.0, 3.0, 1.0, 0.0), (1.0, 1.0, 0.5, 0.1), (0.5, 0.5, 2.0, 0.05)])
def test_fopdt_closed_form_cycle_matches_a_delay_line_simulation(K, T, L, a):
    from dfloop.autotune import fopdt_relay_cycle

    peak, period = fopdt_relay_cycle(K, T, L, 1.0, a)
    run_peak, run_period = _fopdt_run(K, T, L, 1.0, a, t_end=30 * period)
    assert run_peak == pytest.approx(peak, rel=2e-3) and run_period == pytest.approx(period, rel=2e-3)


def test_fopdt_relay_experiment_against_python_control_margins():
    """The true ultimate point of 2 e^{-s}/(3 s + 1) from the closed form agrees with python-control's margins of a
    high-order Pade approximation of the delay; the DF of the ideal relay reproduces it; the experiment is off."""
    from dfloop.autotune import relay_experiment

    G = ct.tf([2.0], [3.0, 1.0])
    res = relay_experiment(G, delay=1.0)
    num, den = ct.pade(1.0, 12)
    gm, _, _, w180, _, _ = ct.stability_margins(G * ct.tf(num, den))
    assert res.Ku == pytest.approx(gm, rel=1e-6) and res.Tu == pytest.approx(2 * math.pi / w180, rel=1e-6)
    assert res.Ku_df == pytest.approx(res.Ku, rel=1e-8) and res.Tu_df == pytest.approx(res.Tu, rel=1e-8)
    assert res.errors["Ku_experiment"] < -0.1          # the classic underestimate of Ku on lag-dominant FOPDT
    with pytest.raises(ValueError, match="first or second order"):
        relay_experiment(G3, delay=1.0)


def test_simc_pi_on_fopdt_has_skogestads_margins():
    """SIMC PI with tau_c = L on K e^{-Ls}/(T s + 1), T <= 8 L: Ti = T cancels the lag and the loop is
    e^{-Ls} / (2 L s): gain crossover 1/(2L), phase margin pi/2 - 1/2 rad = 61.35 deg, gain margin pi (phase -180
    deg at w L = pi/2, |loop| = 1/pi there). python-control's margins of the Pade model agree; the step settles."""
    from dfloop.autotune import closed_loop_check, tune

    K, T, L = 2.0, 3.0, 1.0
    t = tune("simc-pi", model=(K, T, L))
    assert t.Kp == pytest.approx(T / (K * 2 * L)) and t.Ti == pytest.approx(T) and t.Td == 0.0
    check = closed_loop_check(t.controller, ct.tf([K], [T, 1.0]), delay=L, t_end=60.0)
    assert check["gain_margin"] == pytest.approx(math.pi, rel=1e-3)
    assert check["phase_margin"] == pytest.approx(math.degrees(math.pi / 2 - 0.5), rel=1e-3)
    assert check["stable"] and check["final_value"] == pytest.approx(1.0, abs=1e-3)


def test_ziegler_nichols_from_the_relay_experiment():
    """ZN PID from the experiment's (Ku, Tu) on 1/(s+1)^3: the controller is Kp (1 + 1/(Ti s) + Td s/(Td/10 s + 1))
    (evaluated by hand), and the closed loop is stable with the classic large overshoot."""
    from dfloop.autotune import closed_loop_check, relay_experiment, tune

    res = relay_experiment(G3)
    t = tune("zn-pid", Ku=res.Ku_experiment, Tu=res.Tu_experiment)
    assert (t.Kp, t.Ti, t.Td) == pytest.approx((0.6 * res.Ku_experiment, res.Tu_experiment / 2, res.Tu_experiment / 8))
    for w in (0.1, 1.0, 7.0):
        s = 1j * w
        by_hand = t.Kp * (1 + 1 / (t.Ti * s) + t.Td * s / (t.Td / 10 * s + 1))
        assert complex(t.controller(s)) == pytest.approx(by_hand, rel=1e-12)
    check = closed_loop_check(t.controller, G3)
    assert check["stable"] and 0.2 < check["overshoot"] < 0.8 and check["final_value"] == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(ValueError, match="rule"):
        tune("amigo", Ku=1.0, Tu=1.0)
    with pytest.raises(ValueError, match="Ku"):
        tune("zn-pi", Ku=-1.0, Tu=1.0)


def test_relay_experiment_on_any_plant_with_a_pure_delay():
    """A plant of any order with a pure delay (dfloop.delayed): the true ultimate point is evaluated with the exact
    delay, equal to the closed form of a first-order lag (atan(w T) + w L = pi) and to a high-order Pade
    approximant's python-control margins for a third-order plant; the experiment runs on the exact delay flow."""
    import math

    from scipy.optimize import brentq

    K, T, L = 2.0, 3.0, 0.7
    w180 = brentq(lambda w: math.atan(w * T) + w * L - math.pi, 1e-6, math.pi / L)
    first = relay_experiment(df.delayed(ct.tf([K], [T, 1]), L), df.Relay(1.0), exact=False)
    assert first.Ku == pytest.approx(math.sqrt(1 + (w180 * T) ** 2) / K, rel=1e-12)
    assert first.Tu == pytest.approx(2 * math.pi / w180, rel=1e-12)
    G = df.delayed(ct.tf([2], [1, 3, 3, 1]), 0.5)     # its third-order lag is no FOPDT/SOPDT process model
    gm, _, _, wc, _, _ = ct.stability_margins(G.pade(12))
    relay = df.Relay(1.0, hysteresis=0.05)
    r = relay_experiment(G, relay)
    assert r.Ku == pytest.approx(gm, rel=1e-9) and r.Tu == pytest.approx(2 * math.pi / wc, rel=1e-9)
    assert r.exact is not None and r.exact.success and "delay" in r.exact.method
    assert r.Ku_df == pytest.approx(4 * relay.M / (math.pi * r.prediction.amplitude), rel=1e-12)
