"""The exact orbit of a loop with a constant input (exact_cycle / verify_cycle with r0 and load, dfloop.biased)
against Tsypkin's exact relay solution extended to asymmetric cycles, derived here, and long simulations.

Tsypkin extended. A relay loop's plant input is piecewise constant: levels u_j + load held for durations tau_j
(j = 0..k-1, period T = sum tau_j), the relay switching into level j when e = r0 - y passes the level e_j. With G in
partial fractions, G = sum_i r_i / (s - p_i) (distinct real poles), each mode x_i' = p_i x_i + u has the periodic
response, at the segment starts S_j,

    x_i(S_{j+1}) = e^{p tau_j} x_i(S_j) + u_j (e^{p tau_j} - 1) / p,
    x_i(0) = sum_j e^{p (T - S_{j+1})} u_j (e^{p tau_j} - 1) / p / (1 - e^{p T}),

and an integrator (p = 0) is periodic only when sum_j u_j tau_j = 0 (the element's mean output cancels the load:
the integrator limit, exactly), its x(0) = c an unknown. The k switching conditions y(S_j) = r0 - e_j (with the
zero-mean condition and c for an integrator) fix the durations; the mean of e is r0 - (1/T) int y.
"""
import math

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from dfloop import Relay, Saturation, exact_cycle, verify_cycle
from dfloop.biased import biased_cycles
from dfloop.describing.dual_input import DualInputDF
from dfloop.solve.bias import predict_biased_cycles


def _modes(G):
    """Distinct real poles and residues of a strictly proper G (scipy residue)."""
    from scipy.signal import residue

    num, den = (np.asarray(v, float).ravel() for v in ct.tfdata(G))
    r, p, k = residue(num, den)
    assert np.all(np.abs(p.imag) < 1e-12) and len(set(np.round(p.real, 9))) == p.size and k.size == 0
    return p.real, r.real


def _tsypkin(G, drive, levels, r0, guess):
    """Durations tau_j (and the mean of e) of the periodic relay orbit: ``drive`` u_j (plant input, load
    included), ``levels`` e_j at which the relay switches into segment j."""
    p, r = _modes(G)
    u = np.asarray(drive, float)
    integrator = bool(np.any(p == 0))

    def orbit(unknowns):
        tau = unknowns[:u.size]
        T = tau.sum()
        ends = np.cumsum(tau)
        y, integral = np.zeros(u.size), 0.0
        for pi, ri in zip(p, r):
            if pi == 0:
                x = unknowns[-1]
                for j in range(u.size):
                    y[j] += ri * x
                    integral += ri * (x * tau[j] + u[j] * tau[j] ** 2 / 2)
                    x += u[j] * tau[j]
                continue
            steps = np.expm1(pi * tau) / pi
            x = np.sum(np.exp(pi * (T - ends)) * u * steps) / -np.expm1(pi * T)
            for j in range(u.size):
                y[j] += ri * x
                integral += ri * ((x + u[j] / pi) * steps[j] - u[j] * tau[j] / pi)
                x = np.exp(pi * tau[j]) * x + u[j] * steps[j]
        return y, integral / T, T

    def equations(unknowns):
        y, _, _ = orbit(unknowns)
        eq = list(y - (r0 - np.asarray(levels, float)))
        if integrator:
            eq.append(float(np.dot(u, unknowns[:u.size])))
        return eq

    sol, info, status, message = fsolve(equations, guess, xtol=1e-13, full_output=True)
    if status != 1:    # stalled short of xtol (the integrator's state starts at a rough 0): polish from there
        sol = fsolve(equations, sol, xtol=1e-13)
    assert max(abs(v) for v in equations(sol)) < 1e-11
    y, y_mean, T = orbit(sol)
    return sol[:u.size], r0 - y_mean, T


def _durations(ex):
    """Durations between the exact orbit's switches (cyclic, sorted)."""
    s = np.sort(ex.switching_times)
    return np.sort(np.diff(np.append(s, s[0] + ex.period)))


