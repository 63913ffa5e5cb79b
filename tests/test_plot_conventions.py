"""Plots a control engineer reads at a glance: no overlapping labels, no repeated legend entries, the -1 point
marked, arrows along increasing w and A, one unit style, and gaps (not lines) at jumps of N."""
import re
import warnings

import control as ct
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.text import Text  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.describing.base import DescribingFunction  # noqa: E402
from dfloop.impact.kernel import simulate  # noqa: E402
from dfloop.plot import case_labels, plot_loci, plot_nyquist, plot_residual_map, plot_time_response  # noqa: E402
from dfloop.plot._labels import legend  # noqa: E402
from dfloop.solve import LimitCycles  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def RELAY_DELAY(w):  # the plant of models/relay_delay.toml: exp(-0.5 s) / (s + 1)
    return np.exp(-0.5j * w) / (1j * w + 1)


class StepRelay(DescribingFunction):
    """An ideal relay whose level halves at A = 2: N = 4 / (pi A) below, 2 / (pi A) from there on, so -1/N
    runs along the negative real axis from 0 to -pi/2 and then from -pi outwards: a gap (-pi, -pi/2)."""

    def _evaluate(self, A, omega):
        with np.errstate(divide="ignore"):
            return np.where(A < 2.0, 4.0, 2.0) / (np.pi * A) + 0j


def _segments(line):
    z = line.get_xdata() + 1j * line.get_ydata()
    ok = np.isfinite(z[:-1]) & np.isfinite(z[1:])
    return z[:-1][ok], z[1:][ok]


def _text_boxes(ax):
    """(text, screen box) of every label drawn in ``ax`` and in its insets (child axes)."""
    ax.figure.canvas.draw()
    renderer = ax.figure.canvas.get_renderer()
    return [(t.get_text(), Text.get_window_extent(t, renderer)) for a in [ax, *ax.child_axes] for t in a.texts
            if t.get_text()]


def test_close_cycles_get_labels_that_do_not_overlap():
    N = df.Relay(1.0)
    cycles = df.predict_limit_cycles(RELAY_DELAY, N, omega=(0.1, 60.0))
    assert len(cycles) >= 5  # several cycles crowd the origin
    ax = plot_nyquist(cycles).axes[0, 0]
    boxes = _text_boxes(ax)
    for i, (ti, bi) in enumerate(boxes):
        for tj, bj in boxes[:i]:
            assert not bi.overlaps(bj), f"{ti!r} overlaps {tj!r}"
    text = "\n".join(t for t, _ in boxes)
    for c in cycles:  # every cycle is labelled somewhere (beside its point, or in the crowded list)
        assert f"A={c.amplitude:.3g}, ω={c.frequency:.3g} rad/s" in text


def test_minus_one_marked_and_legend_without_repeats():
    G = ct.tf([1.5], [1, 2, 1, 0])
    for cplt in (plot_nyquist(df.predict_limit_cycles(G, df.Backlash(0.2))), plot_loci(df.Backlash(0.2))):
        (critical,) = cplt.lines[-1]
        assert np.ravel(critical.get_data()).tolist() == [-1.0, 0.0]
        assert critical.get_marker() == "+" and critical.get_color() == "r"
        labels = [t.get_text() for t in cplt.axes[0, 0].get_legend().get_texts()]
        assert len(labels) == len(set(labels))
    fig, ax = plt.subplots()
    for k in range(3):
        ax.plot([0, k], [0, 1], color="C0", label="F=50 N")
    ax.plot([0, 1], [1, 0], label="other")
    assert [t.get_text() for t in legend(ax).get_texts()] == ["F=50 N", "other"]


def test_case_labels_show_only_what_varies():
    cases = [{"eps": f"{e:g}", "F": "50 N"} for e in (0.1, 0.2, 0.3)]
    labels, common = case_labels(cases)
    assert labels == ["eps=0.1", "eps=0.2", "eps=0.3"] and common == "F=50 N"
    labels, common = case_labels([{"eps": e, "F": f} for e in ("0.2", "0.5") for f in ("10 N", "20 N")])
    assert len(set(labels)) == 4 and common == ""


