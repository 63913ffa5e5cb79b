"""predict_limit_cycles: completeness and accuracy against closed forms, brute-force references and
python-control's own describing-function test problems."""
import warnings

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq

import dfloop as df
from dfloop.solve import as_plant
from dfloop.describing.base import DescribingFunction

H_SIMPLE = ct.tf([1], [1, 2, 2, 1])
H_LARGER = H_SIMPLE * 8
H_MULTIPLE = H_SIMPLE * ct.tf(*ct.pade(5, 4)) * 4


def _assert_residuals(cycles, G, N):
    g = as_plant(G)
    for c in cycles:
        n = N(c.amplitude, c.frequency) if N.frequency_dependent else N(c.amplitude)
        r = abs(1 + g(np.array([c.frequency]))[0] * n)
        assert r <= 1e-10 * (1 + abs(g(np.array([c.frequency]))[0] * n))
        assert r == pytest.approx(c.residual, abs=1e-12)
        assert np.isfinite([c.amplitude, c.frequency, c.loeb_determinant, c.residual]).all()


def test_python_control_no_intersection():
    cycles = df.predict_limit_cycles(H_SIMPLE, df.Saturation(1.0), amplitude=(1, 4), omega=(0.1, 100))
    ref = ct.describing_function_response(H_SIMPLE, ct.saturation_nonlinearity(1), np.linspace(1, 4, 10),
                                          np.logspace(-1, 2, 100))
    assert len(ref.intersections) == 0 and len(cycles) == 0


def test_python_control_one_intersection_matches_and_is_exact():
    cycles = df.predict_limit_cycles(H_LARGER, df.Saturation(1.0), amplitude=(1, 4), omega=(0.1, 100))
    ref = ct.describing_function_response(H_LARGER, ct.saturation_nonlinearity(1), np.linspace(1, 4, 10),
                                          np.logspace(-1, 2, 100))
    assert len(cycles) == len(ref.intersections) == 1
    a, w = ref.intersections[0]
    assert cycles[0].amplitude == pytest.approx(a, rel=1e-4)
    assert cycles[0].frequency == pytest.approx(w, rel=1e-4)
    # closed form: phase crossover of 8/(s^3+2s^2+2s+1) at w = sqrt(2), G = -8/3, so N_sat(A) = 3/8
    assert cycles[0].frequency == pytest.approx(np.sqrt(2), rel=1e-12)
    assert df.Saturation(1.0)(cycles[0].amplitude).real == pytest.approx(3 / 8, rel=1e-10)
    assert cycles[0].stability == "stable"
    _assert_residuals(cycles, H_LARGER, df.Saturation(1.0))


def test_python_control_docstring_example_default_windows():
    cycles = df.predict_limit_cycles(H_LARGER, df.Saturation(1.0))
    assert len(cycles) == 1
    assert cycles[0].amplitude == pytest.approx(3.343844998258643, rel=1e-4)  # their refinement is ~1e-5
    assert cycles[0].frequency == pytest.approx(1.4142293090899216, rel=1e-4)
    assert cycles.window_source["omega"].startswith("default")
    assert cycles.window_source["amplitude"].startswith("default")
    lo, hi = cycles.amplitude_window
    assert lo < cycles[0].amplitude < hi


def test_python_control_multiple_intersections_backlash():
    N = df.Backlash(h=1.0)
    cycles = df.predict_limit_cycles(H_MULTIPLE, N, amplitude=(0.6, 5), omega=(0.1, 1000))
    ref = ct.describing_function_response(H_MULTIPLE, ct.friction_backlash_nonlinearity(1),
                                          np.linspace(0.6, 5, 50), np.logspace(-1, 3, 50))
    ref = sorted(ref.intersections, key=lambda x: x[1])
    assert len(cycles) == len(ref) == 2
    for c, (a, w) in zip(cycles, ref):
        assert c.amplitude == pytest.approx(a, rel=1e-5)
        assert c.frequency == pytest.approx(w, rel=1e-5)
    assert [c.stability for c in cycles] == ["unstable", "unstable"]
    _assert_residuals(cycles, H_MULTIPLE, N)


