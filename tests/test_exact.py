"""exact_cycle against independent truths: closed-form relay cycles, event-located solve_ivp runs,
finite-difference monodromies."""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.optimize import brentq, fsolve

import dfloop as df
from dfloop.exact import exact_cycle


def _ss(G):
    s = ct.ss(G)
    return np.asarray(s.A, float), np.asarray(s.B, float)[:, 0], np.asarray(s.C, float)[0]


def _phi_gamma(A, B, t):
    """exp(A t) and int_0^t exp(A s) ds B (one block exponential)."""
    n = A.shape[0]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n], big[:n, n] = A, B
    E = expm(big * t)
    return E[:n, :n], E[:n, n]


def _relay_truth(G, M, on, off, T_guess):
    """Symmetric relay cycle from the closed-form periodic solution under the relay's own output.

    y = +M on [0, tau), 0 on [tau, T/2) (no zero phase when off = -on), then the mirror image; half-wave
    symmetry s(T/2) = -s(0) fixes s(0) for given (T, tau); the cycle has x(0) = on (switch on) and x(tau) = off.
    Returns (omega, amplitude of x's fundamental, tau).
    """
    A, B, C = _ss(G)
    n = A.shape[0]

    def s0_of(T, tau):
        P1, g1 = _phi_gamma(A, B, tau)
        P2, _ = _phi_gamma(A, B, T / 2 - tau)
        # s(T/2) = P2 (P1 s0 + g1 M) = -s0
        return np.linalg.solve(np.eye(n) + P2 @ P1, -P2 @ g1 * M), P1, g1

    if off == -on:   # full swing: tau = T/2, one unknown
        def g(T):
            return -C @ s0_of(T, T / 2)[0] - on
        grid = np.linspace(0.6 * T_guess, 1.6 * T_guess, 200)
        vals = [g(T) for T in grid]
        k = next(i for i in range(len(grid) - 1) if vals[i] * vals[i + 1] < 0)
        T = brentq(g, grid[k], grid[k + 1], xtol=1e-15, rtol=1e-15)
        tau = T / 2
    else:
        def F(u):
            T, tau = u
            s0, P1, g1 = s0_of(T, tau)
            return [-C @ s0 - on, -C @ (P1 @ s0 + g1 * M) - off]
        T, tau = fsolve(F, [T_guess, 0.3 * T_guess], xtol=1e-13)
        assert np.max(np.abs(F([T, tau]))) < 1e-13
    w = 2 * math.pi / T
    # fundamental of y (x ~ Im(X e^{jwt}) convention): Y1 = 2j (2M/T) (1 - e^{-jw tau}) / (jw); X1 = -G(jw) Y1
    Y1 = 2j * (2 * M / T) * (1 - np.exp(-1j * w * tau)) / (1j * w)
    G_jw = complex(ct.evalfr(G, 1j * w))
    return w, abs(G_jw * Y1), tau


RELAYS = {
    "ideal": (ct.tf([1], [1, 3, 2, 0]), df.Relay(M=1.0)),
    "hysteresis": (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.1)),
    "dead zone": (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, dead_zone=0.1)),
    "dead zone + hysteresis": (ct.tf([3], [1, 2, 3, 1]), df.Relay(M=1.5, dead_zone=0.2, hysteresis=0.1)),
    # relative degree 2 (x' bends at every switch): multiple-shooting nodes moved across a switch of a
    # hysteretic element must take the mode of the flow reaching them
    "hysteresis, plant with a zero": (ct.tf([1, 0.5], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.05)),
    # the harmonic-balance start lies on the switching surface x = 0 and leaves it
    "ideal, plant with a zero": (ct.tf([1, 0.5], [1, 4, 5, 2, 0]), df.Relay(M=1.0)),
}


@pytest.mark.parametrize("name", list(RELAYS))
def test_relay_cycles_match_the_closed_form_solution(name):
    G, N = RELAYS[name]
    c = df.predict_limit_cycles(G, N)[-1]           # the outer (stable) cycle
    e = exact_cycle(G, N, c)
    assert e.success, e
    w, amp, tau = _relay_truth(G, N.M, N.on_level, N.off_level, c.period)
    assert e.frequency == pytest.approx(w, rel=1e-9)
    assert e.amplitude == pytest.approx(amp, rel=1e-9)
    assert e.switching_times.size == (2 if N.off_level == -N.on_level else 4)
    assert e.stable
    assert e.amplitude_error == pytest.approx((c.amplitude - amp) / amp, rel=1e-6)


