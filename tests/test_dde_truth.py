"""exact_cycle on delayed loops with sloped elements (the delay equation solvers dfloop.hybrid.dde and
dde_memory) against an independent truth: a long DOP853 simulation (rtol 1e-12) with an exact delay buffer
(tests/delay_truth.py: the delayed input read from the previous pieces' dense output, the element's switches
located as events, every input kink an integration boundary), started on the prediction and run until
successive periods agree to 1e-10. Its settled A and w must equal exact_cycle's to 1e-8, and exact_cycle's
stated error estimate must bound the difference (plus the run's own ~1e-10), and its multipliers hold the trivial
one. The elements: saturation, dead zone, backlash, and f with a jump (Coulomb friction, a preloaded spring)."""
import math

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.solve.delay import delayed

from delay_truth import DelayTruth, backlash_element, static_element

SAT = static_element(lambda x: np.clip(x, -1.0, 1.0), [-1.0, 1.0])
DZ = static_element(lambda x: np.where(np.abs(x) > 0.3, x - 0.3 * np.sign(x), 0.0 * x), [-0.3, 0.3])
RELAY_SLOPE = static_element(lambda x: 0.5 * np.sign(x) + 0.3 * x, [0.0])   # a jump of f at 0, then a slope

CASES = {
    # saturation around a second-order plant
    "saturation": (ct.tf([12.0], [1.0, 1.0]) * ct.tf([1.0], [0.5, 1.0]), 0.4, df.Saturation(1.0), SAT),
    # dead zone around a conditionally stable plant (the cycle attracts: more gain at larger amplitude stabilises)
    "dead zone": (ct.tf([5.0, 5.0, 1.25], [1.0, 3.0, 0.0, 0.0, 0.0]), 0.2, df.DeadZone(0.3), DZ),
    # backlash (memory) around a type-1 plant
    "backlash": (ct.tf([3.0], [1.0, 1.0, 0.0]), 0.2, df.Backlash(h=0.5), backlash_element(0.5)),
    # order 8: a Pade chain of order 7 (a second delay made rational) times a lag, and a pure delay
    "order 8": (ct.tf([3.0], [1.0, 1.0]) * ct.tf(*ct.pade(1.5, 7)), 0.5, df.Saturation(1.0), SAT),
    # f jumps where x crosses 0 (Coulomb friction, a preloaded spring): the crossing time moves with the orbit, and
    # Newton's Jacobian and the monodromy carry that move (without it Newton stalled and the multiplier 1 was lost)
    "coulomb": (ct.tf([2.0], [1.0, 1.0, 0.0]) * ct.tf([1.0], [0.2, 1.0]), 0.3, df.CoulombViscousFriction(0.5, 0.3),
                RELAY_SLOPE),
    "preload": (ct.tf([6.0], [1.0, 2.0, 1.0]), 0.4, df.PreloadedSpring(0.5, 0.3), RELAY_SLOPE),
}


def _check_element(N, el):
    # the truth's own element equals dfloop's (static maps: on a grid; the backlash is the play operator)
    if el[0] == "static":
        x = np.linspace(-3.0, 3.0, 601)
        np.testing.assert_allclose(el[1](x), N.output(x), atol=1e-14)


def _error_against_long_run(G0, T, el, start, orbit, max_periods=60):
    """((|A / A_run - 1|, |w / w_run - 1|), run): ``orbit`` against the long run of the loop (G0, delay T, truth
    element ``el``) from the prediction ``start``, which must settle (successive periods within 1e-10)."""
    ss = ct.ss(G0)
    run = DelayTruth(ss.A, ss.B, ss.C, T, el).run(start.amplitude, start.frequency, settle=1e-10,
                                                  max_periods=max_periods)
    assert run.settled, run
    return (abs(orbit.amplitude / run.amplitude - 1), abs(orbit.frequency / run.frequency - 1)), run


@pytest.mark.parametrize("name", list(CASES))
def test_exact_cycle_equals_a_long_exact_delay_simulation_to_1e8(name):
    G0, T, N, el = CASES[name]
    _check_element(N, el)
    G = delayed(G0, T)
    c = [c for c in df.predict_limit_cycles(G, N) if c.stable][0]
    e = df.exact_cycle(G, N, c)
    assert e.success and e.stable and "delay equation" in e.method, e.message
    est = e.extra["error_estimate"]
    assert e.extra["target_met"] and max(est) <= 1e-8
    err, run = _error_against_long_run(G0, T, el, c, e)
    assert max(err) < 1e-8, (err, est)
    # the stated estimate is honest: it bounds the difference (the run's own error is ~1e-10)
    assert err[0] <= est[0] + 2e-10 and err[1] <= est[1] + 2e-10, (err, est)
    # and the DF's prediction is off by far more than that: the comparison is not trivial
    assert abs(c.amplitude / run.amplitude - 1) > 1e-4
    # an autonomous orbit has the trivial multiplier 1 (a shift along the orbit): the monodromy carries every
    # first-order effect, the switches' included
    assert np.min(np.abs(e.multipliers - 1)) < 1e-3, e.multipliers


