"""predict_limit_cycles with describing functions that jump: a synthetic frequency-dependent N with a step
in w and N = 0 below an amplitude limit that grows with w (like the dynamic backlash's w_L), and the real
tabulated DynamicBacklash. Roots are compared with 1-D brute-force references, jump crossings with a
brute-force scan of the chord condition (the segment from R- to R+ passes through 0)."""
import math
import warnings

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq

import dfloop as df
from dfloop.solve import as_plant
from dfloop.describing.base import DescribingFunction
from dfloop.impact.dynamic_backlash import DynamicBacklash
from dfloop.solve import JumpCrossing

K, C_L, TH1, TH2 = 4.0, 0.3, 0.0, -0.6
G_SYN = ct.tf([K], [1, 2, 1, 0])  # K / (s (s + 1)^2)
OMEGA, AMPLITUDE = (0.2, 5.0), (0.03, 100.0)  # crossings where arg N turns fast (A < 0.03) need a finer grid


class SteppedDF(DescribingFunction):
    """N = exp(-j (theta(w) + 0.5 / A)) / A with theta = TH1 below w_j and TH2 above (a step in w), and
    N = 0 for A <= C_L w^2 (no output below an amplitude limit, a jump from 0 on the limit curve)."""

    frequency_dependent = True

    def __init__(self, w_j):
        self.w_j = w_j

    def _evaluate(self, A, omega):
        theta = np.where(omega < self.w_j, TH1, TH2)
        return np.where(A <= C_L * omega ** 2, 0.0, np.exp(-1j * (theta + 0.5 / A)) / A)


def _g(w):
    return as_plant(G_SYN)(np.atleast_1d(np.asarray(w, float)))


def _reference_roots(w_j):
    """Roots of each smooth piece: |G N| = 1 gives A = |G(jw)|, then the phase condition in w alone."""
    out = []
    for theta, lo, hi in ((TH1, OMEGA[0], w_j), (TH2, w_j, OMEGA[1])):
        def f(w, theta=theta):  # arg G N + pi at A = |G|, with arg G = -pi/2 - 2 atan(w)
            return -np.pi / 2 - 2 * np.arctan(w) - theta - 0.5 / abs(_g(w)[0]) + np.pi
        ws = np.linspace(lo, hi, 4001)[1:-1]
        fs = np.array([f(w) for w in ws])
        for i in np.flatnonzero(np.sign(fs[:-1]) != np.sign(fs[1:])):
            w = brentq(f, ws[i], ws[i + 1], xtol=1e-15, rtol=1e-15)
            A = abs(_g(w)[0])
            if A > C_L * w ** 2 and AMPLITUDE[0] < A < AMPLITUDE[1]:
                out.append((A, w))
    return sorted(out, key=lambda p: p[1])


def _chord_crossings(R_minus, R_plus, x):
    """Brute force: where the segment from R- to R+ passes through 0, along a 1-D scan x."""
    c = np.conj(R_minus) * R_plus
    idx = np.flatnonzero((np.sign(c.imag[:-1]) != np.sign(c.imag[1:])) & (c.real[:-1] < 0))
    return x[idx]


def _reference_crossings(w_j, N):
    """Jump crossings on the step w = w_j (scan in A) and on the limit curve A = C_L w^2 (scan in w)."""
    A = np.geomspace(*AMPLITUDE, 200_001)
    A = A[A > C_L * w_j ** 2 * (1 + 1e-9)]
    g = _g(w_j)[0]
    on_step = [(a, w_j) for a in _chord_crossings(1 + g * N(A, w_j * (1 - 1e-12)), 1 + g * N(A, w_j), A)]
    w = np.geomspace(*OMEGA, 200_001)
    a_l = C_L * w ** 2
    w, a_l = w[(a_l > AMPLITUDE[0]) & (a_l < AMPLITUDE[1])], a_l[(a_l > AMPLITUDE[0]) & (a_l < AMPLITUDE[1])]
    on_limit = [(C_L * x ** 2, x) for x in _chord_crossings(np.ones(w.size), 1 + _g(w) * N(a_l * (1 + 1e-12), w), w)]
    return sorted(on_step + on_limit, key=lambda p: p[1])


@pytest.mark.parametrize("w_j", [1.0, 0.8366])  # 0.8366: 2.4e-4 relative above the lower piece's root
def test_stepped_df_roots_on_both_sides_and_jump_crossings_reported(w_j):
    N = SteppedDF(w_j)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        cycles = df.predict_limit_cycles(G_SYN, N, omega=OMEGA, amplitude=AMPLITUDE)
    ref = _reference_roots(w_j)
    assert len(ref) == 2 and ref[0][1] < w_j < ref[1][1]       # one genuine root on each side of the step
    assert len(cycles) == len(ref)                               # both found, nothing invented at the jumps
    for c, (A, w) in zip(cycles, ref):
        assert c.amplitude == pytest.approx(A, rel=1e-8) and c.frequency == pytest.approx(w, rel=1e-9)
        g, n = _g(c.frequency)[0], N(c.amplitude, c.frequency)
        assert abs(1 + g * n) <= 1e-10 * (1 + abs(g * n))
        assert c.valid
    crossings = cycles.jump_crossings
    expected = _reference_crossings(w_j, N)
    assert len(expected) >= 2 and len(crossings) == len(expected)
    for j, (A, w) in zip(crossings, expected):
        assert isinstance(j, JumpCrossing)
        assert j.amplitude == pytest.approx(A, rel=1e-4) and j.frequency == pytest.approx(w, rel=1e-4)
        assert abs(j.winding) == 1 and j.N_sides[0] != j.N_sides[1]
    assert any("jump crossing" in str(r.message) for r in rec)
    assert "jump crossing" in repr(cycles)