def test_ideal_relay_obeys_tsypkins_condition():
    """Hamel/Tsypkin: for the ideal relay, sum over odd k of Im G(jkw)/k = 0 fixes w."""
    G, N = RELAYS["ideal"]
    e = exact_cycle(G, N, df.predict_limit_cycles(G, N)[0])
    k = np.arange(1, 40001, 2)

    def tsypkin(w):
        return float(np.sum(np.imag(1 / ((1j * k * w) * (1j * k * w + 1) * (1j * k * w + 2))) / k))

    w_true = brentq(tsypkin, 1.0, 1.8, xtol=1e-15, rtol=1e-15)
    assert e.frequency == pytest.approx(w_true, rel=1e-9)
    # and the quoted truth
    assert e.amplitude == pytest.approx(0.22261, abs=5e-6) and e.frequency == pytest.approx(1.38059, abs=5e-6)


# ------------------------------------------------------------------- against an event-located solve_ivp run


def _simulate(G, kind, p, s0, e0, periods, T):
    """Long DOP853 run (rtol 1e-12) of the loop with saturation (p = limit) or the play operator (p = h),
    restarted at every switch located by solve_ivp's events. Returns (omega from the last upward zero
    crossings of x, amplitude of x's fundamental over the last period)."""
    A, B, C = _ss(G)
    n = A.shape[0]
    mode = [0]                       # saturation: -1, 0, +1 (saturated low, linear, high); play: 0 free, +-1 engaged

    def y_of(s, e):
        if kind == "saturation":
            return p * mode[0] if mode[0] else -C @ s
        return e

    def rhs(t, u):
        s, e = u[:n], u[n]
        ds = A @ s + B * y_of(s, e)
        return np.append(ds, 0.0 if (kind == "saturation" or mode[0] == 0) else -C @ ds)

    def event(fun, direction, target):
        fun.terminal, fun.direction, fun.target = True, direction, target
        return fun

    def events():
        x = lambda u: -C @ u[:n]                                   # noqa: E731
        if kind == "saturation":
            if mode[0] == 0:
                return [event(lambda t, u: x(u) - p, 1, 1), event(lambda t, u: x(u) + p, -1, -1)]
            return [event(lambda t, u: x(u) - mode[0] * p, -mode[0], 0)]
        if mode[0] == 0:
            return [event(lambda t, u: x(u) - u[n] - p / 2, 1, 1), event(lambda t, u: x(u) - u[n] + p / 2, -1, -1)]
        return [event(lambda t, u: -C @ (A @ u[:n] + B * u[n]), -mode[0], 0)]

    def up_cross(t, u):
        return -C @ u[:n]
    up_cross.direction = 1

    u = np.append(s0, e0)
    x0 = -C @ s0
    if kind == "saturation" and abs(x0) > p:
        mode[0] = int(np.sign(x0))
    t, t_end = 0.0, periods * T
    crossings, ts, xs = [], [], []
    for _ in range(100 * periods):
        evs = events()
        sol = solve_ivp(rhs, (t, t_end), u, method="DOP853", rtol=1e-12, atol=1e-14, events=evs + [up_cross],
                        dense_output=True)
        crossings += list(sol.t_events[-1])
        ts.append(t)
        xs.append(sol.sol)
        t, u = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            break
        hit = next(i for i in range(len(evs)) if sol.t_events[i].size)
        mode[0] = evs[hit].target
    crossings = np.array(crossings)
    period = (crossings[-1] - crossings[-6]) / 5
    w = 2 * math.pi / period
    t0 = crossings[-2]
    grid = t0 + np.arange(4096) * (period / 4096)       # periodic rule: spectral for the smooth x
    seg = np.searchsorted(ts, grid, side="right") - 1
    x = np.empty(grid.size)
    for k in np.unique(seg):
        x[seg == k] = -C @ xs[k](grid[seg == k])[:n]
    amp = abs(2j * np.mean(x * np.exp(-1j * w * grid)))
    return w, amp


def test_saturation_cycle_matches_a_long_event_located_simulation():
    G, N = ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)
    c = df.predict_limit_cycles(G, N)[0]
    e = exact_cycle(G, N, c)
    assert e.success and e.stable
    s0 = e.extra["plant_state"] * 1.02                       # start 2 % off the orbit: multiplier 0.21 per period
    w, amp = _simulate(G, "saturation", 1.0, s0, 0.0, 20, e.period)
    assert e.frequency == pytest.approx(w, rel=1e-8)
    assert e.amplitude == pytest.approx(amp, rel=1e-7)


