"""exact_cycle and verify_cycle on plants of order 11-12 (Pade-8 chains, a zeta = 1e-4 mode, real poles 1e4
apart) for saturation, backlash and dead zone. The truths are independent: python-control's frequency response of
G (the flow's realisation must realise it), an event-located DOP853 simulation with the element written in the
test (tests/loop_reference.py): a long run from 1 % off a stable orbit settles on it (period, fundamental), and
one period integrated from the start of any orbit, stable or unstable, returns to it (rtol 1e-12)."""
import math

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.hybrid import loop_model
from loop_reference import Reference, element_of

s = ct.tf("s")


def _pade(T, n):
    num, den = ct.pade(T, n)
    return ct.tf(num, den)


CASES = {
    "saturation, pade-8, order 11": (6 * _pade(0.3, 8) / ((s + 1) ** 2 * (0.1 * s + 1)), df.Saturation(1.0), 0),
    "backlash, servo + pade-8, order 11": (5 / (s * (s + 1)) * _pade(0.1, 8) / (0.05 * s + 1), df.Backlash(h=1.0), 1),
    "dead zone (unstable), pade-8, order 11": (12 / (s + 1) ** 3 * _pade(0.1, 8), df.DeadZone(0.5), 0),
    "saturation, zeta 1e-4, poles 1e4 apart, pade-6, order 12": (
        ct.tf([8], [1, 2, 2, 1]) * ct.tf([1], [1e-4, 1]) * ct.tf([100], [1, 2e-4 * 10, 100]) * _pade(0.2, 6),
        df.Saturation(1.0), 0),
}


def _orbit(name):
    G, N, pick = CASES[name]
    c = df.predict_limit_cycles(G, N)[pick]
    e = df.exact_cycle(G, N, c)
    assert e.success, e.message
    loop = loop_model(G, N, e.amplitude, e.frequency)
    A, B = loop.plant
    C = -loop.x_row[:loop.n]
    # the flow's realisation realises G: python-control's own frequency response, 40 points over 4 decades
    for w in np.logspace(-2, 2, 40):
        g = complex(G(1j * w))
        got = C @ np.linalg.solve(1j * w * np.eye(loop.n) - A, B)
        assert abs(got - g) <= 1e-8 * abs(g), (name, w)
    return G, N, e, loop, Reference(A, B, C, element_of(N))


def _start(e, loop, ref):
    z0 = e.extra["z0"]
    s0 = z0[:loop.n]
    mode = {0: 0, 1: 1, 2: -1}[int(e.extra["mode0"])] if ref.kind == "backlash" else ref.initial_mode(s0)
    return s0, mode, (float(z0[loop.n]) if ref.kind == "backlash" else 0.0)


@pytest.mark.parametrize("name", list(CASES))
def test_one_period_from_the_orbit_returns_to_it(name):
    """Stable or unstable (the dead zone's multiplier 2.6): the independent integration of one period from the
    orbit's start returns to it within 1e-9 of its size, and meets the same switches."""
    G, N, e, loop, ref = _orbit(name)
    s0, mode, el = _start(e, loop, ref)
    s1, mode1, _, events, _ = ref.run(s0, mode, e.period, e=el)
    assert np.linalg.norm(s1 - s0) <= 1e-9 * np.linalg.norm(s0)
    assert mode1 == mode and len(events) == e.switching_times.size


@pytest.mark.parametrize("name", ["saturation, pade-8, order 11", "backlash, servo + pade-8, order 11"])
def test_stable_orbit_is_where_a_long_simulation_settles(name):
    G, N, e, loop, ref = _orbit(name)
    assert e.stable
    k = math.ceil(math.log(1e-10) / math.log(e.largest_multiplier))       # periods to shrink 1 % below 1e-12
    s0, mode, el = _start(e, loop, ref)
    _, _, _, events, pieces = ref.run(s0 * 1.01, mode, (k + 2) * e.period, e=el)
    first = [t for t, m in events if m == 1]                              # entering one mode: once per period
    assert first[-1] - first[-2] == pytest.approx(e.period, rel=1e-9)
    t = first[-2] + np.arange(4096) * (e.period / 4096)
    x = ref.x_of(pieces, t)
    assert abs(2j * np.mean(x * np.exp(-1j * e.frequency * t))) == pytest.approx(e.amplitude, rel=1e-8)


def test_verify_cycle_runs_on_the_order_12_backlash_loop_and_says_it_diverges():
    """The issue's loop: backlash around an integrator, a Pade-8 delay and two lags. The exact flow used to stop
    on a false sliding release; now both runs are followed: the inside one rests, the outside one diverges (the
    large-amplitude loop has a right-half-plane closed-loop pole, python-control)."""
    G = ct.tf([4.0], [1, 1, 0]) * _pade(1.0, 8) * ct.tf([1], [0.1, 1]) * ct.tf([1], [0.05, 1])
    assert np.max(ct.poles(ct.feedback(G, 1)).real) > 0.1
    N = df.Backlash(h=0.5)
    (c,) = df.predict_limit_cycles(G, N)
    v = df.verify_cycle(G, N, c, periods=10)
    assert v.verdict == "unstable" and "diverged" in v.message and "rest" in v.message


@pytest.mark.parametrize("name,verdict", [("saturation, pade-8, order 11", "stable"),
                                          ("dead zone (unstable), pade-8, order 11", "unstable")])
def test_verify_cycle_agrees_with_the_exact_verdict_on_order_11_loops(name, verdict):
    G, N, pick = CASES[name]
    c = df.predict_limit_cycles(G, N)[pick]
    e = df.exact_cycle(G, N, c)
    assert e.stable == (verdict == "stable")
    v = df.verify_cycle(G, N, (e.amplitude, e.frequency), perturbation=0.05, periods=40)
    assert v.verdict == verdict, v.message
