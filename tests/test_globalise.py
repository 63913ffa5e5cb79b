"""Never a false "no orbit" (issue 16): exact_cycle globalises a failed shooting and, when it still finds no orbit
near the prediction, reports where the motions went. Truths: long event-located simulations (no Newton)."""
import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.harmonics import steady_state
from dfloop.verify import simulate_loop


def test_pade_chain_relay_orbit_is_found_where_shooting_from_the_prediction_stalls():
    num, den = ct.pade(0.5, 5)
    G = ct.tf(num, den) * ct.tf([1.0], [2.0, 1.0])
    N = df.Relay(M=1.0, hysteresis=0.05)
    c = df.predict_limit_cycles(G, N)[0]
    e = df.exact_cycle(G, N, c)
    assert e.success, e.message
    assert e.predicted == (c.amplitude, c.frequency)
    assert e.amplitude_error == pytest.approx((c.amplitude - e.amplitude) / e.amplitude, rel=1e-14)
    # independent: a long run on the exact flow (no shooting) settles on the same orbit
    sim = simulate_loop(G, N, c.amplitude, c.frequency, periods=150, steps_per_period=800)
    st = steady_state(sim.t, sim.x, 20)
    assert st.periodicity < 1e-6
    assert e.frequency == pytest.approx(st.frequency, rel=1e-6)
    assert e.amplitude == pytest.approx(st.amplitude, rel=1e-5)
    assert e.stable
    # the exact delay this Pade chain approximates gives the 2.9496 rad/s (within the Pade error)
    assert abs(e.frequency - 2.9496) < 1e-3


def test_no_orbit_answer_carries_where_the_motions_went():
    G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)    # models/backlash_servo.toml: the inner cycle is an artefact
    inner, outer = df.predict_limit_cycles(G, N)
    miss = df.exact_cycle(G, N, inner)
    hit = df.exact_cycle(G, N, outer)
    assert not miss.success and miss.amplitude is None and hit.success
    # the motions go to the outer cycle or rest; the boundary between the two is rest (tests/test_edge_tracking.py)
    assert miss.extra["outcome"] == "edge rest" and "go to another cycle" in miss.message
    assert f"A={hit.amplitude:.6g}" in miss.message and f"w={hit.frequency:.6g}" in miss.message
    motions = miss.extra["motions"]
    assert len(motions) == 3 and {m["outcome"] for m in motions} <= {"periodic", "rest", "not periodic"}
    periodic = [m for m in motions if m["outcome"] == "periodic"]
    assert periodic
    for m in periodic:    # every settled motion is the outer orbit (an independent run's measure, 1e-3)
        assert m["amplitude"] == pytest.approx(hit.amplitude, rel=1e-3)
        assert m["frequency"] == pytest.approx(hit.frequency, rel=1e-3)
    assert "Evidence:" in miss.message and "periodic, A=" in miss.message


def test_delay_prediction_far_from_any_orbit_reports_the_slow_cycle():
    from dfloop.solve.delay import delayed

    G = delayed(ct.tf([1.0], [1.0, 1.0]), 0.5)
    N = df.Relay(1.0)
    # a made-up prediction far from every orbit (between the 3.78 and 15.9 rad/s orbits): the motions go to 3.78
    miss = df.exact_cycle(G, N, (0.2, 9.0), max_deviation=0.2)
    assert not miss.success
    assert miss.extra["outcome"] == "another cycle"
    w_slow = np.pi / (0.5 + np.log(2 - np.exp(-0.5)))
    assert f"w={w_slow:.6g}" in miss.message


def test_every_prediction_is_classified():
    from dfloop.solve.delay import delayed

    G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)
    inner, outer = df.predict_limit_cycles(G, N, exact=True)
    assert inner.verdict.kind == "artefact" and "another cycle" in inner.verdict.detail
    assert outer.verdict.kind == "confirmed"
    assert outer.verdict.distance == pytest.approx(
        max(abs(np.log(outer.amplitude / outer.exact.amplitude)), abs(np.log(outer.frequency / outer.exact.frequency))),
        rel=1e-12)
    text = repr(df.predict_limit_cycles(G, N, exact=True))
    assert "artefact" in text and "confirmed" in text
    assert df.predict_limit_cycles(G, N)[0].verdict.kind == "not checked"
    # a delay with an element with memory is checked (the delay equation with the element's state in the
    # history); here the DF's unstable cycle sits between motions that rest and motions that diverge and shooting
    # from it does not converge: inconclusive, never "artefact"
    bl = df.predict_limit_cycles(delayed(ct.tf([4.0], [1.0, 1.0, 0.0]), 0.3), df.Backlash(h=0.5), exact=True)
    assert bl and all(c.verdict.kind == "not checked" and "unstable orbit may lie" in c.verdict.detail for c in bl)


def test_relay_delay_scene_report_classifies_its_five_cycles(tmp_path):
    from dfloop.scene import find_scene, load_scene, run_scene

    report = run_scene(load_scene(find_scene("relay_delay")), out_dir=tmp_path, log=lambda *_: None,
                       progress=False)
    kinds = [c.verdict.kind for c in report.cycles]
    assert kinds == ["confirmed"] * 5
    assert [c.exact.stable for c in report.cycles] == [True, False, False, False, False]
    md = report.to_markdown()
    assert md.count("| confirmed |") == 5


def test_nyquist_labels_carry_the_verdicts():
    import matplotlib
    matplotlib.use("Agg")
    from dfloop.plot import plot_nyquist

    G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)
    cycles = df.predict_limit_cycles(G, N, exact=True)
    ax = plot_nyquist(cycles).axes[0, 0]
    insets = [ch for ch in ax.get_children() if isinstance(ch, matplotlib.axes.Axes)]   # the zoom of a crowd
    texts = [t.get_text() for a in [ax, *insets] for t in a.texts]
    for c in cycles:
        assert any(f"{N.input_name}={c.amplitude:.3g}" in t and c.verdict.kind in t for t in texts)
    assert {c.verdict.kind for c in cycles} == {"artefact", "confirmed"}


