"""DF extraction: exact Fourier integrals vs brute-force quadrature, similarity law, bounds, flags, batch."""
import math

import numpy as np
import pytest
from scipy.integrate import trapezoid

from dfloop.impact.extract import (describing_function_from_trajectory, impact_describing_function,
                                   impact_describing_function_batch)
from dfloop.impact.kernel import simulate

M1, M2, H, F = 1.0, 1.0, 0.1, 50.0


def _brute_force_N(eps, w, transient, periods, m1=M1):
    """Fundamental of x1 by dense sampling, end-point detrend and trapezoidal quadrature."""
    tp = 2 * math.pi / w
    tr = simulate(m1, M2, H, eps, F, w, (transient + periods) * tp)
    t = transient * tp + np.linspace(0, periods * tp, 200_001 * 4)
    x = tr.evaluate(t)["x1"]
    x = x - (x[-1] - x[0]) / (t[-1] - t[0]) * (t - t[0])
    return 2 / (periods * tp) * trapezoid(x * np.exp(-1j * w * t), t) / F


@pytest.mark.parametrize("eps,w", [(0.8, 35.0), (0.5, 10.0), (0.0, 30.0), (0.1, 25.0), (0.5, 30.0)])
def test_exact_fundamental_matches_dense_quadrature(eps, w):
    r = impact_describing_function(M1, M2, H, eps, F, w, transient_periods=100, periods=20)
    ref = _brute_force_N(eps, w, 100, r.periods_used)
    assert abs(r.N - ref) <= 1e-7 * abs(r.N)


@pytest.mark.parametrize("eps,w", [(0.8, 35.0), (0.5, 10.0), (0.0, 30.0), (0.3, 70.0)])
def test_similarity_law_dimensional_equals_rescaled(eps, w):
    """N(F, w) = h Xi1(beta) / F, Xi1 from the run with m2 = h = omega = 1, force = beta, m1 = M1/M2."""
    m1, m2, h, force = 3.0, 2.0, 0.04, 17.0
    beta = force / (m2 * h * w * w)
    dim = impact_describing_function(m1, m2, h, eps, force, w, transient_periods=100, periods=20)
    nondim = impact_describing_function(m1 / m2, 1.0, 1.0, eps, beta, 1.0, transient_periods=100, periods=20)
    assert dim.period == nondim.period
    assert abs(dim.N - h * nondim.X1 / force) <= 1e-12 * abs(dim.N)
    assert dim.beta == pytest.approx(nondim.beta, rel=1e-15)


@pytest.mark.parametrize("factor", [1.0, 1.3, 10.0])
def test_no_impacts_at_or_above_wL_gives_exactly_zero(factor):
    w = factor * 2.0 * math.sqrt(1.0 / (1.0 * 1.0))  # w_L of eq. (11): beta = 1/4 / factor^2
    r = impact_describing_function(1.5, 1.0, 1.0, 0.5, 1.0, w, transient_periods=10, periods=10)
    assert r.N == 0 and r.n_impacts == 0 and r.periodicity == 0.0


@pytest.mark.parametrize("eps,w", [(0.5, 1.0), (0.8, 3.0), (0.2, 15.0), (0.5, 25.0), (0.9, 40.0)])
def test_centre_of_mass_bound(eps, w):
    """x1 = x_c - (M2/M) g with x_c's fundamental exactly -F/(M w^2) and g in [0, h]: |G1| <= 2h/pi."""
    M = M1 + M2
    r = impact_describing_function(M1, M2, H, eps, F, w, transient_periods=50, periods=20)
    assert abs(r.N + 1 / (M * w * w)) <= (M2 / M) * (2 * H / math.pi) / F * (1 + 1e-9)
    assert r.n_impacts > 0


def test_periodic_df_does_not_depend_on_window_length():
    tp = 2 * math.pi / 35.0
    tr = simulate(M1, M2, H, 0.8, F, 35.0, 240 * tp)
    a = describing_function_from_trajectory(tr, 200, 5)
    b = describing_function_from_trajectory(tr, 200, 40)
    assert abs(a.N - b.N) < 1e-11 * abs(b.N)


def test_period_two_detected_and_blocks_agree():
    eps, w = 0.5, 30.0
    r = impact_describing_function(M1, M2, H, eps, F, w, transient_periods=200, periods=41)
    assert r.period == 2 and r.regular
    assert r.periods_used == 40
    assert r.periodicity < 1e-10
    # independently: the state repeats after two periods and not after one
    tp = 2 * math.pi / w
    tr = simulate(M1, M2, H, eps, F, w, 210 * tp)
    s = tr.evaluate(200 * tp + tp * np.arange(3))
    assert abs(s["v1"][2] - s["v1"][0]) < 1e-9 < abs(s["v1"][1] - s["v1"][0])


