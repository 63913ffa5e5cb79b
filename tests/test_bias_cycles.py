"""Biased limit cycles (dfloop.solve.bias): the symmetric solver at zero bias, the closed-form DF cycle of a relay with
unequal levels around an integrator, and the exact periodic orbit of such a relay loop (derived here from the
matrix exponential of the plant, checked by a long event-located simulation) next to the DF prediction."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.optimize import fsolve

from dfloop import Relay, Saturation, predict_limit_cycles
from dfloop.describing.dual_input import DualInputDF
from dfloop.errors import DfloopError
from dfloop.solve.bias import predict_biased_cycles, static_gain


@pytest.mark.parametrize("G", [ct.tf([10], [1, 3, 2, 0]), ct.tf([12], [1, 3, 3, 1])])
def test_symmetric_element_without_input_gives_the_symmetric_cycles(G):
    sym = predict_limit_cycles(G, Saturation(1.0), amplitude=(0.05, 50))
    biased = predict_biased_cycles(G, Saturation(1.0), amplitude=(0.05, 50))
    assert biased.bias_monotone and len(biased) == len(sym) >= 1
    for b, s in zip(biased, sym):
        assert abs(b.bias) < 1e-12
        assert b.amplitude == pytest.approx(s.amplitude, rel=1e-9)
        assert b.frequency == pytest.approx(s.frequency, rel=1e-9)
        assert b.stability == s.stability
    assert "biased cycle" in repr(biased)


def test_unequal_relay_with_integrator_closed_form():
    """m(B, A) = 0 gives sin(beta) = B / A with beta = pi (M2 - M1) / (2 (M1 + M2)); N_A = 2 (M1 + M2) cos(beta)
    / (pi A) is real, so w = 1 rad/s where K / (s (s + 1)^2) = -K / 2, and A = K (M1 + M2) cos(beta) / pi."""
    M1, M2, K = 2.0, 0.5, 1.5
    relay = DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0])
    for r0 in (0.0, 0.7):  # with an integrator the bias does not depend on r0
        cycles = predict_biased_cycles(ct.tf([K], [1, 2, 1, 0]), relay, r0=r0, amplitude=(0.05, 50))
        beta = math.pi * (M2 - M1) / (2 * (M1 + M2))
        A = K * (M1 + M2) * math.cos(beta) / math.pi
        (c,) = cycles
        assert c.frequency == pytest.approx(1.0, rel=1e-10)
        assert c.amplitude == pytest.approx(A, rel=1e-10)
        assert c.bias == pytest.approx(A * math.sin(beta), rel=1e-10)
        assert abs(c.mean_output) < 1e-12 and c.stable and cycles.dc_gain == math.inf


def _exact_relay_orbit(G, M1, M2, r0, guess, a=0.0):
    """Periodic orbit of e = r0 - y through a relay switching to M1 when e rises through a and to -M2 when e falls
    through -a, around G (state space): durations (t1, t2) at +M1 and -M2 with y(0) = r0 - a and y(t1) = r0 + a,
    the periodic state from the matrix exponential."""
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B), np.asarray(sys.C)
    n = A.shape[0]

    def flow(t, u):
        big = np.zeros((n + 1, n + 1))
        big[:n, :n], big[:n, n:] = A, B * u
        E = expm(big * t)
        return E[:n, :n], E[:n, n]

    def start(t1, t2):
        P1, q1 = flow(t1, M1)
        P2, q2 = flow(t2, -M2)
        x0 = np.linalg.solve(np.eye(n) - P2 @ P1, P2 @ q1 + q2)
        return x0, P1 @ x0 + q1

    def eqs(t):
        x0, x1 = start(*t)
        return [(C @ x0)[0] - (r0 - a), (C @ x1)[0] - (r0 + a)]

    t1, t2 = fsolve(eqs, guess, xtol=1e-12)
    assert max(abs(v) for v in eqs((t1, t2))) < 1e-11
    x0, _ = start(t1, t2)
    return t1, t2, x0, (A, B, C)


def _simulate(ABC, M1, M2, r0, x0, periods, a=0.0):
    """Event-located simulation of the relay loop from x0 (on +M1), returning the last switching durations."""
    A, B, C = ABC
    times, x, u = [], x0.copy(), M1
    for _ in range(2 * periods):
        level = r0 + a if u == M1 else r0 - a
        ev = lambda t, z, level=level: (C @ z)[0] - level  # noqa: E731
        ev.terminal, ev.direction = True, (1 if u == M1 else -1)
        sol = solve_ivp(lambda t, z: A @ z + B[:, 0] * u, (0, 100), x, events=ev, rtol=1e-11, atol=1e-13,
                        first_step=1e-3)
        dt = sol.t_events[0][0]
        times.append(dt)
        x, u = sol.y_events[0][0], (-M2 if u == M1 else M1)
    return times[-2], times[-1]


def test_unequal_relay_exact_orbit_and_simulation():
    M1, M2, K, r0 = 1.5, 0.6, 4.0, 0.4
    G = ct.tf([K], [1, 3, 3, 1])
    cycles = predict_biased_cycles(G, DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0]), r0=r0,
                                   amplitude=(0.01, 50))
    assert cycles.bias_monotone
    (c,) = cycles
    # the DF balance itself: B + G(0) m = r0 and 1 + G(jw) N_A = 0
    dual = DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0])
    assert c.bias + K * dual.mean(c.bias, c.amplitude) == pytest.approx(r0, abs=1e-12)
    Gw = K / (1j * c.frequency + 1) ** 3
    assert abs(1 + Gw * dual.N_A(c.bias, c.amplitude)) < 1e-10
    # exact orbit from the DF guess: half-periods split by the mean output
    frac = (math.pi + 2 * math.asin(c.bias / c.amplitude)) / (2 * math.pi)
    t1, t2, x0, ABC = _exact_relay_orbit(G, M1, M2, r0, [frac * c.period, (1 - frac) * c.period])
    # a long simulation from a perturbed start settles on it (so the orbit is stable, as the DF says)
    s1, s2 = _simulate(ABC, M1, M2, r0, 0.5 * x0, periods=40)
    assert s1 == pytest.approx(t1, rel=1e-7) and s2 == pytest.approx(t2, rel=1e-7)
    assert c.stable
    T = t1 + t2
    e_mean = r0 - K * (M1 * t1 - M2 * t2) / T  # mean of e = r0 - y, y's mean = G(0) u's mean
    # the DF's error on this loop (measured: period 3.7 % short, bias -0.25287 against the exact mean -0.25268)
    assert abs(c.period - T) / T < 0.05
    assert abs(c.bias - e_mean) < 1e-3


def test_hysteresis_relay_with_input_exact_orbit():
    """A relay with hysteresis (memory: complex N_A) and a constant input, against its exact orbit and a simulation."""
    M, a, K, r0 = 1.0, 0.1, 3.0, 0.5
    G = ct.tf([K], [1, 3, 3, 1])
    cycles = predict_biased_cycles(G, Relay(M, hysteresis=a), r0=r0, amplitude=(0.11, 20))
    assert cycles.bias_monotone
    (c,) = cycles
    frac = (math.pi + 2 * math.asin(c.bias / c.amplitude)) / (2 * math.pi)
    t1, t2, x0, ABC = _exact_relay_orbit(G, M, M, r0, [frac * c.period, (1 - frac) * c.period], a=a)
    s1, s2 = _simulate(ABC, M, M, r0, 0.5 * x0, periods=40, a=a)
    assert s1 == pytest.approx(t1, rel=1e-7) and s2 == pytest.approx(t2, rel=1e-7)
    assert c.stable
    T = t1 + t2
    e_mean = r0 - K * M * (t1 - t2) / T
    # measured DF error: bias 0.1198 against the exact mean 0.1109 (1.4 % of A)
    assert abs(c.period - T) / T < 0.05
    assert abs(c.bias - e_mean) < 0.02 * c.amplitude


def test_load_at_the_element_output_with_integrator():
    """Ideal relay, load d, K / (s (s + 1)^2): m + d = 0 gives 2 M beta / pi = -d, B = A sin(beta), and
    A = 2 K M cos(beta) / pi at w = 1 rad/s."""
    M, d, K = 1.0, 0.3, 2.0
    (c,) = predict_biased_cycles(ct.tf([K], [1, 2, 1, 0]), Relay(M), load=d, amplitude=(0.05, 50))
    beta = -math.pi * d / (2 * M)
    A = 2 * K * M * math.cos(beta) / math.pi
    assert c.frequency == pytest.approx(1.0, rel=1e-10)
    assert c.amplitude == pytest.approx(A, rel=1e-10)
    assert c.bias == pytest.approx(A * math.sin(beta), rel=1e-10)
    assert c.mean_output == pytest.approx(-d, rel=1e-12)


def test_bad_input():
    G = ct.tf([1], [1, 1, 1])
    with pytest.raises(DfloopError, match="amplitude"):
        predict_biased_cycles(G, Relay(1.0), amplitude=(-1, 2))
    with pytest.raises(DfloopError, match="bias"):
        predict_biased_cycles(G, Relay(1.0), amplitude=(0.1, 2), bias=(1.0, -1.0))
    with pytest.raises(DfloopError, match="dc_gain"):
        static_gain(lambda w: 1 / (1j * w + 1))
    assert static_gain(ct.tf([2], [1, 0])) == math.inf and static_gain(G) == pytest.approx(1.0)


def test_exact_biased_orbit_from_the_engine():
    """dfloop's exact engine with the constant input gives the orbit derived above (matrix exponential + fsolve)."""
    from dfloop import exact_cycle

    M1, M2, K, r0 = 1.5, 0.6, 4.0, 0.4
    G = ct.tf([K], [1, 3, 3, 1])
    relay = DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0])
    (c,) = predict_biased_cycles(G, relay, r0=r0, amplitude=(0.01, 50))
    ex = exact_cycle(G, relay.describing_function, c, r0=r0)
    frac = (math.pi + 2 * math.asin(c.bias / c.amplitude)) / (2 * math.pi)
    t1, t2, _, _ = _exact_relay_orbit(G, M1, M2, r0, [frac * c.period, (1 - frac) * c.period])
    T = t1 + t2
    assert ex.success and ex.stable
    assert 2 * math.pi / ex.frequency == pytest.approx(T, rel=1e-10)
    # e's exact mean (the flow's integral) against the duty cycle of u
    assert ex.mean == pytest.approx(r0 - K * (M1 * t1 - M2 * t2) / T, abs=1e-12)
    assert "mean=" in repr(ex)
    # a constant input with a delay (the shifted element of dfloop.hybrid.constant): as the delay goes to 0 the
    # orbit goes to the one above, linearly (measured ratios 9.8 in w and 9.9 in the mean from 10 ms to 1 ms)
    from dfloop.solve.delay import delayed

    d = []
    for delay in (1e-2, 1e-3):
        exd = exact_cycle(delayed(G, delay), relay.describing_function, c, r0=r0, globalise=False)
        assert exd.success, exd.message
        d.append((abs(exd.frequency - ex.frequency), abs(exd.mean - ex.mean)))
    assert 8.0 < d[0][0] / d[1][0] < 12.0 and 8.0 < d[0][1] / d[1][1] < 12.0