def test_dead_zone_motion_resting_off_zero_is_rest_with_where_never_not_periodic():
    # a dead zone around a plant with an integrator: the motion started inside the (unstable) predicted cycle
    # crosses zero a few times, then rests at a nonzero x inside the dead band (any x with |x| <= 0.5 is an
    # equilibrium); the globalisation must say "rest" and where, never "not periodic"
    from scipy.integrate import solve_ivp

    from dfloop.hybrid import harmonic_balance_state, loop_model
    from dfloop.hybrid.globalise import RUN_PERIODS
    from dfloop.solve.verdict import exact_kind

    G, N = ct.tf([3.0], [1.0, 2.0, 1.0, 0.0]), df.DeadZone(0.5)
    c = df.predict_limit_cycles(G, N)[0]
    pred = (0.85 * c.amplitude, c.frequency)
    e = df.exact_cycle(G, N, pred, max_deviation=0.1)   # the unstable orbit (A ~ 1.85) is farther than 0.1
    assert not e.success and "not periodic" not in e.message
    first = e.extra["motions"][0]
    assert first["outcome"] == "rest" and first["y_end"] == 0.0
    assert 0.05 < abs(first["x_end"]) < 0.5                       # off zero, inside the dead band
    assert f"comes to rest at x = {first['x_end']:.4g}" in e.message
    # some motions rest, one diverges: the unstable orbit that separates them (A ~ 1.85) is found by edge tracking,
    # farther than max_deviation from this prediction: another cycle (the orbit itself: tests/test_edge_tracking.py)
    assert e.extra["outcome"] == "another cycle" and e.extra["edge"]["outcome"] == "orbit"
    assert "edge tracking) settles on another cycle, the exact orbit A=1.8504" in e.message and "(unstable)" in e.message
    assert exact_kind(e) == "artefact"
    # independent truth: the same start integrated by scipy (the dead zone is continuous: no events needed)
    loop = loop_model(G, N, *pred)
    A, B = loop.plant
    Cr = -loop.x_row[:A.shape[0]]
    s0 = harmonic_balance_state(loop, N, *pred)

    def rhs(t, s):
        x = -Cr @ s
        return A @ s + B * (np.sign(x) * max(abs(x) - 0.5, 0.0))

    sol = solve_ivp(rhs, (0.0, RUN_PERIODS * 2 * np.pi / pred[1]), s0, method="DOP853", rtol=1e-11, atol=1e-12)
    assert first["x_end"] == pytest.approx(-Cr @ sol.y[:, -1], abs=1e-6)


def test_a_boundary_between_rest_and_divergence_is_followed_by_edge_tracking():
    """A backlash around an order-12 plant (integrator, Pade-8 delay, two lags): the DF's unstable cycle. The
    large-amplitude loop (backlash -> unit gain) has a closed-loop pole in the right half plane (python-control),
    so the motions started on and outside the prediction diverge (followed on the exact flow to the divergence
    bound: they used to stop at a false sliding release, the switch tests drowned in the companion form's
    rounding), the one inside comes to rest. Neither Newton nor the homotopy from the prediction converge. Edge
    tracking between rest and divergence puts the boundary at the start amplitude h/2, where the predicted
    sinusoid stops leaving the play (a start below it is exactly at rest: the DF is 0 there), and finds no
    oscillation on it: the prediction (A = 1.015 h/2) is an artefact of the DF."""
    from dfloop.solve.verdict import exact_kind

    num, den = ct.pade(1.0, 8)
    G = ct.tf([4.0], [1, 1, 0]) * ct.tf(num, den) * ct.tf([1], [0.1, 1]) * ct.tf([1], [0.05, 1])
    assert np.max(ct.poles(ct.feedback(G, 1)).real) > 0.1
    N = df.Backlash(h=0.5)
    (c,) = df.predict_limit_cycles(G, N)
    e = df.exact_cycle(G, N, c)
    kinds = [m["outcome"] for m in e.extra["motions"]]
    assert not e.success and sorted(kinds) == ["divergence", "divergence", "rest"]
    assert "homotopy" in e.message
    assert e.extra["outcome"] == "edge rest" and e.extra["edge"]["outcome"] == "slow"
    assert (e.extra["edge"]["inside"], e.extra["edge"]["outside"]) == ("rest", "divergence")
    assert e.extra["edge"]["boundary"] * c.amplitude == pytest.approx(0.25, rel=1e-6)     # h/2
    assert exact_kind(e) == "artefact"


def test_a_start_far_from_every_orbit_is_answered_from_the_motions_without_endless_newton_steps():
    # a start (0.6 A, 2 w) off the dead zone's unstable cycle of 3/(s(s+1)^2): Newton's steps from it once
    # asked for periods several times the start's, each flow running to its event bound (minutes); a step
    # may now change the period by at most PERIOD_STEP, and the answer comes from the motions: all rest
    # inside the dead band (the unstable cycle, A = 1.85, lies beyond every start)
    G = ct.tf([3.0], [1.0, 2.0, 1.0, 0.0])
    e = df.exact_cycle(G, df.DeadZone(0.5), (0.6 * 1.887, 2.0), max_deviation=0.7)
    assert not e.success and e.extra["outcome"] == "rest", e.message
    assert all(m["outcome"] == "rest" and abs(m["x_end"]) <= 0.5 for m in e.extra["motions"])