def test_regular_region_has_one_alternate_impact_per_side():
    """Paper, Fig. 9: for w_J < w < w_L the motion has one alternate collision on each side."""
    r = impact_describing_function(M1, M2, H, 0.8, F, 35.0)
    assert r.period == 1 and r.max_run_A == 1 and r.max_run_B == 1
    assert r.impacts_per_period == 2.0
    assert r.runs_A.sum() + r.runs_B.sum() == r.n_impacts


def test_irregular_motion_is_flagged_as_average():
    r = impact_describing_function(M1, M2, H, 0.5, F, 22.5, transient_periods=400, periods=60)
    assert r.period == 0 and not r.regular
    assert "average" in repr(r)
    assert r.periodicity > 1e-2


def test_below_wc_flag_and_sticking_makes_it_periodic():
    """Below w_c (eq. 10) the paper reports irregular motion; with sticking resolved it is periodic here."""
    eps, w = 0.2, 15.0
    assert w < ((2 * F / (M2 * H)) ** 2 * (1 - eps) ** 5) ** 0.25  # w_c of eq. (10)
    r = impact_describing_function(M1, M2, H, eps, F, w)
    assert r.below_wc and "below w_c" in repr(r)
    assert r.period == 1 and r.stuck_fraction > 0.1 and r.periodicity < 1e-10
    assert not impact_describing_function(M1, M2, H, eps, F, 35.0).below_wc


def test_stuck_fraction_and_runs_from_the_trajectory():
    eps, w = 0.5, 10.0
    tp = 2 * math.pi / w
    tr = simulate(M1, M2, H, eps, F, w, 60 * tp)
    r = describing_function_from_trajectory(tr, 40, 20)
    t_a, t_b = 40 * tp, 60 * tp
    stuck = sum(max(0.0, min(e, t_b) - max(s, t_a)) for s, e, _ in tr.stuck_intervals)
    assert r.stuck_fraction == pytest.approx(stuck / (t_b - t_a), rel=1e-12)
    sides = tr.impacts["side"][(tr.impacts["t"] >= t_a) & (tr.impacts["t"] < t_b)]
    runs = [len(list(g)) for g in _groups(sides)]
    assert r.max_run_A + r.max_run_B > 0
    assert sorted(runs) == sorted(np.concatenate([r.runs_A, r.runs_B]).tolist())


def _groups(seq):
    import itertools
    return (list(g) for _, g in itertools.groupby(seq.tolist()))


def test_batch_equals_scalar_calls():
    force = np.array([[30.0], [50.0]])
    omega = np.array([20.0, 35.0, 80.0])
    b = impact_describing_function_batch(M1, M2, H, 0.5, force, omega, transient_periods=60, periods=12, workers=2)
    assert b.N.shape == (2, 3)
    for i in range(2):
        for j in range(3):
            r = impact_describing_function(M1, M2, H, 0.5, force[i, 0], omega[j], transient_periods=60, periods=12)
            assert b.N[i, j] == r.N and b.period[i, j] == r.period and b.n_impacts[i, j] == r.n_impacts
    assert "ImpactDFBatch" in repr(b)


@pytest.mark.parametrize("kwargs,name", [({"periods": 0}, "periods"), ({"transient_periods": -1}, "transient"),
                                         ({"force": np.nan}, "force"), ({"omega": 0.0}, "omega"),
                                         ({"restitution": 2.0}, "restitution"), ({"h": -1.0}, "h")])
def test_bad_input(kwargs, name):
    args = dict(m1=M1, m2=M2, h=H, restitution=0.5, force=F, omega=30.0)
    args.update({k: v for k, v in kwargs.items() if k in args})
    extra = {k: v for k, v in kwargs.items() if k not in args}
    with pytest.raises(ValueError, match=name):
        impact_describing_function(**args, **extra)


def test_window_longer_than_run_is_rejected():
    tr = simulate(M1, M2, H, 0.5, F, 30.0, 1.0)
    with pytest.raises(ValueError, match="periods"):
        describing_function_from_trajectory(tr, 2, 10)


def test_empty_batch_rejected():
    with pytest.raises(ValueError, match="empty"):
        impact_describing_function_batch(M1, M2, H, 0.5, np.array([]), np.array([]))


