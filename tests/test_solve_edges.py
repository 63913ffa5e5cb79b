"""The edges of predict_limit_cycles (issue 17): aliasing of sampled plants, quantizer ripple roots and default
windows, default windows from each element's limits, the residual bound on every returned cycle, and the label of
Loeb-stable cycles of open-loop unstable plants. Truths: closed-form phases, the independent 1-D reference of
tests/df_reference.py, dense scans of N, closed-loop simulation."""
import warnings

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.solve import grid
from dfloop.solve.plant import as_plant
from dfloop.solve.predict import LOEB_ONLY
from dfloop.verify import verify_cycle

import df_reference as ref
import fuzz_loops as fl


# ----------------------------------------------------------------------------------------- 1. aliasing


@pytest.mark.parametrize("window", [(5e3, 5e4), (1e4, 1e5)])
def test_sampled_bound_holds_for_a_delay_on_wide_windows(window):
    """Every interval's bound covers the exact phase change of e^{-jw}/(jw + 1) (w T + atan w). The midpoint and
    golden-section check alone let intervals of 34 turns pass on these windows."""
    p = as_plant(lambda w: np.exp(-1j * w) / (1j * w + 1))
    nodes, _, eps, _, bad = grid.resolve_plant(p, np.linspace(*np.log(window), 256))
    w = np.exp(nodes)
    turn = np.diff(w) + np.diff(np.arctan(w))  # both increasing: the exact change of arg G on each interval
    assert np.all(turn <= eps * (1 + 1e-9))
    assert bad.shape == (0, 2)


def test_discontinuous_callable_is_reported_uncertified():
    """A callable whose sign flips at w = 3 cannot be certified there: the report names the interval."""
    g = lambda w: np.where(w < 3.0, 1.0, -1.0) * 5 / (1j * w + 1) ** 3  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cyc = df.predict_limit_cycles(g, df.Saturation(1.0), omega=(0.1, 10.0))
    un = cyc.grid_report.uncertified
    assert len(un) >= 1 and any(lo <= 3.0 <= hi and hi / lo - 1 < 1e-9 for lo, hi in un)
    assert "not certified" in str(cyc.grid_report)


# --------------------------------------------------------------------------------------- 3. quantizer


def _reference(G, N, kind, omega, amplitude):
    poles = np.roots(G.den[0][0]) if hasattr(G, "den") else []
    r = fl.reference_roots(G, poles, [], 0.0, N, kind, omega, amplitude)
    return [x for x in r if omega[0] < x[1] < omega[1]]


def test_quantizer_default_window_does_not_raise_and_finds_the_root():
    G = ct.tf([10], [1, 3, 3, 1])
    cyc = df.predict_limit_cycles(G, df.Quantizer(0.1))
    want = _reference(G, df.Quantizer(0.1), "quantizer", cyc.omega_window, None)
    misses, extras = ref.match(want, [(c.amplitude, c.frequency) for c in cyc])
    assert len(want) >= 1 and not misses and not extras


@pytest.mark.parametrize("level, amplitude", [(0.98, None), (0.98, (0.06, 3.0)), (0.995, (0.06, 3.0)),
                                              (1.01, (0.06, 3.0))])
def test_quantizer_ripple_roots_all_found(level, amplitude):
    """G = K/(s + 1)^3 with |G| = 1/level at the phase crossover: N(A) = level holds on every ripple of the
    quantizer's N until the ripple is smaller than |level - 1| (up to 32 roots); each is found, none extra."""
    G, N = ct.tf([8 / level], [1, 3, 3, 1]), df.Quantizer(0.1)
    cyc = df.predict_limit_cycles(G, N, amplitude=amplitude)
    want = _reference(G, N, "quantizer", cyc.omega_window, amplitude)
    misses, extras = ref.match(want, [(c.amplitude, c.frequency) for c in cyc])
    assert len(want) >= 10 and not misses and not extras


# ---------------------------------------------------------------------------------- 5. default windows


@pytest.mark.parametrize("N, A_inf", [(df.Backlash(h=0.3, k=2.0), 2.0), (df.DeadZone(0.2, k=1.5), 1.5),
                                      (df.Quantizer(0.25), 1.0), (df.Saturation(0.5, k=2.0), 0.0),
                                      (df.Relay(2.0, hysteresis=0.1), 0.0), (df.PreloadedSpring(0.3, 2.0), 2.0),
                                      (df.CoulombViscousFriction(0.4, 0.7), 0.7)])
def test_tail_bounds_hold_on_dense_scans(N, A_inf):
    """|N(A) - N(inf)| <= tail_bound(A) on a dense scan with every edge and threshold (the default window's
    argument rests on it)."""
    lo = float(N.amplitude_domain()[0])
    base = max(lo, 0.01)
    A = np.concatenate([np.geomspace(base * (1 + 1e-12), base * 1e4, 20000), base * (1 + np.geomspace(1e-12, 1, 2000))])
    if isinstance(N, df.Quantizer):
        c = (np.arange(1, 400) - 0.5) * N.step
        A = np.concatenate([A[A < 300 * N.step], c * (1 + 1e-12), c * (1 - 1e-12)])
    A = A[A > lo]
    assert complex(N(np.inf)) == pytest.approx(A_inf)
    assert np.all(np.abs(N(A) - A_inf) <= N.tail_bound(A))


