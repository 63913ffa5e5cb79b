"""Limit frequencies: closed forms, their beta values, and the exact no-impact limit from the kernel."""
import math

import numpy as np
import pytest

from dfloop.describing.composition import MassBacklash
from dfloop.impact import limits as L
from dfloop.impact.dynamic_backlash import DynamicBacklash
from dfloop.impact.kernel import simulate

M1, M2, H = 1.0, 1.0, 0.1


@pytest.fixture(autouse=True)
def tmp_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path))


def test_closed_forms_against_paper_numbers():
    assert MassBacklash(M1, M2, H).limit_frequency(50.0) == pytest.approx(math.sqrt(2 * 50 / (0.1 * 2)))
    assert L.no_impact_frequency(50.0, M2, H) == pytest.approx(2 * math.sqrt(500.0))
    assert L.jump_frequency(50.0, M2, H) == pytest.approx(math.sqrt(500.0))
    # the paper's Figs. 10-11 note: eps = 0.2, F = 50 N gives w_c = 23.9 rad/s
    assert L.lower_limit_frequency(50.0, M2, H, 0.2) == pytest.approx(23.9, abs=0.05)


@pytest.mark.parametrize("F", [10.0, 50.0])
@pytest.mark.parametrize("eps", [0.1, 0.5, 0.9])
def test_limits_are_fixed_betas(F, eps):
    assert L.beta_of(F, L.no_impact_frequency(F, M2, H), M2, H) == pytest.approx(0.25, rel=1e-14)
    assert L.beta_of(F, L.jump_frequency(F, M2, H), M2, H) == pytest.approx(1.0, rel=1e-14)
    assert L.beta_of(F, L.lower_limit_frequency(F, M2, H, eps), M2, H) == pytest.approx(L.beta_lower_limit(eps),
                                                                                      rel=1e-12)
    assert L.omega_of(L.beta_of(F, 7.0, M2, H), F, M2, H) == pytest.approx(7.0, rel=1e-14)


def test_no_impact_limit_exact_with_the_kernel():
    F = 50.0
    wL = L.no_impact_frequency(F, M2, H)
    # just above w_L: no impact ever, and the peak of x2 - x2(0) is 2F/(M2 w^2), reached at t = pi/w
    w = wL * (1 + 1e-7)
    tr = simulate(M1, M2, H, 0.5, F, w, 20 * 2 * math.pi / w)
    assert tr.n_impacts == 0
    t = np.linspace(0, 20 * 2 * math.pi / w, 200001)
    x2 = tr.evaluate(t)["x2"] - tr.evaluate(np.array([0.0]))["x2"]
    peak = tr.evaluate(np.array([math.pi / w]))["x2"][0] - tr.evaluate(np.array([0.0]))["x2"][0]
    assert peak == pytest.approx(L.x2_peak_excursion(F, w, M2), rel=1e-12)
    assert x2.max() <= peak * (1 + 1e-12)
    assert L.x2_peak_excursion(F, wL, M2) == pytest.approx(H / 2, rel=1e-14)
    # just below w_L: the masses collide in the first period
    tr = simulate(M1, M2, H, 0.5, F, wL * (1 - 1e-7), 2 * 2 * math.pi / wL)
    assert tr.n_impacts > 0


def test_measured_limits_against_the_paper():
    db = DynamicBacklash(M1, M2, H, 0.5, transient_periods=100, periods=20)
    m = L.measured_limits(db, beta_max=10.0)
    assert m.beta_no_impact == pytest.approx(0.25, rel=1e-8)
    # regular alternate collisions between w_J and w_L, irregular motion below
    assert 0.25 < m.beta_regular_end < m.beta_irregular_end < 10.0
    # the observed lower limit of regular motion agrees with eq. (10) to within 20 %
    assert m.beta_irregular_end == pytest.approx(L.beta_lower_limit(0.5), rel=0.2)
    om = m.omegas(50.0, M2, H)
    assert om["omega_L"] == pytest.approx(L.no_impact_frequency(50.0, M2, H), rel=1e-8)
    assert om["omega_c"] < om["omega_J"] < om["omega_L"]


@pytest.mark.parametrize("call, name", [
    (lambda: L.no_impact_frequency(-1.0, M2, H), "F"),
    (lambda: L.no_impact_frequency(1.0, 0.0, H), "m2"),
    (lambda: MassBacklash(M1, M2, float("nan")).limit_frequency(1.0), "h"),
    (lambda: L.lower_limit_frequency(1.0, M2, H, 1.2), "restitution"),
    (lambda: L.beta_lower_limit(-0.1), "restitution"),
    (lambda: L.beta_of(1.0, float("nan"), M2, H), "omega"),
])
def test_bad_input(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_elastic_limit():
    assert L.beta_lower_limit(1.0) == math.inf
    assert L.lower_limit_frequency(50.0, M2, H, 1.0) == 0.0
