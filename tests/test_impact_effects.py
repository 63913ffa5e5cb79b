"""Optional effects: the linear-mode engine against the JIT kernel, solve_ivp and closed forms."""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp, trapezoid

from dfloop.impact.effects import GROUND_EVENT, CoulombFriction, EffectsRun, LoadSpring, ViscousDamping
from dfloop.impact.extract import describing_function_from_trajectory
from dfloop.errors import EventLimitError
from dfloop.impact.kernel import forced_motion, simulate
from dfloop.impact.model import ImpactParameters
from dfloop.impact.reference import simulate_solve_ivp

M1, M2, H, F = 1.0, 1.0, 0.1, 50.0


def simulate_with_effects(p, t_end, effects, max_events, chatter_tol):
    """The forced motion from rest on the linear-mode engine (effects, or the paper's model without them)."""
    run = forced_motion(p, effects, chatter_tol, closed_form=False)
    run.advance(t_end, max_events)
    return run.trajectory()


@pytest.mark.parametrize("eps,w", [(0.8, 35.0), (0.0, 30.0), (0.5, 10.0)])
def test_engine_without_effects_matches_jit_kernel(eps, w):
    t_end = 4 * 2 * math.pi / w
    eng = simulate_with_effects(ImpactParameters(M1, M2, H, eps, F, w), t_end, (), 10 ** 6, 1e-9)
    jit = simulate(M1, M2, H, eps, F, w, t_end)
    t = np.linspace(0, t_end, 301)
    assert np.max(np.abs(eng.evaluate(t)["x1"] - jit.evaluate(t)["x1"])) < 1e-12
    if eps > 0.6:  # no chatter: the event sequences are identical
        assert np.max(np.abs(eng.impacts["t"] - jit.impacts["t"])) < 1e-12
    assert np.allclose(eng.stuck_intervals[:, :2].sum(), jit.stuck_intervals[:, :2].sum(), rtol=1e-9)


def test_exact_integrals_of_engine_match_closed_form_integrals():
    eps, w = 0.5, 10.0
    tp = 2 * math.pi / w
    eng = simulate_with_effects(ImpactParameters(M1, M2, H, eps, F, w), 6 * tp, (), 10 ** 6, 1e-9)
    jit = simulate(M1, M2, H, eps, F, w, 6 * tp)
    a = describing_function_from_trajectory(eng, 3, 3)
    b = describing_function_from_trajectory(jit, 3, 3)
    assert a.stuck_fraction > 0.1
    assert abs(a.N - b.N) < 1e-10 * abs(b.N)


C_DAMP, K_SPRING = 0.8, 40.0


@pytest.mark.parametrize("effects,force1", [
    ((ViscousDamping(C_DAMP),), lambda t, x, v: -C_DAMP * v),
    ((LoadSpring(K_SPRING),), lambda t, x, v: -K_SPRING * x),
    ((ViscousDamping(C_DAMP), LoadSpring(K_SPRING)), lambda t, x, v: -K_SPRING * x - C_DAMP * v),
])
@pytest.mark.parametrize("eps,w", [(0.8, 35.0), (0.5, 30.0)])
def test_linear_effects_agree_with_solve_ivp(effects, force1, eps, w):
    t_end = 1.5
    tr = simulate(M1, M2, H, eps, F, w, t_end, effects=effects)
    ref = simulate_solve_ivp(M1, M2, H, eps, F, w, t_end, extra_force1=force1)
    assert tr.impacts["t"].size == ref["t"].size >= 10
    assert np.max(np.abs(tr.impacts["t"] - ref["t"])) < 1e-9
    t = np.linspace(0, t_end, 401)
    assert np.max(np.abs(tr.evaluate(t)["x1"] - ref["sol"](t)[0])) < 1e-9


