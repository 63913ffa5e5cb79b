"""The exact impact kernel against conservation laws, eq. (9), geometry and an independent solve_ivp solver."""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from dfloop.errors import EventLimitError
from dfloop.impact.kernel import simulate
from dfloop.impact.reference import simulate_solve_ivp

M1, M2, H, F = 1.0, 1.0, 0.1, 50.0
# (eps, omega): periodic, chattering + sticking, plastic, nearly plastic, elastic, irregular
CASES = [(0.8, 35.0), (0.5, 10.0), (0.0, 30.0), (1e-6, 20.0), (1.0, 30.0), (0.2, 15.0), (0.5, 30.0)]


def _run(eps, w, periods=60, m1=M1):
    return simulate(m1, M2, H, eps, F, w, periods * 2 * math.pi / w)


@pytest.mark.parametrize("eps,w", CASES)
def test_momentum_at_every_impact(eps, w):
    tr = _run(eps, w)
    imp = tr.impacts
    assert imp["t"].size > 10
    for v1, v2 in (("v1_pre", "v2_pre"), ("v1_post", "v2_post")):
        p = M1 * imp[v1] + M2 * imp[v2]
        assert np.max(np.abs(p - F / w * np.sin(w * imp["t"]))) <= 1e-10 * F / w
    # and on every segment start (including stuck phases, after the plastic settle)
    seg_p = M1 * tr.v1 + M2 * (tr.v1 + tr.u)
    assert np.max(np.abs(seg_p - F / w * np.sin(w * tr.t0))) <= 1e-10 * F / w


@pytest.mark.parametrize("eps,w", CASES)
def test_energy_loss_is_eq9(eps, w):
    imp = _run(eps, w).impacts
    ke = lambda v1, v2: 0.5 * M1 * v1 ** 2 + 0.5 * M2 * v2 ** 2  # noqa: E731
    lost = ke(imp["v1_pre"], imp["v2_pre"]) - ke(imp["v1_post"], imp["v2_post"])
    eq9 = 0.5 * (1 - eps ** 2) * M1 * M2 / (M1 + M2) * (imp["v1_pre"] - imp["v2_pre"]) ** 2
    scale = ke(imp["v1_pre"], imp["v2_pre"]) + ke(imp["v1_post"], imp["v2_post"])
    assert np.max(np.abs(lost - eq9) / scale) < 1e-12
    # Newton's law (6)
    du_pre = imp["v1_pre"] - imp["v2_pre"]
    du_post = imp["v1_post"] - imp["v2_post"]
    assert np.max(np.abs(du_post + eps * du_pre)) <= 1e-12 * np.max(np.abs(du_pre))


@pytest.mark.parametrize("eps,w", CASES)
def test_no_penetration_on_dense_sampling_of_every_segment(eps, w):
    tr = _run(eps, w, periods=30)
    ends = tr.segment_ends
    frac = np.linspace(0.0, 1.0, 41)
    t = (tr.t0[:, None] + (ends - tr.t0)[:, None] * frac[None, :]).ravel()
    g = tr.evaluate(np.minimum(t, tr.t_end))["gap"]
    assert g.min() >= -1e-12 * H
    assert g.max() <= H * (1 + 1e-12)


@pytest.mark.parametrize("eps,w", CASES)
def test_stuck_phases_have_compressive_contact(eps, w):
    tr = _run(eps, w, periods=30)
    for t0, t1, side in tr.stuck_intervals:
        t = np.linspace(t0, t1, 21)
        c = np.cos(w * t)
        # contact force on M1 from M2 is -M1 F cos(wt)/(M1+M2): <= 0 on side A, >= 0 on side B
        if side == 0:
            assert c.max() <= 1e-9
        else:
            assert c.min() >= -1e-9


def test_chattering_cases_stick_and_elastic_never_sticks():
    assert _run(0.5, 10.0).stuck_intervals.shape[0] > 10
    assert _run(1e-6, 20.0).stuck_intervals.shape[0] > 10
    assert _run(1.0, 30.0).stuck_intervals.shape[0] == 0


