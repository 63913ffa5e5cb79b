"""DF forced response (dfloop.solve.forced): a cubic spring in a second-order loop, where the DF balance is a cubic
polynomial in A^2 (derived below) whose double roots are the jumps; and a direct simulation sweeping the forcing
frequency up and down, whose jumps must sit at the predicted folds within the DF's error."""
import math

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq

from dfloop import CubicStiffness, Saturation
from dfloop.errors import DfloopError
from dfloop.solve.forced import forced_response, jump_region

Z, K1, K3, R = 0.1, 1.0, 0.5, 0.3
G = ct.tf([1.0], [1.0, 2 * Z, 1.0])


def _cubic(w, R=R):
    """e = r - G u, u = k1 e + k3 e^3, G = 1/(s^2 + 2 z s + 1), N = k1 + 3 k3 A^2 / 4: with x = A^2,
    A |1 + G N| = R  <=>  x [(1 - w^2 + k1 + 3 k3 x / 4)^2 + 4 z^2 w^2] = R^2 [(1 - w^2)^2 + 4 z^2 w^2],
    a cubic in x: coefficients (highest first)."""
    c = 1 - w * w + K1
    q = 0.75 * K3
    d2 = 4 * Z * Z * w * w
    return np.array([q * q, 2 * c * q, c * c + d2, -R * R * ((1 - w * w) ** 2 + d2)])


def _discriminant(w, R=R):
    a, b, c, d = _cubic(w, R)
    return 18 * a * b * c * d - 4 * b ** 3 * d + b * b * c * c - 4 * a * c ** 3 - 27 * a * a * d * d


@pytest.fixture(scope="module")
def response():
    return forced_response(G, CubicStiffness(K1, K3), R, np.linspace(0.5, 3.0, 101), amplitude=(1e-3, 20))


def test_every_solution_matches_the_polynomial(response):
    for w, sols in zip(response.omega, response.solutions):
        x = np.roots(_cubic(w))
        truth = np.sort(np.sqrt(x[(np.abs(x.imag) < 1e-9 * np.abs(x)) & (x.real > 0)].real))
        got = np.array([p.amplitude for p in sols])
        assert got.size == truth.size, w
        np.testing.assert_allclose(got, truth, rtol=1e-10)
        # the middle solution of a triple-valued frequency is the unstable one
        assert [p.stable for p in sols] == ([True] if len(sols) == 1 else [True, False, True])
        for p in sols:  # plant output amplitude |G N| A
            n = K1 + 0.75 * K3 * p.amplitude ** 2
            assert p.output_amplitude == pytest.approx(abs(n / (1 - w * w + 2j * Z * w)) * p.amplitude, rel=1e-12)
    assert response.multiple.size > 0


def test_jumps_are_the_double_roots(response):
    """The folds are the zeros of the cubic's discriminant in w, located here independently by Brent's method."""
    assert len(response.jumps) == 2
    for jump in response.jumps:
        k = np.searchsorted(response.omega, jump.omega)
        truth = brentq(_discriminant, response.omega[k - 1], response.omega[k], xtol=1e-15, rtol=1e-15)
        assert jump.omega == pytest.approx(truth, rel=1e-12)
        x = np.roots(_cubic(truth))
        assert min(abs(x - jump.amplitude ** 2)) < 1e-5 * jump.amplitude ** 2  # a double root: sqrt(eps) accuracy
    down, up = response.jumps
    assert (down.sweep, up.sweep) == ("down", "up")
    assert down.target > down.amplitude and up.target < up.amplitude
    assert "jump" in repr(response)


def _rk4_sweep(freqs, periods=20, steps=64):
    """Fixed-step RK4 (64 steps a period) of y'' + 2 z y' + y = f(R sin(w t) - y), f(e) = k1 e + k3 e^3, holding each
    frequency for ``periods`` periods (whole periods: the forcing's phase is continuous); returns the fundamental
    amplitude of e over the last period at each frequency."""
    y = np.zeros(2)
    out = []
    for w in freqs:
        h = 2 * math.pi / w / steps

        def f(t, s):
            e = R * math.sin(w * t) - s[0]
            return np.array([s[1], -2 * Z * s[1] - s[0] + K1 * e + K3 * e ** 3])

        acc = 0j
        for n in range(periods * steps):
            t = n * h
            k1 = f(t, y)
            k2 = f(t + h / 2, y + h / 2 * k1)
            k3 = f(t + h / 2, y + h / 2 * k2)
            k4 = f(t + h, y + h * k3)
            if n >= (periods - 1) * steps:
                acc += (R * math.sin(w * t) - y[0]) * complex(math.cos(w * t), -math.sin(w * t))
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(2 * abs(acc) / steps)
    return np.array(out)