def test_flights_follow_the_damped_free_oscillation_of_m1():
    c, k = 0.6, 900.0
    tr = simulate(M1, M2, H, 0.7, F, 30.0, 1.0, effects=(ViscousDamping(c), LoadSpring(k)))
    imp = np.flatnonzero(tr.impact_mask)
    assert imp.size >= 4
    zeta_w = c / (2 * M1)
    wd = math.sqrt(k / M1 - zeta_w ** 2)
    for i in imp[:-1]:
        t0, t1 = tr.t0[i], tr.t0[i + 1]
        x0, v0 = tr.evaluate([t0])["x1"][0], tr.impacts["v1_post"][np.flatnonzero(imp == i)[0]]
        s = np.linspace(0, t1 - t0, 50)[1:-1]
        closed = np.exp(-zeta_w * s) * (x0 * np.cos(wd * s) + (v0 + zeta_w * x0) / wd * np.sin(wd * s))
        assert np.max(np.abs(tr.evaluate(t0 + s)["x1"] - closed)) < 1e-12


def _friction_reference_m2(Ff, w, t_end):
    """A single mass with F cos wt and Coulomb friction: solve_ivp per slip phase, closed-form stick phases."""
    t, x, v = 0.0, 0.0, 0.0
    xs = []
    while t < t_end:
        if v == 0.0:
            # stuck until |F cos wt| > Ff: scan forward on a fine grid then refine with brentq
            from scipy.optimize import brentq
            g = lambda tt: abs(F * math.cos(w * tt)) - Ff  # noqa: E731
            if g(t) <= 0:
                grid = t + np.linspace(0, 2 * math.pi / w, 2001)
                k = np.flatnonzero(np.array([g(tt) for tt in grid]) > 0)
                t_new = brentq(g, grid[k[0] - 1], grid[k[0]], xtol=1e-15)
                xs.append((t, t_new, x, 0.0, 0))
                t = t_new
                if t >= t_end:
                    break
            sign = 1.0 if math.cos(w * t) > 0 else -1.0
        else:
            sign = 1.0 if v > 0 else -1.0
        stop = lambda tt, y: sign * y[1]  # noqa: E731
        stop.terminal, stop.direction = True, -1
        sol = solve_ivp(lambda tt, y: [y[1], (F * math.cos(w * tt) - Ff * sign) / M2], (t, t_end), [x, v],
                        events=stop, rtol=1e-12, atol=1e-15, dense_output=True, method="DOP853")
        xs.append((t, sol.t[-1], sol.sol, sign, 1))
        t, x, v = sol.t[-1], sol.y[0, -1], 0.0
        if sol.status == 0:
            break
    return xs


@pytest.mark.parametrize("Ff", [15.0, 35.0])
def test_coulomb_friction_on_m2_matches_stick_slip_reference(Ff):
    w, t_end = 3.0, 6.0
    tr = simulate(M1, M2, 100.0, 0.5, F, w, t_end, effects=(CoulombFriction(Ff, "m2"),))
    assert tr.n_impacts == 0
    ref = _friction_reference_m2(Ff, w, t_end)
    for t0, t1, sol, _, slipping in ref:
        tt = np.linspace(t0, min(t1, t_end), 40)
        x_ref = sol(tt)[0] if slipping else np.full_like(tt, sol)
        assert np.max(np.abs(tr.evaluate(tt)["x2"] - 50.0 - x_ref)) < 1e-9


def test_friction_above_force_never_moves():
    tr = simulate(M1, M2, H, 0.5, F, 3.0, 5.0, effects=(CoulombFriction(F * 1.01, "m2"),))
    st = tr.evaluate(np.linspace(0, 5.0, 101))
    assert np.all(st["x2"] == H / 2) and np.all(st["v2"] == 0.0) and np.all(st["x1"] == 0.0)


def test_friction_on_m1_decelerates_linearly_and_stops():
    Ff = 20.0
    tr = simulate(M1, M2, H, 0.5, F, 20.0, 1.0, effects=(CoulombFriction(Ff, "m1"),))
    imp = np.flatnonzero(tr.impact_mask)
    i = imp[0]
    t0, t1 = tr.t0[i], tr.t0[imp[1]]
    v0 = tr.impacts["v1_post"][0]
    s = np.linspace(0, t1 - t0, 200)[1:-1]
    v_closed = np.sign(v0) * np.maximum(np.abs(v0) - Ff / M1 * s, 0.0)
    assert np.max(np.abs(tr.evaluate(t0 + s)["v1"] - v_closed)) < 1e-11


