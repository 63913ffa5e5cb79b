"""The adaptive DF of the paper's model (compiled period-by-period driver): early stop, extrapolated restarts,
attractor settling and the mirror symmetry, each checked against an independent truth (long fixed-transient
runs through the trajectory-based extraction, or the trajectory of the same run)."""
import math

import numpy as np
import pytest

from dfloop.impact.sampling import STARTS
from dfloop.impact.extract import (describing_function_from_trajectory, impact_describing_function,
                                   impact_describing_function_batch)
from dfloop.impact.kernel import KernelRun
from dfloop.impact.model import ImpactParameters

M1, M2, H, F = 1.0, 1.0, 0.1, 50.0
ADAPTIVE = dict(transient_periods=None, periods=20)
LONG = dict(transient_periods=1500, periods=36)     # every period up to 12 detectable


def omega_of(beta):
    return math.sqrt(F / (M2 * H * beta))


# (eps, beta): period-1 and period-2 motion, the period-3/5 windows and coexistence regions of the issue
# (eps = 0.7 at 33.8 rad/s, eps = 0.8 at 43.7-44.4 rad/s), slow convergence (eps = 0.5 at 35.9-36.4 rad/s),
# chatter-and-stick motion and a period-12 motion
CASES = [(0.5, 0.3837), (0.5, 0.3880), (0.5, 0.55), (0.7, 0.4376), (0.7, 0.4340), (0.8, 0.2576), (0.8, 0.2624),
         (0.8, 0.2900), (0.2, 3.0), (0.5, 20.0), (0.9, 150.0), (0.3, 0.8)]


@pytest.mark.parametrize("eps, beta", CASES)
def test_early_stopped_run_gives_the_long_run_N_within_its_uncertainty(eps, beta):
    """A periodic adaptive result (stopped as soon as the detection converged, possibly after extrapolated
    restarts) has the period of a 1500-period run and its N within the uncertainty the table uses,
    |N| (periodicity + 1e-6)."""
    w = omega_of(beta)
    r = impact_describing_function(M1, M2, H, eps, F, w, **ADAPTIVE)
    ref = impact_describing_function(M1, M2, H, eps, F, w, **LONG)
    assert r.regular and ref.regular and r.period == ref.period
    assert abs(r.N - ref.N) <= abs(ref.N) * (r.periodicity + 1e-6)
    assert r.transient_periods + r.periods_used < 600          # and far shorter than the reference


def test_driver_DF_equals_the_trajectory_extraction_of_the_same_run():
    """Without restarts the driver simulates the motion that a KernelRun advanced period by period records
    (the same kernel calls): the Fourier integrals, impact counts and stuck time it accumulates in the loop
    equal those of the trajectory-based extraction over the same window."""
    rng = np.random.default_rng(4)
    checked = 0
    for eps, beta in zip(rng.uniform(0.1, 0.9, 30), np.exp(rng.uniform(math.log(0.3), math.log(300.0), 30))):
        r = impact_describing_function(M1 / M2, 1.0, 1.0, eps, beta, 1.0, **ADAPTIVE)
        if r.restarts or not r.regular:
            continue
        beta_run = math.exp(math.log(beta))       # the driver's beta = F / (M2 h w^2), from logarithms
        run = KernelRun(ImpactParameters(M1 / M2, 1.0, 1.0, eps, beta_run, 1.0))
        tp = 2.0 * math.pi / 1.0
        for k in range(1, r.transient_periods + r.periods_used + 1):
            run.advance(k * tp, 10 ** 9)
        ref = describing_function_from_trajectory(run.trajectory(), r.transient_periods, r.periods_used)
        assert abs(r.X1 - ref.X1) <= 1e-12 * abs(ref.X1) + 1e-15
        assert (r.max_run_A, r.max_run_B, r.n_impacts) == (ref.max_run_A, ref.max_run_B, ref.n_impacts)
        assert r.stuck_fraction == pytest.approx(ref.stuck_fraction, abs=1e-12)
        checked += 1
    assert checked >= 15


