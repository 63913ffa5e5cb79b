"""A pure delay as a part of the plant (issue 16): delayed(G, T) in the predictor, its exact grid bound, sweeps
over T, and the exact delay engine (exact_cycle / verify_cycle) against independent truths: the closed form of
the relay around K e^{-sL}/(Tc s + 1), Tsypkin's switching condition with the delay (written here from the
closed-form periodic response, no event location), and long event-located runs of the shipped scene."""
import math

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

import dfloop as df
from dfloop.continuation import sweep
from dfloop.hybrid import loop_model
from dfloop.hybrid.delay import return_map
from dfloop.scene import find_scene, load_scene
from dfloop.solve.delay import DelayedSystem, delayed
from dfloop.solve.plant import as_plant
from dfloop.verify import simulate_loop


def _delay_roots(T, lo, hi):
    """Relay around exp(-sT)/(s + 1): w T + atan w = (2m + 1) pi (brentq, independent)."""
    f = lambda w, m: w * T + np.arctan(w) - (2 * m + 1) * np.pi  # noqa: E731
    m_max = int((hi * T + np.pi / 2) / (2 * np.pi)) + 2
    return np.array([brentq(f, lo, hi, args=(m,), xtol=1e-14, rtol=1e-15) for m in range(m_max)
                     if f(lo, m) < 0 < f(hi, m)])


# ------------------------------------------------------------------------------------------ the plant type


def test_delayed_system_evaluates_multiplies_and_rejects_bad_input():
    G = ct.tf([2.0], [1.0, 3.0, 1.0])
    Gd = delayed(G, 0.7)
    s = np.array([0.3j, 2.0j, 1 + 1j])
    np.testing.assert_allclose(Gd(s), 2 / (s * s + 3 * s + 1) * np.exp(-0.7 * s), rtol=1e-14)
    H = ct.tf([1.0, 1.0], [1.0, 5.0])
    for product in (H * Gd, Gd * H):
        assert isinstance(product, DelayedSystem) and product.delay == 0.7
        np.testing.assert_allclose(product(s), Gd(s) * H(s), rtol=1e-13)
    assert (Gd * delayed(H, 0.2)).delay == pytest.approx(0.9, rel=1e-15)
    assert delayed(Gd, 0.3).delay == pytest.approx(1.0, rel=1e-15)
    np.testing.assert_allclose(as_plant(Gd)(np.array([0.3, 2.0])), Gd(np.array([0.3j, 2.0j])), rtol=1e-14)
    assert as_plant(delayed(G, 0.0)).lti is G            # a zero delay is the plain system
    for bad, match in ((-1.0, "delay"), (math.nan, "delay"), ("x", "delay")):
        with pytest.raises(ValueError, match=match):
            delayed(G, bad)
    with pytest.raises(ValueError, match="SISO"):
        delayed(ct.rss(2, 2, 1), 0.1)
    with pytest.raises(ValueError, match="continuous"):
        delayed(ct.tf([1.0], [1.0, 0.5], dt=0.1), 0.1)
    with pytest.raises(ValueError, match="system"):
        delayed(lambda w: w, 0.1)


def test_delay_variation_bound_is_exact_and_holds_against_dense_sampling():
    rng = np.random.default_rng(3)
    G = ct.zpk([-2.0], [-0.3, -1 + 2j, -1 - 2j], 4.0)
    for T in (0.0, 0.5, 5.0, 50.0):
        p = as_plant(delayed(G, T) if T else G)
        for _ in range(20):
            w0 = 10 ** rng.uniform(-2, 2)
            w1 = w0 * (1 + 10 ** rng.uniform(-4, 0))
            eps = p.log_variation(np.array([w0]), np.array([w1]))[0]
            w = np.linspace(w0, w1, 2001)
            g = p(w)
            dlog = np.log(np.abs(g / g[0])) + 1j * np.unwrap(np.angle(g) - np.angle(g[0]))
            assert np.max(np.abs(dlog)) <= eps * (1 + 1e-9)
            # the delay's turn T (w1 - w0) alone is a lower bound of the phase part: no aliasing possible
            assert eps >= T * (w1 - w0)


