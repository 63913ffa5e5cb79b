"""One error table: every public entry point probed with bad input, as data; docs/errors.md is generated from it.

Each row of PROBES is one probe: the entry point, the bad input (as the user would write it), a callable that
makes the call, the expected outcome (an exception class, or ``"exit N"`` for the command line) and fragments
the message must contain (the parameter and the value). The tests run every probe; a last test regenerates
the markdown table from the same rows and checks that docs/errors.md is identical, so the page cannot drift.

Regenerate the page after changing a probe or a message::

    PYTHONPATH=. python tests/test_error_table.py --write

To add a probe, add one row anywhere (the table groups rows by entry point, in order of first appearance).
"""
from __future__ import annotations

import atexit
import contextlib
import io
import re
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.describing import negative_inverse
from dfloop.impact import (ImpactParameters, beta_of, impact_describing_function, impact_describing_function_batch,
                           lower_limit_frequency, no_impact_frequency, prepare_many, simulate_impacts)
from dfloop.solve import as_plant, graphical_stability
from dfloop import cli, harmonics
from dfloop.solve.confidence import cycle_confidence
from dfloop.errors import DfloopError
from dfloop.impact.kernel import simulate
from dfloop.plot.impact import plot_collision_map, plot_time_response
from dfloop.plot.loci import plot_loci
from dfloop.plot.nyquist import plot_nyquist
from dfloop.scene import load_scene

DOC = Path(__file__).resolve().parents[1] / "docs" / "errors.md"
_SCRATCH = Path(tempfile.mkdtemp(prefix="dfloop_errors_"))
atexit.register(shutil.rmtree, _SCRATCH, True)


@dataclass(frozen=True)
class Probe:
    """One bad call: ``entry`` (the public entry point), ``bad`` (the input, as written by a user), ``call``
    (makes the call), ``expect`` (exception class, or "exit N" for the CLI) and ``fragments`` (each must
    appear in the message)."""

    entry: str
    bad: str
    call: Callable[[], object]
    expect: type | str
    fragments: tuple[str, ...]


def scene_file(text: str, name: str = "scene.toml") -> Path:
    """A scene file in the scratch directory (its path shows as <dir> in the table)."""
    path = _SCRATCH / name
    path.write_text(text)
    return path


_PLANT = '[plant]\ntype = "tf"\nnum = [5.0]\nden = [1.0, 1.0, 0.0]\n'
_ELEMENT = '[element]\ntype = "Backlash"\nh = 1.0\n'
G = ct.tf([5.0], [1.0, 1.0, 0.0])
G3 = ct.tf([10.0], [1.0, 3.0, 3.0, 1.0])
MB = df.MassBacklash(1.0, 1.0, 0.1)
DB = df.DynamicBacklash(1.0, 1.0, 0.1, 0.5)
SAT = df.Saturation(1.0)

# Bad amplitudes every element rejects in the same way (the base class's __call__): one row per kind.
_ELEMENT_CALLS = [
    ("Backlash(h, k)(X)", "X", lambda a: df.Backlash(0.1)(a)),
    ("Saturation(limit, k)(A)", "A", lambda a: SAT(a)),
    ("DeadZone(delta, k)(A)", "A", lambda a: df.DeadZone(1.0)(a)),
    ("Relay(M, hysteresis, dead_zone)(A)", "A", lambda a: df.Relay(1.0, 0.1)(a)),
    ("CubicStiffness(k1, k3)(X)", "X", lambda a: df.CubicStiffness(1.0, 1.0)(a)),
    ("Quantizer(step)(A)", "A", lambda a: df.Quantizer(0.1)(a)),
    ("PreloadedSpring(preload, k)(X)", "X", lambda a: df.PreloadedSpring(1.0)(a)),
    ("CoulombViscousFriction(Fc, c)(V)", "V", lambda a: df.CoulombViscousFriction(1.0)(a)),
    ("NumericDF(element)(A)", "A", lambda a: df.NumericDF(np.tanh)(a)),
    ("MassBacklash(m1, m2, h, k)(F, omega)", "F", lambda a: MB(a, 2.0)),
    ("LinearThenStatic(linear, static)(A, omega)", "A", lambda a: df.LinearThenStatic(G, SAT)(a, 2.0)),
    ("DynamicBacklash(m1, m2, h, restitution)(F, omega)", "F", lambda a: DB(a, 30.0)),
]
_BAD_AMPLITUDES = [
    ("-1", -1.0, ("must be >= 0", "-1.0")),
    ("1 + 1j (complex)", 1 + 1j, ("must be real", "(1+1j)")),
    ('"big" (a string)', "big", ("'big'",)),
    ("None", None, ("None",)),
    ("[[1, 2], [3]] (ragged)", [[1, 2], [3]], ("rectangular array",)),
]