class _ScaledSaturation(ct.DescribingFunctionNonlinearity):
    """python-control's saturation with its output scaled by k (same loop as G*k -> G, N/k)."""

    def __init__(self, k):
        super().__init__()
        self.k = k

    def __call__(self, x):
        return self.k * np.clip(x, -1, 1)

    def describing_function(self, A):
        return self.k * ct.saturation_nonlinearity(1).describing_function(A)


def test_scaling_invariance_where_python_control_loses_the_cycle():
    amp, omega = np.linspace(1, 4, 50), np.logspace(-1, 2, 200)
    assert len(ct.describing_function_response(H_LARGER, _ScaledSaturation(1.0), amp, omega).intersections) == 1
    base = df.predict_limit_cycles(H_LARGER, df.Saturation(1.0), amplitude=(1, 4), omega=(0.1, 100))
    lost = ct.describing_function_response(H_LARGER * 1e-3, _ScaledSaturation(1e3), amp, omega)
    assert len(lost.intersections) == 0  # python-control's absolute 1e-8 cutoff drops it
    for k in (1e-3, 1e3, 1e-9):
        scaled = df.predict_limit_cycles(H_LARGER * k, df.Saturation(1.0, k=1 / k), amplitude=(1, 4),
                                         omega=(0.1, 100))
        assert len(scaled) == 1
        assert scaled[0].amplitude == pytest.approx(base[0].amplitude, rel=1e-9)
        assert scaled[0].frequency == pytest.approx(base[0].frequency, rel=1e-9)
        assert scaled[0].stability == base[0].stability


def test_delay_gives_dozens_of_roots_all_found():
    T = 1.0
    G = lambda w: np.exp(-1j * w * T) / (1j * w + 1)  # noqa: E731
    N = df.Relay(M=1.0)
    cycles = df.predict_limit_cycles(G, N, omega=(0.1, 300))
    # ideal relay: N real > 0, so roots where arg G = -(2m+1) pi: w T + atan(w) = (2m+1) pi
    f = lambda w, m: w * T + np.arctan(w) - (2 * m + 1) * np.pi  # noqa: E731
    ref = np.array([brentq(f, 0.1, 300, args=(m,), xtol=1e-14) for m in range(60) if f(0.1, m) < 0 < f(300, m)])
    assert ref.size >= 40
    assert len(cycles) == ref.size
    freqs = np.array([c.frequency for c in cycles])
    np.testing.assert_allclose(freqs, ref, rtol=1e-9)
    amps = np.array([c.amplitude for c in cycles])
    np.testing.assert_allclose(amps, 4 / (np.pi * np.hypot(1, ref)), rtol=1e-9)  # A = 4 M |G| / pi
    _assert_residuals(cycles, G, N)


def test_very_lightly_damped_resonance():
    zeta = 1e-4
    G = ct.tf([1], [1, 2 * zeta, 1, 0])  # 1 / (s (s^2 + 2 zeta s + 1)): real negative only at w = 1
    cycles = df.predict_limit_cycles(G, df.Relay(M=1.0))
    assert len(cycles) == 1
    assert cycles[0].frequency == pytest.approx(1.0, rel=1e-10)
    assert cycles[0].amplitude == pytest.approx(2 / (np.pi * zeta), rel=1e-8)  # 4 M |G| / pi, |G| = 1/(2 zeta)


def test_backlash_locus_from_infinity_with_integrator_matches_brute_force():
    G, N = ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(h=0.2)
    cycles = df.predict_limit_cycles(G, N, omega=(0.01, 100), amplitude=(0.1 * (1 + 1e-12), 100))
    # brute force: arg G(jw) = -pi/2 - 2 atan(w) is monotone, so for each A the only candidate frequency
    # is w(A) = tan(-(arg(-1/N(A)) + pi/2) / 2); roots are the zeros of |G(j w(A))| |N(A)| - 1 along A
    g = as_plant(G)

    def h(A):
        w = np.tan(-(np.angle(-1 / N(A)) + np.pi / 2) / 2)
        return abs(g(np.array([w]))[0] * N(A)) - 1

    As = 0.1 * (1 + np.logspace(-6, 3, 400))
    vals = np.array([h(A) for A in As])
    ref = [brentq(h, As[i], As[i + 1], xtol=1e-14) for i in np.flatnonzero(vals[:-1] * vals[1:] < 0)]
    assert len(ref) == 2
    np.testing.assert_allclose(sorted(c.amplitude for c in cycles), sorted(ref), rtol=1e-8)
    _assert_residuals(cycles, G, N)