def test_damping_momentum_balance_at_impacts():
    """d/dt (M1 v1 + M2 v2) = F cos wt - c v1, so M1 v1 + M2 v2 = (F/w) sin wt - c x1 (x1(0) = 0)."""
    c, w = 2.0, 30.0
    tr = simulate(M1, M2, H, 0.6, F, w, 1.5, effects=(ViscousDamping(c),))
    imp = tr.impacts
    x1 = tr.evaluate(imp["t"])["x1"]
    p = M1 * imp["v1_post"] + M2 * imp["v2_post"]
    assert imp["t"].size > 10
    assert np.max(np.abs(p - (F / w * np.sin(w * imp["t"]) - c * x1))) < 1e-10 * F / w


def test_damped_df_matches_dense_quadrature_and_is_window_independent():
    c, w = 5.0, 35.0
    tp = 2 * math.pi / w
    tr = simulate(M1, M2, H, 0.8, F, w, 36 * tp, effects=(ViscousDamping(c),))
    r = describing_function_from_trajectory(tr, 30, 3)
    assert r.period == 1 and r.periodicity < 1e-6
    assert abs(describing_function_from_trajectory(tr, 30, 6).N - r.N) < 1e-8 * abs(r.N)
    t = 30 * tp + np.linspace(0, 3 * tp, 9001)
    x = tr.evaluate(t)["x1"]
    x = x - (x[-1] - x[0]) / (t[-1] - t[0]) * (t - t[0])
    ref = 2 / (3 * tp) * trapezoid(x * np.exp(-1j * w * t), t) / F
    assert abs(r.N - ref) < 1e-5 * abs(r.N)


@pytest.mark.parametrize("make,name", [
    (lambda: ViscousDamping(-0.1), "c"), (lambda: ViscousDamping(np.nan), "c"), (lambda: LoadSpring(-1.0), "k"),
    (lambda: LoadSpring(np.nan), "k"),
    (lambda: CoulombFriction(0.0), "force"), (lambda: CoulombFriction(1.0, "m3"), "mass"),
])
def test_effect_validation(make, name):
    with pytest.raises(ValueError, match=name):
        make()


def test_effects_break_similarity_and_two_frictions_rejected():
    assert not any(e.keeps_similarity for e in (ViscousDamping(1.0), LoadSpring(1.0), CoulombFriction(1.0)))
    with pytest.raises(ValueError, match="effects"):
        simulate(M1, M2, H, 0.5, F, 30.0, 1.0, effects=(CoulombFriction(1.0, "m1"), CoulombFriction(1.0, "m2")))
    with pytest.raises(ValueError, match="effects"):
        simulate(M1, M2, H, 0.5, F, 30.0, 1.0, effects=("damping",))


def test_random_effect_combinations_run_without_penetration():
    """Random masses, eps, beta and effect sets (incl. stick-slip of the pair in contact): bounded, no overlap."""
    rng = np.random.default_rng(3)
    for _ in range(16):
        m1 = 10 ** rng.uniform(-0.5, 0.5)
        eps = rng.choice([0.0, rng.uniform(0, 1), 1.0])
        beta = 10 ** rng.uniform(-0.5, 1.5)
        effects = []
        if rng.random() < 0.5:
            effects.append(ViscousDamping(10 ** rng.uniform(-2, 0)))
        if rng.random() < 0.5:
            effects.append(LoadSpring(10 ** rng.uniform(-1, 0.5)))
        if rng.random() < 0.6:
            effects.append(CoulombFriction(beta * 10 ** rng.uniform(-2, 0), str(rng.choice(["m1", "m2"]))))
        tr = simulate(m1, 1.0, 1.0, eps, beta, 1.0, 3 * 2 * math.pi, effects=tuple(effects), max_events=20_000)
        ends = tr.segment_ends
        t = np.minimum((tr.t0[:, None] + (ends - tr.t0)[:, None] * np.linspace(0, 1, 9)).ravel(), tr.t_end)
        g = tr.evaluate(t)["gap"]
        assert g.min() >= -1e-12 and g.max() <= 1 + 1e-12


