"""dfloop elements and loops in python-control: df.to_control(element), df.control_loop(G, N).

Part 1 is a faithful copy of python-control 0.10.2's own describing-function tests
(``control/tests/descfcn_test.py``, RMM, 23 Jan 2021), with each of python-control's nonlinearities
(``saturation_nonlinearity``, ``friction_backlash_nonlinearity``, ``relay_hysteresis_nonlinearity``) replaced by
the dfloop element ``as_element`` makes of it, converted back with ``to_control`` (``_dfloop`` below). The
test's own references (``saturation_class``, ``saturation``) stay as they are: they are the independent truth.
Part 2 checks the conversions against independent truths: python-control's own quadrature of the converted
time-domain map, the play operator sample by sample, and closed-loop runs of ``control.input_output_response``
against dfloop's exact cycles (shooting on the exact flow).
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest

import control as ct
import dfloop as df
from control.descfcn import friction_backlash_nonlinearity, \
    relay_hysteresis_nonlinearity, saturation_nonlinearity
from dfloop.describing import StaticElement
from dfloop.describing.interop import as_element, control_loop, to_control
from dfloop.harmonics import steady_state
from dfloop.impact.dynamic_backlash import DynamicBacklash


def _dfloop(nonlinearity):
    """python-control's nonlinearity -> dfloop element -> python-control nonlinearity."""
    return to_control(as_element(nonlinearity))


# ------------------------------------------------------------------ part 1: python-control's descfcn_test.py
# Static function via a class
class saturation_class:
    # Static nonlinear saturation function
    def __call__(self, x, lb=-1, ub=1):
        return np.clip(x, lb, ub)

    # Describing function for a saturation function
    def describing_function(self, a):
        if -1 <= a and a <= 1:
            return 1.
        else:
            b = 1/a
            return 2/math.pi * (math.asin(b) + b * math.sqrt(1 - b**2))


# Static function without a class
def saturation(x):
    return np.clip(x, -1, 1)


# Static nonlinear system implementing saturation: here dfloop's Saturation as an nlsys
@pytest.fixture
def satsys():
    return _dfloop(saturation_nonlinearity(1)).to_nlsys()


def test_static_nonlinear_call(satsys):
    # Make sure that the saturation system is a static nonlinearity
    assert satsys._isstatic()

    # Make sure the saturation function is doing the right computation
    input = [-2, -1, -0.5, 0, 0.5, 1, 2]
    desired = [-1, -1, -0.5, 0, 0.5, 1, 1]
    for x, y in zip(input, desired):
        np.testing.assert_allclose(satsys(x), y)

    # Test squeeze properties
    assert satsys(0.) == 0.
    assert satsys([0.], squeeze=True) == 0.
    np.testing.assert_allclose(satsys([0.]), [0.])

    # Test SIMO nonlinearity
    def _simofcn(t, x, u, params):
        return np.array([np.cos(u), np.sin(u)])
    simo_sys = ct.NonlinearIOSystem(None, outfcn=_simofcn, input=1, output=2)
    np.testing.assert_allclose(simo_sys([0.]), [1, 0])
    np.testing.assert_allclose(simo_sys([0.], squeeze=True), [1, 0])

    # Test MISO nonlinearity
    def _misofcn(t, x, u, params={}):
        return np.array([np.sin(u[0]) * np.cos(u[1])])
    miso_sys = ct.NonlinearIOSystem(None, outfcn=_misofcn, input=2, output=1)
    np.testing.assert_allclose(miso_sys([0, 0]), [0])
    np.testing.assert_allclose(miso_sys([0, 0], squeeze=True), [0])