def test_tangent_root_is_marginal_and_close_pair_is_split():
    N = df.Relay(M=1.0)
    touching = df.predict_limit_cycles(lambda w: -2 + 1j * (w - 1) ** 2, N, omega=(0.5, 2))
    assert len(touching) == 1 and touching[0].stability == "marginal"
    assert touching[0].amplitude == pytest.approx(8 / np.pi, rel=1e-9)  # 4 M |G| / pi
    assert touching[0].frequency == pytest.approx(1.0, abs=1e-4)
    eps = 1e-3
    pair = df.predict_limit_cycles(lambda w: -2 + 1j * ((w - 1) ** 2 - eps ** 2), N, omega=(0.5, 2))
    assert len(pair) == 2
    # |R| <= 1e-10 (1 + |GN|) = 2e-10 and |dR/dw| = 2 eps N = eps at the roots bound the position error
    np.testing.assert_allclose([c.frequency for c in pair], [1 - eps, 1 + eps], rtol=0, atol=2e-10 / eps)
    assert {c.stability for c in pair} == {"stable", "unstable"}


def test_root_on_window_edge_is_reported_with_warning():
    with pytest.warns(UserWarning, match="edge of the search window"):
        cycles = df.predict_limit_cycles(H_LARGER, df.Saturation(1.0), omega=(0.1, np.sqrt(2)))
    assert len(cycles) == 1 and cycles[0].on_edge
    assert cycles[0].frequency == pytest.approx(np.sqrt(2), rel=1e-12)


def test_roots_near_window_edge_inside_are_found_without_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cycles = df.predict_limit_cycles(H_LARGER, df.Saturation(1.0), omega=(0.1, np.sqrt(2) * (1 + 1e-7)))
    assert len(cycles) == 1 and not cycles[0].on_edge


def test_ss_and_frd_plants_agree_with_tf():
    base = df.predict_limit_cycles(H_MULTIPLE, df.Backlash(h=1.0), amplitude=(0.6, 5), omega=(0.1, 1000))
    ss = df.predict_limit_cycles(ct.ss(H_MULTIPLE), df.Backlash(h=1.0), amplitude=(0.6, 5), omega=(0.1, 1000))
    np.testing.assert_allclose([c.frequency for c in ss], [c.frequency for c in base], rtol=1e-9)
    frd = ct.frd(H_MULTIPLE, np.logspace(-1, 3, 2000))
    fr = df.predict_limit_cycles(frd, df.Backlash(h=1.0), amplitude=(0.6, 5))
    assert fr.window_source["omega"] == "default: the frd's grid"
    np.testing.assert_allclose([c.frequency for c in fr], [c.frequency for c in base], rtol=1e-5)
    np.testing.assert_allclose([c.amplitude for c in fr], [c.amplitude for c in base], rtol=1e-5)


class _DelayedSaturation(DescribingFunction):
    """Saturation followed by a pure delay tau: N(A, w) = N_sat(A) exp(-j w tau) (frequency dependent)."""

    frequency_dependent = True

    def __init__(self, tau):
        self.tau = tau
        self._sat = df.Saturation(1.0)

    def _evaluate(self, A, omega):
        return self._sat(A) * np.exp(-1j * omega * self.tau)