@pytest.mark.parametrize("T", [0.5, 2.0])
def test_predictor_finds_every_delay_crossing_with_an_exact_grid(T):
    ref = _delay_roots(T, 0.1, 200.0)
    cycles = df.predict_limit_cycles(delayed(ct.tf([1.0], [1.0, 1.0]), T), df.Relay(1.0), omega=(0.1, 200.0))
    assert len(cycles) == ref.size
    np.testing.assert_allclose([c.frequency for c in cycles], ref, rtol=1e-10)
    np.testing.assert_allclose([c.amplitude for c in cycles], 4 / (np.pi * np.sqrt(1 + ref ** 2)), rtol=1e-9)
    assert cycles.grid_report.frequency_rule != "sampled"     # the bound is exact, not sampled


def test_sweep_over_the_delay_follows_the_first_crossing():
    G0 = ct.tf([1.0], [1.0, 1.0])
    res = sweep(lambda T: (delayed(G0, T), df.Relay(1.0)), [0.4, 0.8], omega=(0.5, 10.0), progress=False,
                parameter="T", unit="s")
    first = [b for b in res.branches if b.frequency.max() < 10.0 and b.frequency.min() > 2.0]
    assert len(first) == 1
    b = first[0]
    p, A, w = b.at_values()
    for Tk, wk, Ak in zip(p, w, A):
        ref = _delay_roots(Tk, 0.5, 10.0)[0]
        assert wk == pytest.approx(ref, rel=1e-8)
        assert Ak == pytest.approx(4 / (np.pi * math.hypot(1, ref)), rel=1e-8)


# ------------------------------------------------------------------------------------ the exact delay flow


@pytest.mark.parametrize("K, Tc, L", [(2.0, 1.0, 0.5), (1.0, 0.3, 1.5), (0.5, 2.0, 0.05)])
def test_fopdt_relay_cycle_matches_the_closed_form(K, Tc, L):
    # relay +-M around K e^{-sL}/(Tc s + 1): half period L + Tc ln(2 - e^{-L/Tc}), peak of the plant output
    # K M (1 - e^{-L/Tc}); the fundamental of x is that of the output to a square wave: (4 M / pi) |G(jw)|
    M = 1.5
    G = delayed(ct.tf([K], [Tc, 1.0]), L)
    c = df.predict_limit_cycles(G, df.Relay(M), omega=(0.01 / Tc, 20.0 / min(Tc, L)))[0]
    e = df.exact_cycle(G, df.Relay(M), c, samples=4096)
    assert e.success, e.message
    half = L + Tc * math.log(2 - math.exp(-L / Tc))
    assert e.period / 2 == pytest.approx(half, rel=1e-12)
    assert e.amplitude == pytest.approx(4 * M / math.pi * K / math.hypot(1, e.frequency * Tc), rel=1e-11)
    peak = K * M * (1 - math.exp(-L / Tc))
    assert np.max(e.x) <= peak * (1 + 1e-12)
    assert np.max(e.x) >= peak - 2 * K * M / Tc * e.period / 4096   # sampled: within one sample of the slope
    assert e.stable and e.switching_times.size == 2


def _tsypkin_half_period(G, L, M, a, h_guess):
    """Half period h of the symmetric relay (hysteresis a) orbit around G(s) e^{-sL}, from Tsypkin's condition:
    with u = +M on [0, h), -M on [h, 2h) the periodic state is s0 = -(I + e^{Ah})^{-1} Gamma(h) M, and the
    element switches to -M where x = -C s crosses -a, a time L before u does: x((h - L) mod 2h) = -a."""
    ss = ct.ss(G)
    A, B, C = np.asarray(ss.A), np.asarray(ss.B)[:, 0], np.asarray(ss.C)[0]
    n = A.shape[0]

    def x_at(h, t):
        big = np.zeros((n + 1, n + 1))
        big[:n, :n], big[:n, n] = A, B
        E = expm(big * h)
        s0 = -np.linalg.solve(np.eye(n) + E[:n, :n], E[:n, n] * M)
        t = t % (2 * h)
        sign = 1.0 if t < h else -1.0
        start = s0 if t < h else -s0
        Et = expm(big * (t % h))
        return -C @ (Et[:n, :n] @ start + Et[:n, n] * M * sign)

    def f(h):
        return x_at(h, h - L) + a

    h = brentq(f, h_guess * 0.97, h_guess * 1.03, xtol=1e-15, rtol=1e-15)
    return h, x_at


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_relay_with_hysteresis_and_delay_satisfies_tsypkin(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 5))
    poles = -np.sort(rng.uniform(0.3, 3.0, n))
    G = ct.zpk([], poles, float(np.prod(-poles)) * rng.uniform(1.0, 4.0))
    L = rng.uniform(0.1, 2.0)
    M, a = 1.0, rng.uniform(0.01, 0.2)
    N = df.Relay(M, hysteresis=a)
    cycles = df.predict_limit_cycles(delayed(G, L), N, omega=(0.01, 50.0))
    c = max(cycles, key=lambda c: c.amplitude)                 # the slowest, stable crossing
    e = df.exact_cycle(delayed(G, L), N, c)
    assert e.success, e.message
    h, x_at = _tsypkin_half_period(G, L, M, N.on_level, e.period / 2)
    assert e.period / 2 == pytest.approx(h, rel=1e-10)
    # the orbit has no extra crossing: x stays beyond the thresholds between the two switches (dense check)
    t = np.linspace(0, 2 * h, 4001)[:-1]
    x = np.array([x_at(h, ti) for ti in t])
    t_minus = (h - L) % (2 * h)
    phase = (t - t_minus) % (2 * h)            # time since the switch to -M
    assert np.all(x[(phase > 1e-9) & (phase < h - 1e-9)] < N.on_level)   # no switch back to +M before h
    assert np.all(x[(phase > h + 1e-9)] > -N.on_level)
    assert e.amplitude == pytest.approx(4 * M / math.pi * abs(complex(G(1j * math.pi / h))), rel=1e-10)


