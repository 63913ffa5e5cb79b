"""Table2D: interpolation in a power of 1/w between lines, check samples reused by the line built at their y,
resumable builds (saved after every line); each against a closed-form function."""
import numpy as np
import pytest

from dfloop.tables import Samples, Table1D, Table2D, TableSettings


def d(x, y):
    # smooth in t = exp(-y) (as D = N M2 w^2 is in c/(M2 w) at fixed beta; here a quadratic), a jump in x
    t = 5.0 * np.exp(-y)
    return np.exp(1j * x) * (1 + (0.4 + 0.6j) * t + 0.3 * t ** 2) + 0.5 * (x > 0.55)


def _sampler(log=None):
    def sampler(x, y):
        if log is not None:
            log.extend((float(v), float(y)) for v in x)
        reg = (x > 0.55).astype(int)
        return Samples(d(x, y), reg, np.ones(x.size, bool))
    return sampler


def _settings():
    return (TableSettings(tol=1e-5, base_dx=0.1, block_dx=0.4, probe_dx=0.05),
            TableSettings(tol=1e-5, base_dx=0.25, min_dx=1e-3))


def _within_estimate(tab, x_window, y_window, n=3000, seed=3):
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(*x_window, n), rng.uniform(*y_window, n)
    tv = tab.evaluate(x, y)
    exact = d(x, y)
    assert np.count_nonzero(tv.valid) > 0.95 * n
    ok = tv.valid
    assert np.all(np.abs(tv.value - exact)[ok] <= tv.error[ok] + 1e-9)


def test_interpolation_in_a_power_of_one_over_w_needs_fewer_lines_and_stays_within_its_estimate():
    x_window, y_window = (0.0, 1.0), (1.6, 4.1)          # ln w over w = 5 .. 60 rad/s
    in_y = Table2D.build(_sampler(), x_window, y_window, *_settings())
    in_t = Table2D.build(_sampler(), x_window, y_window, *_settings(), y_rate=1.0)
    for tab in (in_y, in_t):
        _within_estimate(tab, x_window, y_window)
    assert in_t.y.size <= 0.6 * in_y.y.size
    assert in_t.yerr.max() < 1e-12                         # a cubic in t reproduces a quadratic exactly
    with pytest.raises(ValueError, match="y_rate"):
        Table2D(*_settings(), y_rate=-1.0)


def test_check_samples_are_served_again_to_the_line_built_at_their_y_and_change_nothing():
    log = []
    tab = Table2D.build(_sampler(log), (0.0, 1.0), (1.6, 4.1), *_settings())
    assert tab._n_reused > 0
    assert tab.n_sampled == len(log)                      # every evaluation counted once
    st = _settings()[0]
    for y, line in zip(tab.y, tab.lines):                 # each line as if built directly at its y
        direct = Table1D.build(lambda x, y=y: _sampler()(x, y), line.lo, line.hi, st)
        np.testing.assert_array_equal(direct.x, line.x)
        np.testing.assert_array_equal(direct.value, line.value)
        np.testing.assert_array_equal(direct.err, line.err)


def test_a_build_interrupted_mid_way_resumes_from_the_last_saved_line():
    x_window, y_window = (0.0, 1.0), (1.6, 4.1)
    full = Table2D.build(_sampler(), x_window, y_window, *_settings())
    saved = {}
    calls = {"n": 0}

    def flaky(x, y):
        calls["n"] += 1
        if calls["n"] > 60:
            raise KeyboardInterrupt
        return _sampler()(x, y)

    tab = Table2D(*_settings())
    with pytest.raises(KeyboardInterrupt):
        tab.extend(flaky, x_window, y_window, checkpoint=lambda: saved.update(tab.to_arrays()))
    assert saved
    back = Table2D.from_arrays(saved, *_settings())
    assert not back.covers(x_window, y_window)           # unfinished: lines or y checks missing
    back.extend(_sampler(), x_window, y_window)
    assert back.covers(x_window, y_window)
    assert 0 < back.n_sampled < full.n_sampled           # the saved lines were not sampled again
    _within_estimate(back, x_window, y_window)
    assert back.windows.shape[0] == 1                     # the same window asked again is stored once