def test_pair_in_contact_slips_together_under_friction():
    """eps = 0, friction on M2: the pair stops on the ground in contact, then the force drags both along."""
    m1, beta, ff = 0.4973237958578009, 10.102918201731354, 5.084509767004841
    tr = simulate(m1, 1.0, 1.0, 0.0, beta, 1.0, 2.5, effects=(CoulombFriction(ff, "m2"),))
    st = tr.evaluate(np.array([2.2, 2.4]))
    assert np.all(st["gap"] == 0.0)                    # still in contact on side A
    assert np.all(st["v1"] == st["v2"]) and st["v1"][1] < 0.0  # sliding together backwards


def _oscillator_with_offset(wn, x0, v0):
    """z = [x, v, 0, 0, 0, 0, 1] of x'' = -wn^2 x (the unused slots of the engine's state kept at 0)."""
    A = np.zeros((7, 7))
    A[0, 1], A[1, 0] = 1.0, -wn ** 2
    return A, np.array([x0, v0, 0.0, 0.0, 0.0, 0.0, 1.0])


def test_jit_step_scan_finds_the_closed_form_crossing():
    """x = x0 cos(wn t) + v0/wn sin(wn t) crosses x = -b first at a closed-form time; rows hold r.z >= 0."""
    from scipy.linalg import expm

    from dfloop.impact._effects_core import scan_steps
    wn, x0, v0, b = 3.0, 0.2, 1.1, 0.35
    A, z = _oscillator_with_offset(wn, x0, v0)
    rows = np.zeros((2, 7))
    rows[0, 0], rows[0, 6] = 1.0, b          # x + b >= 0
    rows[1, 0], rows[1, 6] = -1.0, 10.0      # never violated
    dt = 2 * math.pi / wn / 32
    amp, phase = math.hypot(x0, v0 / wn), math.atan2(v0 / wn, x0)
    t_cross = (math.pi - math.acos(b / amp) + phase) / wn  # first wn t - phase with cos = -b / amp
    t, hit = scan_steps(A, expm(A * dt), dt, rows, rows @ A, rows @ A @ A, np.zeros(2, dtype=np.bool_), z, 0.0, 10.0)
    assert hit == 0
    assert abs(t - t_cross) < 1e-14
    assert abs(z[0] + b) < 1e-14 and abs(z[1] - (-amp * wn * math.sin(wn * t - phase))) < 1e-12


def test_jit_step_scan_takes_the_short_last_step_and_propagate_matches_expm():
    from scipy.linalg import expm

    from dfloop.impact._effects_core import propagate, scan_steps
    A, z0 = _oscillator_with_offset(2.0, 0.3, -0.4)
    rows = np.zeros((1, 7))
    rows[0, 6] = 1.0                          # 1 >= 0 always holds
    dt = 0.1
    z = z0.copy()
    t, hit = scan_steps(A, expm(A * dt), dt, rows, rows @ A, rows @ A @ A, np.zeros(1, dtype=np.bool_), z, 0.0, 1.05)
    assert hit == -1 and t == 1.05      # ten exact steps, then the short last one on the Taylor series
    assert np.max(np.abs(z - expm(A * t) @ z0)) < 1e-14
    s = np.array([0.0, 0.37, 1.05, 0.099999, 2.5])
    ref = np.array([expm(A * si) @ z0 for si in s])
    assert np.max(np.abs(propagate(A, expm(A * dt), z0, s, dt) - ref)) < 1e-13