def test_cubic_head_bound_is_the_closed_form():
    N = df.CubicStiffness(2.0, 0.3)
    A = np.geomspace(1e-6, 10, 1000)
    assert np.all(np.abs(N(A) - 2.0) <= N.head_bound(A))


@pytest.mark.parametrize("gain", [0.9, 0.97])
def test_mass_backlash_default_window_holds_every_root(gain):
    """192 gain/(s + 1)^6 is real positive at w = sqrt(3), where the rigid-mass limit N(inf) = -1/w^2 nearly
    closes the loop: a root at a large force (0.38, 1.46) besides the one near the play. A slow pole-zero pair at
    1e-4 rad/s stretches the default omega window down to 1e-6, where the play's edge h/2 m w^2 is 5e-15 N:
    the window must still reach the large root (it stopped at 1e8 times the smallest edge before)."""
    N = df.MassBacklash(0.5, 0.5, h=0.01)
    num, den = np.poly([-1e-4]) * 192 * gain, np.polymul(np.poly([-1] * 6), np.poly([-1.0001e-4]))
    G = ct.tf(num, den)
    cyc = df.predict_limit_cycles(G, N)
    assert cyc.omega_window[0] < 1e-5
    want = fl.reference_roots(G, np.roots(den), np.roots(num), 0.0, N, "mass_backlash", cyc.omega_window, None)
    want = [x for x in want if cyc.omega_window[0] < x[1] < cyc.omega_window[1]]
    misses, extras = ref.match(want, [(c.amplitude, c.frequency) for c in cyc])
    assert len(want) == 2 and max(F for F, _ in want) > 0.3 and not misses and not extras


# -------------------------------------------------------------------------------------- 4. residual bound


@pytest.mark.parametrize("seed", range(8))
def test_every_returned_cycle_satisfies_its_residual_bound(seed):
    """Mass + backlash loops around lightly damped plants (dead band where N = 0, steep edges): every returned
    cycle has |1 + G N| within the residual bound, evaluated here independently with python-control."""
    rng = np.random.default_rng(100 + seed)
    zeta, wn = 10 ** rng.uniform(-6, -1), 10 ** rng.uniform(-0.5, 0.5)
    G = ct.tf([10 ** rng.uniform(-1, 2)], [1, 2 * zeta * wn, wn ** 2])
    N = df.MassBacklash(1.0, 1.0, h=10 ** rng.uniform(-2, 0))
    cyc = df.predict_limit_cycles(G, N)
    for c in cyc:
        g = complex(G(1j * c.frequency))
        n = complex(N(c.amplitude, c.frequency))
        # the floor where R turns faster than ln w can be represented: |dR/d ln w| times 32 roundings of ln w
        floor = 32 * abs(g * n) * (2 / zeta) * np.spacing(abs(np.log(c.frequency))) + 1e-9
        assert abs(1 + g * n) <= max(1e-10 * (1 + abs(g * n)), floor)
        assert c.residual == pytest.approx(abs(1 + g * n), rel=1e-3, abs=1e-12)


# ---------------------------------------------------------------------------- 7. open-loop unstable poles


def test_loeb_stable_cycle_of_unstable_plant_is_labelled_and_diverges_in_simulation():
    """Relay with hysteresis around 0.36/((s - 0.175)(s + 2.07)): the Loeb criterion says stable, the closed
    loop leaves the cycle (simulation); the label says the criterion alone cannot decide."""
    G = ct.tf([0.3600465426331211], np.poly([0.1746511169559748, -2.0669937908044296]))
    N = df.Relay(1.0, hysteresis=0.1)
    cyc = df.predict_limit_cycles(G, N)
    loeb = [c for c in cyc if c.loeb_determinant > 0]
    assert len(loeb) == 1 and loeb[0].stability == LOEB_ONLY and not loeb[0].stable
    assert verify_cycle(G, N, loeb[0], periods=30).verdict == "unstable"


def test_exact_multipliers_decide_the_label_of_an_unstable_plant():
    """Saturation around 5/((s - 0.2)(s + 1)^3): with exact=True the Floquet multipliers decide (stable), and a
    closed-loop simulation agrees; without, the label is 'loeb-stable only'."""
    G = ct.tf([5], np.polymul([1, -0.2], [1, 3, 3, 1]))
    N = df.Saturation(1.0)
    assert [c.stability for c in df.predict_limit_cycles(G, N)] == [LOEB_ONLY]
    cyc = df.predict_limit_cycles(G, N, exact=True)
    assert [c.stability for c in cyc] == ["stable"]
    assert verify_cycle(G, N, cyc[0], periods=30).verdict == "stable"


def test_stable_plants_keep_loeb_labels():
    cyc = df.predict_limit_cycles(ct.tf([10], [1, 3, 3, 1]), df.Saturation(1.0))
    assert [c.stability for c in cyc] == ["stable"]