def test_a_relay_like_element_on_a_first_order_lag_converges_to_the_long_run():
    # A preload (a jump of f at 0) around a first-order lag with a short delay: x has corners where the delayed jump
    # arrives, so the discretisation converges slowly (the target 1e-8 is not met at max_nodes: said, with the
    # estimate). Newton stalled here before the switch's term was in its Jacobian ("no shooting converged").
    G0, T = ct.tf([6.0], [1.0, 0.27]), 0.1
    N = df.PreloadedSpring(0.5, 0.13)
    el = static_element(lambda x: 0.5 * np.sign(x) + 0.13 * x, [0.0])
    _check_element(N, el)
    G = delayed(G0, T)
    c = df.predict_limit_cycles(G, N)[0]
    e = df.exact_cycle(G, N, c)
    assert e.success and e.stable and e.iterations <= 4, e.message
    est = e.extra["error_estimate"]
    err, run = _error_against_long_run(G0, T, el, c, e)
    assert err[0] <= est[0] + 2e-10 and err[1] <= est[1] + 2e-10, (err, est)
    assert max(err) < 1e-6 and np.min(np.abs(e.multipliers - 1)) < 1e-2, (err, e.multipliers)


def test_a_strongly_distorted_orbit_is_found_where_the_df_misplaces_it():
    # A dead zone barely exceeded around a conditionally stable plant with a triple integrator: the orbit is a
    # train of short pulses, far from the DF's sinusoid (the DF's frequency is 75 % off), and its plant states reach
    # 1e8 times x. Newton from the sinusoid fails; the orbit must still be found (from the settled motion), to
    # 1e-8 of a long exact-delay run, and reported as this prediction's orbit: the loop has no other prediction.
    G0 = 5.714e-3 * ct.tf([1.0, 0.0056, 0.0028 ** 2], [1.0, 0.266, 0.0, 0.0, 0.0])
    T = 14.26
    G = delayed(G0, T)
    c = df.predict_limit_cycles(G, df.DeadZone(0.3))
    assert len(c) == 1 and c[0].stable
    e = df.exact_cycle(G, df.DeadZone(0.3), c[0])
    assert e.success and e.stable, e.message
    assert "no other DF prediction" in e.message
    err, run = _error_against_long_run(G0, T, DZ, c[0], e)
    assert max(err) < 1e-8, err
    assert abs(math.log(c[0].frequency / run.frequency)) > 0.5     # beyond the default max_deviation


@pytest.mark.parametrize("limit", [1e-3, 1e-2])
def test_a_steep_saturation_crossing_both_kinks_in_one_step(limit):
    # A saturation whose sloped part (|x| < limit, output +-1) is far narrower than a step of the discretisation
    # (A ~ 3.4): the delayed x crosses both kinks inside one step. The step is cut at both crossings (it was
    # integrated twice, once per kink: at 1e-3 the orbit was 1e-4 off after 12 s; at 1e-2 it was called unstable).
    G0, T = ct.tf([12.0], [1.0, 1.0]) * ct.tf([1.0], [0.5, 1.0]), 0.4
    N = df.Saturation(limit, 1.0 / limit)
    el = static_element(lambda x: np.clip(x, -limit, limit) / limit, [-limit, limit])
    _check_element(N, el)
    G = delayed(G0, T)
    c = [c for c in df.predict_limit_cycles(G, N) if c.stable][0]
    e = df.exact_cycle(G, N, c)
    assert e.success and e.stable and e.extra["target_met"], e.message
    est = e.extra["error_estimate"]
    err, run = _error_against_long_run(G0, T, el, c, e)
    assert max(err) < 1e-8 and err[0] <= est[0] + 2e-10 and err[1] <= est[1] + 2e-10, (err, est)
    assert np.min(np.abs(e.multipliers - 1)) < 1e-3, e.multipliers


def test_settle_periods_finds_the_stable_orbit_beside_an_unstable_one():
    # A softening cubic around a lightly damped lag with a long delay: the DF's one stable cycle (A 9.33) has two
    # true orbits near it, an unstable one (A 9.02, a real multiplier 1.56) that Newton from the sinusoid finds,
    # and the stable one (A 8.71) that the loop settles on. settle_periods (ignored with a delay before) starts
    # Newton from the settled motion: the stable orbit, equal to the independent long run.
    G0, T = ct.tf([0.0996], [1.0, 0.574, 0.254]), 2.0
    N = df.CubicStiffness(9.81, -0.0927)
    el = static_element(lambda x: 9.81 * x - 0.0927 * x ** 3, [])
    _check_element(N, el)
    G = delayed(G0, T)
    c = df.predict_limit_cycles(G, N)[0]
    assert c.stable
    near = df.exact_cycle(G, N, c)
    settled = df.exact_cycle(G, N, c, settle_periods=50)
    assert near.success and not near.stable and max(abs(near.multipliers)) > 1.2, near.multipliers
    assert settled.success and settled.stable, settled.message
    assert abs(near.amplitude / settled.amplitude - 1) > 0.02      # two orbits, not one found twice
    err, run = _error_against_long_run(G0, T, el, c, settled, max_periods=200)
    assert max(err) < 1e-8, err