def test_backlash_servo_outer_cycle_matches_simulation_and_inner_one_has_no_orbit():
    G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)    # models/backlash_servo.toml
    inner, outer = df.predict_limit_cycles(G, N)
    e = exact_cycle(G, N, outer)
    assert e.success and e.stable and e.largest_multiplier < 1
    z0 = e.extra["z0"]
    w, amp = _simulate(G, "play", 1.0, e.extra["plant_state"] * 1.001, z0[2], 40, e.period)
    assert e.frequency == pytest.approx(w, rel=1e-8)
    assert e.amplitude == pytest.approx(amp, rel=1e-7)
    # the DF's inner (unstable) cycle has no true orbit: every motion that engages the play grows to the
    # outer cycle (simulated from the predicted inner sinusoid); exact_cycle says so instead of inventing one
    miss = exact_cycle(G, N, inner)
    assert not miss.success and miss.amplitude is None and "Newton" in miss.message
    A, B, C = _ss(G)
    a_in, w_in = inner.amplitude * 1.02, inner.frequency     # plant state on the sinusoid x = a_in sin(w t), t = 0
    s_in = (np.linalg.solve(1j * w_in * np.eye(2) - A, B) * complex(N(a_in)) * a_in).imag
    w_in, amp_in = _simulate(G, "play", 1.0, s_in, -(inner.amplitude * 1.02) + 0.5, 25, outer.period)
    assert amp_in == pytest.approx(e.amplitude, rel=1e-3)


# ------------------------------------------------------------------------------------- Floquet multipliers


FLOQUET = {
    "relay with hysteresis": (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.1), -1),
    "saturation": (ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0), -1),
    "backlash": (ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(h=0.2), -1),
    "dead zone (unstable)": (ct.tf([12], [1, 3, 3, 1]), df.DeadZone(0.5), 0),
}


@pytest.mark.parametrize("name", list(FLOQUET))
def test_monodromy_matches_finite_differences(name):
    from dfloop.hybrid import loop_model

    G, N, pick = FLOQUET[name]
    c = df.predict_limit_cycles(G, N)[pick]
    e = exact_cycle(G, N, c)
    assert e.success
    loop = loop_model(G, N, e.amplitude, e.frequency)
    z0, mode = e.extra["z0"], e.extra["mode0"]
    M = loop.flow(z0, mode, e.period, monodromy=True).monodromy
    nx = loop.size - 1
    fd = np.empty((nx, nx))
    for j in range(nx):
        h = 1e-6 * max(1.0, abs(z0[j]))
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        fd[:, j] = (loop.flow(zp, mode, e.period).z[:nx] - loop.flow(zm, mode, e.period).z[:nx]) / (2 * h)
    np.testing.assert_allclose(M[:nx, :nx], fd, atol=1e-6 * np.abs(fd).max())
    mu_fd = np.sort(np.abs(np.linalg.eigvals(fd)))[::-1]
    np.testing.assert_allclose(np.sort(np.abs(e.multipliers))[::-1], mu_fd, atol=1e-5)
    assert np.min(np.abs(e.multipliers - 1)) < 1e-6        # the trivial multiplier of an autonomous orbit


def test_unstable_cycle_has_a_multiplier_outside_the_unit_circle_and_repels_at_that_rate():
    G, N = ct.tf([12], [1, 3, 3, 1]), df.DeadZone(0.5)
    c = df.predict_limit_cycles(G, N)[0]
    e = exact_cycle(G, N, c)
    assert e.success and not e.stable
    mu = e.largest_multiplier
    assert mu > 1.2
    # independent run (DOP853, no events): an offset along the unstable eigenvector grows by mu per period
    from dfloop.hybrid import loop_model
    loop = loop_model(G, N, e.amplitude, e.frequency)
    z0 = e.extra["plant_state"]
    lam, vecs = np.linalg.eig(loop.flow(e.extra["z0"], e.extra["mode0"], e.period, monodromy=True).monodromy[:3, :3])
    v = loop.basis @ np.real(vecs[:, np.argmax(np.abs(lam))])     # the flow's realisation -> python-control's
    A, B, C = _ss(G)

    def rhs(t, s):
        x = -C @ s
        return A @ s + B * (x - np.clip(x, -0.5, 0.5))

    def dist(k, eps):
        sol = solve_ivp(rhs, (0, k * e.period), z0 + eps * v, method="DOP853", rtol=1e-12, atol=1e-14)
        return np.linalg.norm(sol.y[:, -1] - z0)

    assert dist(3, 1e-7) / dist(2, 1e-7) == pytest.approx(mu, rel=2e-3)