_PLAIN_SCRIPT = """
import json, math
from dfloop.impact.effects import CoulombFriction, ViscousDamping
from dfloop.impact.kernel import forced_motion, simulate
tr = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 15.0, 1.0, effects=(ViscousDamping(0.5), CoulombFriction(20.0, "m2")))
print(json.dumps({"t": tr.t0.tolist(), "cause": tr.cause.tolist(), "x1": tr.evaluate([0.3, 0.9])["x1"].tolist()}))
"""


def test_engine_gives_the_same_events_with_jit_disabled():
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    out = subprocess.run([sys.executable, "-c", _PLAIN_SCRIPT], env=env, capture_output=True, text=True,
                         timeout=120, check=True)
    plain = json.loads(out.stdout)
    tr = simulate(M1, M2, H, 0.5, F, 15.0, 1.0, effects=(ViscousDamping(0.5), CoulombFriction(20.0, "m2")))
    assert tr.n_impacts >= 10 and np.any(tr.cause == GROUND_EVENT)  # impacts and stick-slip events
    assert plain["cause"] == tr.cause.tolist()
    assert np.allclose(plain["t"], tr.t0, rtol=1e-13, atol=1e-15)
    assert np.allclose(plain["x1"], tr.evaluate([0.3, 0.9])["x1"], rtol=1e-12, atol=1e-15)


def test_scene_damping_case_settles_its_chatter_and_keeps_momentum_balance():
    """models/dynamic_backlash_pd.toml's suggested ViscousDamping(5) at F = 42 N, w = 5 rad/s: chatter on a wall
    with nanometre bounces must converge into sticking (it used to run away in the rounding of x2 - x1), and
    M1 v1 + M2 v2 = (F/w) sin wt - c x1 must hold at every impact."""
    c, F42, w = 5.0, 42.07, 5.0
    tr = simulate(M1, M2, H, 0.5, F42, w, 20 * 2 * math.pi / w, effects=(ViscousDamping(c),), max_events=200_000)
    assert tr.n_events < 200 * 20 and tr.stuck_intervals.shape[0] >= 10
    imp = tr.impacts
    p = M1 * imp["v1_post"] + M2 * imp["v2_post"]
    x1 = tr.evaluate(imp["t"])["x1"]
    assert np.max(np.abs(p - (F42 / w * np.sin(w * imp["t"]) - c * x1))) < 1e-10 * F42 / w


def test_window_bounds_the_records_and_keeps_the_df():
    p = ImpactParameters(M1, M2, H, 0.5, F, 10.0)
    tp = 2 * math.pi / 10.0
    effects = (ViscousDamping(1.0),)
    full = simulate_with_effects(p, 40 * tp, effects, 10 ** 6, 1e-9)
    run = forced_motion(p, effects, 1e-9)
    tail = run.window(30 * tp, 40 * tp, 10 ** 6)
    assert tail.t0[0] == 30 * tp and tail.t0.size < 0.4 * full.t0.size
    assert run.n_events == full.n_events
    a = describing_function_from_trajectory(full, 30, 10)
    b = describing_function_from_trajectory(tail, 30, 10)
    assert a.n_impacts == b.n_impacts and abs(a.N - b.N) <= 1e-12 * abs(a.N)
    with pytest.raises(ValueError, match="t must lie"):
        tail.evaluate([tp])


def test_zero_damping_and_zero_spring_are_the_paper_model():
    p = ImpactParameters(M1, M2, H, 0.8, F, 35.0)
    t_end = 4 * 2 * math.pi / 35.0
    plain = simulate_with_effects(p, t_end, (), 10 ** 6, 1e-9)
    zero = simulate_with_effects(p, t_end, (ViscousDamping(0.0), LoadSpring(0.0)), 10 ** 6, 1e-9)
    assert np.array_equal(plain.t0, zero.t0) and np.array_equal(plain.post, zero.post)


def test_event_limit_error_says_how_to_raise_it():
    with pytest.raises(EventLimitError, match="larger max_events"):
        simulate(M1, M2, H, 0.5, F, 10.0, 2.0, effects=(ViscousDamping(1.0),), max_events=10)