# Test saturation describing function in multiple ways
def test_saturation_describing_function(satsys):
    satfcn = saturation_class()

    # Store the analytic describing function for comparison
    amprange = np.linspace(0, 10, 100)
    df_anal = [satfcn.describing_function(a) for a in amprange]

    # Compute describing function for a static function
    df_fcn = ct.describing_function(saturation, amprange)
    np.testing.assert_almost_equal(df_fcn, df_anal, decimal=3)

    # Compute describing function for a describing function nonlinearity
    df_fcn = ct.describing_function(satfcn, amprange)
    np.testing.assert_almost_equal(df_fcn, df_anal, decimal=3)

    # Compute describing function for a static I/O system
    df_sys = ct.describing_function(satsys, amprange)
    np.testing.assert_almost_equal(df_sys, df_anal, decimal=3)

    # Compute describing function on an array of values
    df_arr = ct.describing_function(satsys, amprange)
    np.testing.assert_almost_equal(df_arr, df_anal, decimal=3)

    # (added) the converted dfloop element, by its method and by python-control's quadrature of its map
    ours = _dfloop(saturation_nonlinearity(1))
    np.testing.assert_almost_equal(ct.describing_function(ours, amprange), df_anal, decimal=12)
    np.testing.assert_almost_equal(ct.describing_function(ours, amprange, try_method=False), df_anal, decimal=3)

    # Evaluate static function at a negative amplitude
    with pytest.raises(ValueError, match="cannot evaluate"):
        ct.describing_function(saturation, -1)

    # Create describing function nonlinearity w/out describing_function method
    # and make sure it drops through to the underlying computation
    class my_saturation(ct.DescribingFunctionNonlinearity):
        def __call__(self, x):
            return saturation(x)
    satfcn_nometh = my_saturation()
    df_nometh = ct.describing_function(satfcn_nometh, amprange)
    np.testing.assert_almost_equal(df_nometh, df_anal, decimal=3)


@pytest.mark.parametrize("fcn, amin, amax", [
    [_dfloop(saturation_nonlinearity(1)), 0, 10],
    [_dfloop(friction_backlash_nonlinearity(2)), 1, 10],
    [_dfloop(relay_hysteresis_nonlinearity(1, 1)), 3, 10],
    ])
def test_describing_function(fcn, amin, amax):
    # Store the analytic describing function for comparison
    amprange = np.linspace(amin, amax, 100)
    df_anal = [fcn.describing_function(a) for a in amprange]

    # Compute describing function on an array of values
    df_arr = ct.describing_function(
        fcn, amprange, zero_check=False, try_method=False)
    np.testing.assert_almost_equal(df_arr, df_anal, decimal=1)

    # Make sure the describing function method also works
    df_meth = ct.describing_function(fcn, amprange, zero_check=False)
    np.testing.assert_almost_equal(df_meth, df_anal)

    # Make sure that evaluation at negative amplitude generates an exception
    with pytest.raises(ValueError, match="cannot evaluate"):
        ct.describing_function(fcn, -1)


def test_describing_function_response():
    # Simple linear system with at most 1 intersection
    H_simple = ct.tf([1], [1, 2, 2, 1])
    omega = np.logspace(-1, 2, 100)

    # Saturation nonlinearity
    F_saturation = _dfloop(ct.descfcn.saturation_nonlinearity(1))
    amp = np.linspace(1, 4, 10)

    # No intersection
    xsects = ct.describing_function_response(H_simple, F_saturation, amp, omega)
    assert len(xsects) == 0

    # One intersection
    H_larger = H_simple * 8
    xsects = ct.describing_function_response(H_larger, F_saturation, amp, omega)
    for a, w in xsects:
        np.testing.assert_almost_equal(
            H_larger(1j*w),
            -1/ct.describing_function(F_saturation, a), decimal=5)

    # Multiple intersections
    H_multiple = H_simple * ct.tf(*ct.pade(5, 4)) * 4
    omega = np.logspace(-1, 3, 50)
    F_backlash = _dfloop(ct.descfcn.friction_backlash_nonlinearity(1))
    amp = np.linspace(0.6, 5, 50)
    xsects = ct.describing_function_response(H_multiple, F_backlash, amp, omega)
    for a, w in xsects:
        np.testing.assert_almost_equal(
            -1/ct.describing_function(F_backlash, a),
            H_multiple(1j*w), decimal=5)


def test_describing_function_plot():
    # Simple linear system with at most 1 intersection
    H_larger = ct.tf([1], [1, 2, 2, 1]) * 8
    omega = np.logspace(-1, 2, 100)

    # Saturation nonlinearity
    F_saturation = _dfloop(ct.descfcn.saturation_nonlinearity(1))
    amp = np.linspace(1, 4, 10)

    # Plot via response
    plt.clf()                                   # clear axes
    response = ct.describing_function_response(
        H_larger, F_saturation, amp, omega)
    assert len(response.intersections) == 1
    assert len(plt.gcf().get_axes()) == 0       # make sure there is no plot

    cplt = response.plot()
    assert len(plt.gcf().get_axes()) == 1       # make sure there is a plot
    assert len(cplt.lines[0]) == 5 and len(cplt.lines[1]) == 1

    # Call plot directly
    cplt = ct.describing_function_plot(H_larger, F_saturation, amp, omega)
    assert len(cplt.lines[0]) == 5 and len(cplt.lines[1]) == 1
    plt.close("all")


