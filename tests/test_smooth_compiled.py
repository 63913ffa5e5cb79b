"""The compiled DOP853 of smooth loops (dfloop.hybrid.smooth_compiled): the same orbits as scipy's solve_ivp path
(DFLOOP_COMPILED=0), and the orbit a long event-located simulation written here settles on."""
from __future__ import annotations

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import dfloop as df
from dfloop import progress
from dfloop.hybrid import HybridError, loop_model, smooth, smooth_compiled, start_on_prediction

S = ct.tf("s")
CUBE = ct.tf([1], [1, 3, 3, 1])
LOOPS = {
    "stable": (CUBE, df.CubicStiffness(10.0, -1.0), {}),
    "unstable": (CUBE, df.CubicStiffness(6.0, 1.0), {}),
    "order 5": (1 / ((S + 1) ** 3 * (0.1 * S + 1) * (0.05 * S + 1)), df.CubicStiffness(15.0, -2.0), {}),
    "constant input": (CUBE, df.CubicStiffness(10.0, -1.0), {"r0": 0.3, "load": -0.2}),
}


def _both(G, N, kw, monkeypatch):
    c = df.predict_limit_cycles(G, N)[0]
    compiled = df.exact_cycle(G, N, c, **kw)
    monkeypatch.setenv("DFLOOP_COMPILED", "0")
    reference = df.exact_cycle(G, N, c, **kw)
    monkeypatch.delenv("DFLOOP_COMPILED")
    return compiled, reference


@pytest.mark.parametrize("name", list(LOOPS))
def test_compiled_orbit_is_scipys_to_1e10(name, monkeypatch):
    G, N, kw = LOOPS[name]
    assert loop_model(G, N, 1.0, 1.0, **kw).compiled
    got, ref = _both(G, N, kw, monkeypatch)
    assert got.success and ref.success and got.method == ref.method
    assert got.stable == ref.stable == (name != "unstable")
    assert got.amplitude == pytest.approx(ref.amplitude, rel=1e-10, abs=0)
    assert got.frequency == pytest.approx(ref.frequency, rel=1e-10, abs=0)
    assert got.mean == pytest.approx(ref.mean, rel=0, abs=1e-10 * ref.amplitude)
    np.testing.assert_allclose(got.multipliers, ref.multipliers, rtol=0, atol=1e-10)
    np.testing.assert_allclose(got.harmonics, ref.harmonics, rtol=0, atol=1e-10 * ref.amplitude)
    np.testing.assert_allclose(got.x, ref.x, rtol=0, atol=1e-10 * ref.amplitude)
    np.testing.assert_allclose(got.y, ref.y, rtol=0, atol=1e-10 * np.max(np.abs(ref.y)))


def test_stable_orbit_is_where_a_long_simulation_settles():
    """Truth: the plant in python-control's realisation and f = 10 x - x^3 written here, run 40 periods from the
    prediction by solve_ivp (DOP853, rtol 1e-12) with the upward zero crossings of x located as events. The period
    between the last crossings and the fundamental over the last period agree with exact_cycle to 1e-8; the
    intervals between crossings approach the period by the slowest multiplier per period."""
    G, N = LOOPS["stable"][:2]
    c = df.predict_limit_cycles(G, N)[0]
    e = df.exact_cycle(G, N, c)
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]

    def rhs(t, s):
        x = -C @ s
        return A @ s + B * (10.0 * x - x ** 3)

    def up(t, s):
        return -C @ s
    up.direction = 1.0

    s0 = (np.linalg.solve(1j * c.frequency * np.eye(3) - A, B) * complex(N(c.amplitude)) * c.amplitude).imag
    run = solve_ivp(rhs, (0.0, 40 * 2 * np.pi / c.frequency), s0, method="DOP853", rtol=1e-12, atol=1e-14,
                    events=up, dense_output=True)
    crossings = run.t_events[0]
    periods = np.diff(crossings)
    assert periods.size >= 35
    assert periods[-1] == pytest.approx(e.period, rel=1e-8)
    t = crossings[-2] + np.arange(4096) * (periods[-1] / 4096)
    x = -C @ run.sol(t)
    amplitude = abs(2.0 * np.mean(x * np.exp(-2j * np.pi * np.arange(4096) / 4096)))
    assert e.amplitude == pytest.approx(amplitude, rel=1e-8)
    deviation = periods - e.period          # shrinks by the slowest multiplier per period once it dominates
    mu = np.max(np.abs(np.delete(e.multipliers, np.argmin(np.abs(e.multipliers - 1.0)))))
    ratios = deviation[1:] / deviation[:-1]
    settled = (np.abs(deviation[:-1]) < 1e-4 * e.period) & (np.abs(deviation[:-1]) > 1e-8 * e.period)
    assert settled.sum() >= 5
    np.testing.assert_allclose(ratios[settled], mu, rtol=1e-3)