def _guess(c, levels, integrator=False):
    """Durations of the predicted biased sinusoid between its crossings of the switching levels (the start of the
    closed form's Newton iteration: independent of the exact engine)."""
    B, A, T = c.bias, c.amplitude, c.period
    phases = []
    for level, rising in levels:
        s = math.asin((level - B) / A)
        phases.append((s if rising else math.pi - s) % (2 * math.pi))
    ph = np.array(phases)
    tau = np.diff(np.append(ph, ph[0] + 2 * math.pi)) % (2 * math.pi) * T / (2 * math.pi)
    return list(tau) + ([0.0] if integrator else [])


@pytest.mark.parametrize("G, r0, load", [(ct.tf([30.0], [1, 6, 11, 6]), 0.4, 0.0),       # no integrator
                                         (ct.tf([2.0], [1, 3, 2, 0]), 0.7, -0.3)])      # integrator and a load
def test_unequal_relay_against_tsypkin(G, r0, load):
    M1, M2 = 1.5, 0.6
    relay = DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0])
    (c,) = biased_cycles(G, relay, r0=r0, load=load, amplitude=(0.01, 50))
    ex = c.exact
    integrator = load != 0.0
    tau, e_mean, T = _tsypkin(G, [M1 + load, -M2 + load], [0.0, 0.0], r0,
                              _guess(c, [(0.0, True), (0.0, False)], integrator))
    assert ex.success and ex.stable
    assert ex.period == pytest.approx(T, rel=1e-10)
    assert ex.mean == pytest.approx(e_mean, abs=1e-10 * ex.amplitude)
    assert _durations(ex) == pytest.approx(np.sort(tau), rel=1e-9)
    if integrator:   # the integrator limit, exactly: the relay's mean output cancels the load
        assert (M1 + load) * tau[0] == pytest.approx((M2 - load) * tau[1], rel=1e-10)
    # the prediction's own bias equation holds, and the DF's errors are those the confidence estimates
    assert c.confidence.available and abs(c.bias - ex.mean) < 0.05 * ex.amplitude


def test_dead_zone_relay_stable_and_unstable_biased_orbits():
    """Relay with a dead zone and a reference around 22/((s+1)(s+2)(s+3)): the DF predicts an inner (unstable) and
    an outer (stable) biased cycle; the exact engine, started on each biased prediction, finds both orbits of the
    four-switch closed form, and the multipliers say which attracts. Long simulations agree: from just inside
    the inner orbit the motion comes to rest, from just outside it reaches the outer orbit."""
    G, M, d, r0 = ct.tf([22.0], [1, 6, 11, 6]), 1.0, 0.2, 0.15
    relay = Relay(M, dead_zone=d)
    cycles = biased_cycles(G, relay, r0=r0, amplitude=(0.201, 20))
    assert [c.stability for c in sorted(cycles, key=lambda c: c.amplitude)] == ["unstable", "stable"]
    levels = [(d, True), (d, False), (-d, False), (-d, True)]
    orbits = []
    for c in cycles:
        ex = c.exact
        tau, e_mean, T = _tsypkin(G, [M, 0.0, -M, 0.0], [x for x, _ in levels], r0, _guess(c, levels))
        assert ex.success and ex.stable == (c.stability == "stable")
        assert ex.period == pytest.approx(T, rel=1e-9)
        assert ex.mean == pytest.approx(e_mean, abs=1e-9 * ex.amplitude)
        assert _durations(ex) == pytest.approx(np.sort(tau), rel=1e-8)
        orbits.append(ex)
    inner, outer = sorted(orbits, key=lambda e: e.amplitude)
    assert inner.largest_multiplier > 1 > outer.largest_multiplier
    # long simulations (exact flow, 150 periods) from the inner orbit scaled by 0.9 and 1.1
    v = verify_cycle(G, relay, (inner.amplitude, inner.frequency), bias=inner.mean, r0=r0, perturbation=0.1,
                     periods=150)
    assert v.verdict == "unstable"
    assert "came to rest" in v.message.split(";")[0]
    assert v.outside.amplitude == pytest.approx(outer.amplitude, rel=1e-3)
    assert v.means[1] == pytest.approx(outer.mean, abs=2e-3 * outer.amplitude)


