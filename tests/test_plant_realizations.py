"""Default windows and cycles do not depend on how G is written: tf, zpk, ss (control.ss / control.tf2ss) and a
diagonally rescaled state basis of the same plant give the same window and the same cycles.

Independent truth: the plant's poles and zeros as drawn (the window must be two decades beyond them, with no
spurious zero from rounding in the ss -> tf conversion), and the tf form's cycles.
"""
from __future__ import annotations

import warnings

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.solve.plant import as_plant


def _random_plant(rng):
    n = int(rng.integers(1, 7))
    m = int(rng.integers(0, n))
    poles = -np.abs(rng.normal(size=n)) * 10 ** rng.uniform(-2, 2, size=n)
    zeros = rng.normal(size=m) * 10 ** rng.uniform(-2, 2, size=m)
    return zeros, poles, 10 ** rng.uniform(-2, 2)


def _forms(zeros, poles, gain, rng):
    G = ct.zpk(zeros, poles, gain)
    tf = ct.tf(np.real(np.poly(zeros)) * gain, np.real(np.poly(poles)))
    scale = np.diag(10 ** rng.uniform(-2, 2, size=poles.size))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # python-control's own warnings on badly scaled conversions
        return {"zpk": G, "tf": tf, "ss": ct.ss(tf), "tf2ss": ct.tf2ss(tf),
                "scaled ss": ct.similarity_transform(ct.ss(tf), scale)}


def test_default_window_is_the_same_for_every_form():
    rng = np.random.default_rng(22)
    for _ in range(60):
        zeros, poles, gain = _random_plant(rng)
        mags = np.abs(np.concatenate([zeros, poles]))
        truth = (mags.min() / 100, mags.max() * 100)
        for name, G in _forms(zeros, poles, gain, rng).items():
            lo, hi = as_plant(G).default_window
            # equal to the drawn roots' window up to the conditioning of the polynomial's roots
            assert lo == pytest.approx(truth[0], rel=1e-3), (name, zeros, poles)
            assert hi == pytest.approx(truth[1], rel=1e-3), (name, zeros, poles)


def test_the_issues_servo_as_ss_has_the_tf_window_and_cycles():
    G = ct.tf([5.0], [1.0, 1.0, 0.0])
    N = df.Backlash(h=1.0)
    a = df.predict_limit_cycles(G, N)
    b = df.predict_limit_cycles(ct.tf2ss(G), N)
    assert a.omega_window == b.omega_window == (0.01, 100.0)
    assert a.grid_shape == b.grid_shape
    assert [c.stability for c in a] == [c.stability for c in b] == ["unstable", "stable"]
    for ca, cb in zip(a, b):
        assert cb.amplitude == pytest.approx(ca.amplitude, rel=1e-9)
        assert cb.frequency == pytest.approx(ca.frequency, rel=1e-9)


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_same_cycles_for_every_form(seed):
    """A saturation loop on a random stable plant with enough gain to oscillate: every form finds the tf form's
    cycles (count, stability, amplitude and frequency to 1e-7)."""
    rng = np.random.default_rng(seed)
    poles = -np.sort(10 ** rng.uniform(-0.5, 0.5, size=3))
    zeros = np.empty(0)
    e1, e2, e3 = np.real(np.poly(poles))[1:]
    gain = 2.0 * (e1 * e2 - e3)   # twice the Routh critical gain: |G N| = 1 at the phase crossover for N = 1/2
    forms = _forms(zeros, poles, gain, rng)
    N = df.Saturation(1.0)
    ref = df.predict_limit_cycles(forms["tf"], N)
    assert len(ref) >= 1
    for name, G in forms.items():
        got = df.predict_limit_cycles(G, N)
        assert got.omega_window == pytest.approx(ref.omega_window, rel=1e-9), name
        assert [c.stability for c in got] == [c.stability for c in ref], name
        for cg, cr in zip(got, ref):
            assert cg.amplitude == pytest.approx(cr.amplitude, rel=1e-7), name
            assert cg.frequency == pytest.approx(cr.frequency, rel=1e-7), name
