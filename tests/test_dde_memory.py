"""A backlash (an element with memory) in a loop with a pure delay: the delay differential equation with the
element's state in the history (dfloop.hybrid.dde_memory). Truths: an independent fixed-step run written here
(exact plant flow for a first-order-hold input, the play operator applied to the samples, a delay of a whole
number of steps; second order, extrapolated), the exact hybrid engine on Pade chains of rising order (an
independent discretisation of the delay), and the scheme's own measured order."""
import math

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm

import dfloop as df
from dfloop.hybrid import loop_model
from dfloop.hybrid.dde_memory import MemoryDDELoop, memory_orbit
from dfloop.solve.delay import delayed

K, T, CLEARANCE = 3.0, 0.2, 0.5
G0 = ct.tf([K], [1.0, 1.0, 0.0])
N = df.Backlash(h=CLEARANCE)
PRED = (0.824516, 1.38756)       # the stable cycle predict_limit_cycles gives (checked below)


def reference_run(steps_per_period: int, periods: float, A0=0.82, w0=1.39):
    """x(t) of K/(s(s+1)) e^{-sT} around the backlash: s' = A s + B u with u linear between samples (exact
    flow of the augmented system), y = the play operator on the samples of x, u(t) = y(t - T) with T a whole
    number d of steps (a ring buffer of y)."""
    P = 2 * math.pi / w0
    d = max(1, round(T / (P / steps_per_period)))
    h = T / d
    M = np.zeros((4, 4))
    M[:2, :2] = [[0.0, 1.0], [0.0, -1.0]]
    M[1, 2] = K
    M[2, 3] = 1.0 / h
    E = expm(M * h)
    (a00, a01), (a10, a11) = E[:2, :2]
    g0, g1 = E[:2, 2] - E[:2, 3], E[:2, 3]      # s(h) = Phi s + g0 u(0) + g1 u(h)
    half, e = CLEARANCE / 2, 0.0
    buf = []
    for k in range(d + 1):                       # the element driven by the sinusoid over the delay
        x = A0 * math.sin(w0 * (k - d) * h)
        e = x - half if x - e > half else x + half if x - e < -half else e
        buf.append(e)
    s1, s2 = 0.0, A0 * w0
    n = int(periods * P / h)
    xs = np.empty(n)
    i = 0
    for k in range(n):
        u0, u1 = buf[i], buf[(i + 1) % (d + 1)]
        s1, s2 = a00 * s1 + a01 * s2 + g0[0] * u0 + g1[0] * u1, a10 * s1 + a11 * s2 + g0[1] * u0 + g1[1] * u1
        x = -s1
        e = x - half if x - e > half else x + half if x - e < -half else e
        buf[i] = e
        i = (i + 1) % (d + 1)
        xs[k] = x
    return np.arange(1, n + 1) * h, xs


def measure(t, x, periods=10):
    """(amplitude of the fundamental, frequency) over the last whole periods: upward zero crossings by cubic
    interpolation of 4 samples, the fundamental by the trapezoid rule between the first and last crossing."""
    k = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))[-(periods + 1):]
    cr = []
    for i in k:
        p = np.polyfit(t[i - 1:i + 3] - t[i], x[i - 1:i + 3], 3)
        r = np.roots(p)
        r = r[np.isreal(r)].real
        cr.append(t[i] + r[(r >= 0) & (r <= t[i + 1] - t[i])][0])
    w = 2 * math.pi * periods / (cr[-1] - cr[0])
    m = (t >= cr[0]) & (t < cr[-1])
    c = 2 / (cr[-1] - cr[0]) * np.trapezoid(x[m] * np.exp(-1j * w * t[m]), t[m])
    return abs(c), w


@pytest.fixture(scope="module")
def orbits():
    loop = loop_model(delayed(G0, T), N, *PRED)
    assert isinstance(loop, MemoryDDELoop)
    return {n: memory_orbit(loop, *PRED, nodes=n, max_nodes=2 * n) for n in (128,)}


# an unstable cycle with a long delay (T = 1 s, a sixth of the period): the step can vary over a wide range
G1, T1 = ct.tf([4.0], [1.0, 2.0, 1.0]), 1.0


@pytest.fixture(scope="module")
def unstable():
    G = delayed(G1, T1)
    c = df.predict_limit_cycles(G, N)[0]
    loop = loop_model(G, N, c.amplitude, c.frequency)
    return c, {n: memory_orbit(loop, c.amplitude, c.frequency, nodes=n, max_nodes=2 * n) for n in (32, 64, 128, 256, 512)}