def test_hysteresis_relay_orbit_against_tsypkin_and_an_event_located_simulation():
    """Memory element: relay with hysteresis a and a reference around 30/((s+1)(s+2)(s+3))."""
    G, M, a, r0 = ct.tf([30.0], [1, 6, 11, 6]), 1.0, 0.1, 0.5
    (c,) = biased_cycles(G, Relay(M, hysteresis=a), r0=r0, amplitude=(0.11, 20))
    ex = c.exact
    levels = [(a, True), (-a, False)]
    tau, e_mean, T = _tsypkin(G, [M, -M], [a, -a], r0, _guess(c, levels))
    assert ex.success and ex.stable
    assert ex.period == pytest.approx(T, rel=1e-10)
    assert ex.mean == pytest.approx(e_mean, abs=1e-10 * ex.amplitude)
    # an independent event-located simulation (solve_ivp) from rest with the relay at +M settles on the orbit
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    x, u, durations = np.zeros(A.shape[0]), M, []
    for _ in range(40):
        level = r0 - (-a if u == M else a)   # switch down when e falls to -a: y rises to r0 + a

        def ev(t, z, level=level):
            return C @ z - level

        ev.terminal, ev.direction = True, 1 if u == M else -1
        sol = solve_ivp(lambda t, z: A @ z + B * u, (0, 100), x, events=ev, rtol=1e-12, atol=1e-14)
        durations.append(sol.t_events[0][0])
        x, u = sol.y_events[0][0], -u
    assert sorted(durations[-2:]) == pytest.approx(np.sort(tau), rel=1e-7)


def test_constant_input_zero_is_the_symmetric_orbit_and_verify_reports_means():
    G, N = ct.tf([10.0], [1, 3, 3, 1]), Saturation(1.0)
    (c,) = predict_biased_cycles(G, N, amplitude=(0.05, 30))
    sym = exact_cycle(G, N, (c.amplitude, c.frequency))
    biased = exact_cycle(G, N, c)     # a BiasedCycle with bias 0 and no constant input
    assert biased.amplitude == pytest.approx(sym.amplitude, rel=1e-12)
    assert biased.frequency == pytest.approx(sym.frequency, rel=1e-12)
    assert abs(biased.mean) < 1e-12 * biased.amplitude
    (c,) = biased_cycles(G, N, r0=0.5, amplitude=(0.05, 30))
    v = verify_cycle(G, N, c, r0=0.5, periods=60)
    assert v.verdict == "stable"
    assert all(m == pytest.approx(c.exact.mean, abs=1e-3) for m in v.means)
    with pytest.raises(ValueError, match="r0"):
        exact_cycle(G, N, c, r0=math.nan)


def test_confidence_estimates_the_errors_of_biased_cycles():
    """On low-distortion biased cycles (saturation with a reference; the outer cycle of a dead-zone relay with a
    reference) the estimated errors of A, w and the bias lie within a factor 2 of the true ones (exact orbit's)."""
    checked = 0
    for G, element, r0 in ((ct.tf([10.0], [1, 3, 3, 1]), Saturation(1.0), 0.5),
                           (ct.tf([3.5], [1, 3, 3, 1]), Relay(1.0, dead_zone=0.2), 0.15)):
        for c in biased_cycles(G, element, r0=r0, amplitude=(0.201, 30)):
            ex, conf = c.exact, c.confidence
            if not conf.reliable:
                continue
            true = {"A": (c.amplitude - ex.amplitude) / ex.amplitude, "w": (c.frequency - ex.frequency) / ex.frequency,
                    "bias": c.bias - ex.mean}
            est = {"A": conf.amplitude_error, "w": conf.frequency_error, "bias": conf.bias_error}
            for k in true:
                assert abs(true[k]) <= 2 * abs(est[k]) and abs(est[k]) <= 2 * abs(true[k]), (k, true[k], est[k])
            checked += 1
    assert checked == 3   # the saturation's cycle, both dead-zone cycles (distortion 1.0 % and 4.7 %)


