"""The exact forced response (dfloop.hybrid.forced): orbits at the forcing period next to the DF's forced solutions,
checked against a conservation law (Liouville), long independent simulations (scipy solve_ivp), and the marking of
subharmonic and quasi-periodic responses."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dfloop import CubicStiffness, Saturation, exact_cycle, predict_limit_cycles
from dfloop.hybrid.forced import exact_forced_point, exact_forced_response
from dfloop.solve.forced import forced_response

Z, K1, K3, R = 0.1, 1.0, 0.5, 0.3


def _duffing_run(w, x0, v0, periods):
    """e = R sin(w t) - y, y'' + 2 Z y' + y = K1 e + K3 e^3 (the loop of 1/(s^2 + 2 Z s + 1) and the cubic spring),
    by solve_ivp (rtol 1e-11): y and y' sampled once per forcing period, and e over the last period."""
    def rhs(t, s):
        e = R * math.sin(w * t) - s[0]
        return [s[1], -2 * Z * s[1] - s[0] + K1 * e + K3 * e ** 3]

    T = 2 * math.pi / w
    t_eval = (periods - 1) * T + np.linspace(0, T, 257)[:-1]
    sol = solve_ivp(rhs, (0, periods * T), [x0, v0], rtol=1e-11, atol=1e-13, t_eval=t_eval, method="DOP853")
    e = R * np.sin(w * sol.t) - sol.y[0]
    return abs(2 * np.mean(e * np.exp(-1j * w * sol.t)))


def test_duffing_orbits_match_the_df_branches_and_liouville():
    G, N = ct.tf([1.0], [1.0, 2 * Z, 1.0]), CubicStiffness(K1, K3)
    res = forced_response(G, N, R, [1.7, 1.8, 2.0], amplitude=(1e-3, 20))
    ex = exact_forced_response(G, N, res, observe=False)
    triple = 0
    for w, sols, row in zip(res.omega, res.solutions, ex.points):
        triple += len(sols) == 3
        for df, p in zip(sols, row):
            assert p.periodic and p.stable == df.stable      # the incremental criterion agrees with the multipliers
            # Liouville: the loop's divergence is -2 Z everywhere (the spring adds no damping): det = exp(-2 Z T)
            assert abs(np.prod(p.multipliers)) == pytest.approx(math.exp(-2 * Z * 2 * math.pi / w), rel=1e-8)
            assert abs(p.amplitude_error) < 0.02             # measured: at most 1.1 % (middle branch, w = 1.8)
    assert triple >= 2 and ex.disagreements() == [] and ex.largest_difference < 0.02
    # an independent simulation from rest at w = 2 settles on the exact (lower) stable orbit's amplitude
    p = ex.points[-1][0]
    assert _duffing_run(2.0, 0.0, 0.0, 100) == pytest.approx(p.amplitude, rel=1e-7)
    assert "ExactForcedResponse" in repr(ex) and ex.to_dict()["largest_difference"] == ex.largest_difference


@pytest.fixture(scope="module")
def saturation_loop():
    G, N = ct.tf([10.0], [1, 3, 3, 1]), Saturation(1.0)
    (c,) = predict_limit_cycles(G, N, amplitude=(0.05, 30))
    return G, N, exact_cycle(G, N, c).frequency


def _saturation_strobe(G, Rf, w, periods=150):
    """Stroboscopic samples of the forced saturation loop by solve_ivp (state space of G; saturation continuous)."""
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]

    def rhs(t, s):
        return A @ s + B * float(np.clip(Rf * math.sin(w * t) - C @ s, -1.0, 1.0))

    T = 2 * math.pi / w
    sol = solve_ivp(rhs, (0, periods * T), 0.1 * np.ones(A.shape[0]), t_eval=np.arange(periods + 1) * T,
                    rtol=1e-10, atol=1e-12, max_step=T / 16)
    return sol.y.T[-30:]


@pytest.mark.parametrize("Rf, ratio, order", [(0.6, 2.0, 2), (0.3, 2.3, None)])
def test_subharmonic_and_quasi_periodic_responses_are_marked(saturation_loop, Rf, ratio, order):
    """A self-oscillating loop (saturation, 10/(s+1)^3, exact cycle at w_c) forced at 2 w_c locks to a
    subharmonic of order 2; at 2.3 w_c it stays quasi-periodic. The orbit at the forcing period exists but
    is unstable there; the run from the DF solution says what the motion does, as does solve_ivp."""
    G, N, wc = saturation_loop
    w = ratio * wc
    res = forced_response(G, N, Rf, [w, 1.001 * w], amplitude=(1e-3, 30))
    p = exact_forced_point(G, N, Rf, w, res.solutions[0][0].amplitude)
    assert p.periodic and not p.stable
    S = _saturation_strobe(G, Rf, w)
    size = np.max(np.abs(S))
    assert np.max(np.abs(S[1:] - S[:-1])) > 1e-2 * size                   # no period-T motion
    S = S[-12:]
    if order is None:
        assert p.observed == "not periodic" and "quasi-periodic" in p.message
        for k in range(1, 9):
            assert np.max(np.abs(S[k:] - S[:-k])) > 1e-3 * size
    else:
        assert p.observed == "subharmonic" and p.order == order
        assert np.max(np.abs(S[order:] - S[:-order])) < 1e-6 * size         # solve_ivp repeats every `order`


def test_bad_input():
    G, N = ct.tf([1.0], [1.0, 0.2, 1.0]), CubicStiffness(1.0, 0.5)
    for kw in (dict(R=-1.0), dict(omega=0.0), dict(amplitude=math.nan)):
        args = {"R": 0.3, "omega": 1.0, "amplitude": 0.5, **kw}
        with pytest.raises(ValueError, match=next(iter(kw))):
            exact_forced_point(G, N, **args)
    res = forced_response(G, N, 0.3, [1.0, 1.1], amplitude=(1e-3, 20))
    with pytest.raises(ValueError, match="every"):
        exact_forced_response(G, N, res, every=0)