def test_friction_stop_at_a_wall_with_elastic_impacts_settles_without_penetration():
    """eps = 1, friction on M1, strong damping: a Zeno sequence of impacts and friction stops ends with the pair
    resting against wall B on the ground (the stop leaves a relative speed below the chatter threshold, which
    must be settled, not left to drift through the wall)."""
    effects = (ViscousDamping(4.976344254909839), LoadSpring(0.21923888400854755),
               CoulombFriction(1.379172144107993, "m1"))
    tr = simulate(0.3720301234082074, 1.0, 1.0, 1.0, 5.260012043419313, 1.0, 4 * 2 * math.pi, effects=effects,
                  max_events=200_000)
    assert tr.stuck_intervals.shape[0] >= 1
    ends = tr.segment_ends
    t = np.minimum((tr.t0[:, None] + (ends - tr.t0)[:, None] * np.linspace(0, 1, 9)).ravel(), tr.t_end)
    g = tr.evaluate(t)["gap"]
    assert g.min() >= -1e-12 and g.max() <= 1 + 1e-12


@pytest.mark.parametrize("effects,w", [((ViscousDamping(5.0),), 12.0), ((CoulombFriction(5.0, "m2"),), 10.0)])
def test_continued_run_is_the_single_run(effects, w):
    # advance / forget / advance as an adaptive transient uses it: the same motion as one run from rest
    p = ImpactParameters(M1, M2, H, 0.5, F, w)
    tp = 2 * math.pi / w
    one = simulate_with_effects(p, 45 * tp, effects, 10 ** 6, 1e-9)
    run = EffectsRun(p, effects, 1e-9)
    run.advance(10 * tp, 10 ** 6, keep=False)
    run.advance(25 * tp, 10 ** 6, keep=False)
    run.forget()
    run.advance(35 * tp, 10 ** 6)
    run.advance(45 * tp, 10 ** 6)                     # two stored pieces joined
    cont = run.trajectory()
    assert run.n_events == one.n_events
    a = describing_function_from_trajectory(one, 25, 20)
    b = describing_function_from_trajectory(cont, 25, 20)
    assert a.n_impacts == b.n_impacts and abs(a.N - b.N) <= 1e-9 * abs(a.N)
    t = np.linspace(25 * tp, 45 * tp, 301)
    np.testing.assert_allclose(cont.evaluate(t)["x1"], one.evaluate(t)["x1"], rtol=0, atol=1e-12)
    with pytest.raises(EventLimitError):
        EffectsRun(p, effects, 1e-9).advance(45 * tp, 10)


@pytest.mark.parametrize("initial", [(0.01, -0.3, 0.0, 0.7), (-0.02, 0.1, 0.1, -0.4), (0.0, 0.0, 0.03, 0.0)])
def test_both_paths_of_the_engine_agree_from_any_start(initial):
    """forced_motion: the closed-form fast path and the linear-mode engine from the same free-flight start (on a wall
    or inside the clearance) are one motion, impact for impact."""
    p = ImpactParameters(M1, 1.3, H, 0.7, F, 25.0)
    tp = p.period
    fast = forced_motion(p, (), 1e-9, initial)
    general = forced_motion(p, (), 1e-9, initial, closed_form=False)
    a, b = fast.window(3 * tp, 6 * tp, 10 ** 6), general.window(3 * tp, 6 * tp, 10 ** 6)
    t = np.linspace(3 * tp, 6 * tp, 401)
    for key in ("x1", "v1", "gap"):
        np.testing.assert_allclose(b.evaluate(t)[key], a.evaluate(t)[key], rtol=0, atol=1e-11)
    ta, tb = (r.impacts["t"][r.impacts["t"] > 3 * tp] for r in (a, b))    # the window's impacts (the closed form
    assert ta.size > 0 and np.max(np.abs(ta - tb)) < 1e-12                  # also keeps the one starting its segment)