def test_two_biased_cycles_stability_against_the_exact_flow():
    """A dead-zone relay with a load around 3/(s(s+1)(s+2)): an inner cycle the reduced Loeb test calls unstable
    and an outer one it calls stable. The exact engine confirms the outer orbit (stable by its multipliers); from
    the inner prediction (a DF artefact this close to the dead zone) every motion goes to the outer orbit."""
    from dfloop import exact_cycle

    G, relay = ct.tf([3.0], [1, 3, 2, 0]), Relay(1.0, dead_zone=0.2)
    cycles = predict_biased_cycles(G, relay, load=0.1, amplitude=(0.201, 20))
    assert cycles.bias_monotone and [c.stability for c in cycles] == ["unstable", "stable"]
    inner, outer = sorted(cycles, key=lambda c: c.amplitude)
    for c in cycles:  # the DF balance with an integrator: mean output cancels the load
        assert c.mean_output == pytest.approx(-0.1, abs=1e-12)
    ex = exact_cycle(G, relay, outer, load=0.1)
    assert ex.success and ex.stable
    assert abs(ex.amplitude - outer.amplitude) < 0.05 * ex.amplitude  # DF error measured: -2.9 %
    assert abs(ex.mean - outer.bias) < 0.01  # measured: exact -0.0814, DF -0.0868
    gone = exact_cycle(G, relay, inner, load=0.1)
    assert not gone.success and gone.extra["outcome"] == "another cycle"
    assert f"A={ex.amplitude:.6g}" in gone.message