def test_frequency_dependent_dfs_match_equivalent_amplitude_only_loops():
    G = ct.tf([2], [1, 2, 2, 1])
    tau = 0.3
    fd = df.predict_limit_cycles(G, _DelayedSaturation(tau), omega=(0.1, 10), amplitude=(1, 50))
    eq = df.predict_limit_cycles(lambda w: as_plant(G)(w) * np.exp(-1j * w * tau), df.Saturation(1.0),
                                 omega=(0.1, 10), amplitude=(1, 50))
    assert len(fd) == len(eq) >= 1
    np.testing.assert_allclose([c.frequency for c in fd], [c.frequency for c in eq], rtol=1e-9)
    np.testing.assert_allclose([c.amplitude for c in fd], [c.amplitude for c in eq], rtol=1e-9)
    assert [c.stability for c in fd] == [c.stability for c in eq]
    # mass then backlash: with X = |G_m| F = F / (m w^2) it is backlash on the plant G G_m
    m, h = 2.0, 0.1
    Gp = ct.tf([1, 0.5], [1, 1])
    N = df.MassBacklash(m1=0.5, m2=1.5, h=h)  # N(F, w) = G_m(jw) N_bl(|G_m(jw)| F), G_m = 1/(m s^2)
    fd = df.predict_limit_cycles(Gp, N, omega=(0.05, 20), amplitude=(1e-4, 1e3))
    eq = df.predict_limit_cycles(Gp * ct.tf([1], [m, 0, 0]), df.Backlash(h=h), omega=(0.05, 20),
                                 amplitude=(h / 2 * (1 + 1e-12), 1e5))
    assert len(fd) == len(eq) >= 1
    w = np.array([c.frequency for c in fd])
    np.testing.assert_allclose(w, [c.frequency for c in eq], rtol=1e-8)
    np.testing.assert_allclose([c.amplitude for c in fd], [c.amplitude * m * wc ** 2 for c, wc in zip(eq, w)],
                               rtol=1e-8)
    _assert_residuals(fd, Gp, N)


def test_table_repr_and_result_fields():
    cycles = df.predict_limit_cycles(H_MULTIPLE, df.Backlash(h=1.0), amplitude=(0.6, 5), omega=(0.1, 1000))
    text = repr(cycles)
    assert "2 limit cycle(s)" in text and "omega window [0.1, 1000]" in text
    assert text.count("unstable") == 2 and "Loeb det" in text
    c = cycles[0]
    assert c.G == pytest.approx(as_plant(H_MULTIPLE)(np.array([c.frequency]))[0])
    assert c.G == pytest.approx(-1 / c.N, rel=1e-9)
    assert c.period == pytest.approx(2 * np.pi / c.frequency)
    assert [c.frequency for c in cycles] == sorted(c.frequency for c in cycles)


class _Polynomial(DescribingFunction):
    """N = 1 - z with z = (x + i y)^k - eps^k, x = ln(A/A0), y = ln(w/w0): with G = -1 the residual is
    z, holomorphic in x + i y, so its k roots x + i y = eps exp(2 pi i m / k) all have degree +1."""

    frequency_dependent = True

    def __init__(self, k, eps, A0=1.0, w0=1.0, invalid_above=np.inf):
        self.k, self.eps, self.A0, self.w0, self.invalid_above = k, eps, A0, w0, invalid_above

    def _evaluate(self, A, omega):
        z = (np.log(A / self.A0) + 1j * np.log(omega / self.w0)) ** self.k - self.eps ** self.k
        return 1 - z

    def validity(self, A, omega=None):
        return np.asarray(A) < self.invalid_above


@pytest.mark.parametrize("k", [2, 3])
def test_clustered_roots_of_equal_degree_in_one_cell_are_all_found(k):
    eps = 1e-3
    cycles = df.predict_limit_cycles(lambda w: -np.ones_like(w), _Polynomial(k, eps), omega=(0.5, 2),
                                     amplitude=(0.5, 2), grid=(5, 5))
    z = eps * np.exp(2j * np.pi * np.arange(k) / k)
    assert len(cycles) == k
    found = np.array([np.log(c.amplitude) + 1j * np.log(c.frequency) for c in cycles])
    # |R| <= 1e-10 (1 + |GN|) = 2e-10 with |dR/d(x + iy)| = k eps^(k-1) bounds the position error
    # each expected root has its own found root within the bound (matched by distance: sorting by angle is
    # ill-defined for roots on the negative real axis, where a rounding-level imaginary part flips +-pi)
    distance = np.abs(found[:, None] - z[None, :])
    assert sorted(np.argmin(distance, axis=0)) == list(range(k))
    assert np.max(np.min(distance, axis=0)) <= 2e-10 / (k * eps ** (k - 1))
    assert all(c.stability == "stable" for c in cycles)


def test_validity_of_N_is_reported_per_cycle():
    cycles = df.predict_limit_cycles(lambda w: -np.ones_like(w), _Polynomial(2, 0.1, invalid_above=1.0),
                                     omega=(0.5, 2), amplitude=(0.5, 2))
    assert len(cycles) == 2
    assert [c.valid for c in sorted(cycles, key=lambda c: c.amplitude)] == [True, False]
    assert "N not valid" in repr(cycles)