def test_jump_crossing_alone_is_not_a_cycle():
    # G in the gap of the w_j step only: a window around the step that excludes both genuine roots
    N = SteppedDF(1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = df.predict_limit_cycles(G_SYN, N, omega=(0.9, 1.1), amplitude=(1.0, 3.0))
    assert len(cycles) == 0
    assert len(cycles.jump_crossings) == 1
    j = cycles.jump_crossings[0]
    assert j.frequency == pytest.approx(1.0, rel=1e-6)
    # the chord from R- to R+ at the reported amplitude passes (to the box resolution) through 0
    g = _g(1.0)[0]
    r_minus, r_plus = 1 + g * N(j.amplitude, 1.0 - 1e-9), 1 + g * N(j.amplitude, 1.0)
    assert abs(abs(np.angle(r_plus / r_minus)) - np.pi) < 1e-5


# ---------------------------------------------------------------- the real dynamic backlash
M1, M2, H, EPS = 1.0, 1.0, 0.1, 0.5


@pytest.fixture(scope="module")
def backlash():
    return DynamicBacklash(M1, M2, H, EPS, cache=False)


def _pd_through(nl, beta0, w0, tau):
    """PD with roll-off 1/(tau s + 1)^2 putting G(j w0) on -1/N(F0, w0), F0 = beta0 M2 h w0^2."""
    f0 = beta0 * M2 * H * w0 ** 2
    pd = complex(nl.negative_inverse(f0, w0)) * (1j * w0 * tau + 1) ** 2
    return ct.tf([pd.imag / w0, pd.real], [tau ** 2, 2 * tau, 1]), f0


def _check_against_table(cycles, G, nl):
    g = as_plant(G)
    for c in cycles:
        gn = g(np.array([c.frequency]))[0] * nl(c.amplitude, c.frequency)
        assert abs(1 + gn) <= 1e-10 * (1 + abs(gn))
        assert c.valid == bool(nl.validity(c.amplitude, c.frequency))
        assert (("average over irregular motion" in str(c)) == (not c.valid))


@pytest.mark.parametrize("beta0, valid", [(0.32, True), (0.85, False)])  # period-1 band / chaotic band
def test_dynamic_backlash_window_across_w_L(backlash, beta0, valid):
    w0 = 30.0
    G, f0 = _pd_through(backlash, beta0, w0, 1 / (3 * w0))
    omega = (20.0, 2 * math.sqrt(100.0 / (H * M2)))                # up to w_L of the largest force
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = df.predict_limit_cycles(G, backlash, omega=omega, amplitude=(10.0, 100.0))
    _check_against_table(cycles, G, backlash)
    design = [c for c in cycles if abs(c.amplitude / f0 - 1) < 1e-8 and abs(c.frequency / w0 - 1) < 1e-8]
    assert len(design) == 1 and design[0].valid is valid
    assert bool(backlash.validity(f0, w0)) is valid


def test_dynamic_backlash_gap_at_w_L_is_a_jump_crossing(backlash):
    # PD whose phase reaches arg(-1/N) just above the no-impact limit: G passes through the w_L gap
    G = ct.tf([30.0, 800.0], [1 / 300.0 ** 2, 2 / 300.0, 1])
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        cycles = df.predict_limit_cycles(G, backlash, omega=(20.0, 45.0), amplitude=(10.0, 50.0))
    _check_against_table(cycles, G, backlash)
    assert len(cycles.jump_crossings) == 1 and any("jump crossing" in str(r.message) for r in rec)
    j = cycles.jump_crossings[0]
    beta = j.amplitude / (M2 * H * j.frequency ** 2)
    assert 0.25 < beta < 0.25 * (1 + 1e-2)                          # on the jump right above beta = 1/4
    # below the jump N is (numerically) zero, above it G N is real and below -1: the chord R- -> R+ hits 0
    g = as_plant(G)(np.array([j.frequency]))[0]
    n_lo, n_hi = backlash(j.amplitude * (1 - 2e-7), j.frequency), backlash(j.amplitude * (1 + 2e-7), j.frequency)
    assert abs(g * n_lo) < 1e-9
    assert (g * n_hi).real < -1 and abs(np.angle(-g * n_hi)) < 1e-5
