"""Adaptive tables against synthetic functions with known closed forms, jumps and an irregular region."""
import numpy as np
import pytest

from dfloop.tables import Samples, Table1D, Table2D, TableSettings

X_JUMP = 0.7345678      # regime change
X_IRREGULAR = 2.0       # beyond: "chaotic" samples (noisy, not regular)


def smooth(x):
    return np.where(x < X_JUMP, np.exp(1j * x) * (1 + 0.3 * np.sin(3 * x)), 2 * np.exp(-1j * x) + 0.5)


class Counting:
    def __init__(self):
        self.calls = 0
        self.points = 0

    def __call__(self, x):
        self.calls += 1
        self.points += x.size
        regular = x < X_IRREGULAR
        value = smooth(x) + np.where(regular, 0.0, 0.1 * np.sin(1e3 * x))
        return Samples(value, np.where(x < X_JUMP, 1, 2), regular, {"x_copy": x.copy()})


@pytest.mark.parametrize("method", ["linear", "pchip", "cubic"])
def test_relative_accuracy_and_jump_location(method):
    f = Counting()
    tab = Table1D.build(f, -1.0, 3.0, TableSettings(tol=1e-4, method=method))
    assert f.points == tab.n_sampled == tab.x.size
    q = np.random.default_rng(1).uniform(-1.0, X_IRREGULAR, 20000)
    tv = tab.evaluate(q)
    rel = np.abs(tv.value - smooth(q)) / np.abs(smooth(q))
    far = (np.abs(q - X_JUMP) > tab.settings.jump_dx) & (X_IRREGULAR - q > tab.settings.edge_dx)
    assert np.all(tv.valid[far])
    assert rel[tv.valid].max() <= 1e-4
    # the jump is bracketed to jump_dx and never interpolated across
    j = np.flatnonzero(tab.jumps() & tab.regular[:-1] & tab.regular[1:])
    assert j.size == 1
    assert tab.x[j[0]] < X_JUMP <= tab.x[j[0] + 1]
    assert tab.x[j[0] + 1] - tab.x[j[0]] <= tab.settings.jump_dx
    # extras travel with their samples
    np.testing.assert_array_equal(tab.extra["x_copy"], tab.x)


def test_error_estimate_bounds_cubic_error():
    tab = Table1D.build(Counting(), -1.0, 3.0, TableSettings(tol=1e-4, method="cubic"))
    q = np.random.default_rng(2).uniform(-1.0, X_IRREGULAR, 20000)
    tv = tab.evaluate(q)
    actual = np.abs(tv.value - smooth(q))
    assert np.all(actual[tv.valid] <= tv.error[tv.valid])


def test_cubic_needs_fewer_samples_than_linear():
    n = {m: Table1D.build(Counting(), -1.0, 2.0, TableSettings(method=m)).x.size for m in ("linear", "cubic")}
    assert n["cubic"] < n["linear"] / 2


def test_irregular_region_flagged_and_not_refined():
    tab = Table1D.build(Counting(), -1.0, 3.0, TableSettings(base_dx=0.1))
    beyond = tab.x > X_IRREGULAR
    # only the base grid (spacing 0.1) and the bisection of the boundary lie in the irregular part
    assert np.count_nonzero(beyond) <= 11
    tv = tab.evaluate(np.linspace(2.05, 2.95, 50))
    assert not np.any(tv.valid)
    assert np.all(tv.error > 0)
    edge = np.flatnonzero(tab.regular[:-1] & ~tab.regular[1:])
    assert edge.size == 1 and tab.x[edge[0]] < X_IRREGULAR <= tab.x[edge[0] + 1] <= X_IRREGULAR + tab.settings.edge_dx