PROBES: list[Probe] = [
    # ------------------------------------------------------------------ element constructors
    Probe("Backlash(h, k)", "h = 0", lambda: df.Backlash(0.0), DfloopError, ("h must be > 0", "0.0")),
    Probe("Backlash(h, k)", "h = nan", lambda: df.Backlash(np.nan), DfloopError, ("h must not be NaN",)),
    Probe("Backlash(h, k)", "h = inf", lambda: df.Backlash(np.inf), DfloopError, ("h must be finite", "inf")),
    Probe("Backlash(h, k)", 'h = "wide"', lambda: df.Backlash("wide"), DfloopError, ("h must be a real number", "'wide'")),
    Probe("Backlash(h, k)", "h = 0.1 + 0j", lambda: df.Backlash(0.1 + 0j), DfloopError, ("h must be a real number", "complex")),
    Probe("Backlash(h, k)", "k = -1", lambda: df.Backlash(0.1, -1.0), DfloopError, ("k must be > 0", "-1.0")),
    Probe("PlayOperator(h, k)", "h = -0.1", lambda: df.PlayOperator(-0.1), DfloopError, ("h must be > 0", "-0.1")),
    Probe("Saturation(limit, k)", "limit = 0", lambda: df.Saturation(0.0), DfloopError, ("limit must be > 0", "0.0")),
    Probe("Saturation(limit, k)", "k = True", lambda: df.Saturation(1.0, True), DfloopError, ("k must be a real number", "True")),
    Probe("Saturation(limit, k)", "slope = 2 (unknown keyword)", lambda: df.Saturation(limit=1.0, slope=2.0), TypeError,
          ("Saturation has no parameter 'slope' (did you mean 'k'?)", "limit, k")),
    Probe("DeadZone(delta, k)", "delta = -1", lambda: df.DeadZone(-1.0), DfloopError, ("delta must be > 0", "-1.0")),
    Probe("Relay(M, hysteresis, dead_zone)", "M = 0", lambda: df.Relay(0.0), DfloopError, ("M must be > 0", "0.0")),
    Probe("Relay(M, hysteresis, dead_zone)", "hysteresis = -0.1", lambda: df.Relay(1.0, -0.1), DfloopError,
          ("hysteresis must be >= 0", "-0.1")),
    Probe("Relay(M, hysteresis, dead_zone)", "dead_zone = nan", lambda: df.Relay(1.0, 0.0, np.nan), DfloopError,
          ("dead_zone must not be NaN",)),
    Probe("RelayOperator(M, on, off)", "off = 0.6 > on = 0.5", lambda: df.RelayOperator(1.0, 0.5, 0.6), DfloopError,
          ("off must lie in [-0.5, 0.5]", "0.6")),
    Probe("CubicStiffness(k1, k3)", "k3 = 0", lambda: df.CubicStiffness(1.0, 0.0), DfloopError, ("k3 must be non-zero", "0.0")),
    Probe("CubicStiffness(k1, k3)", "k1 = 0", lambda: df.CubicStiffness(0.0, 1.0), DfloopError, ("k1 must be > 0", "0.0")),
    Probe("Quantizer(step)", "step = inf", lambda: df.Quantizer(np.inf), DfloopError, ("step must be finite", "inf")),
    Probe("PreloadedSpring(preload, k)", "k = -1", lambda: df.PreloadedSpring(1.0, -1.0), DfloopError, ("k must be >= 0", "-1.0")),
    Probe("CoulombViscousFriction(Fc, c)", "Fc = 0", lambda: df.CoulombViscousFriction(0.0), DfloopError, ("Fc must be > 0", "0.0")),
    Probe("MassBacklash(m1, m2, h, k)", "m2 = -1", lambda: df.MassBacklash(1.0, -1.0, 0.1), DfloopError, ("m2 must be > 0", "-1.0")),
    Probe("LinearThenStatic(linear, static)", "linear with 2 inputs and 2 outputs",
          lambda: df.LinearThenStatic(ct.ss(-np.eye(2), np.eye(2), np.eye(2), 0), SAT), DfloopError,
          ("linear must be SISO", "2 inputs and 2 outputs")),
    Probe("LinearThenStatic(linear, static)", 'linear = "G"', lambda: df.LinearThenStatic("G", SAT), DfloopError,
          ("linear must be a python-control LTI or a callable", "'G'")),
    Probe("LinearThenStatic(linear, static)", "static = MassBacklash(...)", lambda: df.LinearThenStatic(G, MB), DfloopError,
          ("static must be an amplitude-only DescribingFunction", "MassBacklash")),
    Probe("NumericDF(element, ...)", "element = 3.0", lambda: df.NumericDF(3.0), DfloopError, ("element must be callable", "3.0")),
    Probe("NumericDF(element, ...)", "nodes = 2.5", lambda: df.NumericDF(np.tanh, nodes=2.5), DfloopError,
          ("nodes must be an integer >= 2", "2.5")),
    Probe("NumericDF(element, ...)", "nodes = 10**9", lambda: df.NumericDF(np.tanh, nodes=10**9), DfloopError,
          ("nodes must be <= 1024", "1000000000")),
    Probe("NumericDF(element, ...)", "samples = 10**9", lambda: df.NumericDF(np.tanh, samples=10**9), DfloopError,
          ("samples must be <= 65536", "1000000000")),
    Probe("NumericDF(element, ...)", 'breakpoints = ["a"]', lambda: df.NumericDF(np.tanh, breakpoints=["a"]), DfloopError,
          ("breakpoints must be a real number or an array of them", "['a']")),
    Probe("NumericDF(element, ...)", "breakpoints = [nan]", lambda: df.NumericDF(np.tanh, breakpoints=[np.nan]), DfloopError,
          ("breakpoints must be finite", "nan")),
    Probe("NumericDF(element, ...)", 'hysteretic = "no"', lambda: df.NumericDF(np.tanh, hysteretic="no"), DfloopError,
          ("hysteretic must be True or False (or None)", "'no'")),
    Probe("NumericDF(element, ...)", "input_name = 3", lambda: df.NumericDF(np.tanh, input_name=3), DfloopError,
          ("input_name must be a string", "3")),
    Probe("NumericDF(element, ...)", "samples = 8", lambda: df.NumericDF(np.tanh, samples=8), DfloopError,
          ("samples must be an integer >= 16", "8")),
    Probe("NumericDF(element, ...)", "rtol = 0.5", lambda: df.NumericDF(np.tanh, rtol=0.5), DfloopError,
          ("rtol must lie in", "0.5")),
    Probe("NumericDF(element, ...)", 'method = "fft"', lambda: df.NumericDF(np.tanh, method="fft"), DfloopError,
          ("method must be 'pieces' or 'sampled'", "'fft'")),
    Probe("NumericDF(element, ...)", "breakpoints with hysteretic=True", lambda: df.NumericDF(df.Backlash(0.1), breakpoints=[0.05]),
          DfloopError, ("breakpoints apply to static functions only", "[0.05]")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", "restitution = 1.5", lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 1.5),
          DfloopError, ("restitution must lie in [0.0, 1.0]", "1.5")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", "h = 0", lambda: df.DynamicBacklash(1.0, 1.0, 0.0, 0.5),
          DfloopError, ("h must be > 0", "0.0")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", "min_dx = 0.5 > base_dx = 0.1",
          lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, base_dx=0.1, min_dx=0.5), DfloopError,
          ("min_dx must be <= base_dx = 0.1", "0.5")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", 'cache = "off"',
          lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, cache="off"), DfloopError, ("cache must be True or False", "'off'")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", 'progress = "bar"',
          lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, progress="bar"), DfloopError,
          ("progress must be True, False, None or a callable(n, stage)", "'bar'")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", "max_transient_periods = 10**8",
          lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, max_transient_periods=10**8), ValueError,
          ("max_transient_periods + periods spans 1e+08 forcing periods, above the bound of 1e+07",)),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", "periods = 2.5",
          lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, periods=2.5), DfloopError, ("periods must be an integer >= 1", "2.5")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", "beta_max = 0.2", lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, beta_max=0.2),
          ValueError, ("beta_max must exceed 1/4", "0.2")),
    Probe("DynamicBacklash(m1, m2, h, restitution, ...)", 'effects = ("damping",)',
          lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5, effects=("damping",)), ValueError,
          ("effects: 'damping' is not an effect object",)),
    Probe("DynamicBacklash(...).amplitude_domain(omega)", "omega = None", lambda: DB.amplitude_domain(None), ValueError,
          ("omega is required", "None")),
    Probe("impact_describing_function_batch(..., workers)", "workers = 0",
          lambda: impact_describing_function_batch(1.0, 1.0, 0.1, 0.5, 50.0, [30.0], workers=0), ValueError,
          ("workers must be an integer >= 1", "0")),
    Probe("no_impact_frequency(F, m2, h)", "F = 50 + 1j", lambda: no_impact_frequency(50.0 + 1j, 1.0, 0.1), ValueError,
          ("F must be real", "(50+1j)")),
    Probe("ViscousDamping(c)", "c = -1", lambda: df.ViscousDamping(-1.0), DfloopError, ("c must be", "-1.0")),
    Probe("LoadSpring(k)", "k = nan", lambda: df.LoadSpring(np.nan), DfloopError, ("k must not be NaN",)),
    Probe("CoulombFriction(force, mass)", 'mass = "m3"', lambda: df.CoulombFriction(1.0, "m3"), ValueError,
          ("mass must be 'm1' or 'm2'", "'m3'")),
    Probe("ImpactParameters(m1, m2, h, restitution, force, omega)", "m1 = 0",
          lambda: ImpactParameters(0.0, 1.0, 0.1, 0.5, 50.0, 30.0), DfloopError, ("m1 must be > 0", "0.0")),
    # ------------------------------------------------------------------ evaluating elements: N(A, omega)
    *[Probe(entry, f"{name} = {label}", (lambda call=call, value=value: call(value)), DfloopError, (name, *frag))
      for entry, name, call in _ELEMENT_CALLS for label, value, frag in _BAD_AMPLITUDES],
    Probe("NumericDF(element)(A)", "A = 0 (no numeric limit)", lambda: df.NumericDF(np.tanh)(0.0), DfloopError,
          ("A (amplitude) must lie in [1e-250, 1e+250]", "0.0")),
    Probe("NumericDF(element)(A)", "A = inf", lambda: df.NumericDF(np.tanh)(np.inf), DfloopError, ("A (amplitude) must lie in", "inf")),
    Probe("NumericDF(element)(A)", "element output not finite (x**3 at A = 1e200)",
          lambda: df.NumericDF(lambda x: np.float64(1e200) * x)(1e200), DfloopError, ("not finite", "1e+200")),
    Probe("Quantizer(step)(A)", "A / step > 1e7 levels", lambda: df.Quantizer(0.1)(1e7), DfloopError,
          ("exceeds the bound of 10000000 quantization levels", "A = 10000000.0")),
    Probe("MassBacklash(m1, m2, h, k)(F, omega)", "omega = 0", lambda: MB(1.0, 0.0), DfloopError,
          ("omega (frequency, rad/s) must be finite and > 0", "0.0")),
    Probe("MassBacklash(m1, m2, h, k)(F, omega)", "omega = inf", lambda: MB(1.0, np.inf), DfloopError,
          ("omega (frequency, rad/s) must be finite and > 0", "inf")),
    Probe("MassBacklash(m1, m2, h, k)(F, omega)", "omega missing", lambda: MB(1.0), DfloopError, ("omega is required", "None")),
    Probe("MassBacklash(m1, m2, h, k)(F, omega)", "shapes (2,) and (3,)", lambda: MB([1.0, 2.0], [1.0, 2.0, 3.0]), DfloopError,
          ("must broadcast together", "(2,)", "(3,)")),
    Probe("Saturation(limit, k)(A, omega)", "omega = -1 (validated, then ignored)", lambda: SAT(1.0, -1.0), DfloopError,
          ("omega (frequency, rad/s) must be finite and > 0", "-1.0")),
    Probe("DynamicBacklash(m1, m2, h, restitution)(F, omega)", "omega = 1 - 1j", lambda: DB(1.0, 1 - 1j), DfloopError,
          ("omega must be real", "(1-1j)")),
    # ------------------------------------------------------------------ element and result methods
    Probe("MassBacklash.limit_frequency(F)", "F = 0", lambda: MB.limit_frequency([10.0, 0.0]), DfloopError,
          ("F (force amplitude, N) must be finite and > 0", "0.0")),
    Probe("LinearThenStatic.amplitude_domain(omega)", "omega missing", lambda: df.LinearThenStatic(G, SAT).amplitude_domain(),
          DfloopError, ("omega is required", "None")),
    Probe("LinearThenStatic.gain(omega)", "omega = -2", lambda: df.LinearThenStatic(G, SAT).gain(-2.0), DfloopError,
          ("omega (frequency, rad/s) must be finite and > 0", "-2.0")),
    Probe("StaticElement.output(x)", 'Saturation(1).output("a")', lambda: SAT.output("a"), DfloopError,
          ("x must be a real number or an array of them", "'a'")),
    Probe("StaticElement.output(x)", "DeadZone(1).output(1j)", lambda: df.DeadZone(1.0).output(1j), DfloopError,
          ("x must be real", "1j")),
    Probe("operator()(x)", "PlayOperator(0.1)(1 + 1j)", lambda: df.PlayOperator(0.1)(1 + 1j), DfloopError,
          ("x must be a real number", "(1+1j)")),
    Probe("operator()(x)", "RelayOperator(1, 0.5, 0.2)(None)", lambda: df.RelayOperator(1.0, 0.5, 0.2)(None), DfloopError,
          ("x must be a real number", "None")),
    Probe("operator()(x)", 'Saturation(1).operator()("s")', lambda: SAT.operator()("s"), DfloopError,
          ("x must be a real number", "'s'")),
    Probe("DescribingFunction.amplitude_domain(omega)", "Backlash(0.1).amplitude_domain(-1)",
          lambda: df.Backlash(0.1).amplitude_domain(-1.0), DfloopError, ("omega (frequency, rad/s) must be finite and > 0", "-1.0")),
    Probe("Quantizer.breakpoints(A_max)", "A_max missing", lambda: df.Quantizer(0.1).breakpoints(), DfloopError,
          ("A_max is required", "None")),
    Probe("NumericDF.error_estimate(A)", "A = -2", lambda: df.NumericDF(np.tanh).error_estimate(-2.0), DfloopError,
          ("A (amplitude) must be >= 0", "-2.0")),
    Probe("DynamicBacklash.validity(F, omega)", "omega missing", lambda: DB.validity(1.0), ValueError, ("omega is required",)),
    Probe("DynamicBacklash.prepare(F, omega)", "F = -5", lambda: DB.prepare(-5.0, 30.0), DfloopError, ("F (amplitude) must be >= 0", "-5.0")),
    Probe("DynamicBacklash.save(path)", "before any evaluation", lambda: df.DynamicBacklash(1.0, 1.0, 0.1, 0.5).save(_SCRATCH / "t.npz"),
          ValueError, ("nothing to save",)),
    Probe("negative_inverse(N, A, omega)", "N = 3", lambda: negative_inverse(3, 1.0), DfloopError,
          ("N must be a dfloop DescribingFunction", "int")),
    Probe("negative_inverse(N, A, omega)", "A = -1", lambda: negative_inverse(SAT, -1.0), DfloopError, ("A (amplitude) must be >= 0", "-1.0")),
    # ------------------------------------------------------------------ solver
    Probe("predict_limit_cycles(G, N, ...)", "tol = None", lambda: df.predict_limit_cycles(G3, SAT, tol=None), ValueError,
          ("tol must be a real number", "None")),
    Probe("predict_limit_cycles(G, N, ...)", "improper G", lambda: df.predict_limit_cycles(ct.tf([1.0, 2.0, 3.0, 4.0], [1.0, 1.0]), SAT),
          ValueError, ("G must be proper", "degrees 3 > 1")),
    Probe("predict_limit_cycles(G, N, ...)", "zero G", lambda: df.predict_limit_cycles(ct.tf([0.0], [1.0, 1.0]), SAT), ValueError,
          ("G is zero",)),
    Probe("predict_limit_cycles(G, N, ...)", "grid = (20000, 20000)", lambda: df.predict_limit_cycles(G3, SAT, grid=(20000, 20000)),
          ValueError, ("20000 x 20000", "29.8 GiB")),
    Probe("predict_limit_cycles(G, N, ...)", "grid = (6000, 7000), frequency-dependent N",
          lambda: df.predict_limit_cycles(G3, MB, grid=(6000, 7000)), ValueError,
          ("6000 x 7000 points would need 6.3 GiB", "160 bytes per point", "DFLOOP_MEMORY_LIMIT")),
    Probe("predict_limit_cycles(G, N, ...)", "G of order 5000",
          lambda: df.predict_limit_cycles(ct.tf([1.0], np.poly(-np.ones(5000))), SAT), ValueError,
          ("G has order 5000, above the bound of 1000", "reduce the model")),
    Probe("predict_limit_cycles(G, N, ...)", 'DFLOOP_MEMORY_LIMIT = "lots"', lambda: _with_env("DFLOOP_MEMORY_LIMIT", "lots",
          lambda: df.predict_limit_cycles(G3, SAT)), ValueError, ("DFLOOP_MEMORY_LIMIT must be a positive number of GiB", "'lots'")),
    Probe("predict_limit_cycles(G, N, ...)", "callable G of wrong shape",
          lambda: df.predict_limit_cycles(lambda w: np.ones(3), SAT, omega=(0.1, 10.0)), ValueError,
          ("G(omega) must return an array of the same shape as omega", "(3,)")),
    Probe("predict_limit_cycles(G, N, ...)", "callable G returning NaN",
          lambda: df.predict_limit_cycles(lambda w: np.full(w.shape, np.nan + 0j), SAT, omega=(0.1, 10.0)), ValueError,
          ("G(jw) is not finite", "omega=0.1")),
    Probe("predict_limit_cycles(G, N, ...)", "continuum (saturation around 1/s^2)",
          lambda: df.predict_limit_cycles(ct.tf([1.0], [1.0, 0.0, 0.0]), SAT), df.ContinuumError,
          ("continuum of solutions", "A in [")),
    Probe("predict_limit_cycles(G, N, ...)", "exact = 'yes'", lambda: df.predict_limit_cycles(G3, SAT, exact="yes"), ValueError,
          ("exact must be True or False", "'yes'")),
    Probe("predict_limit_cycles(G, N, ...)", "N = 3.0", lambda: df.predict_limit_cycles(G, 3.0), ValueError,
          ("N must be a dfloop DescribingFunction", "got float: 3.0")),
    Probe("predict_limit_cycles(G, N, ...)", 'G = "plant"', lambda: df.predict_limit_cycles("plant", SAT), ValueError,
          ("G must be a python-control tf/ss/frd or a callable", "str")),
    Probe("predict_limit_cycles(G, N, ...)", "G with 2 inputs",
          lambda: df.predict_limit_cycles(ct.ss(-np.eye(2), np.eye(2), np.ones((1, 2)), 0), SAT), ValueError,
          ("G must be SISO", "2 inputs")),
    Probe("predict_limit_cycles(G, N, ...)", "tol = nan", lambda: df.predict_limit_cycles(G3, SAT, tol=np.nan), ValueError,
          ("tol must not be NaN", "nan")),
    Probe("predict_limit_cycles(G, N, ...)", "omega = (2, 1)", lambda: df.predict_limit_cycles(G3, SAT, omega=(2.0, 1.0)), ValueError,
          ("omega window must satisfy lo < hi", "(2.0, 1.0)")),
    Probe("predict_limit_cycles(G, N, ...)", "omega = (1, inf)", lambda: df.predict_limit_cycles(G3, SAT, omega=(1.0, np.inf)), ValueError,
          ("omega window must be finite", "inf")),
    Probe("predict_limit_cycles(G, N, ...)", "amplitude = 5", lambda: df.predict_limit_cycles(G3, SAT, amplitude=5.0), ValueError,
          ("amplitude window must be a pair", "5.0")),
    Probe("predict_limit_cycles(G, N, ...)", "grid = (1, 100)", lambda: df.predict_limit_cycles(G3, SAT, grid=(1, 100)), ValueError,
          ("grid[0] (amplitudes) must be an integer >= 2", "got 1")),
    Probe("predict_limit_cycles(G, N, ...)", "grid = (inf, 10)", lambda: df.predict_limit_cycles(G3, SAT, grid=(np.inf, 10)),
          ValueError, ("grid[0] (amplitudes) must be finite", "inf")),
    Probe("predict_limit_cycles(G, N, ...)", "grid = (2.5, 10)", lambda: df.predict_limit_cycles(G3, SAT, grid=(2.5, 10)),
          ValueError, ("grid[0] (amplitudes) must be an integer >= 2", "2.5")),
    Probe("predict_limit_cycles(G, N, ...)", "grid = (64, 10**400)",
          lambda: df.predict_limit_cycles(G3, SAT, grid=(64, 10**400)), ValueError,
          ("grid[1] (frequencies) must be representable as a float", "1000000")),
    Probe("predict_limit_cycles(G, N, ...)", "NaN in den", lambda: df.predict_limit_cycles(ct.tf([1.0], [1.0, np.nan, 1.0]), SAT),
          ValueError, ("G (tf) must have finite coefficients", "den = [1.0, nan, 1.0]")),
    Probe("predict_limit_cycles(G, N, ...)", "NaN in ss.A",
          lambda: df.predict_limit_cycles(ct.ss([[-1.0, 0.0], [np.nan, -2.0]], [[1.0], [0.0]], [[0.0, 1.0]], 0.0), SAT),
          ValueError, ("G (ss) must have finite matrices", "A = [[-1. 0.] [nan -2.]]")),
    Probe("predict_limit_cycles(G, N, ...)", "order-200 plant, omega up to 1e154",
          lambda: df.predict_limit_cycles(ct.tf([1.0], np.poly(-np.ones(200))), SAT, omega=(1.0, 1e154)), ValueError,
          ("G(jw) overflows", "omega=1e+154", "degree-200", "narrow the omega window")),
    Probe("predict_limit_cycles(G, N, ...)", "omega = (True, 10)", lambda: df.predict_limit_cycles(G3, SAT, omega=(True, 10.0)),
          ValueError, ("omega window must be a real number", "True")),
    Probe("graphical_stability(G, N, amplitude, frequency)", "N frequency-dependent",
          lambda: graphical_stability(G3, MB, 1.0, 1.0), ValueError, ("N must be amplitude-only",)),
    Probe("graphical_stability(G, N, amplitude, frequency)", "amplitude = None",
          lambda: graphical_stability(G3, SAT, None, 1.0), ValueError, ("amplitude must be a real number", "None")),
    Probe("graphical_stability(G, N, amplitude, frequency)", "step = 2",
          lambda: graphical_stability(G3, SAT, 1.0, 1.0, step=2.0), ValueError, ("step must lie in [1e-12, 0.5]", "2.0")),
    Probe("graphical_stability(G, N, amplitude, frequency)", "N = 2.0",
          lambda: graphical_stability(G3, 2.0, 1.0, 1.0), ValueError, ("N must be a dfloop DescribingFunction", "float")),
    Probe("as_plant(G)", "G = 3", lambda: as_plant(3), ValueError, ("G must be a python-control tf/ss/frd or a callable", "int")),
    Probe("as_plant(G)", "discrete-time G without a sampling period", lambda: as_plant(ct.tf([1.0], [1.0, -0.5], True)),
          ValueError, ("numeric sampling period dt > 0", "dt=True")),
    # ------------------------------------------------------------------ verification
    Probe("simulate_loop(G, N, amplitude, frequency, ...)", "amplitude = -1", lambda: df.simulate_loop(G3, SAT, -1.0, 1.0),
          DfloopError, ("amplitude must be > 0", "-1.0")),
    Probe("simulate_loop(G, N, amplitude, frequency, ...)", "frequency = nan", lambda: df.simulate_loop(G3, SAT, 1.0, np.nan),
          DfloopError, ("frequency must not be NaN",)),
    Probe("simulate_loop(G, N, amplitude, frequency, ...)", "steps_per_period = 10",
          lambda: df.simulate_loop(G3, SAT, 1.0, 1.0, steps_per_period=10), ValueError,
          ("steps_per_period must lie in [20, 10000000]", "10")),
    Probe("verify_cycle(G, N, cycle, ...)", "periods = inf", lambda: df.verify_cycle(G3, SAT, (1.0, 1.0), periods=np.inf),
          ValueError, ("periods must be finite", "inf")),
    Probe("verify_cycle(G, N, cycle, ...)", "N = 3", lambda: df.verify_cycle(G3, 3, (1.0, 1.0)), ValueError,
          ("N must be a dfloop DescribingFunction", "int: 3")),
    Probe("verify_cycle(G, N, cycle, ...)", "periods = 1e9", lambda: df.verify_cycle(G3, SAT, (1.0, 1.0), periods=1e9),
          ValueError, ("periods must lie in [0.0, 100000]", "1000000000.0")),
    Probe("verify_cycle(G, N, cycle, ...)", "periods = 1e5 at 400 steps per period",
          lambda: df.verify_cycle(G3, SAT, (1.0, 1.0), periods=1e5), ValueError,
          ("periods * steps_per_period = 100000 * 400 = 4e+07 samples exceeds the bound of 1e+07",
           "lower periods or steps_per_period")),
    Probe("exact_cycle(G, N, cycle, ...)", "max_events = 2.5", lambda: df.exact_cycle(G3, SAT, (1.0, 1.0), max_events=2.5),
          ValueError, ("max_events must be an integer >= 1", "2.5")),
    Probe("verify_cycle(G, N, cycle, ...)", "cycle frequency = 1e-320", lambda: df.verify_cycle(G3, SAT, (1.0, 1e-320)),
          ValueError, ("cycle frequency must lie in [1e-300, 1e+300]", "1e-320")),
    Probe("cycle_confidence(G, N, amplitude, frequency)", "amplitude = 1e-320", lambda: cycle_confidence(G3, SAT, 1e-320, 1.0),
          ValueError, ("amplitude must lie in [1e-300, 1e+300]", "1e-320")),
    Probe("exact_cycle(G, N, cycle, ...)", "N = None", lambda: df.exact_cycle(G3, None, (1.0, 1.0)), ValueError,
          ("N must be a dfloop DescribingFunction", "NoneType: None")),
    Probe("cycle_confidence(G, N, amplitude, frequency)", "frequency missing",
          lambda: cycle_confidence(G3, SAT, 1.0), ValueError, ("frequency is required", "amplitude=1.0")),
    Probe("sweep(loop_at, values, ...)", "unknown keyword bogus = 3",
          lambda: df.sweep(lambda k: (k * G3, SAT), [1.0, 2.0], bogus=3), ValueError,
          ("unknown keyword argument(s) 'bogus'", "the solver options are grid, tol")),
    Probe("sweep(loop_at, values, ...)", "values = [1, 10**400]", lambda: df.sweep(lambda k: (k * G3, SAT), [1, 10**400]),
          ValueError, ("values must be a 1-D sequence of numbers",)),
    Probe("predict_many(loops, ...)", "loops = 3.0", lambda: df.predict_many(3.0), ValueError,
          ("loops must be an iterable of (G, N) pairs", "3.0")),
    Probe("predict_many(loops, ...)", "unknown keyword tolerance = 1e-8", lambda: df.predict_many([(G3, SAT)], tolerance=1e-8),
          ValueError, ("unknown keyword argument(s) 'tolerance'", "omega, amplitude, grid, tol")),
    Probe("predict_many(loops, ...)", "chunksize = 2.5", lambda: df.predict_many([(G3, SAT)], chunksize=2.5), ValueError,
          ("chunksize must be an integer >= 1", "2.5")),
    Probe("predict_many(loops, ...)", 'progress = "yes"', lambda: df.predict_many([(G3, SAT)], progress="yes"), ValueError,
          ("progress must be True or False (or None)", "'yes'")),
    Probe("verify_cycle(G, N, cycle, ...)", "cycle = None", lambda: df.verify_cycle(G3, SAT, None), ValueError,
          ("cycle must be a LimitCycle or an (amplitude, frequency) pair", "None")),
    Probe("verify_cycle(G, N, cycle, ...)", "a list of cycles", lambda: df.verify_cycle(G3, SAT, [(1.0, 1.0)]), ValueError,
          ("cycle must be one LimitCycle", "list of 1 items")),
    Probe("exact_cycle(G, N, cycle, ...)", "cycle = None", lambda: df.exact_cycle(G3, SAT, None), ValueError,
          ("cycle must be a LimitCycle or an (amplitude, frequency) pair", "None")),
    Probe("exact_cycle(G, N, cycle, ...)", "G not strictly proper",
          lambda: df.exact_cycle(ct.tf([1.0, 0.0], [1.0, 1.0]), SAT, (1.0, 1.0)), ValueError,
          ("G must be strictly proper", "D = 1.0")),
    Probe("exact_cycle(G, N, cycle, ...)", "amplitude = -1", lambda: df.exact_cycle(G3, SAT, (-1.0, 1.0)), ValueError,
          ("cycle amplitude must be > 0", "-1.0")),
    Probe("cycle_confidence(G, N, amplitude, frequency)", "amplitude = nan",
          lambda: df.cycle_confidence(G3, SAT, np.nan, 1.0), ValueError, ("amplitude must not be NaN", "nan")),
    Probe("simulate_loop(G, N, amplitude, frequency, ...)", "G not strictly proper",
          lambda: df.simulate_loop(ct.tf([1.0, 0.0], [1.0, 1.0]), SAT, 1.0, 1.0), ValueError, ("strictly proper",)),
    Probe("verify_cycle(G, N, cycle, ...)", "perturbation = 2", lambda: df.verify_cycle(G3, SAT, (1.0, 1.0), perturbation=2.0),
          DfloopError, ("perturbation must lie in [0.001, 0.95]", "2.0")),
    # ------------------------------------------------------------------ impact kernel, DF extraction, limits
    Probe("simulate_impacts(m1, m2, h, restitution, force, omega, t_end, ...)", "t_end = 0",
          lambda: simulate_impacts(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 0.0), DfloopError, ("t_end must be > 0", "0.0")),
    Probe("simulate_impacts(m1, m2, h, restitution, force, omega, t_end, ...)", "max_events = 0",
          lambda: simulate_impacts(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 1.0, max_events=0), ValueError,
          ("max_events must be an integer >= 1", "0")),
    Probe("simulate_impacts(m1, m2, h, restitution, force, omega, t_end, ...)", "restitution = -0.1",
          lambda: simulate_impacts(1.0, 1.0, 0.1, -0.1, 50.0, 30.0, 1.0), DfloopError, ("restitution must lie in", "-0.1")),
    Probe("simulate_impacts(m1, m2, h, restitution, force, omega, t_end, ...)", "omega = 1e12 with t_end = 1 s",
          lambda: simulate_impacts(1.0, 1.0, 0.1, 0.5, 50.0, 1e12, 1.0), ValueError,
          ("spans 1.59e+11 forcing periods, above the bound of 1e+07", "shorten the run")),
    Probe("simulate_impacts(m1, m2, h, restitution, force, omega, t_end, ...)", "effects = 3",
          lambda: simulate_impacts(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 1.0, effects=3), ValueError,
          ("effects must be a sequence of effect objects", "3")),
    Probe("Trajectory.evaluate(t)", "t = -1", lambda: simulate(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 1.0).evaluate(-1.0), ValueError,
          ("t must lie in [0, t_end = 1.0]",)),
    Probe("impact_describing_function(m1, m2, h, restitution, force, omega, ...)", "omega = 0",
          lambda: impact_describing_function(1.0, 1.0, 0.1, 0.5, 50.0, 0.0), DfloopError, ("omega must be > 0", "0.0")),
    Probe("impact_describing_function(m1, m2, h, restitution, force, omega, ...)", "periods = 0",
          lambda: impact_describing_function(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, periods=0), DfloopError,
          ("periods must be an integer >= 1", "got 0")),
    Probe("impact_describing_function(m1, m2, h, restitution, force, omega, ...)", "periods = 1e12",
          lambda: impact_describing_function(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, periods=1e12), ValueError,
          ("transient_periods + periods spans 1e+12 forcing periods",)),
    Probe("impact_describing_function(m1, m2, h, restitution, force, omega, ...)", "max_events = 2.5",
          lambda: impact_describing_function(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, max_events=2.5), ValueError,
          ("max_events must be an integer >= 1", "2.5")),
    Probe("impact_describing_function(m1, m2, h, restitution, force, omega, ...)", "initial = nan",
          lambda: impact_describing_function(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, initial=np.nan), ValueError,
          ("initial must be four numbers (x1, v1, gap, u)", "nan")),
    Probe("impact_describing_function_batch(m1, m2, h, restitution, force, omega, ...)", "force = [50 + 1j]",
          lambda: impact_describing_function_batch(1.0, 1.0, 0.1, 0.5, [50 + 1j], [30.0]), ValueError,
          ("force must be real", "(50+1j)")),
    Probe("impact_describing_function_batch(m1, m2, h, restitution, force, omega, ...)", "force = [] (empty grid)",
          lambda: impact_describing_function_batch(1.0, 1.0, 0.1, 0.5, [], 30.0), ValueError, ("empty grid",)),
    Probe("beta_of(F, omega, m2, h)", "m2 = 0", lambda: beta_of(50.0, 30.0, 0.0, 0.1), DfloopError, ("m2 must be > 0", "0.0")),
    Probe("beta_of(F, omega, m2, h)", "omega = -30", lambda: beta_of(50.0, -30.0, 1.0, 0.1), ValueError, ("omega must be finite and > 0",)),
    Probe("lower_limit_frequency(F, m2, h, restitution)", "restitution = 1.2", lambda: lower_limit_frequency(50.0, 1.0, 0.1, 1.2),
          DfloopError, ("restitution must lie in", "1.2")),
    Probe("prepare_many(elements, F, omega, workers)", "workers = 0", lambda: prepare_many([], 1.0, 1.0, workers=0), ValueError,
          ("workers must be >= 1", "0")),
    # ------------------------------------------------------------------ harmonics
    Probe("harmonics.fundamental(t, x, omega)", "omega = 0", lambda: harmonics.fundamental(np.arange(5.0), np.zeros(5), 0.0),
          DfloopError, ("omega must be > 0", "0.0")),
    Probe("harmonics.fundamental(t, x, omega)", "t not increasing", lambda: harmonics.fundamental([0.0, 2.0, 1.0], [0.0, 1.0, 0.0], 1.0),
          DfloopError, ("t must hold at least 3 strictly increasing samples", "index 1")),
    Probe("harmonics.fundamental(t, x, omega)", "x with NaN", lambda: harmonics.fundamental(np.arange(3.0), [0.0, np.nan, 1.0], 1.0),
          DfloopError, ("x must be finite", "nan")),
    Probe("harmonics.fundamental(t, x, omega)", "shapes (5,) and (4,)", lambda: harmonics.fundamental(np.arange(5.0), np.zeros(4), 1.0),
          DfloopError, ("one length", "(5,)", "(4,)")),
    Probe("harmonics.steady_state(t, x, periods)", "periods = 0", lambda: harmonics.steady_state(np.arange(5.0), np.zeros(5), 0),
          DfloopError, ("periods must be an integer >= 1", "0")),
    # ------------------------------------------------------------------ plots
    Probe("plot_loci(N, amplitudes, omega, ax)", "frequency-dependent N without omega", lambda: plot_loci(MB), ValueError,
          ("amplitudes and omega are required",)),
    Probe("plot_loci(N, amplitudes, omega, ax)", "ax = 3", lambda: plot_loci(SAT, ax=3), ValueError,
          ("ax must be a matplotlib Axes or None", "int")),
    Probe("plot_loci(N, amplitudes, omega, ax)", "N = 'relay'", lambda: plot_loci("relay"), ValueError,
          ("N must be a dfloop DescribingFunction", "str")),
    Probe("plot_nyquist(cycles, ax, omega, ...)", "omega = (0, 1)",
          lambda: plot_nyquist(df.predict_limit_cycles(G3, SAT), omega=(0.0, 1.0)), ValueError,
          ("omega window must be positive", "(0.0, 1.0)")),
    Probe("plot_time_response(traj, quantity, ...)", 'quantity = "v9"',
          lambda: plot_time_response(simulate(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 1.0), "v9"), ValueError,
          ("quantity must be one of", "'v9'")),
    Probe("plot_collision_map(omega, runs, regular, labels, side)", 'side = "C"',
          lambda: plot_collision_map([30.0], [[2.0]], side="C"), ValueError, ("side must be 'A' or 'B'", "'C'")),
    # ------------------------------------------------------------------ scene loader
    Probe("load_scene(path)", "missing file", lambda: load_scene(_SCRATCH / "missing.toml"), ValueError,
          ("scene file not found", "missing.toml")),
    Probe("load_scene(path)", "no [plant] table", lambda: load_scene(scene_file(_ELEMENT)), ValueError,
          ("plant: missing required section", "scene.toml")),
    Probe("load_scene(path)", 'plant.type = "frd"', lambda: load_scene(scene_file('[plant]\ntype = "frd"\n' + _ELEMENT)), ValueError,
          ("plant.type: unknown type", "'frd'")),
    Probe("load_scene(path)", "plant.delay = -1", lambda: load_scene(scene_file(_PLANT + "delay = -1.0\n" + _ELEMENT)), ValueError,
          ("plant.delay: must be >= 0.0, got -1.0",)),
    Probe("load_scene(path)", "plant of order 1001",
          lambda: load_scene(scene_file('[plant]\ntype = "tf"\nnum = [1.0]\nden = [1.0' + ", 0.0" * 1000 + ", 1.0]\n" + _ELEMENT)),
          ValueError, ("plant: order 1001 is above the solver's bound of 1000", "reduce the model")),
    Probe("load_scene(path)", 'element.type = "Gearbox"', lambda: load_scene(scene_file(_PLANT + '[element]\ntype = "Gearbox"\n')),
          ValueError, ("unknown type", "'Gearbox'")),
    Probe("load_scene(path)", "element.h = -1", lambda: load_scene(scene_file(_PLANT + '[element]\ntype = "Backlash"\nh = -1.0\n')),
          ValueError, ("h must be > 0", "-1.0")),
    Probe("load_scene(path)", 'analysis.plots = ["bode"]',
          lambda: load_scene(scene_file(_PLANT + _ELEMENT + '[analysis]\nplots = ["bode"]\n')), ValueError,
          ("analysis.plots", "'bode'")),
    Probe("load_scene(path)", "analysis.omega = [1]", lambda: load_scene(scene_file(_PLANT + _ELEMENT + "[analysis]\nomega = [1.0]\n")),
          ValueError, ("analysis.omega: needs at least 2 values, got 1 value: [1.0]", "[lo, hi]")),
    Probe("load_scene(path)", "element slope = 2 (Saturation)",
          lambda: load_scene(scene_file(_PLANT + '[element]\ntype = "Saturation"\nlimit = 1.0\nslope = 2.0\n')),
          ValueError, ("element.slope: unknown parameter of Saturation", "did you mean 'k'?")),
    Probe("load_scene(path)", "misspelt key analysis.verfy",
          lambda: load_scene(scene_file(_PLANT + _ELEMENT + "[analysis]\nverfy = true\n")), ValueError,
          ("analysis.verfy: unknown key", "did you mean 'verify'")),
    Probe("load_scene(path)", "misspelt section [analysys]",
          lambda: load_scene(scene_file(_PLANT + _ELEMENT + "[analysys]\nverify = true\n")), ValueError,
          ("analysys: unknown section", "did you mean 'analysis'")),
    Probe("load_scene(path)", 'analysis.verify = "false"',
          lambda: load_scene(scene_file(_PLANT + _ELEMENT + '[analysis]\nverify = "false"\n')), ValueError,
          ("analysis.verify: wrong type", "'false'", "expected bool")),
    Probe("load_scene(path)", "unknown element parameter hh",
          lambda: load_scene(scene_file(_PLANT + '[element]\ntype = "Backlash"\nhh = 1.0\n')), ValueError,
          ("element.hh: unknown parameter of Backlash", "did you mean 'h'")),
    Probe("load_scene(path)", "broken TOML",
          lambda: load_scene(scene_file(_PLANT + _ELEMENT + "[analysis\n")), ValueError,
          ("scene.toml: invalid TOML", "line 8")),
    # ------------------------------------------------------------------ command line
    Probe("dfloop run SCENE...", "missing scene file", lambda: cli.main(["run", str(_SCRATCH / "missing.toml")]), "exit 1",
          ("scene file not found", "missing.toml")),
    Probe("dfloop run SCENE...", "scene with element.h = -1",
          lambda: cli.main(["run", str(scene_file(_PLANT + '[element]\ntype = "Backlash"\nh = -1.0\n', "bad.toml"))]), "exit 1",
          ("h must be > 0", "-1.0")),
    Probe("dfloop", "unknown option --fast", lambda: cli.main(["--fast"]), "exit 2", ("unrecognized arguments: --fast",)),
    Probe("dfloop run SCENE...", "--out is a regular file", lambda: cli.main(["run", "relay_hysteresis", "--out", str(_a_file())]),
          "exit 2", ("--out <dir>/a_file: exists and is not a directory",)),
    Probe("dfloop run SCENE...", "--out cannot be created",
          lambda: cli.main(["run", "relay_hysteresis", "--out", str(_a_file() / "out")]), "exit 2",
          ("--out <dir>/a_file/out: cannot write there (Not a directory)",)),
    Probe("dfloop run SCENE...", 'DFLOOP_CACHE_DIR=""', lambda: _with_cache_dir("", ["run", "relay_hysteresis"]), "exit 2",
          ("DFLOOP_CACHE_DIR is set but empty",)),
    Probe("dfloop cache info|clear", 'DFLOOP_CACHE_DIR=""', lambda: _with_cache_dir("", ["cache", "info"]), "exit 2",
          ("DFLOOP_CACHE_DIR is set but empty", "unset it for the default")),
    Probe("dfloop cache info|clear", "clear without --yes, stdin not a terminal",
          lambda: _with_cache_dir(_full_cache(), ["cache", "clear"]), "exit 2",
          ("cache clear: refused to remove this file without confirmation", "pass --yes")),
    Probe("dfloop cache info|clear", "clear --yes on a read-only cache",
          lambda: _with_cache_dir(_full_cache(), ["cache", "clear", "--yes"], read_only=True), "exit 2",
          ("could not remove 1 of 1 files; first: <dir>/cache/t.npz: Permission denied",)),
    Probe("dfloop cache info|clear", "cache directory not listable",
          lambda: _with_cache_dir(_full_cache(), ["cache", "info"], unlistable=True), "exit 2",
          ("cache info: [Errno 13] Permission denied",)),
]


