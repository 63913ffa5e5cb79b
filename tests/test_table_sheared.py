"""Sheared 2-D table windows: every line spans only the x range its own y-intervals need."""
import numpy as np
import pytest

from dfloop.tables import Samples, Table2D, TableSettings


def f2(x, y):
    return np.exp(1j * x * (1 + 0.2 * y)) * (1 + 0.1 * y ** 2)


def _sampler(counter):
    def sampler(x, y):
        counter.append(x.size)
        reg = (x > 0.5 + 0.1 * y).astype(int)            # a slanted regime jump
        return Samples(f2(x, y) + 0.5 * reg, reg, np.ones(x.size, bool))
    return sampler


def _settings():
    return (TableSettings(tol=1e-4, base_dx=0.1, block_dx=0.4),
            TableSettings(tol=1e-4, base_dx=0.25, min_dx=1e-3))


def test_sheared_window_matches_the_function_with_fewer_samples():
    shear = 2.0                                          # x + 2 y in [0, 1]: x spans [-4, 1] over y in [0, 2]
    n_sheared, n_rect = [], []
    tab = Table2D.build(_sampler(n_sheared), (0.0, 1.0), (0.0, 2.0), *_settings(), shear=shear)
    Table2D.build(_sampler(n_rect), (-4.0, 1.0), (0.0, 2.0), *_settings())
    assert sum(n_sheared) < 0.75 * sum(n_rect)           # lines do not span the union of the window
    rng = np.random.default_rng(5)
    y = rng.uniform(0, 2, 4000)
    x = rng.uniform(0, 1, 4000) - shear * y
    tv = tab.evaluate(x, y)
    exact = f2(x, y) + 0.5 * (x > 0.5 + 0.1 * y)
    err = np.abs(tv.value - exact)
    assert np.count_nonzero(tv.valid) > 0.9 * x.size
    assert np.all(err[tv.valid] <= tv.error[tv.valid] + 1e-4 * np.abs(exact[tv.valid]))
    assert tab.covers((0.0, 1.0), (0.0, 2.0), shear=shear)
    assert not tab.covers((0.0, 2.5), (0.0, 2.0), shear=shear)
    # a far corner of the rectangle around the window was never asked for
    with pytest.raises(ValueError):
        tab.evaluate(1.0, 2.0)


def test_sheared_window_extends_and_round_trips():
    n = []
    tab = Table2D.build(_sampler(n), (0.0, 1.0), (0.0, 0.5), *_settings(), shear=2.0)
    tab.extend(_sampler(n), (0.5, 1.5), (0.25, 1.0), shear=2.0)
    assert tab.covers((0.0, 1.0), (0.0, 0.5), shear=2.0) and tab.covers((0.5, 1.5), (0.25, 1.0), shear=2.0)
    rng = np.random.default_rng(6)
    y = rng.uniform(0.0, 1.0, 2000)
    x = np.where(y < 0.5, rng.uniform(0, 1, y.size), rng.uniform(0.5, 1.5, y.size)) - 2.0 * y
    tv = tab.evaluate(x, y)
    exact = f2(x, y) + 0.5 * (x > 0.5 + 0.1 * y)
    assert np.all(np.abs(tv.value - exact)[tv.valid] <= tv.error[tv.valid] + 1e-4 * np.abs(exact[tv.valid]))
    back = Table2D.from_arrays(tab.to_arrays(), *_settings())
    assert back.covers((0.5, 1.5), (0.25, 1.0), shear=2.0)
    np.testing.assert_array_equal(back.evaluate(x, y).value, tv.value)


def test_a_wider_window_checks_again_the_y_intervals_it_widens():
    # a function smooth in y over x < 1 and strongly curved in y beyond: a first window over x < 1 needs few
    # lines; asking for x up to 2 later must refine in y there instead of reusing the old checks
    def g(x, y):
        return (1 + 0.01 * y) * (1 + np.where(x > 1.0, (x - 1.0) * np.sin(3 * y), 0.0)) + 0j

    def sampler(x, y):
        return Samples(g(x, y), np.zeros(x.size, int), np.ones(x.size, bool))

    st = (TableSettings(tol=1e-4, base_dx=0.1, block_dx=0.4), TableSettings(tol=1e-4, base_dx=0.25, min_dx=1e-3))
    tab = Table2D.build(sampler, (0.0, 0.8), (0.0, 1.0), *st)
    n_lines = tab.y.size
    tab.extend(sampler, (0.0, 2.0), (0.0, 1.0))
    assert tab.y.size > n_lines
    rng = np.random.default_rng(7)
    x, y = rng.uniform(0, 2, 3000), rng.uniform(0, 1, 3000)
    tv = tab.evaluate(x, y)
    exact = g(x, y)
    assert np.all(tv.valid)
    assert np.all(np.abs(tv.value - exact) <= tv.error + 1e-4 * np.abs(exact))
