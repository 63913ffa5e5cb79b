"""python-control interop, both directions, against closed forms and python-control's own formulas."""
import math
import warnings

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq

import dfloop as df
from dfloop.describing.interop import ControlDescribingFunction, as_element

A = np.concatenate([np.geomspace(0.01, 100.0, 61), [0.2, 0.3, 1.0, 2.0]])


class Play:
    """A friction-backlash (play) operator written as a user would: plain class, no python-control base."""

    def __init__(self, b):
        self.b, self.center = b, 0.0

    def __call__(self, x):
        if x - self.center > self.b / 2:
            self.center = x - self.b / 2
        elif x - self.center < -self.b / 2:
            self.center = x + self.b / 2
        return self.center


# --------------------------------------------------------------------------- python-control -> dfloop


@pytest.mark.parametrize("obj, cls, params", [
    (ct.saturation_nonlinearity(1.5), df.Saturation, {"limit": 1.5, "k": 1.0}),
    (ct.friction_backlash_nonlinearity(0.4), df.Backlash, {"h": 0.4, "k": 1.0}),
    (ct.relay_hysteresis_nonlinearity(2.0, 0.3), df.Relay, {"M": 2.0, "hysteresis": 0.3, "dead_zone": 0.0}),
])
def test_control_nonlinearities_map_to_analytic_elements(obj, cls, params):
    element = as_element(obj)
    assert type(element) is cls and vars(element) == params
    a = A[A > 0.3]  # python-control's relay returns NaN inside its band, dfloop's gives 0 there (no switching)
    np.testing.assert_allclose(element(a), ct.describing_function(obj, a), rtol=1e-12, atol=1e-15)


def test_asymmetric_saturation_numeric_matches_control_closed_form():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # python-control warns about the bias term
        obj = ct.saturation_nonlinearity(1.0, -2.0)
    element = as_element(obj)
    a = A[A > 2.0]  # python-control's formula is only valid above both limits
    np.testing.assert_allclose(element(a), ct.describing_function(obj, a), rtol=1e-12, atol=1e-15)


def test_predict_limit_cycles_with_control_saturation_against_closed_form():
    # G = 8 / (s + 1)(s^2 + s + 1): Im G(jw) = 0 at w = sqrt(2), G = -8/3, so the cycle has N(A) = 3/8
    G = ct.tf([8], [1, 2, 2, 1])
    cycles = df.predict_limit_cycles(G, as_element(ct.saturation_nonlinearity(1)))
    u = brentq(lambda u: 2 / np.pi * (math.asin(u) + u * math.sqrt(1 - u * u)) - 3 / 8, 1e-6, 1 - 1e-12,
               xtol=1e-16)
    assert len(cycles) == 1 and cycles[0].stable
    assert cycles[0].amplitude == pytest.approx(1 / u, rel=1e-10)
    assert cycles[0].frequency == pytest.approx(math.sqrt(2), rel=1e-10)


@pytest.mark.parametrize("f, exact, lo", [
    (lambda x: math.copysign(min(abs(x), 1.0), x), df.Saturation(1.0), 0.0),  # scalar-only code
    (np.sign, df.Relay(1.0), 0.0),  # ufunc with a jump at 0
    (lambda x: 0.0 if abs(x) <= 0.5 else math.copysign(2.0, x), df.Relay(2.0, dead_zone=0.5), 0.5 * 1.001),
    (lambda x: x - np.clip(x, -0.3, 0.3), df.DeadZone(0.3), 0.3 * 1.001),
])
def test_plain_static_functions_are_exact(f, exact, lo):
    element = as_element(f)
    assert isinstance(element, df.NumericDF) and not element.hysteretic
    a = A[A > lo]
    np.testing.assert_allclose(element(a), exact(a), rtol=1e-12, atol=1e-14)


def test_callable_with_memory_is_detected_as_hysteretic():
    element = as_element(Play(0.4))
    assert isinstance(element, df.NumericDF) and element.hysteretic
    a = np.array([0.21, 0.3, 1.0, 7.0])
    np.testing.assert_allclose(element(a), df.Backlash(0.4)(a), rtol=1e-12, atol=1e-14)


def test_control_base_without_method_falls_back_to_numeric():
    class Cubic(ct.DescribingFunctionNonlinearity):  # describing_function raises NotImplementedError
        def __call__(self, x):
            return x + 0.5 * x**3

    element = as_element(Cubic())
    assert isinstance(element, df.NumericDF) and not element.hysteretic
    np.testing.assert_allclose(element(A), df.CubicStiffness(1.0, 0.5)(A), rtol=1e-12)