def test_positions_continuous_and_velocity_is_derivative():
    tr = _run(0.5, 10.0, periods=10)
    w = 10.0
    # position continuity across every event: evaluate just before each segment start
    before = tr.evaluate(np.nextafter(tr.t0[1:], 0.0))
    assert np.max(np.abs(before["x1"] - tr.x1[1:])) < 1e-12
    assert np.max(np.abs(before["gap"] - tr.gap[1:])) < 1e-12
    # velocity = d/dt position inside segments (central differences)
    mid = 0.5 * (tr.t0[:-1] + tr.t0[1:])
    d = 1e-6 * (tr.t0[1:] - tr.t0[:-1])
    ok = d > 1e-9 / w
    for pos, vel in (("x1", "v1"), ("x2", "v2")):
        fd = (tr.evaluate(mid + d)[pos] - tr.evaluate(mid - d)[pos]) / (2 * d)
        assert np.allclose(fd[ok], tr.evaluate(mid)[vel][ok], rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("eps,w", [(0.8, 35.0), (0.5, 30.0), (0.2, 40.0), (0.3, 25.0)])
def test_agrees_with_solve_ivp_on_periodic_cases(eps, w):
    t_end = 1.0  # the reference's own error (rtol 1e-12) grows through the transient: stay within 1e-10 s
    ref = simulate_solve_ivp(M1, M2, H, eps, F, w, t_end)
    tr = simulate(M1, M2, H, eps, F, w, t_end)
    imp = tr.impacts
    assert imp["t"].size == ref["t"].size >= 10
    assert np.array_equal(imp["side"], ref["side"])
    assert np.max(np.abs(imp["t"] - ref["t"])) < 1e-10
    t = np.linspace(0, t_end, 777)
    assert np.max(np.abs(tr.evaluate(t)["x1"] - ref["sol"](t)[0])) < 1e-8 * H


def test_no_impact_below_beta_quarter_keeps_x1_at_zero():
    w = 1.01 * 2 * math.sqrt(F / (H * M2))
    tr = simulate(M1, M2, H, 0.5, F, w, 50 * 2 * math.pi / w)
    assert tr.n_impacts == 0
    t = np.linspace(0, tr.t_end, 1001)
    st = tr.evaluate(t)
    assert np.all(st["x1"] == 0.0)
    # x2 - x2(0) = F/(M2 w^2) (1 - cos wt): peak 2F/(M2 w^2) < h/2
    assert np.allclose(st["x2"] - H / 2, F / (M2 * w * w) * (1 - np.cos(w * t)), rtol=0, atol=1e-15)


def test_similar_runs_are_rescaled_copies():
    eps, w = 0.8, 35.0
    beta = F / (M2 * H * w * w)
    a = simulate(M1, M2, H, eps, F, w, 20 * 2 * math.pi / w)
    b = simulate(M1 / M2, 1.0, 1.0, eps, beta, 1.0, 20 * 2 * math.pi)
    assert np.allclose(a.impacts["t"] * w, b.impacts["t"], rtol=1e-12, atol=1e-12)
    assert np.allclose(a.x1 / H, b.x1, rtol=1e-11, atol=1e-13)


def test_event_limit_raises_naming_bound_and_time():
    with pytest.raises(EventLimitError, match=r"max_events = 50 reached at t = "):
        simulate(M1, M2, H, 0.5, F, 10.0, 10.0, max_events=50)


@pytest.mark.parametrize("name,args", [
    ("m1", (0.0, 1, 0.1, 0.5, 50, 30, 1)), ("m2", (1, -1, 0.1, 0.5, 50, 30, 1)),
    ("h", (1, 1, 0.0, 0.5, 50, 30, 1)), ("restitution", (1, 1, 0.1, 1.5, 50, 30, 1)),
    ("restitution", (1, 1, 0.1, -0.1, 50, 30, 1)), ("force", (1, 1, 0.1, 0.5, 0.0, 30, 1)),
    ("omega", (1, 1, 0.1, 0.5, 50, -3, 1)), ("t_end", (1, 1, 0.1, 0.5, 50, 30, 0)),
    ("m1", (np.nan, 1, 0.1, 0.5, 50, 30, 1)), ("force", (1, 1, 0.1, 0.5, np.nan, 30, 1)),
    ("restitution", (1, 1, 0.1, np.nan, 50, 30, 1)), ("omega", (1, 1, 0.1, 0.5, 50, np.inf, 1)),
])
def test_bad_input_names_the_parameter(name, args):
    with pytest.raises(ValueError, match=name):
        simulate(*args)


def test_evaluate_rejects_times_outside_the_run():
    tr = simulate(M1, M2, H, 0.5, F, 30.0, 1.0)
    with pytest.raises(ValueError, match="t must lie"):
        tr.evaluate([0.5, 1.5])
    with pytest.raises(ValueError, match="t must lie"):
        tr.evaluate([np.nan])


_SCRIPT = """
import json, sys
import numpy as np
from dfloop.impact.kernel import simulate
tr = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 10.0, 1.5)
print(json.dumps({"t": tr.t0.tolist(), "x1": tr.x1.tolist(), "v1": tr.v1.tolist(), "cause": tr.cause.tolist()}))
"""


def test_same_results_with_jit_disabled():
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    out = subprocess.run([sys.executable, "-c", _SCRIPT], env=env, capture_output=True, text=True, timeout=120,
                         check=True)
    plain = json.loads(out.stdout)
    tr = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 10.0, 1.5)
    assert plain["cause"] == tr.cause.tolist()
    assert tr.stuck_intervals.shape[0] > 0  # the case exercises chatter and stuck phases
    assert np.allclose(plain["t"], tr.t0, rtol=1e-13, atol=1e-15)
    assert np.allclose(plain["x1"], tr.x1, rtol=1e-12, atol=1e-15)
    assert np.allclose(plain["v1"], tr.v1, rtol=1e-12, atol=1e-14)