def test_describing_function_exceptions():
    # Describing function with non-zero bias
    with pytest.warns(UserWarning, match="asymmetric"):
        saturation = _dfloop(ct.descfcn.saturation_nonlinearity(lb=-1, ub=2))
        assert saturation(-3) == -1
        assert saturation(3) == 2

    # Turn off the bias check
    ct.describing_function(saturation, 0, zero_check=False)

    # Function should evaluate to zero at zero amplitude
    f = lambda x: x + 0.5
    with pytest.raises(ValueError, match="must evaluate to zero"):
        ct.describing_function(f, 0, zero_check=True)

    # Evaluate at a negative amplitude
    with pytest.raises(ValueError, match="cannot evaluate"):
        ct.describing_function(saturation, -1)

    # Describing function with bad label
    H_simple = ct.tf([8], [1, 2, 2, 1])
    F_saturation = _dfloop(ct.descfcn.saturation_nonlinearity(1))
    amp = np.linspace(1, 4, 10)
    with pytest.raises(ValueError, match="formatting string"):
        ct.describing_function_plot(H_simple, F_saturation, amp, label=1)

    # Unrecognized keyword
    with pytest.raises(TypeError, match="unrecognized keyword"):
        ct.describing_function_response(
            H_simple, F_saturation, amp, None, unknown=None)

    # Unrecognized keyword
    with pytest.raises(AttributeError, match="no property|unexpected keyword"):
        response = ct.describing_function_response(H_simple, F_saturation, amp)
        response.plot(unknown=None)

    # Describing function plot for non-describing function object
    resp = ct.frequency_response(H_simple)
    with pytest.raises(TypeError, match="data must be DescribingFunction"):
        ct.describing_function_plot(resp)
    plt.close("all")


# ------------------------------------------------------------------ part 2: the conversions themselves
ELEMENTS = [df.Saturation(1.5, k=2.0), df.DeadZone(0.5, k=1.5), df.Relay(M=2.0, dead_zone=0.3),
            df.CubicStiffness(1.0, 0.5), df.Quantizer(0.5), df.PreloadedSpring(0.4, k=2.0),
            df.Backlash(h=1.0, k=2.0), df.Relay(M=1.0, hysteresis=0.4), df.Relay(M=1.0, hysteresis=0.2, dead_zone=0.5),
            df.NumericDF(lambda x: np.tanh(x))]


@pytest.mark.parametrize("element", ELEMENTS, ids=lambda e: type(e).__name__)
def test_every_element_converts_and_its_map_has_its_describing_function(element):
    """python-control's own quadrature of the converted map F(x) (its try_method=False path, 4000 points, one
    amplitude per call so that its warm-up period puts a hysteretic element in its periodic state) gives
    dfloop's N(A) to the quadrature's accuracy; the method gives dfloop's values exactly."""
    F = to_control(element)
    assert isinstance(F, ct.DescribingFunctionNonlinearity)
    amps = np.array([0.7, 1.3, 2.9, 6.0])
    np.testing.assert_array_equal(ct.describing_function(F, amps), element(amps))
    numeric = []
    for a in amps:
        F.reset()
        numeric.append(ct.describing_function(F, a, num_points=4000, zero_check=False, try_method=False))
    np.testing.assert_allclose(np.ravel(numeric), element(amps), atol=3e-3)
    assert F._isstatic() == (isinstance(element, (StaticElement, df.NumericDF))
                             or (isinstance(element, df.Relay) and element.hysteresis == 0.0))


def test_static_map_is_the_elements_output():
    x = np.linspace(-3, 3, 61)
    for element in ELEMENTS[:6]:
        F = to_control(element)
        np.testing.assert_array_equal(F(x), element.output(x) if hasattr(element, "output")
                                      else np.vectorize(element.operator())(x))