def test_object_with_describing_function_is_used_as_is():
    class Custom:
        def describing_function(self, a):
            return 1.0 + 0.75 * a * a - 0.1j

    element = as_element(Custom())
    assert isinstance(element, ControlDescribingFunction)
    np.testing.assert_array_equal(element(A), 1.0 + 0.75 * A * A - 0.1j)

    class Broken:
        def describing_function(self, a):
            return float("nan")

    with pytest.raises(ValueError, match="returned NaN"):
        as_element(Broken())(np.array([1.0]))


def test_static_nonlinear_io_system_is_exact_and_dynamic_systems_are_refused():
    sat = ct.nlsys(None, lambda t, x, u, p: np.clip(u, -1.0, 1.0), inputs=1, outputs=1)
    a = np.geomspace(0.1, 10.0, 7)
    np.testing.assert_allclose(as_element(sat)(a), df.Saturation(1.0)(a), rtol=1e-12)
    lag = ct.nlsys(lambda t, x, u, p: -x + u, lambda t, x, u, p: x, inputs=1, outputs=1, states=1)
    with pytest.raises(ValueError, match="1 states"):
        as_element(lag)
    with pytest.raises(ValueError, match="belongs in the plant G"):
        as_element(ct.tf([1], [1, 1]))


def test_dfloop_elements_pass_through_unchanged():
    element = df.Backlash(0.1)
    assert as_element(element) is element


@pytest.mark.parametrize("bad, match", [
    (3.0, "NumericDF"),
    ("saturation", "callable static map"),
    (lambda x: np.array([x, x]), "one number per input"),
    (lambda x: 1.0 / x, r"failed at x = 0.0: ZeroDivisionError"),
])
def test_bad_input_says_what_is_accepted(bad, match):
    with pytest.raises(ValueError, match=match):
        as_element(bad)


def test_invalid_control_parameters_named_as_control_names_them():
    with pytest.raises(ValueError, match="ub must be > 0"):
        as_element(ct.saturation_nonlinearity(0.0))
    with pytest.raises(ValueError, match="c must be >= 0"):
        as_element(ct.relay_hysteresis_nonlinearity(1.0, -0.1))
    with pytest.raises(ValueError, match="b must be > 0"):
        as_element(ct.friction_backlash_nonlinearity(0.0))


# --------------------------------------------------------------------------- dfloop -> python-control

ELEMENTS = [df.Backlash(0.2), df.Saturation(1.0, 2.0), df.DeadZone(0.5), df.Relay(1.0, 0.1, 0.2),
            df.CubicStiffness(1.0, 0.5), df.Quantizer(0.5), df.PreloadedSpring(1.0), df.CoulombViscousFriction(1.0, 0.2),
            df.NumericDF(df.Saturation(1.0))]


@pytest.mark.parametrize("element", ELEMENTS, ids=lambda e: type(e).__name__)
def test_control_describing_function_uses_the_element(element):
    a = A if not isinstance(element, (df.PreloadedSpring, df.CoulombViscousFriction)) else A[A > 0]
    np.testing.assert_allclose(ct.describing_function(element, a), element(a), rtol=1e-12, atol=0)


def test_frequency_dependent_element_refuses_with_pointer_to_dfloop():
    with pytest.raises(ValueError, match="predict_limit_cycles"):
        df.MassBacklash(1.0, 1.0, 0.1).describing_function(1.0)


def test_control_response_and_plot_agree_with_dfloop():
    import matplotlib.pyplot as plt

    G = ct.tf([8], [1, 2, 2, 1])
    N = df.Saturation(1.0)
    amps = np.linspace(1.0, 5.0, 60)
    omega = np.linspace(0.5, 3.0, 600)
    resp = ct.describing_function_response(G, N, amps, omega)
    np.testing.assert_allclose(resp.N_vals, -1.0 / N(amps), rtol=1e-12)
    cycles = df.predict_limit_cycles(G, N)
    assert len(resp.intersections) == len(cycles) == 1
    c = cycles[0]
    # python-control's own residual at dfloop's root (its G and its DF call): zero to rounding
    assert abs(1 + G(1j * c.frequency) * ct.describing_function(N, c.amplitude)) < 1e-12
    # its root (scipy.optimize.minimize on |1 + G N|^2, default tolerances) lies near dfloop's
    a_ct, w_ct = resp.intersections[0]
    assert a_ct == pytest.approx(c.amplitude, rel=1e-3) and w_ct == pytest.approx(c.frequency, rel=1e-3)
    cplt = ct.describing_function_plot(G, N, amps, omega)
    assert isinstance(cplt, ct.ControlPlot)
    line = cplt.lines[1][0]
    np.testing.assert_allclose(line.get_xdata() + 1j * line.get_ydata(), -1.0 / N(amps), rtol=1e-12)
    plt.close(cplt.figure)
