"""Exact cycles in the user interface: the scene report, the Nyquist marker, ExactCycle.plot, Verification.plot.

The loop: a hysteresis relay (M = 1, up at x = +0.01, down at x = -0.01) around the conditionally stable plant
2 (s + 0.3)^2 / (s^3 (s + 2) (s + 3)), whose Nyquist curve crosses the negative real axis twice: two predicted
cycles (an unstable one at w ~ 0.44 rad/s, a stable one at w ~ 1.56 rad/s), both with an exact orbit.
"""
import math

import control as ct
import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.exact import exact_cycle  # noqa: E402
from dfloop.plot.nyquist import EXACT_LABEL, plot_nyquist  # noqa: E402
from dfloop.scene import load_scene, run_scene  # noqa: E402
from dfloop.verify import verify_cycle  # noqa: E402

NUM, DEN = [2.0, 1.2, 0.18], [1.0, 5.0, 6.0, 0.0, 0.0, 0.0]
HYSTERESIS = 0.01
G = ct.tf(NUM, DEN)
N = df.Relay(1.0, hysteresis=HYSTERESIS)

SCENE = f"""
[scene]
name = "relay_conditional"
title = "Hysteresis relay around a conditionally stable plant"

[plant]
num = {NUM}
den = {DEN}

[element]
type = "Relay"
M = 1.0
hysteresis = {HYSTERESIS}

[analysis]
exact = true
plots = []
"""


@pytest.fixture(scope="module")
def cycles():
    found = df.predict_limit_cycles(G, N, exact=True)
    assert len(found) == 2 and all(c.exact is not None and c.exact.success for c in found)
    return found


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _table_rows(markdown: str) -> list[list[str]]:
    lines = markdown.splitlines()
    start = lines.index("## Prediction, confidence and exact orbit")
    rows = []
    for line in lines[start + 4:]:  # title, blank, header, separator
        if not line.startswith("| "):
            break
        rows.append([cell.strip() for cell in line.strip("|").split(" | ")])
    return rows


def _percent(cell: str) -> float:
    assert cell.endswith(" %")
    return float(cell[:-2]) / 100


def test_scene_report_lists_the_exact_cycles_of_exact_cycle(tmp_path):
    path = tmp_path / "relay_conditional.toml"
    path.write_text(SCENE)
    report = run_scene(load_scene(path), tmp_path / "out", log=lambda _: None, progress=False)
    rows = _table_rows((tmp_path / "out" / "relay_conditional_report.md").read_text())
    assert len(rows) == len(report.cycles) == 2
    for row, c in zip(rows, report.cycles):
        # an independent exact_cycle call from the printed prediction gives the printed exact orbit
        ref = exact_cycle(G, N, (c.amplitude, c.frequency))
        assert ref.success
        assert float(row[1]) == pytest.approx(c.amplitude, rel=1e-5)
        assert float(row[2]) == pytest.approx(c.frequency, rel=1e-5)
        assert _percent(row[3]) == pytest.approx(c.confidence.distortion, rel=2e-3)
        assert _percent(row[4]) == pytest.approx(c.confidence.amplitude_error, rel=2e-3, abs=1e-5)
        assert _percent(row[5]) == pytest.approx(c.confidence.frequency_error, rel=2e-3, abs=1e-5)
        assert float(row[6]) == pytest.approx(ref.amplitude, rel=1e-7)
        assert float(row[7]) == pytest.approx(ref.frequency, rel=1e-7)
        word, modulus = row[8].split(" (")
        assert word == ("stable" if ref.stable else "unstable")
        assert float(modulus.rstrip(")")) == pytest.approx(ref.largest_multiplier, rel=1e-3)
        # the DF errors are (predicted - exact) / exact of the printed numbers
        assert _percent(row[9]) == pytest.approx(c.amplitude / ref.amplitude - 1, rel=2e-3)
        assert _percent(row[10]) == pytest.approx(c.frequency / ref.frequency - 1, rel=2e-3)
    # Floquet stability agrees with the DF's (Loeb) verdict on this loop: one unstable and one stable cycle
    assert sorted(r[8].split(" (")[0] for r in rows) == ["stable", "unstable"]
    assert [c.stability for c in report.cycles] == [r[8].split(" (")[0] for r in rows]


def test_report_without_exact_leaves_the_exact_columns_empty(tmp_path):
    path = tmp_path / "relay_conditional.toml"
    path.write_text(SCENE.replace("exact = true", "exact = false"))
    run_scene(load_scene(path), tmp_path, log=lambda _: None, progress=False)
    rows = _table_rows((tmp_path / "relay_conditional_report.md").read_text())
    assert len(rows) == 2 and all(r[6:11] == ["-"] * 5 for r in rows)
    assert all(r[11].startswith("not checked (no exact orbit asked for") for r in rows)   # the verdict column