def test_simulated_sweeps_jump_at_the_folds(response):
    down, up = response.jumps
    freqs = np.arange(1.56, 2.1, 0.03)
    a_up = _rk4_sweep(freqs)
    a_down = _rk4_sweep(freqs[::-1])[::-1]
    # one jump each way: the largest drop sweeping up, the largest rise sweeping down
    i_up = int(np.argmin(np.diff(a_up)))
    i_down = int(np.argmax(np.diff(a_down[::-1])))  # in sweep order (decreasing w)
    w_up = 0.5 * (freqs[i_up] + freqs[i_up + 1])
    w_down = 0.5 * (freqs[::-1][i_down] + freqs[::-1][i_down + 1])
    assert a_up[i_up] > 2 * a_up[i_up + 1] and a_down[::-1][i_down + 1] > 1.5 * a_down[::-1][i_down]
    # the DF's error here (third harmonic of a stiff cubic): measured 2.3 % (up), 0.5 % (down)
    assert abs(w_up - up.omega) < 0.03 * up.omega
    assert abs(w_down - down.omega) < 0.03 * down.omega
    # hysteresis: between the jumps the sweeps sit on the DF's upper and lower stable branches (within 5 %)
    k = int(np.argmin(abs(response.omega - 1.8)))
    j = int(np.argmin(abs(freqs - response.omega[k])))
    sols = response.solutions[k]
    assert a_up[j] == pytest.approx(sols[2].amplitude, rel=0.05)
    assert a_down[j] == pytest.approx(sols[0].amplitude, rel=0.05)


def test_bad_input_and_saturation():
    with pytest.raises(DfloopError, match="R"):
        forced_response(G, Saturation(1.0), -1.0, [1.0, 2.0], amplitude=(0.1, 10))
    with pytest.raises(DfloopError, match="omega"):
        forced_response(G, Saturation(1.0), 1.0, [2.0, 1.0], amplitude=(0.1, 10))
    # a saturation is softening: below the linear resonance the response is single-valued at small R
    res = forced_response(G, Saturation(1.0), 0.1, np.linspace(0.5, 2.0, 31), amplitude=(1e-3, 10))
    assert all(len(s) == 1 and s[0].stable for s in res.solutions) and not res.jumps


def test_jump_region_against_the_discriminant():
    """Folds at several R are the discriminant's zeros; at small R (below the cusp) there are none, and the
    discriminant keeps one sign (a single real root) on the whole grid."""
    w = np.linspace(0.8, 2.6, 61)
    region = jump_region(G, CubicStiffness(K1, K3), [0.02, 0.27, 0.3], w, amplitude=(1e-3, 20))
    assert region.band(0) is None
    assert all(_discriminant(x, 0.02) < 0 for x in w)
    for i, r in enumerate(region.R[1:], start=1):
        assert len(region.folds[i]) == 2
        for jump in region.folds[i]:
            k = np.searchsorted(w, jump.omega)
            truth = brentq(lambda x: _discriminant(x, r), w[k - 1], w[k], xtol=1e-15, rtol=1e-15)
            assert jump.omega == pytest.approx(truth, rel=1e-12)
    lo1, hi1 = region.band(1)
    lo2, hi2 = region.band(2)
    assert hi2 - lo2 > hi1 - lo1  # the band widens with the forcing
    assert "no jump" in repr(region)


def test_branches_run_through_the_folds(response):
    """Three curves: the solution from low frequencies up to the upper fold, the lower branch born at the lower
    fold, and the unstable middle one between the folds; every solution on exactly one curve, the folds on two."""
    curves = response.branches()
    assert len(curves) == 3
    n_points = sum(len(s) for s in response.solutions)
    assert sum(len(c) for c in curves) == n_points + 4  # each fold point ends or starts two curves
    down, up = response.jumps
    for c in curves:
        w = [p.omega for p in c]
        assert np.all(np.diff(w) > 0)
        assert len({p.stable for p in c if p.omega not in (down.omega, up.omega)}) == 1
    middle = next(c for c in curves if not c[1].stable)
    assert (middle[0].omega, middle[-1].omega) == (down.omega, up.omega)
    assert middle[0].output_amplitude == pytest.approx(down.output_amplitude)