def test_relay_delay_scene_high_frequency_cycles_are_unstable_and_motions_leave_for_the_slow_one():
    scene = load_scene(find_scene("relay_delay"))
    G, N = scene.plant, scene.element
    assert isinstance(G, DelayedSystem) and G.delay == 0.5
    cycles = df.predict_limit_cycles(G, N, omega=scene.omega)
    assert len(cycles) == 5
    w_slow = math.pi / (0.5 + math.log(2 - math.exp(-0.5)))          # the closed form: 3.7769 rad/s
    exact = [df.exact_cycle(G, N, c) for c in cycles]
    assert all(e.success for e in exact)
    assert exact[0].frequency == pytest.approx(w_slow, rel=1e-12) and exact[0].stable
    assert not any(e.stable for e in exact[1:])
    for c in cycles[1:3]:      # the 15.8 and 28.3 rad/s predictions: a long exact-delay run ends on 3.78 rad/s
        sim = simulate_loop(G, N, c.amplitude, c.frequency, periods=200, steps_per_period=64)
        tail = sim.t > sim.t[-1] - 4 * 2 * math.pi / w_slow
        up = np.flatnonzero((sim.y[tail][:-1] < 0) & (sim.y[tail][1:] > 0))
        period = np.diff(sim.t[tail][up])
        assert period.size >= 2
        np.testing.assert_allclose(period, 2 * math.pi / w_slow, atol=2 * 2 * math.pi / c.frequency / 64)


def test_stability_verdicts_agree_with_perturbed_runs():
    G = delayed(ct.tf([1.0], [1.0, 1.0]), 0.5)
    N = df.Relay(1.0)
    for c in df.predict_limit_cycles(G, N, omega=(0.1, 30.0)):
        e = df.exact_cycle(G, N, c)
        assert e.success
        loop = loop_model(G, N, c.amplitude, c.frequency)
        ex = e.extra
        s0, queue = ex["s0"], [list(q) for q in ex["queue0"]]
        rng = np.random.default_rng(1)
        d = 1e-3 * (np.linalg.norm(s0) * rng.standard_normal(s0.size) / math.sqrt(s0.size))
        s = s0 + d
        dist0 = np.linalg.norm(d)
        for _ in range(12):
            out = return_map(loop, s, ex["mode0"], ex["u0"], queue, ex["section"], horizon=50.0, tangent=False)
            s, queue = out[0], out[2]
        dist = np.linalg.norm(s - s0) + sum(abs(a[0] - b[0]) for a, b in zip(queue, ex["queue0"]))
        if e.stable:
            assert dist < 0.5 * dist0
        else:
            assert dist > 2 * dist0 or len(queue) != len(ex["queue0"])


