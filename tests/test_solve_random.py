"""Property test of predict_limit_cycles over random plants (order 2-6: stable, unstable, integrators,
delays) and the library's elements: every reported cycle solves the equation to the residual bound, and
rescaling G by k and N by 1/k changes nothing. Bounded: 30 examples, a deadline per example."""
from datetime import timedelta

import control as ct
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dfloop as df
from dfloop.describing.base import DescribingFunction
from dfloop.solve import ContinuumError

ELEMENTS = [df.Saturation(1.0), df.DeadZone(0.5), df.Relay(1.0), df.Relay(1.0, hysteresis=0.2),
            df.Backlash(h=1.0), df.CubicStiffness(1.0, 0.5), df.CoulombViscousFriction(1.0, 0.3)]
TOL = 1e-10


class _Scaled(DescribingFunction):
    """N / k: the same loop when G is multiplied by k."""

    def __init__(self, N, k):
        self.N, self.k = N, k

    def _evaluate(self, A, omega):
        return self.N(A) / self.k

    def amplitude_domain(self, omega=None):
        return self.N.amplitude_domain(omega)


@st.composite
def plants(draw):
    order = draw(st.integers(2, 6))
    integrators = draw(st.integers(0, min(2, order - 1)))
    poles = [0.0] * integrators
    while len(poles) < order:
        if order - len(poles) >= 2 and draw(st.booleans()):
            zeta = draw(st.floats(0.05, 0.9))
            wn = draw(st.floats(0.2, 5.0))
            poles += [complex(-zeta * wn, wn * np.sqrt(1 - zeta ** 2)), complex(-zeta * wn, -wn * np.sqrt(1 - zeta ** 2))]
        else:
            unstable = draw(st.booleans()) and draw(st.booleans())
            poles.append(draw(st.floats(0.05, 1.0)) if unstable else -draw(st.floats(0.1, 5.0)))
    zeros = [-draw(st.floats(0.1, 5.0)) for _ in range(draw(st.integers(0, order - 1)))]
    gain = 10 ** draw(st.floats(-1, 2))
    G = ct.tf(gain * np.real(np.poly(zeros)) if zeros else [gain], np.real(np.poly(poles)))
    T = draw(st.sampled_from([0.0, 0.0, 0.1, 0.5, 2.0]))
    return G, T


def _solve(G, T, N, k):
    if T == 0:
        return df.predict_limit_cycles(G * k, N)
    g = lambda w: k * np.exp(-1j * w * T) * G(1j * np.asarray(w))  # noqa: E731
    return df.predict_limit_cycles(g, N, omega=(0.05, 20.0))


@settings(max_examples=30, deadline=timedelta(seconds=30), derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(plants(), st.sampled_from(ELEMENTS), st.sampled_from([1e-4, 1e3]))
def test_random_loops_residual_bound_and_scale_invariance(plant, N, k):
    G, T = plant
    try:
        base = _solve(G, T, N, 1.0)
    except ContinuumError:
        base = "continuum"
    try:
        scaled = _solve(G, T, _Scaled(N, k), k)
    except ContinuumError:
        scaled = "continuum"
    if base == "continuum" or scaled == "continuum":
        assert base == scaled
        return
    for c in base:
        # independent residual: evaluate the loop directly with python-control and the element
        g = complex(G(1j * c.frequency)) * np.exp(-1j * c.frequency * T)
        r = abs(1 + g * complex(N(c.amplitude))) / (1 + abs(g * complex(N(c.amplitude))))
        assert r <= 10 * TOL
    assert len(base) == len(scaled)
    for c, d in zip(base, scaled):
        assert d.amplitude == np.float64(c.amplitude) or abs(d.amplitude / c.amplitude - 1) < 1e-7
        assert abs(d.frequency / c.frequency - 1) < 1e-7
        assert d.stability == c.stability


# ------------------------------------------------------------------------------------------- standing fuzz
# Every element kind, default and explicit windows, against the independent 1-D reference of df_reference.py
# (brentq on dense scans, written apart from the solver). The longer run is benchmarks/fuzz_solver.py.

import fuzz_loops  # noqa: E402

import pytest  # noqa: E402

FUZZ_KINDS = [k for k in fuzz_loops.KINDS if k != "numeric_hysteretic"]  # ~6 ms per N: benchmarks/ only


@pytest.mark.parametrize("kind", FUZZ_KINDS)
@pytest.mark.parametrize("seed, default", [(11, True), (12, False), (13, True), (14, False)])
def test_fuzz_every_root_against_independent_reference(kind, seed, default):
    out = fuzz_loops.run_case(seed, default_windows=default, kind=kind)
    assert out["error"] in (None, "continuum", "outside domain"), out["error"]
    assert out["misses"] == [] and out["extras"] == [], (out["misses"], out["extras"])
    assert out["bad_residual"] == []