def test_hysteretic_map_is_the_operator_and_its_discrete_nlsys_the_play():
    """Backlash: F(x) sample by sample is the PlayOperator from rest; the discrete-time nlsys (state: the play)
    driven by the same samples gives the same outputs."""
    rng = np.random.default_rng(5)
    x = np.cumsum(rng.normal(0.0, 0.4, 300))
    element = df.Backlash(h=1.0, k=2.0)
    op = element.operator()
    expected = np.array([op(v) for v in x])
    F = to_control(element)
    np.testing.assert_array_equal(F(x), expected)
    sys_d = F.to_nlsys(dt=0.1)
    resp = ct.input_output_response(sys_d, np.arange(x.size) * 0.1, x, [0.0])
    np.testing.assert_allclose(resp.outputs, expected, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="dt is required"):
        F.to_nlsys()
    relay = to_control(df.Relay(M=1.0, hysteresis=0.2, dead_zone=0.5))
    op = df.Relay(M=1.0, hysteresis=0.2, dead_zone=0.5).operator()
    np.testing.assert_array_equal(relay(x), [op(v) for v in x])


def test_mass_backlash_is_a_continuous_nlsys_with_its_describing_function():
    """MassBacklash (force -> position of a free mass -> backlash): the nlsys driven by F sin(w t) from its
    periodic start gives an output whose fundamental over one period is N(F, w) F."""
    element = df.MassBacklash(m1=1.0, m2=1.0, h=0.1)
    sys_c = to_control(element)
    assert isinstance(sys_c, ct.NonlinearIOSystem) and sys_c.nstates == 3
    force, w = 5.0, 3.0
    period = 2 * np.pi / w
    # periodic start, derived here: the mass (m1 + m2 = 2) under F sin(wt) moves as x = -F/(m w^2) sin(wt), so
    # x(0) = 0, v(0) = -F/(m w); x has just passed its maximum X = F/(m w^2) > h/2, so the play is held at
    # c = X - h/2 until dragged down at x = c - h/2: at t = 0 (x = 0) c = min(X - h/2, h/2)
    amplitude_x = force / (2.0 * w**2)
    start = [0.0, -force / (2.0 * w), min(amplitude_x - 0.05, 0.05)]
    T = np.linspace(0.0, period, 4001)
    resp = ct.input_output_response(sys_c, T, force * np.sin(w * T), start,
                                    solve_ivp_kwargs=dict(rtol=1e-10, atol=1e-12, max_step=period / 400))
    y = resp.outputs
    fundamental = np.trapezoid(y * np.exp(-1j * w * T), T) * 2j / period   # y ~ Im(Y e^{jwt})
    assert fundamental / force == pytest.approx(complex(element(force, w)), rel=2e-4)


def test_dynamic_backlash_says_what_to_use_instead():
    from dfloop.impact.dynamic_backlash import DynamicBacklash

    with pytest.raises(ValueError, match="dt=.*simulate_loop"):
        to_control(DynamicBacklash(1.0, 1.0, 0.1, 0.5))
    with pytest.raises(ValueError, match="dt"):
        to_control(df.Backlash(h=1.0), dt=0.1)

    class Stop:   # a user's hysteretic operator: its state is opaque to dfloop
        def __init__(self):
            self.y = 0.0

        def __call__(self, x):
            self.y = min(max(self.y + 0.1 * x, -1.0), 1.0)
            return self.y

    with pytest.raises(ValueError, match="hysteretic NumericDF of an operator other than"):
        to_control(df.NumericDF(Stop(), hysteretic=True)).to_nlsys(dt=0.1)

    class OnlyDF(df.DescribingFunction):   # a DF without any time-domain model
        def _evaluate(self, A, omega):
            return np.ones_like(A, dtype=complex)

    with pytest.raises(ValueError, match="no time-domain map"):
        to_control(OnlyDF())