class AsymmetricHysteresisRelay:
    """A user's element known only by its time model: +M1 after e rises through a1, -M2 after e falls through -a2
    (two modes; no dfloop class has these unequal levels and thresholds)."""

    def __new__(cls, M1, M2, a1, a2):
        from dfloop.describing.base import DescribingFunction
        from dfloop.describing.time_model import Guard, Mode, PiecewiseAffine

        class _Relay(DescribingFunction):
            def _evaluate(self, A, omega):
                dual = DualInputDF(self)
                return dual.N_A(0.0, A)

            def time_model(self, amplitude):
                modes = [Mode(g1=-M2, guards=(Guard(cx=-1.0, c1=a1, target=1),), label="-M2"),
                         Mode(g1=M1, guards=(Guard(cx=1.0, c1=a2, target=0),), label="+M1")]

                def initial(history, xdot):
                    state = 0
                    for x in history:
                        state = 1 if x > a1 else 0 if x < -a2 else state
                    return state, 0.0

                def response(x):
                    state, out = initial(x, 0.0)[0], []
                    for v in x:
                        state = 1 if v > a1 else 0 if v < -a2 else state
                        out.append(M1 if state else -M2)
                    return np.array(out)

                return PiecewiseAffine("asymmetric hysteresis relay", modes, 0, initial, response)

        return _Relay()


def test_numeric_dual_input_df_of_a_hysteretic_element_against_quadrature():
    """The dual-input DF from the element's time model (switching phases, exact) against scipy quad of the output
    written out by hand, to 1e-12; then predict_biased_cycles and exact_cycle run on it, against Tsypkin."""
    from scipy.integrate import quad

    M1, M2, a1, a2 = 1.4, 0.8, 0.15, 0.05
    el = AsymmetricHysteresisRelay(M1, M2, a1, a2)
    dual = DualInputDF(el)
    assert dual.memory and dual.method == "switching phases of the time model"
    rng = np.random.default_rng(3)
    for B, A in zip(rng.uniform(-0.6, 0.6, 25), rng.uniform(0.3, 2.0, 25)):
        on = math.asin((a1 - B) / A)              # rising through a1
        off = math.pi - math.asin((-a2 - B) / A)  # falling through -a2

        pieces = ((-math.pi / 2, on, -M2), (on, off, M1), (off, 1.5 * math.pi, -M2))   # the output, by hand

        def integral(weight):
            return sum(level * quad(weight, lo, hi, epsabs=1e-14, epsrel=1e-12)[0] for lo, hi, level in pieces)

        m = integral(lambda t: 1.0) / (2 * math.pi)
        ns = integral(math.sin) / (math.pi * A)
        nc = integral(math.cos) / (math.pi * A)
        assert abs(float(dual.mean(B, A)) - m) < 1e-12
        assert abs(complex(dual.N_A(B, A)) - (ns + 1j * nc)) < 1e-12
    G, r0 = ct.tf([30.0], [1, 6, 11, 6]), 0.3
    (c,) = biased_cycles(G, dual, r0=r0, amplitude=(0.2, 5), n_amplitudes=40, n_bias=60)
    ex = c.exact
    tau, e_mean, T = _tsypkin(G, [M1, -M2], [a1, -a2], r0, _guess(c, [(a1, True), (-a2, False)]))
    assert ex.success and ex.stable and ex.period == pytest.approx(T, rel=1e-10)
    assert ex.mean == pytest.approx(e_mean, abs=1e-10 * ex.amplitude)


def test_operator_only_element_gets_a_sampled_dual_input_df_with_an_honest_error_estimate():
    """An element known only as a stateful operator (a hysteresis relay written as a Python class): its dual-input
    DF from its sampled periodic response, within twice the stated error estimate of the relay's closed form."""
    from dfloop import NumericDF

    class Op:
        def __init__(self):
            self.s = -1.0

        def __call__(self, x):
            self.s = 1.0 if x > 0.1 else -1.0 if x < -0.1 else self.s
            return self.s

    dual = DualInputDF(NumericDF(Op(), hysteretic=True))
    exact = DualInputDF(Relay(1.0, hysteresis=0.1))
    assert dual.method.startswith("sampled operator")
    B, A = np.array([0.3, -0.5, 0.1, 0.0]), np.array([0.5, 1.0, 2.0, 0.7])
    err = np.maximum(np.abs(dual.mean(B, A) - exact.mean(B, A)), np.abs(dual.N_A(B, A) - exact.N_A(B, A)))
    estimate = dual.error_estimate(B, A)
    assert np.all(err <= 2 * estimate) and np.all(err < 1e-3)   # measured: 1e-4 .. 6e-4