def test_a_start_that_settles_on_the_rest_orbit_reaches_the_rest_motion():
    """Where a probed start is reported settled on the rest orbit (or its mirror image), a long run from that
    start gives the rest start's N (1e-6); where it settles on another motion it is not reported settled."""
    n_settled = 0
    for eps, beta in [(0.5, 0.45), (0.5, 0.55), (0.8, 0.2576), (0.8, 0.2624), (0.2, 3.0), (0.6, 0.35), (0.9, 150.0)]:
        w = omega_of(beta)
        rest = impact_describing_function(M1, M2, H, eps, F, w, **ADAPTIVE)
        assert rest.regular and rest.orbit.shape == (2 * rest.period, 3)
        for gap, u_rel in STARTS[:2]:          # the starts a table probes by default
            start = (0.0, 0.0, gap * H, u_rel * F / (M2 * w))
            s = impact_describing_function(M1, M2, H, eps, F, w, initial=start, attractor=rest.orbit, **ADAPTIVE)
            long = impact_describing_function(M1, M2, H, eps, F, w, initial=start, **LONG)
            same = long.regular and abs(long.N - rest.N) <= 1e-6 * abs(rest.N)
            if s.settled:
                assert same and math.isnan(s.N.real)
                n_settled += 1
            else:
                assert math.isfinite(abs(s.N))          # a full result of its own
    assert n_settled >= 6


def test_the_mirror_image_of_a_periodic_motion_is_a_motion_with_the_same_DF():
    """The second half of ``orbit`` is the motion half a period later reflected (gap -> h - gap, u -> -u): started
    there (x1 = 0, momentum of the rest motion), a long run is periodic with the rest motion's N."""
    for eps, beta in [(0.5, 0.45), (0.2, 2.5), (0.3, 0.8), (0.5, 0.55)]:
        r = impact_describing_function(M1 / M2, 1.0, 1.0, eps, beta, 1.0, **ADAPTIVE)
        p = r.period
        gap, u, mode = r.orbit[p]
        assert mode == 0
        u *= max(1.0, beta)                               # rows are normalised by max(h w, F / (M2 w))
        v1 = -M2 * u / (M1 + M2)                          # zero total momentum at a period boundary
        m = impact_describing_function(M1 / M2, 1.0, 1.0, eps, beta, 1.0, initial=(0.0, v1, gap, u), **LONG)
        assert m.regular and m.period == p
        assert abs(m.N - r.N) <= 1e-6 * abs(r.N)


def test_batch_equals_single_calls_and_keeps_event_limits_bounded():
    beta = np.array([0.3, 0.45, 2.0, 30.0])
    b = impact_describing_function_batch(M1, M2, H, 0.6, F, np.sqrt(F / (M2 * H * beta)), **ADAPTIVE)
    for i, bi in enumerate(beta):
        r = impact_describing_function(M1, M2, H, 0.6, F, math.sqrt(F / (M2 * H * bi)), **ADAPTIVE)
        assert b.N[i] == r.N and b.period[i] == r.period and b.transient_periods[i] == r.transient_periods
        assert b.max_run_A[i] == r.max_run_A and np.array_equal(b.orbit[i], r.orbit)
    with pytest.raises(ValueError, match="omega"):
        impact_describing_function_batch(M1, M2, H, 0.6, F, [10.0, -1.0], **ADAPTIVE)
    with pytest.raises(ValueError, match="attractor"):
        impact_describing_function(M1, M2, H, 0.6, F, 30.0, attractor=np.zeros((3, 2)), **ADAPTIVE)
    with pytest.raises(ValueError, match="attractor"):
        impact_describing_function(M1, M2, H, 0.6, F, 30.0, attractor=np.zeros((2, 3)), transient_periods=10)
    for bad in ("orbit", np.full((2, 3), np.nan)):
        with pytest.raises(ValueError, match="attractor"):
            impact_describing_function(M1, M2, H, 0.6, F, 30.0, attractor=bad, **ADAPTIVE)
