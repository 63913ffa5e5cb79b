"""Every public constructor of the describing-function library rejects bad parameters by name."""
import control as ct
import numpy as np
import pytest

import dfloop as df

BAD_POSITIVE = [0.0, -1.0, np.nan, np.inf]
BAD_NONNEGATIVE = [-1.0, np.nan, np.inf]

# (constructor, valid keyword arguments, parameter, bad values)
CASES = [
    (df.Backlash, {"h": 0.1, "k": 1.0}, "h", BAD_POSITIVE),
    (df.Backlash, {"h": 0.1, "k": 1.0}, "k", BAD_POSITIVE),
    (df.PlayOperator, {"h": 0.1, "k": 1.0}, "h", BAD_POSITIVE),
    (df.PlayOperator, {"h": 0.1, "k": 1.0}, "k", BAD_POSITIVE),
    (df.Saturation, {"limit": 1.0, "k": 1.0}, "limit", BAD_POSITIVE),
    (df.Saturation, {"limit": 1.0, "k": 1.0}, "k", BAD_POSITIVE),
    (df.DeadZone, {"delta": 1.0, "k": 1.0}, "delta", BAD_POSITIVE),
    (df.DeadZone, {"delta": 1.0, "k": 1.0}, "k", BAD_POSITIVE),
    (df.Relay, {"M": 1.0, "hysteresis": 0.1, "dead_zone": 0.1}, "M", BAD_POSITIVE),
    (df.Relay, {"M": 1.0, "hysteresis": 0.1, "dead_zone": 0.1}, "hysteresis", BAD_NONNEGATIVE),
    (df.Relay, {"M": 1.0, "hysteresis": 0.1, "dead_zone": 0.1}, "dead_zone", BAD_NONNEGATIVE),
    (df.RelayOperator, {"M": 1.0, "on": 0.5, "off": 0.2}, "M", BAD_POSITIVE),
    (df.RelayOperator, {"M": 1.0, "on": 0.5, "off": 0.2}, "on", BAD_NONNEGATIVE),
    (df.RelayOperator, {"M": 1.0, "on": 0.5, "off": 0.2}, "off", [0.6, -0.6, np.nan, np.inf]),
    (df.CubicStiffness, {"k1": 1.0, "k3": 1.0}, "k1", BAD_POSITIVE),
    (df.CubicStiffness, {"k1": 1.0, "k3": 1.0}, "k3", [0.0, np.nan, np.inf, -np.inf]),
    (df.Quantizer, {"step": 0.1}, "step", BAD_POSITIVE),
    (df.PreloadedSpring, {"preload": 1.0, "k": 1.0}, "preload", BAD_POSITIVE),
    (df.PreloadedSpring, {"preload": 1.0, "k": 1.0}, "k", BAD_NONNEGATIVE),
    (df.CoulombViscousFriction, {"Fc": 1.0, "c": 1.0}, "Fc", BAD_POSITIVE),
    (df.CoulombViscousFriction, {"Fc": 1.0, "c": 1.0}, "c", BAD_NONNEGATIVE),
    (df.MassBacklash, {"m1": 1.0, "m2": 1.0, "h": 0.1, "k": 1.0}, "m1", BAD_POSITIVE),
    (df.MassBacklash, {"m1": 1.0, "m2": 1.0, "h": 0.1, "k": 1.0}, "m2", BAD_POSITIVE),
    (df.MassBacklash, {"m1": 1.0, "m2": 1.0, "h": 0.1, "k": 1.0}, "h", BAD_POSITIVE),
    (df.MassBacklash, {"m1": 1.0, "m2": 1.0, "h": 0.1, "k": 1.0}, "k", BAD_POSITIVE),
    (df.NumericDF, {"element": np.tanh}, "nodes", [0, 1, 2.5, np.nan]),
    (df.NumericDF, {"element": np.tanh}, "samples", [0, 8, 100.5, np.nan]),
    (df.NumericDF, {"element": np.tanh}, "rtol", [0.0, -1e-9, 0.5, np.nan, np.inf]),
    (df.NumericDF, {"element": np.tanh}, "method", ["fft", None]),
    (df.NumericDF, {"element": np.tanh}, "element", [3.0, None]),
]


@pytest.mark.parametrize("ctor,good,name,bad", CASES, ids=[f"{c[0].__name__}-{c[2]}" for c in CASES])
def test_bad_parameter_raises_naming_it(ctor, good, name, bad):
    ctor(**good)  # the valid set is accepted
    for value in bad:
        with pytest.raises(ValueError, match=name):
            ctor(**{**good, name: value})


def test_non_numeric_parameter_raises_naming_it():
    with pytest.raises(ValueError, match="h"):
        df.Backlash("wide")


def test_numeric_df_breakpoints():
    with pytest.raises(ValueError, match="breakpoints"):
        df.NumericDF(df.Backlash(0.1), breakpoints=[0.05])  # hysteretic: not applicable
    with pytest.raises(ValueError, match="breakpoints"):
        df.NumericDF(np.sign, breakpoints=[np.nan])(1.0)


def test_linear_then_static_rejects_mimo_and_non_static():
    with pytest.raises(ValueError, match="linear"):
        df.LinearThenStatic(ct.rss(2, 2, 2), df.Backlash(0.1))
    with pytest.raises(ValueError, match="linear"):
        df.LinearThenStatic("G", df.Backlash(0.1))
    with pytest.raises(ValueError, match="static"):
        df.LinearThenStatic(ct.tf([1], [1, 0]), df.MassBacklash(1.0, 1.0, 0.1))
    with pytest.raises(ValueError, match="static"):
        df.LinearThenStatic(ct.tf([1], [1, 0]), np.tanh)


@pytest.mark.parametrize("F", [0.0, -1.0, np.nan, np.inf])
def test_limit_frequency_rejects_bad_force(F):
    with pytest.raises(ValueError, match="F"):
        df.MassBacklash(1.0, 1.0, 0.1).limit_frequency([10.0, F])


def test_negative_or_bad_amplitudes_and_frequencies():
    with pytest.raises(ValueError, match="X"):
        df.Backlash(0.1)(-1e-3)
    with pytest.raises(ValueError, match="F"):
        df.MassBacklash(1.0, 1.0, 0.1)(-1.0, 2.0)
    with pytest.raises(ValueError, match="omega"):
        df.MassBacklash(1.0, 1.0, 0.1)(1.0, -2.0)
    with pytest.raises(ValueError, match="A"):
        df.NumericDF(np.tanh)(np.inf)
