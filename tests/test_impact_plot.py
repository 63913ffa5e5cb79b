"""Impact plots: drawn data equals the trajectory / the batch results, axes returned."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from dfloop.impact.extract import impact_describing_function_batch  # noqa: E402
from dfloop.impact.kernel import simulate  # noqa: E402
from dfloop.plot.impact import plot_collision_map, plot_time_response  # noqa: E402


def test_time_response_draws_the_trajectory_with_jumps_unbridged():
    tr = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 25.0, 1.0)
    fig, ax = plt.subplots()
    assert plot_time_response(tr, "v1", ax=ax, samples=500) is ax
    t, y = ax.lines[0].get_data()
    ok = np.isfinite(t)
    assert np.array_equal(y[ok], tr.evaluate(t[ok])["v1"])
    assert np.count_nonzero(~ok) == tr.t0.size - 1  # one break per event
    plt.close(fig)


def test_time_response_rejects_bad_quantity_and_window():
    tr = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 25.0, 0.5)
    with pytest.raises(ValueError, match="quantity"):
        plot_time_response(tr, "speed")
    with pytest.raises(ValueError, match="t_range"):
        plot_time_response(tr, t_range=(0.2, 0.9))


def test_collision_map_plots_the_run_lengths():
    w = np.array([15.0, 35.0])
    ax = plot_collision_map(1.0, 1.0, 0.1, 50.0, w, [0.2, 0.8], transient_periods=60, periods=12)
    ref = impact_describing_function_batch(1.0, 1.0, 0.1, 0.8, 50.0, w, transient_periods=60, periods=12)
    lines = [ln for ln in ax.lines if ln.get_linestyle() == "-"]
    assert len(lines) == 2
    assert np.array_equal(lines[1].get_ydata(), ref.max_run_A)
    with pytest.raises(ValueError, match="side"):
        plot_collision_map(1.0, 1.0, 0.1, 50.0, w, [0.5], side="C")
    plt.close("all")