def test_value_jump_within_one_regime_is_located():
    xj = 0.3141

    def sampler(x):
        return Samples(np.where(x < xj, 1.0 + x, 3.0 + x) + 0j, np.zeros(x.size, int), np.ones(x.size, bool))

    tab = Table1D.build(sampler, 0.0, 1.0, TableSettings(tol=1e-6))
    j = np.flatnonzero(tab.jumps())
    assert j.size == 1
    assert tab.x[j[0]] < xj <= tab.x[j[0] + 1] and tab.x[j[0] + 1] - tab.x[j[0]] <= tab.settings.jump_dx
    q = np.linspace(0, 1, 1001)
    q = q[np.abs(q - xj) > 1e-6]
    tv = tab.evaluate(q)
    np.testing.assert_allclose(tv.value.real, np.where(q < xj, 1.0 + q, 3.0 + q), rtol=1e-6)


def test_extend_reuses_samples_and_matches_direct_build():
    f = Counting()
    tab = Table1D.build(f, 0.0, 1.0)
    n0 = f.points
    tab.extend(f, 0.0, 1.0)
    assert f.points == n0                     # covered window: nothing sampled
    tab.extend(f, -1.0, 1.5)
    assert tab.covers(-1.0, 1.5)
    q = np.linspace(-1.0, 1.5, 3001)
    tv = tab.evaluate(q)
    rel = np.abs(tv.value - smooth(q)) / np.abs(smooth(q))
    assert rel[tv.valid].max() <= 1e-4


def test_outside_window_raises_not_extrapolates():
    tab = Table1D.build(Counting(), 0.0, 1.0)
    with pytest.raises(ValueError, match="outside the table window"):
        tab.evaluate([1.5])
    with pytest.raises(ValueError, match="NaN"):
        tab.evaluate([np.nan])


def test_max_samples_bound_raises():
    with pytest.raises(RuntimeError, match="max_samples"):
        Table1D.build(Counting(), -1.0, 2.0, TableSettings(tol=1e-12, max_samples=200))


@pytest.mark.parametrize("kw", [dict(tol=0.0), dict(method="quintic"), dict(min_dx=float("nan")),
                                dict(abs_floor=-1.0)])
def test_bad_settings(kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        TableSettings(**kw)


def test_round_trip_arrays():
    tab = Table1D.build(Counting(), -1.0, 3.0)
    back = Table1D.from_arrays(tab.to_arrays(), tab.settings)
    q = np.linspace(-1, 3, 777)
    a, b = tab.evaluate(q), back.evaluate(q)
    np.testing.assert_array_equal(a.value, b.value)
    np.testing.assert_array_equal(a.error, b.error)
    assert back.n_sampled == 0


def f2(x, y):
    return np.exp(1j * x * (1 + 0.2 * y)) * (1 + 0.1 * y ** 2)


def test_2d_table_accuracy_and_regime_band():
    # regime changes at x = 0.5 + 0.1 y: a slanted jump line
    def sampler(x, y):
        reg = (x > 0.5 + 0.1 * y).astype(int)
        return Samples(f2(x, y) + 0.5 * reg, reg, np.ones(x.size, bool))

    s = TableSettings(tol=1e-4, base_dx=0.1)
    tab = Table2D.build(sampler, (0.0, 1.0), (0.0, 1.0), s, TableSettings(tol=1e-4, base_dx=0.25, min_dx=1e-3))
    rng = np.random.default_rng(3)
    x, y = rng.uniform(0, 1, 5000), rng.uniform(0, 1, 5000)
    tv = tab.evaluate(x, y)
    exact = f2(x, y) + 0.5 * (x > 0.5 + 0.1 * y)
    rel = np.abs(tv.value - exact) / np.abs(exact)
    assert rel[tv.valid].max() <= 1e-4
    assert np.all(np.abs(tv.value - exact)[tv.valid] <= tv.error[tv.valid] + 1e-4 * np.abs(exact[tv.valid]))
    # invalid only in a band around the jump line no wider than the 4-line stencil (3 spacings in y)
    bad = ~tv.valid
    assert np.all(np.abs(x[bad] - 0.5 - 0.1 * y[bad]) <= 0.1 * 3 * np.diff(tab.y).max() + 1e-6)
    with pytest.raises(ValueError, match="outside"):
        tab.evaluate(0.5, 1.5)
