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
    assert plot_time_response(tr, "v1", ax=ax, samples=500).axes[0, 0] is ax
    t, y = ax.lines[0].get_data()
    ok = np.isfinite(t)
    assert np.array_equal(y[ok], tr.evaluate(t[ok])["v1"])
    assert np.count_nonzero(~ok) == tr.t0.size - 1  # one break per event
    plt.close(fig)


def test_time_response_jump_connectors_obey_the_impact_law():
    """The dotted connectors join the two sides of each velocity jump: across an impact the momentum
    m1 v1 + m2 v2 is conserved and the relative velocity reverses with factor eps (Newton's law, eqs. 6-7)."""
    m1, m2, eps = 1.0, 1.0, 0.5
    tr = simulate(m1, m2, 0.1, eps, 50.0, 25.0, 1.0)
    cplt = plot_time_response(tr, "v1", samples=500)
    (jumps,) = cplt.lines[1]
    t, v1 = jumps.get_xdata().reshape(-1, 3)[:, :2], jumps.get_ydata().reshape(-1, 3)[:, :2]
    assert np.all(t[:, 0] == t[:, 1]) and t.shape[0] == tr.t0.size - 1
    before = tr.evaluate(np.nextafter(t[:, 0], -np.inf))
    after = tr.evaluate(t[:, 0])
    np.testing.assert_array_equal(v1[:, 0], before["v1"])
    np.testing.assert_array_equal(v1[:, 1], after["v1"])
    impacts = np.abs(after["v1"] - before["v1"]) > 1e-9  # events that are impacts (not stick / release)
    assert np.count_nonzero(impacts) > 5
    p_before = m1 * before["v1"] + m2 * before["v2"]
    p_after = m1 * after["v1"] + m2 * after["v2"]
    np.testing.assert_allclose(p_after[impacts], p_before[impacts], atol=1e-9)
    rel_before = (before["v2"] - before["v1"])[impacts]
    rel_after = (after["v2"] - after["v1"])[impacts]
    np.testing.assert_allclose(rel_after, -eps * rel_before, rtol=1e-6, atol=1e-9)
    plt.close("all")


def test_time_response_rejects_bad_quantity_and_window():
    tr = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 25.0, 0.5)
    with pytest.raises(ValueError, match="quantity"):
        plot_time_response(tr, "speed")
    with pytest.raises(ValueError, match="t_range"):
        plot_time_response(tr, t_range=(0.2, 0.9))


def test_collision_map_plots_the_run_lengths():
    w = np.array([15.0, 35.0])
    batches = [impact_describing_function_batch(1.0, 1.0, 0.1, eps, 50.0, w, transient_periods=60, periods=12)
               for eps in (0.2, 0.8)]
    cplt = plot_collision_map(w, [b.max_run_A for b in batches], [b.regular for b in batches],
                              ["eps=0.2", "eps=0.8"])
    lines = cplt.lines[0]
    assert len(lines) == 2
    assert np.array_equal(lines[1].get_ydata(), batches[1].max_run_A)
    # irregular points, and only those, carry an open marker
    assert sum(m.get_xdata().size for m in cplt.lines[1]) == sum(int(np.count_nonzero(~b.regular)) for b in batches)
    assert [t.get_text() for t in cplt.legend.get_texts()] == ["eps=0.2", "eps=0.8"]
    assert lines[0].get_color() != lines[1].get_color() and lines[0].get_marker() != lines[1].get_marker()
    with pytest.raises(ValueError, match="side"):
        plot_collision_map(w, [b.max_run_A for b in batches], side="C")
    with pytest.raises(ValueError, match="runs must have shape"):
        plot_collision_map(w, [[1.0, 2.0, 3.0]])
    plt.close("all")