def test_backlash_delay_orbit_equals_an_independent_run_and_the_df_is_close(orbits):
    c = df.predict_limit_cycles(delayed(G0, T), N)[-1]
    assert (c.amplitude, c.frequency) == pytest.approx(PRED, rel=1e-5) and c.stable
    e = df.exact_cycle(delayed(G0, T), N, c)
    assert e.success and e.stable, e.message
    assert "element's state in the history" in e.method
    runs = [measure(*reference_run(spp, 100)) for spp in (1000, 2000)]
    # the independent run is second order: its change 1000 -> 2000 steps per period is about 3 times its error
    A_ref = runs[1][0] + (runs[1][0] - runs[0][0]) / 3
    w_ref = runs[1][1] + (runs[1][1] - runs[0][1]) / 3
    assert abs(runs[1][0] - runs[0][0]) > 1e-6          # the extrapolation is needed, and does something
    assert e.amplitude == pytest.approx(A_ref, rel=3e-7)
    assert e.frequency == pytest.approx(w_ref, rel=3e-7)
    # the DF places it within its usual few per cent; the error estimate is tiny beside that
    assert abs(e.amplitude_error) < 0.05 and abs(e.frequency_error) < 0.02
    assert max(e.extra["error_estimate"]) < 1e-5
    assert e.switching_times.size == 4               # two engagements, two releases per period


def test_backlash_delay_scheme_converges_at_fourth_order(unstable):
    c, orb = unstable
    ref = orb[512]                                   # 1024 steps per period
    assert ref["success"] and not ref["stable"]
    steps = np.array([64, 128, 256, 512])
    for key in ("amplitude", "frequency"):
        err = np.array([abs(orb[n // 2][key] / ref[key] - 1) for n in steps])
        # the error constant depends on where the element's switches fall between the nodes, so single ratios
        # scatter (a lucky 128); the least-squares slope over an 8-fold range is the order
        order = -np.polyfit(np.log2(steps), np.log2(err), 1)[0]
        assert order > 3.3, (key, err, order)
    # the reported error estimate (the change between the two resolutions) bounds the finer one's error
    for n in (32, 64, 128):
        est = orb[n]["extra"]["error_estimate"]
        assert abs(orb[n]["amplitude"] / ref["amplitude"] - 1) <= est[0]
        assert abs(orb[n]["frequency"] / ref["frequency"] - 1) <= est[1]


def _pade_orbits(G, delay, start, orders):
    out = []
    for order in orders:
        num, den = ct.pade(delay, order)
        h = df.exact_cycle(G * ct.tf(num, den), N, start, nodes=1)
        assert h.success, h.message
        out.append(h)
    return out


def _gap(h, fine):
    return max(abs(h.amplitude / fine["amplitude"] - 1), abs(h.frequency / fine["frequency"] - 1))


def test_backlash_delay_orbit_is_the_limit_of_pade_chains_on_the_exact_engine(orbits, unstable):
    fine = orbits[128]
    pade = _pade_orbits(G0, T, PRED, (1, 2, 3, 5))
    gaps = [_gap(h, fine) for h in pade]
    assert gaps[0] > gaps[1] > gaps[2] and gaps[3] < 1e-6, gaps
    # the stable cycle's multipliers: the non-trivial one equals the Pade-5 engine's (its saltation matrices)
    mu = fine["multipliers"]
    nontrivial = np.delete(mu, int(np.argmin(np.abs(mu - 1))))
    assert abs(nontrivial[0]) == pytest.approx(pade[-1].largest_multiplier, rel=1e-4)
    assert np.all(np.abs(nontrivial[1:]) < 1e-3) and fine["stable"] and pade[-1].stable
    # the unstable cycle with the long delay: the backlash's slowly decaying harmonics reach w T ~ 5, where a Pade
    # chain of order 5-9 still errs by ~1e-5, so the chain scatters around the delay equation's orbit by that much
    c, orb = unstable
    fine = orb[512]
    pade = _pade_orbits(G1, T1, (c.amplitude, c.frequency), (5, 7, 9))
    assert max(_gap(h, fine) for h in pade) < 5e-5
    mu = fine["multipliers"]
    assert abs(mu[0]) > 1 and not fine["stable"]
    for h in pade:
        assert abs(mu[0]) == pytest.approx(h.largest_multiplier, rel=1e-4) and not h.stable


def test_verify_cycle_runs_the_backlash_delay_loop_and_settles_on_the_orbit(orbits):
    v = df.verify_cycle(delayed(G0, T), N, PRED, periods=60, steps_per_period=128)
    assert v.verdict == "stable", v.message
    assert "element's state in the history" in v.method
    assert v.inside.amplitude == pytest.approx(orbits[128]["amplitude"], rel=1e-5)
    assert v.outside.frequency == pytest.approx(orbits[128]["frequency"], rel=1e-5)