@pytest.mark.parametrize("G, N", [
    (ct.tf([8.0], [1.0, 2.0, 2.0, 1.0]), df.Saturation(1.0)),
    (ct.tf([1.0], [1.0, 3.0, 2.0, 0.0]), df.Relay(M=1.0)),
    (ct.tf([5.0], [1.0, 1.0, 0.0]), df.Backlash(h=1.0)),
    (ct.ss(ct.tf([2.0], [1.0, 3.0, 2.0, 0.0])), df.Relay(M=1.0, hysteresis=0.1)),
], ids=["saturation", "relay", "backlash", "relay-hysteresis-ss"])
def test_closed_loop_in_python_control_settles_on_the_exact_cycle(G, N):
    """control.input_output_response of cycles.to_control(), started on the stable cycle's harmonic-balance
    orbit, settles on dfloop's exact cycle (multiple shooting on the exact flow): amplitude and frequency
    within 1e-5 (measured up to 5e-6 at rtol 1e-8; the DF's own amplitude error on these loops is 1.5-4.7 %)."""
    cycles = df.predict_limit_cycles(G, N, exact=True)
    (cycle,) = [c for c in cycles if c.stable]
    assert cycle.exact.success
    loop = cycles.to_control()
    T = np.linspace(0.0, 15 * cycle.period, 1501)
    resp = ct.input_output_response(loop, T, 0.0, loop.initial_state(cycle),
                                    solve_ivp_kwargs=dict(rtol=1e-8, atol=1e-10))
    x = resp.outputs[0]
    run = steady_state(T, x, 4)
    assert run.amplitude == pytest.approx(cycle.exact.amplitude, rel=1e-5)
    assert run.frequency == pytest.approx(cycle.exact.frequency, rel=1e-5)
    assert abs(run.amplitude / cycle.amplitude - 1) > 1e-3   # the DF prediction alone would not pass


def test_control_loop_rejects_what_it_cannot_simulate():
    with pytest.raises(ValueError, match="strictly proper"):
        control_loop(ct.tf([1.0, 1.0], [1.0, 2.0]), df.Saturation(1.0))
    with pytest.raises(ValueError, match="G must be a SISO python-control tf or ss"):
        control_loop(lambda s: 1 / s, df.Saturation(1.0))


@pytest.mark.parametrize("element", [df.Backlash(h=1.0, k=2.0), df.Relay(M=1.0, hysteresis=0.2, dead_zone=0.5),
                                     df.Relay(M=1.5, hysteresis=0.3)], ids=["backlash", "relay-3-level", "relay-hyst"])
def test_hysteretic_numeric_df_of_dfloop_operators_is_a_play_nlsys(element):
    """A hysteretic NumericDF of dfloop's play or relay operator converts like the element itself: F(x) is the
    operator from rest, the discrete-time nlsys (state: the play) gives the same outputs on a random input, and
    describing_function(A) is the NumericDF's own N(A)."""
    N = df.NumericDF(element.operator(), hysteretic=True)
    rng = np.random.default_rng(8)
    x = np.cumsum(rng.normal(0.0, 0.3, 300))
    op = element.operator()
    expected = np.array([op(v) for v in x])
    F = to_control(N)
    np.testing.assert_array_equal(F(x), expected)
    resp = ct.input_output_response(F.to_nlsys(dt=0.1), np.arange(x.size) * 0.1, x, [0.0])
    np.testing.assert_allclose(resp.outputs, expected, rtol=0, atol=1e-12)
    amps = np.array([0.9, 2.5])
    np.testing.assert_array_equal(ct.describing_function(F, amps), N(amps))


def test_closed_loop_of_a_hysteretic_numeric_df_settles_on_the_exact_cycle():
    """control_loop(G, NumericDF(play operator)) in control.input_output_response settles on the exact cycle of the
    same loop with the analytic Backlash (the same map; dfloop's exact engine): amplitude and frequency within 1e-5."""
    G = ct.tf([5.0], [1.0, 1.0, 0.0])
    cycles = df.predict_limit_cycles(G, df.Backlash(h=1.0), exact=True)
    (cycle,) = [c for c in cycles if c.stable]
    assert cycle.exact.success
    loop = control_loop(G, df.NumericDF(df.Backlash(h=1.0).operator(), hysteretic=True))
    T = np.linspace(0.0, 15 * cycle.period, 1501)
    resp = ct.input_output_response(loop, T, 0.0, loop.initial_state((cycle.amplitude, cycle.frequency)),
                                    solve_ivp_kwargs=dict(rtol=1e-8, atol=1e-10))
    run = steady_state(T, resp.outputs[0], 4)
    assert run.amplitude == pytest.approx(cycle.exact.amplitude, rel=1e-5)
    assert run.frequency == pytest.approx(cycle.exact.frequency, rel=1e-5)