# ------------------------------------------------------------------------------------- smooth and failures


def test_smooth_element_runs_on_dop853_and_says_so():
    G, N = ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0)
    e = exact_cycle(G, N, df.predict_limit_cycles(G, N)[0])
    assert e.success and e.stable and "DOP853" in e.method
    A, B, C = _ss(G)
    # a long plain run (multiplier 0.49: 25 periods shrink a 1 % offset below 1e-9)
    sol = solve_ivp(lambda t, s: A @ s + B * N.output(-C @ s), (0, 25 * e.period), e.extra["z0"][:3] * 1.01,
                    method="RK45", rtol=1e-11, atol=1e-13, dense_output=True)
    t = 24 * e.period + np.arange(2048) * (e.period / 2048)
    x = -C @ sol.sol(t)
    amp = abs(2j * np.mean(x * np.exp(-1j * e.frequency * t)))
    assert e.amplitude == pytest.approx(amp, rel=1e-6)


def test_bad_input_and_missing_models_raise_clear_errors():
    G, N = ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)
    with pytest.raises(ValueError, match="strictly proper"):
        exact_cycle(ct.tf([1, 0], [1, 1]), N, (1.0, 1.0))
    with pytest.raises(ValueError, match="cycle"):
        exact_cycle(G, N, None)
    with pytest.raises(ValueError, match="one LimitCycle"):
        exact_cycle(G, N, df.predict_limit_cycles(G, N) * 2)
    with pytest.raises(ValueError, match="cycle amplitude"):
        exact_cycle(G, N, (-1.0, 1.0))
    with pytest.raises(ValueError, match="^N: "):
        exact_cycle(G, df.NumericDF(lambda x: np.tanh(x) if False else x, hysteretic=True), (1.0, 1.0))


def test_repr_reports_errors_and_stability():
    G, N = RELAYS["ideal"]
    e = exact_cycle(G, N, df.predict_limit_cycles(G, N)[0])
    text = repr(e)
    assert "stable" in text and "DF error" in text and "exact" in text


def test_discontinuous_static_elements_map_to_the_exact_engine():
    """A quantizer whose cycle stays below 1.5 steps is a dead-zone relay (M = step, d = step/2); a preloaded
    spring k x + F0 sign(x) around G is an ideal relay of level F0 around G / (1 + k G). Both are checked against
    the closed-form relay solution."""
    G = ct.tf([7.5], [1, 3, 3, 1])
    N = df.Quantizer(0.5)
    c = df.predict_limit_cycles(G, N, amplitude=(0.26, 5.0))[1]        # the small stable cycle
    e = exact_cycle(G, N, c)
    assert e.success and "exact" in e.method and np.max(np.abs(e.x)) < 0.75
    w, amp, _ = _relay_truth(G, 0.5, 0.25, 0.25, e.period)
    assert e.frequency == pytest.approx(w, rel=1e-9) and e.amplitude == pytest.approx(amp, rel=1e-9)

    G = ct.tf([1], [0.1, 1.1, 1, 0])
    N = df.PreloadedSpring(0.3, k=1.0)
    e = exact_cycle(G, N, df.predict_limit_cycles(G, N)[0])
    assert e.success and "exact" in e.method
    w, amp, _ = _relay_truth(ct.feedback(G, 1.0), 0.3, 0.0, 0.0, e.period)
    assert e.frequency == pytest.approx(w, rel=1e-9) and e.amplitude == pytest.approx(amp, rel=1e-9)


# ---------------------------------------------------------------------------------- user-defined time model