def _loops(r0=0.0, load=0.0):
    """The order-5 loop's model twice: compiled and on scipy's solve_ivp (no compiled form)."""
    G, N = LOOPS["order 5"][:2]
    compiled = loop_model(G, N, 2.5, 1.4, r0=r0, load=load)
    tm = N.time_model(2.5)
    reference = smooth.SmoothLoop(compiled.A, compiled.B, compiled.C, tm.f, tm.name, 2 * np.pi / 1.4, tm.slope,
                                  r0=r0, load=load)
    assert compiled.compiled and not reference.compiled
    return compiled, reference


def test_node_flows_monodromies_and_dense_output_match_scipys():
    """Random starts, unequal spans, a constant input: end states, monodromies, the joined period's states and
    the field at the flows' ends against scipy's run of the same equations."""
    compiled, reference = _loops(r0=0.2, load=0.1)
    rng = np.random.default_rng(7)
    N = LOOPS["order 5"][1]
    zs = [start_on_prediction(compiled, N, 2.5, 1.4, t)[0] * (1.0 + rng.normal(0.0, 0.05, compiled.size))
          for t in rng.uniform(0.0, 4.0, 4)]    # near the orbit, 5 % apart (the spring softens far out)
    zs = [np.append(z[:-1], 1.0) for z in zs]
    spans = np.array([0.3, 0.7, 1.1, 0.45])
    got = compiled.flow_many(zs, [0] * 4, spans, monodromy=True)
    ref = reference.flow_many(zs, [0] * 4, spans, monodromy=True)
    for g, r in zip(got, ref):
        scale = np.max(np.abs(r.z))
        np.testing.assert_allclose(g.z, r.z, rtol=0, atol=1e-11 * scale)
        np.testing.assert_allclose(g.monodromy, r.monodromy, rtol=0, atol=1e-10 * np.max(np.abs(r.monodromy)))
        np.testing.assert_allclose(compiled.field(g.z), reference.field(g.z), rtol=1e-12, atol=1e-14 * scale)
    # a period joined from equal node flows: its dense output everywhere, and x's harmonics
    period = 4.4
    starts = [g.z for g in compiled.flow_many(zs[:1] * 4, [0] * 4, np.arange(4) * period / 4)]
    got = compiled.join(compiled.flow_many(starts, [0] * 4, period / 4, monodromy=True), period)
    ref = reference.join(reference.flow_many(starts, [0] * 4, period / 4, monodromy=True), period)
    t = np.sort(rng.uniform(0.0, period, 300))
    scale = np.max(np.abs(reference.states(ref, t)))
    np.testing.assert_allclose(compiled.states(got, t), reference.states(ref, t), rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(got.monodromy, ref.monodromy, rtol=0, atol=1e-9 * np.max(np.abs(ref.monodromy)))
    np.testing.assert_allclose(compiled.fourier(got, period, 2 * np.pi / period, 8),
                               reference.fourier(ref, period, 2 * np.pi / period, 8), rtol=0, atol=1e-10 * scale)


def test_user_variant_of_a_builtin_keeps_its_own_f_on_scipy():
    """A subclass that computes its own output inherits no compiled form: its f runs, on scipy's path."""

    class Stiffer(df.CubicStiffness):
        def output(self, x):
            return super().output(x) + 0.5 * np.tanh(x)

    G = CUBE
    loop = loop_model(G, Stiffer(10.0, -1.0), 1.6, 1.7)
    assert not loop.compiled
    plain = loop_model(G, df.CubicStiffness(10.0, -1.0), 1.6, 1.7)
    z = np.array([0.1, -0.2, 0.9, 1.0])
    x = float(loop.x(z))
    assert loop.field(z)[0] - plain.field(z)[0] == pytest.approx(0.5 * np.tanh(x), rel=1e-12)


def test_failures_say_why(monkeypatch):
    """A softening spring far out escapes to infinity in finite time; a step bound names itself."""
    compiled, _ = _loops()
    with pytest.raises(HybridError, match="DOP853 failed on node 0 of 1: the step size fell below"):
        compiled.flow(np.append(np.full(compiled.n, 40.0), 1.0), 0, 50.0)
    monkeypatch.setattr(smooth_compiled, "MAX_STEPS", 3)
    with pytest.raises(HybridError, match="MAX_STEPS = 3 accepted steps"):
        compiled.flow(np.append(np.full(compiled.n, 0.5), 1.0), 0, 5.0)


def test_first_compile_is_announced_on_the_progress_channel(monkeypatch, capsys):
    monkeypatch.setattr(progress, "_ANNOUNCED", set())
    monkeypatch.setattr(progress, "_READY", set())
    monkeypatch.setattr(smooth, "_ANNOUNCED", [])
    monkeypatch.setattr(progress, "compile_pending", lambda *dispatchers: True)   # as on a fresh installation
    monkeypatch.delenv("DFLOOP_PROGRESS", raising=False)
    compiled, _ = _loops()
    compiled.flow(np.append(np.full(compiled.n, 0.5), 1.0), 0, 0.1)
    compiled.flow(np.append(np.full(compiled.n, 0.5), 1.0), 0, 0.1)
    err = capsys.readouterr().err
    assert err.count("dfloop: the smooth-loop integrator: compiling once for this installation, about "
                     f"{smooth_compiled.COMPILE_SECONDS} s") == 1
