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
    assert miss.extra["outcome"] == "another cycle"
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
    # a delay with an element with memory has no exact engine: not checked, with the reason naming N
    bl = df.predict_limit_cycles(delayed(ct.tf([4.0], [1.0, 1.0, 0.0]), 0.3), df.Backlash(h=0.5), exact=True)
    assert bl and all(c.verdict.kind == "not checked" and "N: Backlash" in c.verdict.detail for c in bl)


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