def test_nyquist_marks_each_exact_cycle_on_g_at_the_exact_frequency(cycles):
    cplt = plot_nyquist(cycles)
    ax = cplt.axes[0, 0]
    exact_markers = cplt.lines[4]
    assert len(exact_markers) == len(cycles) == 2
    for marker, c in zip(exact_markers, cycles):
        g = complex(ct.evalfr(G, 1j * c.exact.frequency))  # python-control's own G(j w_exact)
        (x,), (y,) = marker.get_data()
        assert abs(complex(x, y) - g) <= 1e-9 * max(1.0, abs(g))
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert x0 < x < x1 and y0 < y < y1  # framed in view
        assert marker.get_marker() != cplt.lines[2][0].get_marker()  # distinct from the predicted markers
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels.count(EXACT_LABEL) == 1
    assert cplt.lines[-1][0].get_marker() == "+"  # the -1 marker stays last


def test_nyquist_draws_no_exact_marker_without_a_converged_orbit():
    G2 = ct.tf([5.0], [1.0, 1.0, 0.0])  # backlash servo: the inner (unstable) cycle's shooting does not converge
    found = df.predict_limit_cycles(G2, df.Backlash(1.0), exact=True)
    converged = [c for c in found if c.exact.success]
    cplt = plot_nyquist(found)
    assert len(cplt.lines[4]) == len(converged)
    labels = [t.get_text() for t in cplt.axes[0, 0].get_legend().get_texts()]
    assert labels.count(EXACT_LABEL) == (1 if converged else 0)


def test_exact_cycle_plot_draws_its_waveform_and_the_switches_at_the_thresholds(cycles):
    for c in cycles:
        ex = c.exact
        ax = ex.plot(unit="rad").axes[0, 0]
        wave, switches = ax.lines[0], ax.lines[1]
        assert np.array_equal(wave.get_xdata(), ex.t) and np.array_equal(wave.get_ydata(), ex.x)
        assert np.array_equal(switches.get_xdata(), ex.switching_times)
        # the relay switches where x crosses +/- the hysteresis: the marked points sit there, to within one
        # sample's change of x (they are interpolated on the sampled waveform)
        step = np.max(np.abs(np.diff(ex.x)))
        assert ex.switching_times.size == 2
        assert np.all(np.abs(np.abs(switches.get_ydata()) - HYSTERESIS) <= step)
        assert ax.get_xlabel() == "Time [s]" and ax.get_ylabel() == "Element input x [rad]"
        assert ax.get_xlim() == pytest.approx((0.0, 2 * math.pi / ex.frequency))


def test_exact_cycle_plot_rejects_bad_ax_and_a_failed_orbit(cycles):
    with pytest.raises(ValueError, match="ax must be a matplotlib Axes"):
        cycles[0].exact.plot(ax="left")
    with pytest.raises(ValueError, match="ax must be a matplotlib Axes"):
        cycles[0].exact.plot(ax=plt.subplots(1, 2)[1])
    failed = exact_cycle(G, N, cycles[0], max_deviation=1e-9)   # the orbit lies farther than that from it
    assert not failed.success
    with pytest.raises(ValueError, match="no orbit to plot"):
        failed.plot()


def test_verification_plot_draws_both_runs_over_the_predicted_and_exact_bands(cycles):
    stable = next(c for c in cycles if c.stability == "stable")
    v = verify_cycle(G, N, stable, periods=30, steps_per_period=100, measure_periods=5)
    fig, ax = plt.subplots()
    cplt = v.plot(ax, unit="rad", periods=None)
    assert cplt.axes[0, 0] is ax
    inside, outside = cplt.lines[0]
    for line, run in zip((inside, outside), v.runs):
        assert np.array_equal(line.get_xdata(), run.t) and np.array_equal(line.get_ydata(), run.x)
    T = 2 * math.pi / v.frequency
    d = v.perturbation
    # both runs end on the exact orbit found by shooting (an independent algorithm): the peak of |x| over the
    # last period equals the orbit's peak to 1 %
    peak = np.max(np.abs(stable.exact.x))
    for r in v.runs:
        assert abs(np.max(np.abs(r.x[r.t > r.t[-1] - T])) - peak) < 0.01 * peak
    edges = [float(line.get_ydata()[0]) for line in cplt.lines[1]]
    assert edges == pytest.approx([v.amplitude, -v.amplitude, stable.exact.amplitude, -stable.exact.amplitude])
    assert v.exact_amplitude == stable.exact.amplitude
    assert ax.get_ylabel() == "Element input x [rad]" and ax.get_xlabel() == "Time [s]"
    labels = [t.get_text() for t in cplt.legend.get_texts()]
    assert len(labels) == len(set(labels)) == 4 and all("settled at A=" in t for t in labels[:2])
    assert v.verdict == "stable" and d == 0.3
    # the default view: the first 20 predicted periods, where the runs converge
    ax2 = v.plot().axes[0, 0]
    assert ax2.get_xlim()[1] == pytest.approx(min(20 * T, v.runs[0].t[-1]))
    with pytest.raises(ValueError, match="ax must be a matplotlib Axes"):
        v.plot(ax=fig)