def test_closed_loop_of_linear_then_static_with_feedthrough_settles_on_the_exact_cycle():
    """A lag (0.5 s + 1)/(2 s + 1) (D = 1/4: a feedthrough into the play) then a backlash, around 2 / (s^2 + s):
    the loop is the backlash loop around G G_lin, whose exact cycle (dfloop's exact engine) gives the element's
    output y(t). control_loop(G, N) in control.input_output_response, started from the harmonic-balance orbit of the
    composite's stable cycle, settles on it: frequency and the fundamental amplitude of y within 1e-4. A standalone
    nlsys of this element is refused (its play needs the input's rate)."""
    lin, G, bl = ct.tf([0.5, 1.0], [2.0, 1.0]), ct.tf([2.0], [1.0, 1.0, 0.0]), df.Backlash(h=1.0)
    N = df.LinearThenStatic(lin, bl)
    equivalent = df.predict_limit_cycles(G * lin, bl, exact=True)
    (ex,) = [c.exact for c in equivalent if c.exact.success and c.exact.stable]
    y_fundamental = 2 * abs(np.fft.rfft(ex.y)[1]) / ex.y.size   # y sampled uniformly over one period
    (cycle,) = [c for c in df.predict_limit_cycles(G, N) if c.stable]
    loop = control_loop(G, N)
    T = np.linspace(0.0, 30 * 2 * np.pi / cycle.frequency, 3001)
    resp = ct.input_output_response(loop, T, 0.0, loop.initial_state(cycle),
                                    solve_ivp_kwargs=dict(rtol=1e-8, atol=1e-10))
    run = steady_state(T, resp.outputs[1], 4)
    assert run.frequency == pytest.approx(ex.frequency, rel=1e-4)
    assert run.amplitude == pytest.approx(y_fundamental, rel=1e-4)
    assert abs(cycle.frequency / ex.frequency - 1) > 1e-3   # the DF prediction alone would not pass
    with pytest.raises(ValueError, match="control_loop"):
        to_control(N)


def _held_response(m1, m2, h, eps, dt, force):
    sys_d = to_control(DynamicBacklash(m1, m2, h, eps), dt=dt)
    assert sys_d.isdtime() and sys_d.nstates == 4
    T = np.arange(force.size) * dt
    return ct.input_output_response(sys_d, T, force, sys_d.model.initial())


def test_sampled_dynamic_backlash_keeps_momentum_under_any_held_force():
    """Impacts conserve momentum: m1 v1 + m2 v2 at every sample equals the impulse of the held force so far,
    whatever the impacts, chatter and sticking in between (random force levels, eps 0 to 1)."""
    rng = np.random.default_rng(7)
    for eps in (0.0, 0.5, 1.0):
        m1, m2, h, dt = 1.3, 0.7, 0.05, 0.02
        force = rng.uniform(-40.0, 40.0, 300)
        r = _held_response(m1, m2, h, eps, dt, force)
        x1, v1, gap, u = r.states
        impulse = np.concatenate([[0.0], np.cumsum(force[:-1]) * dt])
        assert np.max(np.abs(m1 * v1 + m2 * (v1 + u) - impulse)) < 1e-9 * np.max(np.abs(impulse))
        assert np.all((gap >= 0.0) & (gap <= h))
        np.testing.assert_array_equal(r.outputs, x1)


def test_sampled_dynamic_backlash_under_constant_force_follows_the_closed_form():
    """A constant force F on M2 from rest (gap h/2): before the first impact M2 alone accelerates (gap = h/2 +
    F t^2/(2 m2), x1 = 0); after the chatter has settled the pair moves as one body pressed on wall B, its centre
    of mass at m2 h/(2M) + F t^2/(2M)."""
    m1, m2, h, eps, F, dt = 1.0, 2.0, 0.1, 0.5, 5.0, 0.01
    r = _held_response(m1, m2, h, eps, dt, np.full(600, F))
    t = r.time
    x1, v1, gap, u = r.states
    before = t < np.sqrt(h * m2 / F)
    np.testing.assert_allclose(gap[before], h / 2 + F * t[before] ** 2 / (2 * m2), rtol=0, atol=1e-14)
    assert np.all(x1[before] == 0.0)
    M = m1 + m2
    late = t > 4.0
    assert np.all(gap[late] == h) and np.all(u[late] == 0.0)
    np.testing.assert_allclose(x1[late], m2 * h / (2 * M) + F * t[late] ** 2 / (2 * M) - m2 * h / M, rtol=1e-12)