def _closed_form_check(e, G, L, thresholds):
    """An exact orbit with a piecewise-constant element, checked without event location: the plant's input is
    the element output y(t - L) (levels read between the reported switches), the periodic plant state follows
    from (I - e^{AP}) s0 = sum of the segments' forced responses, and then (a) x at every reported switch lies
    on a threshold of the element, (b) x over the period equals the reported waveform."""
    ss = ct.ss(G)
    A, B, C = np.asarray(ss.A), np.asarray(ss.B)[:, 0], np.asarray(ss.C)[0]
    n = A.shape[0]
    P = e.period
    sw = np.sort(e.switching_times)
    mids = 0.5 * (sw + np.roll(sw, -1) + np.where(np.arange(sw.size) == sw.size - 1, P, 0.0))
    levels = np.interp(mids % P, e.t, e.y, period=P)
    levels = np.round(levels, 9)
    # u(t) = y(t - L): level k holds on [sw_k + L, sw_{k+1} + L) mod P
    starts = (sw + L) % P
    order = np.argsort(starts)
    starts, lev = starts[order], levels[order]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n], big[:n, n] = A, B

    def flow(s, u, h):
        E = expm(big * h)
        return E[:n, :n] @ s + E[:n, n] * u

    u_at0 = lev[-1]                       # the level started last before t = P wraps to t = 0
    bounds = np.concatenate([[0.0], starts, [P]])
    us = np.concatenate([[u_at0], lev])
    Phi, F = np.eye(n), np.zeros(n)
    for a, b, u in zip(bounds[:-1], bounds[1:], us):
        E = expm(big * (b - a))
        Phi, F = E[:n, :n] @ Phi, E[:n, :n] @ F + E[:n, n] * u
    s0 = np.linalg.solve(np.eye(n) - Phi, F)

    def x_at(t):
        k = np.searchsorted(bounds, t, side="right") - 1
        s = s0
        for a, b, u in zip(bounds[:k], bounds[1:k + 1], us[:k]):
            s = flow(s, u, b - a)
        return -C @ flow(s, us[k], t - bounds[k])

    scale = np.max(np.abs(e.x))
    for t in sw:
        assert np.min(np.abs(x_at(t) - thresholds)) <= 1e-9 * scale
    xs = np.array([x_at(t) for t in e.t[::8]])
    np.testing.assert_allclose(xs, e.x[::8], rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize("seed", [3, 4])
def test_dead_zone_relay_and_quantizer_orbits_are_true_orbits(seed):
    rng = np.random.default_rng(seed)
    poles = -np.sort(rng.uniform(0.5, 3.0, 3))
    G = ct.zpk([], poles, float(np.prod(-poles)) * rng.uniform(4.0, 8.0))
    L = rng.uniform(0.2, 1.5)
    hyst, dz = rng.uniform(0.02, 0.1), rng.uniform(0.05, 0.2)
    relay = df.Relay(1.0, hysteresis=hyst, dead_zone=dz)
    # the quantizer tends to a unit gain: scale G so that |G| = 0.9 at its phase crossover (bounded motion)
    w180 = brentq(lambda w: np.pi - np.sum(np.arctan(w / -poles)) - w * L, 1e-6, 100.0)   # arg G e^{-jwL} = -pi
    Gq = G * (0.9 / abs(complex(G(1j * w180))))
    q = df.Quantizer(0.1)
    thresholds_q = 0.1 * (np.arange(-200, 201) + 0.5)
    for N, plant, thr in ((relay, G, np.array([relay.on_level, relay.off_level, -relay.on_level,
                                                -relay.off_level])), (q, Gq, thresholds_q)):
        cycles = df.predict_limit_cycles(delayed(plant, L), N, omega=(0.05, 20.0), amplitude=(0.05, 50.0))
        stable = [c for c in cycles if c.stability == "stable"]
        c = max(stable, key=lambda c: c.amplitude)
        e = df.exact_cycle(delayed(plant, L), N, c, samples=256)
        assert e.success, e.message
        _closed_form_check(e, plant, L, thr)


def test_random_delayed_relay_loops_settled_runs_are_the_exact_orbits():
    # a small version of benchmarks/bench_delay_exact.py: the orbit a long event-located run from the slowest
    # prediction settles on (return map iterated to 1e-13, no Newton) is exact_cycle's orbit to 1e-8
    rng = np.random.default_rng(11)
    for _ in range(3):
        n = int(rng.integers(2, 6))
        poles = -10 ** rng.uniform(-0.5, 0.5, n)
        G = delayed(ct.zpk([], poles, float(np.prod(-poles)) * rng.uniform(1.5, 4.0)), rng.uniform(0.05, 5.0)
                    / abs(poles).min())
        N = df.Relay(rng.uniform(0.5, 2.0), hysteresis=rng.uniform(0, 0.1), dead_zone=rng.uniform(0, 0.1))
        c = min(df.predict_limit_cycles(G, N, omega=(0.01, 20.0)), key=lambda c: c.frequency)
        e = df.exact_cycle(G, N, c)
        assert e.success, e.message
        loop = loop_model(G, N, c.amplitude, c.frequency)
        from dfloop.hybrid.delay import predicted_start
        s, mode, u, queue, section = predicted_start(loop, c.amplitude, c.frequency)
        prev = None
        for _ in range(2000):
            s, u, queue, t1, _, fl = return_map(loop, s, mode, u, queue, section, horizon=100.0, tangent=False)
            v = np.concatenate([s, [q[0] for q in queue], [t1]])
            if prev is not None and prev.size == v.size and np.linalg.norm(v - prev) <= 1e-13 * np.linalg.norm(v):
                break
            prev = v
        else:
            pytest.fail("the run did not settle")
        A_run = abs(2j * loop.fourier(fl, t1, 2 * math.pi / t1, 1)[0])
        assert e.frequency == pytest.approx(2 * math.pi / t1, rel=1e-8)
        assert e.amplitude == pytest.approx(A_run, rel=1e-8)
        assert e.stable


@pytest.mark.parametrize("G, N", [(delayed(ct.tf([1.0], [1.0, 1.0]), 0.5), df.Relay(1.0)),
                                  (delayed(ct.tf([3.0], [1.0, 0.8, 1.5]), 1.3), df.Relay(1.0, hysteresis=0.05)),
                                  (delayed(ct.tf([6.0], [1.0, 2.0, 1.5]), 1.3), df.Relay(1.0, 0.05, 0.1))])
def test_multipliers_equal_those_of_a_finite_difference_return_map(G, N):
    # the exact tangent (saltation of the delayed switches included) against central differences of the
    # event-located return map, on orbits with several pending switches in the delay line
    checked = 0
    for c in df.predict_limit_cycles(G, N, omega=(0.1, 20.0))[:3]:
        e = df.exact_cycle(G, N, c)
        if not e.success:
            continue
        checked += 1
        ex = e.extra
        loop = loop_model(G, N, e.amplitude, e.frequency)
        q0 = [list(q) for q in ex["queue0"]]
        v0 = np.concatenate([ex["s0"], [q[0] for q in q0]])
        n = loop.n

        def F(v):
            out = return_map(loop, v[:n], ex["mode0"], ex["u0"], [[t, q[1]] for t, q in zip(v[n:], q0)],
                             ex["section"], horizon=100.0, tangent=False)
            return np.concatenate([out[0], [q[0] for q in out[2]]])

        J = np.zeros((v0.size, v0.size))
        for k in range(v0.size - 1):          # the last pending switch is the section's own: fixed at T
            h = 1e-6 * max(1.0, abs(v0[k]))
            d = np.zeros(v0.size)
            d[k] = h
            J[:, k] = (F(v0 + d) - F(v0 - d)) / (2 * h)
        mu_fd = np.linalg.eigvals(J)
        mu_fd = np.sort_complex(mu_fd[np.abs(mu_fd) > 1e-6])
        mu = e.multipliers[np.abs(e.multipliers - 1.0) > 1e-12]   # without the trivial one added
        mu = np.sort_complex(mu[np.abs(mu) > 1e-6])
        assert mu.size == mu_fd.size
        np.testing.assert_allclose(mu, mu_fd, atol=1e-6 * max(1.0, np.abs(mu).max(initial=0.0)))
    assert checked >= 2


def test_confidence_carries_the_delay_in_every_harmonic():
    from dfloop.solve.confidence import cycle_confidence

    G0 = ct.tf([2.0], [1.0, 2.0, 1.0])
    N = df.Relay(1.0, hysteresis=0.05)
    a = cycle_confidence(delayed(G0, 0.8), N, 0.9, 1.7)
    # independent: the same plant as a callable G(jw) e^{-jwT}
    b = cycle_confidence(lambda w: 2.0 / ((1j * w) ** 2 + 2j * w + 1.0) * np.exp(-0.8j * w), N, 0.9, 1.7)
    np.testing.assert_allclose(a.harmonics, b.harmonics, rtol=1e-12, atol=1e-15)
    assert a.amplitude_error == pytest.approx(b.amplitude_error, rel=1e-6)
    assert a.frequency_error == pytest.approx(b.frequency_error, rel=1e-6)
