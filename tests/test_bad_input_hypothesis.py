"""Random bad input at the elements and entry points: only the documented exception types come out
(``ValueError``, which includes :class:`dfloop.errors.DfloopError`), and never NaN for finite input.

Inputs mix NaN, +/-inf, negative, zero, huge and tiny floats, Python integers beyond the float range,
complex numbers, strings, None, booleans, ragged lists and arrays of other shapes (docs/errors.md).
"""
import math
import re

import control as ct
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import dfloop as df
from dfloop.describing import StaticElement, negative_inverse
from dfloop import harmonics

SETTINGS = settings(max_examples=60, deadline=2000, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

_floats = st.one_of(
    st.sampled_from([0.0, -0.0, -1.0, 1.0, np.nan, np.inf, -np.inf, 1e-320, 5e-324, 1e300, 1.7e308, -1e-300]),
    st.floats(allow_nan=True, allow_infinity=True),
)
scalars = st.one_of(
    _floats,
    st.integers(-(10**400), 10**400),
    st.complex_numbers(allow_nan=True, allow_infinity=True),
    st.text(max_size=3),
    st.none(),
    st.booleans(),
)
arrays = st.one_of(
    st.lists(_floats, min_size=0, max_size=5),
    st.lists(scalars, min_size=1, max_size=3),
    st.lists(st.lists(_floats, min_size=1, max_size=3), min_size=1, max_size=3),  # ragged or 2-D
    st.builds(lambda n, m, x: np.full((n, m), x), st.integers(1, 3), st.integers(1, 3), _floats),
)
values = st.one_of(scalars, arrays)

G = ct.tf([10.0], [1.0, 3.0, 3.0, 1.0])
AMPLITUDE_ONLY = [df.Backlash(0.2, 3.0), df.Saturation(1.5, 2.0), df.DeadZone(0.5), df.Relay(2.0), df.Relay(1.0, 0.1, 0.2),
                  df.CubicStiffness(2.0, -0.5), df.Quantizer(0.25), df.PreloadedSpring(1.0, 3.0),
                  df.CoulombViscousFriction(1.0, 0.5), df.NumericDF(np.tanh), df.NumericDF(df.Relay(1.0, 0.1))]
FREQUENCY_DEPENDENT = [df.MassBacklash(1.0, 3.0, 0.1), df.LinearThenStatic(G, df.Relay(1.0)),
                       df.LinearThenStatic(lambda s: 1.0 / (s * s), df.PreloadedSpring(1.0))]


def _test_id(el) -> str:
    """The element's repr without object addresses (a lambda's): the same test ids in every process (pytest-xdist
    checks that its workers collect the same tests)."""
    return re.sub(r" at 0x[0-9a-f]+", "", repr(el))


def check_element(el, A, omega=None):
    """N is either rejected by a ValueError or free of NaN wherever no input entry is NaN."""
    try:
        n = el(A, omega) if omega is not None or el.frequency_dependent else el(A)
    except ValueError:
        return
    inputs = [np.asarray(A, dtype=float)] + ([] if omega is None else [np.asarray(omega, dtype=float)])
    nan_in = np.logical_or.reduce([np.isnan(x) for x in np.broadcast_arrays(*inputs)])
    assert n.shape == nan_in.shape
    assert not np.any(np.isnan(n) & ~nan_in), (el, A, omega, n)


@pytest.mark.parametrize("el", AMPLITUDE_ONLY, ids=repr)
@SETTINGS
@given(A=values)
def test_amplitude_only_elements(el, A):
    check_element(el, A)


@pytest.mark.parametrize("el", FREQUENCY_DEPENDENT, ids=_test_id)
@SETTINGS
@given(A=values, omega=values)
def test_frequency_dependent_elements(el, A, omega):
    check_element(el, A, omega)


_CTORS = [
    (df.Backlash, 2), (df.Saturation, 2), (df.DeadZone, 2), (df.Relay, 3), (df.CubicStiffness, 2), (df.Quantizer, 1),
    (df.PreloadedSpring, 2), (df.CoulombViscousFriction, 2), (df.MassBacklash, 4), (df.PlayOperator, 2),
    (df.RelayOperator, 3),
]


@pytest.mark.parametrize("ctor,n", _CTORS, ids=[c.__name__ for c, _ in _CTORS])
@SETTINGS
@given(data=st.data())
def test_constructors_accept_or_reject_by_value_error(ctor, n, data):
    args = [data.draw(st.one_of(scalars, st.floats(0.01, 10.0))) for _ in range(n)]
    try:
        el = ctor(*args)
    except ValueError:
        return
    if hasattr(el, "frequency_dependent"):  # a valid element: N at ordinary inputs is rejected or not NaN
        check_element(el, np.array([0.0, 0.3, 1.0, 7.0, np.inf]), 2.0 if el.frequency_dependent else None)


_window_scalars = st.one_of(_floats, st.integers(-(10**400), 10**400),
                            st.complex_numbers(allow_nan=True, allow_infinity=True), st.text(max_size=3), st.none(),
                            st.booleans())
# grid sizes: every kind of bad value, and valid ones small enough to keep the run short
_grid_sizes = st.one_of(st.integers(-3, 40), st.sampled_from([2.5, 16.0, np.inf, -np.inf, np.nan, True, 10**400, "16",
                                                              None, 1 + 0j, np.int64(16), 2_000_001]))
_LIGHT = settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


@settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(omega=st.one_of(st.none(), _window_scalars, st.tuples(_window_scalars, _window_scalars)),
       amplitude=st.one_of(st.none(), _window_scalars, st.tuples(_window_scalars, _window_scalars)))
def test_predict_limit_cycles_windows(omega, amplitude):
    try:
        res = df.predict_limit_cycles(G, df.Saturation(1.0), omega=omega, amplitude=amplitude, grid=(16, 32))
    except ValueError:
        return
    for c in res:
        assert math.isfinite(c.amplitude) and math.isfinite(c.frequency)


@_LIGHT
@given(grid=st.one_of(st.tuples(_grid_sizes, _grid_sizes), _grid_sizes, st.lists(_grid_sizes, max_size=3)))
def test_predict_limit_cycles_grid(grid):
    """A grid is a pair of integers >= 2 (2.5 is not truncated, inf does not overflow): else a ValueError."""
    try:
        res = df.predict_limit_cycles(G, df.Saturation(1.0), grid=grid)
    except ValueError:
        ok = False
    else:
        ok = True
        assert all(math.isfinite(c.amplitude) for c in res)
    pair = grid if isinstance(grid, (tuple, list)) else ()
    assert ok == (len(pair) == 2 and all(_valid_size(x) for x in pair)), grid


def _valid_size(x) -> bool:
    if isinstance(x, bool) or not isinstance(x, (int, np.integer, float)):
        return False
    return 2 <= x <= 1_000_000 and x == int(x)  # NaN and inf fail the range; big integers too


def _plant_coefficients():
    entry = st.one_of(st.floats(-10, 10), st.sampled_from([np.nan, np.inf, -np.inf, 0.0]))
    return st.lists(entry, min_size=1, max_size=5)


@_LIGHT
@given(num=_plant_coefficients(), den=_plant_coefficients())
def test_predict_limit_cycles_plant_coefficients(num, den):
    """Any tf coefficients: a result or a ValueError (NaN used to escape as LinAlgError)."""
    try:
        G_bad = ct.tf(num, den)
    except (ValueError, ZeroDivisionError, TypeError):  # python-control's own checks (e.g. a zero denominator)
        return
    try:
        df.predict_limit_cycles(G_bad, df.Relay(1.0), grid=(8, 16))
    except ValueError:
        return


@_LIGHT
@given(entry=st.sampled_from([np.nan, np.inf, -np.inf]), where=st.sampled_from("ABCD"), i=st.integers(0, 1))
def test_predict_limit_cycles_state_space_with_non_finite_entries(entry, where, i):
    m = {"A": -np.eye(2), "B": np.ones((2, 1)), "C": np.ones((1, 2)), "D": np.zeros((1, 1))}
    m[where].flat[min(i, m[where].size - 1)] = entry
    with pytest.raises(ValueError, match=f"G \\(ss\\) must have finite matrices; got {where} ="):
        df.predict_limit_cycles(ct.ss(m["A"], m["B"], m["C"], m["D"]), df.Relay(1.0))


@_LIGHT
@given(N=st.one_of(scalars, st.just(df.Saturation(1.0))), cycle=st.one_of(values, st.tuples(scalars, scalars)),
       periods=scalars, perturbation=st.one_of(scalars, st.just(0.3)))
def test_verify_cycle(N, cycle, periods, perturbation):
    """Bad N, cycle, periods or perturbation: a ValueError (N = 3 was an AttributeError, periods = 1e9 ran
    unbounded). Valid calls are kept short (periods <= 4)."""
    from dfloop.verify import verify_cycle

    try:
        p = float(periods)
    except (TypeError, ValueError, OverflowError):
        p = math.nan
    assume(not (0 < p <= 1e5 and not isinstance(periods, (bool, str))) or p <= 4)
    try:
        v = verify_cycle(G, N, cycle, periods=periods, perturbation=perturbation, measure_periods=1)
    except ValueError:
        return
    assert v.verdict in ("stable", "unstable", "inconclusive")


@_LIGHT
@given(amplitude=st.one_of(scalars, st.just(1.0)), frequency=st.one_of(st.none(), scalars, st.just(1.0)),
       N=st.one_of(st.none(), scalars, st.just(df.Saturation(1.0))))
def test_cycle_confidence(amplitude, frequency, N):
    from dfloop.solve.confidence import cycle_confidence

    try:
        c = cycle_confidence(G, N, amplitude, frequency)
    except ValueError:
        return
    assert not c.available or math.isfinite(c.distortion)


@_LIGHT
@given(name=st.text(min_size=1, max_size=8).filter(lambda s: s not in ("grid", "tol", "marginal_tol", "exact")),
       value=scalars)
def test_sweep_unknown_keyword(name, value):
    """An unknown keyword is a ValueError naming it, before any solve (it was a RuntimeError from the batch)."""
    from dfloop.continuation import sweep

    solved = []

    def loop_at(k):
        solved.append(k)
        return k * G, df.Saturation(1.0)

    with pytest.raises(ValueError, match="unknown keyword"):
        sweep(loop_at, [1.0, 2.0], **{name: value})
    assert solved == []


@_LIGHT
@given(nodes=st.one_of(scalars, st.integers(-5, 10**12)), samples=st.one_of(scalars, st.integers(-5, 10**12)))
def test_numeric_df_constructor(nodes, samples):
    """nodes and samples: integers in a bounded range, else a ValueError (10**9 was accepted, then MemoryError)."""
    try:
        el = df.NumericDF(np.tanh, nodes=nodes, samples=samples)
    except ValueError:
        return
    assert 2 <= el.nodes <= 1024 and 16 <= el.samples <= 2**16
    n = el(np.array([0.5, 2.0]))
    assert np.all(np.isfinite(n))


@_LIGHT
@given(base_dx=st.one_of(scalars, st.floats(1e-3, 1.0)), min_dx=st.one_of(scalars, st.floats(1e-5, 1.0)),
       periods=st.one_of(scalars, st.integers(-2, 50)), starts=st.one_of(scalars, st.integers(-1, 4)))
def test_dynamic_backlash_constructor(base_dx, min_dx, periods, starts):
    """Table settings: a ValueError, or consistent settings (min_dx <= base_dx, integer counts)."""
    from dfloop.impact.dynamic_backlash import DynamicBacklash

    try:
        el = DynamicBacklash(1.0, 1.0, 0.1, 0.5, base_dx=base_dx, min_dx=min_dx, periods=periods, starts=starts,
                             cache=False)
    except ValueError:
        return
    assert float(min_dx) <= float(base_dx)
    assert el.periods == float(periods) and el.starts == float(starts) and el.periods >= 1


@SETTINGS
@given(t=values, x=values, omega=scalars)
def test_harmonics_fundamental(t, x, omega):
    try:
        c = harmonics.fundamental(t, x, omega)
    except ValueError:
        return
    assert np.isfinite(c)


@SETTINGS
@given(A=values, omega=st.one_of(st.none(), values))
def test_negative_inverse(A, omega):
    try:
        z = negative_inverse(df.Saturation(1.0), A, omega)
    except ValueError:
        return
    assert not np.any(np.isnan(z) & ~np.isnan(np.asarray(A, dtype=float)))


@SETTINGS
@given(F=values)
def test_mass_backlash_limit_frequency(F):
    try:
        w = df.MassBacklash(1.0, 1.0, 0.1).limit_frequency(F)
    except ValueError:
        return
    assert np.all(np.isfinite(w)) and np.all(w > 0)


@settings(max_examples=25, deadline=5000, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(F=values, omega=values)
def test_dynamic_backlash(F, omega, tmp_path_factory):
    el = df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, tol=1e-2, transient_periods=10, periods=4, base_dx=0.3, min_dx=1e-2,
                            beta_max=30.0, cache=False)
    check_element(el, F, omega)


STATIC = [el for el in AMPLITUDE_ONLY if isinstance(el, StaticElement)]


@pytest.mark.parametrize("el", STATIC + [df.Backlash(0.2), df.Relay(1.0, 0.1, 0.2)], ids=repr)
@settings(max_examples=30, deadline=2000, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(x=values)
def test_outputs_and_operators(el, x):
    """y = f(x) and the time-domain operator: a ValueError, or no NaN where x is not NaN."""
    if isinstance(el, StaticElement):
        try:
            y = el.output(x)
        except ValueError:
            pass
        else:
            assert not np.any(np.isnan(y) & ~np.isnan(np.asarray(x, dtype=float)))
    op = el.operator()
    for sample in (np.ravel(np.asarray(x, dtype=object)) if isinstance(x, (list, np.ndarray)) else [x]):
        try:
            y = op(sample)
        except ValueError:
            continue
        assert isinstance(y, float)


def _as_float(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError, OverflowError):
        return math.nan


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(periods=scalars, transient=st.one_of(st.none(), scalars), max_events=st.one_of(st.none(), scalars),
       effects=st.one_of(st.just(()), scalars), initial=st.one_of(st.none(), values))
def test_impact_describing_function_run_settings(periods, transient, max_events, effects, initial):
    """Run lengths, event bounds, effects and the initial state: a ValueError, or a finite DF (periods = 1e12
    was a MemoryError, transient_periods = 1e12 ran unbounded). Valid runs are kept short."""
    from dfloop.impact.extract import impact_describing_function

    assume(not (_as_float(periods) > 4 and _as_float(periods) <= 1e7))
    assume(transient is None or not (_as_float(transient) > 20 and _as_float(transient) <= 1e7))
    try:
        out = impact_describing_function(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, periods=periods, transient_periods=transient,
                                         max_events=max_events, effects=effects, initial=initial)
    except ValueError:
        return
    except RuntimeError as exc:  # the event bound of a valid run, reached: it must say how to raise it
        assert "max_events" in str(exc)
        return
    assert np.isfinite(out.N)
