"""plot_loci draws the expected curves with the expected data."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.plot.loci import default_amplitudes, plot_loci  # noqa: E402


def data_lines(cplt):
    """The -1/N curves of a ControlPlot returned by plot_loci (lines[0]; lines[1] is the -1 marker)."""
    return cplt.lines[0]


def test_amplitude_only_single_curve_over_domain():
    b = df.Backlash(0.1)
    cplt = plot_loci(b)
    lines = data_lines(cplt)
    assert len(lines) == 1
    A = default_amplitudes(b)
    assert A[0] > 0.05 and np.isclose(A[-1], 50.0)
    z = -1 / b(A)
    np.testing.assert_allclose(lines[0].get_xdata(), z.real)
    np.testing.assert_allclose(lines[0].get_ydata(), z.imag)
    plt.close(cplt.figure)


def test_given_amplitudes_and_existing_axes_and_kwargs():
    fig, ax = plt.subplots()
    A = np.array([0.5, 1.0, 2.0, 4.0])
    out = plot_loci(df.Relay(1.0, hysteresis=0.2), amplitudes=A, ax=ax, color="red")
    assert out.axes[0, 0] is ax and out.figure is fig
    (line,) = data_lines(out)
    z = -1 / df.Relay(1.0, hysteresis=0.2)(A)
    np.testing.assert_allclose(line.get_xdata() + 1j * line.get_ydata(), z)
    assert line.get_color() == "red"
    plt.close(fig)


def test_frequency_dependent_family_like_fig3_leaves_out_n_zero():
    mb = df.MassBacklash(1.0, 1.0, 0.1)
    F = [10.0, 20.0, 30.0, 40.0, 50.0]
    w = np.linspace(0.5, 40.0, 200)  # w_L = 10 ... 22.4 rad/s: the tail has N = 0
    cplt = plot_loci(mb, amplitudes=F, omega=w)
    lines = data_lines(cplt)
    assert len(lines) == 5
    for Fi, line in zip(F, lines):
        keep = w < mb.limit_frequency(Fi)
        z = -1 / mb(Fi, w[keep])
        drawn = line.get_xdata() + 1j * line.get_ydata()
        np.testing.assert_allclose(drawn[keep], z, rtol=1e-14)
        assert np.all(np.isnan(drawn[~keep]))  # N = 0 there: a gap, not a point at infinity
        assert line.get_label() == f"F = {Fi:g} N"
    plt.close(cplt.figure)


def test_frequency_dependent_requires_omega():
    with pytest.raises(ValueError, match="omega"):
        plot_loci(df.MassBacklash(1.0, 1.0, 0.1), amplitudes=[10.0])


def test_default_amplitudes_span_each_kind_of_domain():
    soft = df.CubicStiffness(2.0, -0.6)  # domain (0, hi): N = 0 at hi
    A = default_amplitudes(soft, n=50)
    hi = soft.amplitude_domain()[1]
    assert np.isclose(A[0], 1e-3 * hi) and A[-1] < hi and np.all(soft(A) != 0)
    A = default_amplitudes(df.Saturation(2.0), n=50)  # domain (0, inf): a fixed span
    assert np.isclose(A[0], 1e-3) and np.isclose(A[-1], 1e3)
    A = default_amplitudes(df.DeadZone(2.0), n=50)  # domain (delta, inf): just above the edge
    assert 2.0 < A[0] < 2.0 * (1 + 1e-5) and np.all(df.DeadZone(2.0)(A) != 0)