def test_arrows_point_along_increasing_frequency_and_amplitude():
    G = ct.tf([1.5], [1, 2, 1, 0])
    cplt = plot_nyquist(df.predict_limit_cycles(G, df.Backlash(0.2)))
    ax = cplt.axes[0, 0]
    arrows = [t for t in ax.texts if t.get_gid() == "dfloop-direction"]
    curves = [cplt.lines[0][0], *cplt.lines[1]]  # drawn in order of increasing w (G) and A (-1/N)
    assert len(arrows) == len(curves)
    for arrow, line in zip(arrows, curves):
        z = line.get_xdata() + 1j * line.get_ydata()
        tail = np.nanargmin(np.abs(z - complex(*arrow.xyann)))
        head = np.nanargmin(np.abs(z - complex(*arrow.xy)))
        assert z[tail] == complex(*arrow.xyann) and z[head] == complex(*arrow.xy)
        assert head > tail


def test_locus_breaks_at_a_jump_in_amplitude_and_reaches_both_sides():
    cplt = plot_loci(StepRelay(), amplitudes=np.geomspace(0.1, 10.0, 300))
    (line,) = cplt.lines[0]
    a, b = _segments(line)
    lo, hi = np.minimum(a.real, b.real), np.maximum(a.real, b.real)
    assert not np.any((lo < -np.pi / 2 - 1e-3) & (hi > -np.pi + 1e-3)), "a segment bridges the gap"
    x = line.get_xdata()
    assert np.nanmin(np.abs(x + np.pi / 2)) < 1e-9 and np.nanmin(np.abs(x + np.pi)) < 1e-9  # both sides drawn


def test_nyquist_locus_leaves_a_gap_at_the_reported_jump():
    G = ct.tf([4], [1, 2, 1, 0])  # crosses the negative real axis at -2, inside the gap (-pi, -pi/2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = df.predict_limit_cycles(G, StepRelay(), omega=(0.2, 5.0), amplitude=(0.1, 10.0))
    (j,) = cycles.jump_crossings
    ends = sorted((-1 / n).real for n in j.N_sides)
    assert ends == pytest.approx([-np.pi, -np.pi / 2], rel=1e-6)
    (line,) = plot_nyquist(cycles).lines[1]
    a, b = _segments(line)
    lo, hi = np.minimum(a.real, b.real), np.maximum(a.real, b.real)
    assert not np.any((lo < ends[1] - 1e-6) & (hi > ends[0] + 1e-6)), "a segment spans the reported jump"


def test_frequency_step_breaks_the_loci_family():
    from test_solve_jumps import SteppedDF

    N = SteppedDF(1.0)  # phase of N steps at w = 1 for every amplitude
    w = np.linspace(0.2, 1.8, 161)
    for line in plot_loci(N, amplitudes=[0.8, 2.0], omega=w).lines[0]:
        A = float(re.search(r"= ([0-9.]+)", line.get_label()).group(1))
        left, right = -1 / N(A, 1.0 - 1e-12), -1 / N(A, 1.0)
        a, b = _segments(line)
        assert np.max(np.abs(b - a)) < 0.5 * abs(right - left)
        z = line.get_xdata() + 1j * line.get_ydata()
        assert np.nanmin(np.abs(z - left)) < 1e-9 and np.nanmin(np.abs(z - right)) < 1e-9


def test_one_unit_style_on_every_axis():
    G, N = ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(0.2)
    cycles = df.predict_limit_cycles(G, N)
    axes = [plot_nyquist(cycles).axes[0, 0], plot_residual_map(cycles, shape=(10, 10)).axes[0, 0],
            plot_loci(N).axes[0, 0], plot_time_response(simulate(1.0, 1.0, 0.1, 0.5, 50.0, 25.0, 0.3), "v1").axes[0, 0]]
    labels = [lab for ax in axes for lab in (ax.get_xlabel(), ax.get_ylabel())]
    assert all(lab for lab in labels)
    assert not any(re.search(r"\((m|s|N|rad/s|m/s|N/m)\)", lab) for lab in labels)  # units in [brackets]
    assert axes[1].get_xlabel() == "Frequency [rad/s]" and axes[1].get_ylabel() == "Amplitude X [m]"
    assert axes[3].get_xlabel() == "Time [s]"


def test_limit_cycles_plot_returns_the_nyquist_picture():
    G, N = ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(0.2)
    cycles = df.predict_limit_cycles(G, N)
    cplt = cycles.plot()
    assert isinstance(cplt, ct.ControlPlot) and len(cplt.lines[2]) == len(cycles)
    bare = LimitCycles([], (0.1, 1.0), (0.1, 1.0), {"amplitude": "given", "omega": "given"}, (2, 2), 0)
    with pytest.raises(ValueError, match="records the plant and element"):
        bare.plot()