# ------------------------------------------------------------------------------ labels at the model's edges
@pytest.mark.parametrize("rel", [1e-9, 0.0])
def test_no_impact_motion_labelled_as_such_right_up_to_wL(rel):
    """Just below w_L a motion from rest grazes once and then flies freely: x1 is exactly linear over the
    window, so N = 0 exactly, labelled periodic no-impact motion (not 'irregular')."""
    w = 2.0 * math.sqrt(F / (H * M2)) * (1 - rel)
    for transient in (None, 200):
        r = impact_describing_function(M1, M2, H, 0.5, F, w, transient_periods=transient, periods=20)
        assert r.N == 0 and r.n_impacts == 0 and r.regular and r.periodicity == 0.0
        assert "no impacts in the window" in repr(r)


def test_grazing_motion_that_drifts_into_impacts_is_labelled_by_its_window():
    """At w_L (1 - 1e-6) the gap drifts after the grazing impact until impacts resume (after ~100 periods):
    a window before is no-impact motion (N = 0), a window after a periodic impacting motion."""
    w = 2.0 * math.sqrt(F / (H * M2)) * (1 - 1e-6)
    early = impact_describing_function(M1, M2, H, 0.5, F, w, transient_periods=10, periods=20)
    late = impact_describing_function(M1, M2, H, 0.5, F, w, transient_periods=400, periods=20)
    assert early.N == 0 and early.n_impacts == 0 and early.regular
    assert late.n_impacts > 0 and late.regular and late.periodicity < 1e-9


@pytest.mark.parametrize("force,omega,h", [(1e300, 1.5e150, 0.1), (1e-3, 3e3, 1e-12), (1e250, 1e130, 1e-8)])
def test_extreme_force_and_clearance_keep_the_similarity_law_without_overflow(force, omega, h):
    import warnings

    beta = force / (M2 * h * omega * omega)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = impact_describing_function(M1, M2, h, 0.5, force, omega, transient_periods=100, periods=20)
    ref = impact_describing_function(M1 / M2, 1.0, 1.0, 0.5, beta, 1.0, transient_periods=100, periods=20)
    assert r.period == ref.period > 0
    assert r.N == pytest.approx(h * ref.X1 / force, rel=1e-9)
    assert math.isfinite(abs(r.N)) and r.beta == pytest.approx(beta, rel=1e-12)


def test_beta_overflow_is_a_clear_error():
    with pytest.raises(ValueError, match="force: beta"):
        impact_describing_function(M1, M2, 1e-300, 0.5, 1e300, 1e-5, transient_periods=1, periods=1)


@pytest.mark.parametrize("w", [35.9, 36.1, 36.3])
def test_adaptive_transient_follows_slow_convergence(w):
    """eps = 0.5 at 35.9-36.4 rad/s converges over ~1000 periods: a fixed 100-period transient calls it
    irregular; the adaptive one finds period 1 and the DF of a 2500-period run (within its own uncertainty
    and 1e-6), in far fewer periods (restarts from the extrapolated fixed point of the stroboscopic map)."""
    assert not impact_describing_function(M1, M2, H, 0.5, F, w, transient_periods=100, periods=20).regular
    r = impact_describing_function(M1, M2, H, 0.5, F, w, transient_periods=None, periods=20)
    ref = impact_describing_function(M1, M2, H, 0.5, F, w, transient_periods=2500, periods=20)
    assert r.period == ref.period == 1
    assert abs(r.N - ref.N) <= min(1e-6, r.periodicity + 1e-6) * abs(ref.N)
    assert r.transient_periods + r.periods_used < 400


def test_adaptive_transient_stops_early_on_irregular_motion():
    r = impact_describing_function(M1, M2, H, 0.5, F, 22.5, transient_periods=None, periods=20)
    assert not r.regular and r.transient_periods <= 200


def test_batch_records_event_limit_failures_and_goes_on():
    w = np.array([40.0, 5.0])            # period-1 motion; chattering low-frequency motion
    kw = dict(transient_periods=None, periods=20, max_events=100)
    with pytest.raises(Exception, match="max_events"):
        impact_describing_function_batch(M1, M2, H, 0.5, F, w, **kw)
    b = impact_describing_function_batch(M1, M2, H, 0.5, F, w, on_event_limit="record", **kw)
    assert b.failure[0] == "" and "max_events = 100" in b.failure[1]
    assert b.regular[0] and not b.regular[1] and np.isnan(b.N[1])
    assert b.N[0] == impact_describing_function(M1, M2, H, 0.5, F, 40.0, **kw).N