def test_a_user_element_with_its_own_time_model_runs_on_the_exact_engine():
    """An element defined outside dfloop by its DF and a hand-built two-mode time model (an ideal relay M sign x)
    gets the closed-form relay cycle from exact_cycle, and its confidence from the model's response."""
    from dfloop.solve.confidence import cycle_confidence
    from dfloop.describing.base import DescribingFunction
    from dfloop.describing.time_model import Guard, Mode, PiecewiseAffine

    class UserRelay(DescribingFunction):
        def __init__(self, M):
            self.M = M

        def _evaluate(self, A, omega):
            with np.errstate(divide="ignore"):
                return 4.0 * self.M / (np.pi * A) + 0j

        def time_model(self, amplitude):
            M = self.M
            modes = [Mode(g1=-M, guards=(Guard(cx=-1.0, target=1),), label="-M"),   # x <= 0 until x crosses 0
                     Mode(g1=M, guards=(Guard(cx=1.0, target=0),), label="+M")]

            def initial(history, xdot):
                return (1 if history[-1] > 0 or (history[-1] == 0 and xdot > 0) else 0), 0.0

            return PiecewiseAffine("UserRelay", modes, 0, initial, lambda x: M * np.sign(x))

    G = RELAYS["ideal"][0]
    N = UserRelay(1.0)
    c = df.predict_limit_cycles(G, N)[0]
    e = exact_cycle(G, N, c)
    assert e.success and "exact" in e.method
    w, amp, _ = _relay_truth(G, 1.0, 0.0, 0.0, e.period)
    assert e.frequency == pytest.approx(w, rel=1e-9) and e.amplitude == pytest.approx(amp, rel=1e-9)
    mine = cycle_confidence(G, N, c.amplitude, c.frequency)
    theirs = cycle_confidence(G, df.Relay(1.0), c.amplitude, c.frequency)
    # sign(0) = 0 on the one sample at x = 0, where dfloop's relay holds its output: 1 of 2048 samples differs
    assert mine.available and mine.distortion == pytest.approx(theirs.distortion, rel=1e-3)


def test_smooth_orbit_harmonics_and_multiplier_against_an_independent_run():
    """Cubic stiffness (DOP853 path, nodes integrated together, period joined from the node flows): the harmonics
    against an FFT of a plain solve_ivp run settled on the orbit, the non-trivial multiplier against the decay
    of an offset along its eigenvector in that run."""
    G, N = ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0)
    e = exact_cycle(G, N, df.predict_limit_cycles(G, N)[0])
    assert e.success and 1 <= e.iterations and e.residual <= 1e-11
    A, B, C = _ss(G)

    def rhs(t, s):
        return A @ s + B * N.output(-C @ s)

    z0 = e.extra["z0"][:3]
    sol = solve_ivp(rhs, (0, 30 * e.period), z0 * 1.01, method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True)
    t = 29 * e.period + np.arange(2048) * (e.period / 2048)
    X = 2j * np.fft.fft(-C @ sol.sol(t))[1:16] / t.size
    X = X * np.exp(-1j * np.arange(1, 16) * np.angle(X[0]))
    np.testing.assert_allclose(X, e.harmonics, atol=1e-8 * e.amplitude)
    # the slow multiplier (0.485): an offset along its eigenvector shrinks by it per period
    mu = e.multipliers[np.argsort(np.abs(e.multipliers - 1))[1]]
    assert abs(mu.imag) < 1e-12 and 0.3 < mu.real < 0.7
    fd = np.empty((3, 3))
    for j in range(3):                       # finite-difference monodromy of the independent integrator
        h = 1e-6 * max(1.0, abs(z0[j]))
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        run = [solve_ivp(rhs, (0, e.period), z, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1] for z in (zp, zm)]
        fd[:, j] = (run[0] - run[1]) / (2 * h)
    lam = np.linalg.eigvals(fd)
    assert np.min(np.abs(lam - mu)) < 1e-6 and np.min(np.abs(lam - 1.0)) < 1e-6


@pytest.mark.parametrize("G,N", [(ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)),
                                 (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.1)),
                                 (ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0))], ids=["sat", "relay", "cubic"])
def test_settling_first_finds_the_same_stable_orbit(G, N):
    """settle_periods > 0: nodes on the motion settled from the prediction, period detected on it; the orbit is the
    one found from the predicted sinusoid itself."""
    c = df.predict_limit_cycles(G, N)[0]
    direct = exact_cycle(G, N, c, settle_periods=0)
    settled = exact_cycle(G, N, c, settle_periods=12.5)
    assert direct.success and settled.success and settled.stable
    assert settled.frequency == pytest.approx(direct.frequency, rel=1e-9)
    assert settled.amplitude == pytest.approx(direct.amplitude, rel=1e-9)
    np.testing.assert_allclose(np.abs(settled.multipliers), np.abs(direct.multipliers), atol=1e-7)