def _with_env(name: str, value: str, call: Callable[[], object]):
    from unittest import mock

    with mock.patch.dict("os.environ", {name: value}):
        return call()


def _a_file() -> Path:
    path = _SCRATCH / "a_file"
    path.write_text("")
    return path


def _full_cache() -> str:
    """A cache directory holding one table (of the current code version)."""
    from dfloop.tables.cache import save_table

    directory = _SCRATCH / "cache"
    save_table(directory / "t.npz", {"x": np.arange(3.0)}, "k", {}, {})
    return str(directory)


def _with_cache_dir(value: str, argv: list[str], read_only: bool = False, unlistable: bool = False):
    """cli.main(argv) with DFLOOP_CACHE_DIR = value, stdin not a terminal, and optionally a cache whose files
    cannot be removed (PermissionError, as from a read-only directory; the suite may run as root) or listed."""
    from unittest import mock

    def refuse(path, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(path))

    with contextlib.ExitStack() as stack:
        stack.enter_context(mock.patch.dict("os.environ", {"DFLOOP_CACHE_DIR": value}))
        stack.enter_context(mock.patch("sys.stdin", io.StringIO("")))
        if read_only:
            stack.enter_context(mock.patch.object(Path, "unlink", refuse))
        if unlistable:
            stack.enter_context(mock.patch.object(Path, "glob", refuse))
        return cli.main(argv + (["--out", str(_SCRATCH / "out")] if argv[0] == "run" else []))


