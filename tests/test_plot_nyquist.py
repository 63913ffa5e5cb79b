"""plot_nyquist / plot_residual_map: the drawn data are the plant response, the -1/N locus and the cycles."""
import re

import control as ct
import matplotlib

matplotlib.use("Agg")
import matplotlib.colors as mcolors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.solve import as_plant
from dfloop.describing.base import DescribingFunction  # noqa: E402
from dfloop.plot.nyquist import plot_nyquist, plot_residual_map  # noqa: E402

G = ct.tf([1.5], [1, 2, 1, 0])
N = df.Backlash(h=0.2)


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def test_nyquist_draws_plant_locus_and_cycles_by_stability():
    cycles = df.predict_limit_cycles(G, N)
    cplt = plot_nyquist(cycles)
    assert isinstance(cplt, ct.ControlPlot)
    ax = cplt.axes[0, 0]
    (g_line,), (n_line,) = cplt.lines[0], cplt.lines[1]
    w_pick = np.geomspace(*cycles.omega_window, 2000)[100]
    x, y = g_line.get_data()
    gp = as_plant(G)(np.array([w_pick]))[0]
    assert np.min(np.abs(x + 1j * y - gp)) < 1e-12
    xs, ys = n_line.get_data()
    lo, hi = cycles.amplitude_window
    # -1/N over log-spaced amplitudes of the window plus points crowding its lower edge (steep there)
    A = np.unique(np.concatenate([np.geomspace(lo, hi, 1000),
                                  lo + (min(hi, 10 * lo) - lo) * np.geomspace(1e-9, 1.0, 400)]))
    np.testing.assert_allclose(xs + 1j * ys, -1 / N(A))
    markers = cplt.lines[2]
    assert len(markers) == len(cycles) == 2
    for c, m in zip(cycles, markers):
        np.testing.assert_allclose(np.ravel(m.get_data()), [c.G.real, c.G.imag])
        assert (m.get_markerfacecolor() != "none") == c.stable  # filled iff stable
    texts = [t.get_text() for t in ax.texts]
    assert any(f"X={c.amplitude:.3g} m, ω={c.frequency:.3g} rad/s" in t and c.stability in t for c in cycles for t in texts)


class _DelayedSaturation(DescribingFunction):
    frequency_dependent = True

    def _evaluate(self, A, omega):
        return df.Saturation(1.0)(A) * np.exp(-0.3j * omega)


def test_frequency_dependent_locus_family_and_marginal_marker():
    Nf = _DelayedSaturation()
    cycles = df.predict_limit_cycles(ct.tf([2], [1, 2, 2, 1]), Nf, omega=(0.1, 10), amplitude=(1, 50))
    cplt = plot_nyquist(cycles, n_loci=4)
    # one locus over the frequency window per amplitude: 4 spanning the amplitude window (none within 10 % of a
    # cycle's, which would duplicate its curve) and each cycle's amplitude
    (c,) = cycles
    grid = [a for a in np.geomspace(1, 50, 4) if abs(a / c.amplitude - 1) >= 0.1]
    labels = [line.get_label() for line in cplt.lines[1]]
    drawn = sorted(float(re.search(r"A=([0-9.e+-]+)", lab).group(1)) for lab in labels)
    np.testing.assert_allclose(drawn, sorted(grid + [c.amplitude]), rtol=5e-3)  # labels carry 3 digits
    # the cycle's locus -1/N(A*, w) passes through the cycle's point G(j w*) (1 + G N = 0 there)
    (mine,) = [line for line in cplt.lines[1] if "a cycle's amplitude" in line.get_label()]
    z = mine.get_xdata() + 1j * mine.get_ydata()
    assert np.nanmin(np.abs(z - c.G)) < 1e-9 * abs(c.G)
    fig, ax2 = plt.subplots()
    touching = df.predict_limit_cycles(lambda w: -2 + 1j * (w - 1) ** 2, df.Relay(M=1.0), omega=(0.5, 2))
    cplt2 = plot_nyquist(touching, ax=ax2)
    assert cplt2.axes[0, 0] is ax2
    (marker,) = cplt2.lines[2]
    assert touching[0].marginal and marker.get_marker() == "D"
    assert mcolors.to_hex(marker.get_markeredgecolor()) == mcolors.to_hex("C1")


def test_residual_map_shows_the_relative_residual_and_zero_lines():
    cycles = df.predict_limit_cycles(G, N)
    cplt = plot_residual_map(cycles, shape=(40, 50), amplitude=(0.15, 3.0), omega=(0.05, 5.0))
    ax = cplt.axes[0, 0]
    mesh = ax.collections[0]
    A = np.geomspace(0.15, 3.0, 40)
    w = np.geomspace(0.05, 5.0, 50)
    P = N(A)[:, None] * as_plant(G)(w)[None, :]
    expected = np.log10(np.maximum(np.abs(1 + P) / (1 + np.abs(P)), 1e-16))
    np.testing.assert_allclose(np.asarray(mesh.get_array()).reshape(40, 50), expected)
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    pts = np.array([np.ravel(m.get_data()) for m in cplt.lines[0]])
    np.testing.assert_allclose(sorted(pts[:, 0]), sorted(c.frequency for c in cycles))
    # default view: a decade around the cycles, inside the search windows
    ax = plot_residual_map(cycles, shape=(10, 10)).axes[0, 0]
    edges = ax.collections[0].get_coordinates()[:, 0, 1]  # cell edges midway between the sampled A
    centres = (edges[:-1] + edges[1:]) / 2
    lo, hi = centres[0], centres[-1]
    amps = [c.amplitude for c in cycles]
    assert lo == pytest.approx(max(min(amps) / 10, cycles.amplitude_window[0]))
    assert hi == pytest.approx(min(max(amps) * 10, cycles.amplitude_window[1]))


def test_plot_needs_a_limit_cycles_result():
    with pytest.raises(ValueError, match="LimitCycles returned by predict_limit_cycles"):
        plot_nyquist([])
    with pytest.raises(ValueError, match="n_loci must be >= 1"):
        plot_nyquist(df.predict_limit_cycles(G, N), n_loci=0)


def test_nyquist_marks_jump_crossings_apart_from_cycles():
    """A DF with a step in w (the stepped DF of test_solve_jumps): the crossing of the gap is drawn as a
    cross at G(jw) of the crossing, and no cycle marker is drawn."""
    import warnings

    from test_solve_jumps import G_SYN, SteppedDF

    N = SteppedDF(1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = df.predict_limit_cycles(G_SYN, N, omega=(0.9, 1.1), amplitude=(1.0, 3.0))
    cplt = plot_nyquist(cycles)
    (j,) = cycles.jump_crossings
    assert cplt.lines[2] == []
    (marker,) = cplt.lines[3]
    np.testing.assert_allclose(np.ravel(marker.get_data()), [j.G.real, j.G.imag])
    assert any("no cycle" in t.get_text() for t in cplt.axes[0, 0].texts)