def test_random_parameters_keep_momentum_and_no_penetration():
    """Mass ratios 0.1..10, eps in {0, 1e-6, U(0,1), 1}, beta 0.2..500: invariants hold everywhere."""
    rng = np.random.default_rng(1)
    for _ in range(120):
        m1 = 10 ** rng.uniform(-1, 1)
        eps = rng.choice([0.0, 1e-6, rng.uniform(0, 1), 1.0])
        beta = 10 ** rng.uniform(-0.7, 2.7)
        tr = simulate(m1, 1.0, 1.0, eps, beta, 1.0, 40 * 2 * math.pi)
        ends = tr.segment_ends
        t = np.minimum((tr.t0[:, None] + (ends - tr.t0)[:, None] * np.linspace(0, 1, 9)).ravel(), tr.t_end)
        g = tr.evaluate(t)["gap"]
        assert g.min() >= -1e-12 and g.max() <= 1 + 1e-12
        imp = tr.impacts
        p = m1 * imp["v1_post"] + imp["v2_post"]
        assert np.max(np.abs(p - beta * np.sin(imp["t"])), initial=0.0) <= 1e-10 * beta


def test_default_event_bound_grows_with_the_run_and_covers_chatter():
    """The default bound is sized from the number of periods; a chattering run of many periods stays inside
    it (counted events per period against the per-period bound), and the error says how to raise it."""
    from dfloop.impact.model import DEFAULT_MAX_EVENTS, default_max_events

    assert default_max_events(0.5, 1e-9, 10) == DEFAULT_MAX_EVENTS
    assert default_max_events(0.5, 1e-9, 1e6) > 10 * DEFAULT_MAX_EVENTS
    for eps in (0.2, 0.5, 0.9):
        periods = 200
        tr = simulate(M1 / M2, 1.0, 1.0, eps, 300.0, 1.0, periods * 2 * math.pi)   # beta = 300: chatter
        per_period = default_max_events(eps, 1e-9, 1e9) / 1e9
        assert tr.t0.size / periods <= per_period
        assert tr.n_impacts / periods > 20                                      # it does chatter
    with pytest.raises(EventLimitError, match=r"pass a larger max_events \(e.g. max_events=100\)"):
        simulate(M1, M2, H, 0.5, F, 10.0, 10.0, max_events=50)


def test_kernel_run_with_forget_is_exact_and_bounded():
    """Continuing a run in pieces and forgetting the past gives the same motion as one run."""
    from dfloop.impact.kernel import KernelRun
    from dfloop.impact.model import ImpactParameters

    p = ImpactParameters(M1, M2, H, 0.5, F, 30.0)
    one = simulate(M1, M2, H, 0.5, F, 30.0, 60 * p.period)
    run = KernelRun(p, initial=None, capacity=8)
    run.advance(40 * p.period, 10**6, keep=False)
    run.forget()
    run.advance(60 * p.period, 10**6)
    part = run.trajectory()
    assert part.t0.size < one.t0.size
    t = np.linspace(40.5 * p.period, 60 * p.period, 301)
    np.testing.assert_allclose(part.evaluate(t)["x1"], one.evaluate(t)["x1"], rtol=0, atol=1e-12 * H)