def _normalise(message: str) -> str:
    """The message as shown in the table: scratch paths as <dir>, object addresses elided, one line."""
    message = message.replace(str(_SCRATCH), "<dir>")
    message = re.sub(r" at 0x[0-9a-fA-F]+", "", message)
    return " ".join(message.split())


def outcome(probe: Probe) -> tuple[str, str, BaseException | None]:
    """(kind, message, exception) of one probe: kind is the exception's class name or "exit N"."""
    if isinstance(probe.expect, str):
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = probe.call()
        except SystemExit as stop:  # argparse
            code = stop.code
        return f"exit {code}", _normalise(err.getvalue()), None
    try:
        with np.errstate(all="ignore"):
            probe.call()
    except Exception as exc:  # noqa: BLE001 - any exception is an outcome to compare
        return type(exc).__name__, _normalise(str(exc)), exc
    return "no error", "", None


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def render(probes: list[Probe] = PROBES) -> str:
    """docs/errors.md: the policy, then one table row per probe, grouped by entry point (in order of first
    appearance in ``probes``, rows in their order)."""
    lines = [
        "# Errors: what each entry point rejects",
        "",
        "<!-- Generated by tests/test_error_table.py from its probes; do not edit by hand. Regenerate with",
        "     `PYTHONPATH=. python tests/test_error_table.py --write`. -->",
        "",
        "Every rejection of bad input is a `ValueError` naming the parameter and the value. The checks in",
        "`dfloop._checks` raise `dfloop.errors.DfloopError`, a `ValueError` subclass, so `except ValueError` and",
        "`except DfloopError` both work. Nothing returns NaN for finite input: NaN entries of an amplitude or",
        "frequency array give NaN in those entries only.",
        "",
        "- Amplitudes are real and >= 0; `A = 0` and `A = inf` give the element's limit (stated under",
        "  \"Limits\" in each element's docstring, possibly infinite, never NaN). `NumericDF` cannot take a limit",
        "  numerically and raises outside [1e-250, 1e250].",
        "- Frequencies are real, finite and > 0 (rad/s); amplitude-only elements validate and ignore them.",
        "- The disk cache never raises: an unreadable, unwritable, corrupted or stale cache file gives one",
        "  `dfloop.errors.CacheWarning` naming what failed and where, and the table is computed in memory.",
        "- Work and memory are bounded before they are spent: a solver grid whose estimated memory exceeds the",
        "  limit (2 GiB; the environment variable `DFLOOP_MEMORY_LIMIT`, in GiB, changes it) is refused with the",
        "  estimate and the knobs, and so are run lengths beyond their bounds (`verify_cycle` periods, impact runs",
        "  of more than 1e7 forcing periods, plants of order > 1000); an impact run whose record reaches the limit",
        "  stops with an `EventLimitError` (a `RuntimeError`) saying so.",
        "- The command line prints one line `dfloop: <message>` on stderr, without a traceback, and exits with",
        "  status 1 when a scene failed (the others still run) or 2 for bad usage or environment: an `--out` that",
        "  is a file or cannot be written, a cache that cannot be listed or cleared, `DFLOOP_CACHE_DIR` set but",
        "  empty (refused rather than taken to mean the default directory: unset it for the default).",
        "  `dfloop cache clear` lists the files it would remove and asks first; `--yes` skips the question, and",
        "  without it a non-interactive stdin refuses.",
        "",
        "| Entry point | Bad input | Raises | Message |",
        "|---|---|---|---|",
    ]
    first = {}
    for i, p in enumerate(probes):
        first.setdefault(p.entry, i)
    previous = None
    for p in sorted(probes, key=lambda p: first[p.entry]):
        kind, message, _ = outcome(p)
        entry = f"`{p.entry}`" if p.entry != previous else ""
        previous = p.entry
        lines.append(f"| {_cell(entry)} | {_cell(p.bad)} | {kind} | {_cell(message)} |")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("probe", PROBES, ids=[f"{p.entry}: {p.bad}" for p in PROBES])
def test_probe(probe):
    kind, message, exc = outcome(probe)
    if isinstance(probe.expect, str):
        assert kind == probe.expect, message
    else:
        assert exc is not None, f"{probe.entry} accepted {probe.bad}"
        assert isinstance(exc, probe.expect), f"{kind}: {message}"
        assert isinstance(exc, ValueError), f"{kind} is not a ValueError: {message}"
    for fragment in probe.fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def test_rows_are_unique():
    keys = [(p.entry, p.bad) for p in PROBES]
    assert len(keys) == len(set(keys))


def test_docs_errors_md_is_the_generated_table():
    assert DOC.read_text() == render(), "docs/errors.md is stale: run PYTHONPATH=. python tests/test_error_table.py --write"


if __name__ == "__main__":
    text = render()
    if "--write" in sys.argv[1:]:
        DOC.write_text(text)
        print(f"wrote {DOC} ({len(PROBES)} probes)")
    else:
        sys.stdout.write(text)
