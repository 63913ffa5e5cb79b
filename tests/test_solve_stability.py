"""Loeb criterion: closed-form determinant, invariances, and agreement with the classical graphical rule."""
import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.solve import as_plant
from dfloop.solve.roots import Residual
from dfloop.solve.stability import graphical_stability, loeb


def test_loeb_determinant_closed_form_saturation():
    G, N = ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)
    c = df.predict_limit_cycles(G, N)[0]
    A, w = c.amplitude, c.frequency
    # R = 1 + G(w) N(A) with N real and G(jw) = -8/3 real: det = Re G N'(A) Im G'(w) N = -N'(A) Im G'(w)
    dN = -4 / (np.pi * A ** 2) * np.sqrt(1 - 1 / A ** 2)
    s = 1j * w
    dG = 1j * (-8 * (3 * s ** 2 + 4 * s + 2) / (s ** 3 + 2 * s ** 2 + 2 * s + 1) ** 2)
    assert c.loeb_determinant == pytest.approx(-dN * dG.imag, rel=1e-6)
    assert c.loeb_determinant > 0 and c.stable


def test_loeb_sign_flipped_by_conjugation():
    # N real: 1 + conj(G) N = conj(1 + G N) has the same root, with the determinant's sign flipped
    G, N = ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)
    c = df.predict_limit_cycles(G, N)[0]
    a, v = np.log([c.amplitude]), np.log([c.frequency])
    base = loeb(Residual(as_plant(G), N), a, v)[0][0]
    conj = as_plant(lambda w: np.conj(as_plant(G)(w)))
    flipped = loeb(Residual(conj, N), a, v)[0][0]
    assert flipped == pytest.approx(-base, rel=1e-6)


def _f(u):
    u = np.minimum(u, 1.0)
    return 2 / np.pi * (np.arcsin(u) + u * np.sqrt(1 - u * u))


PROBLEMS = [
    (ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0), {}),
    (ct.tf([1], [1, 2, 2, 1]) * ct.tf(*ct.pade(5, 4)) * 4, df.Backlash(h=1.0), {"amplitude": (0.6, 5)}),
    (ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(h=0.2), {}),
    (ct.tf([2], [1, 3, 2, 0]), df.Relay(M=1.0, hysteresis=0.1), {}),
    (ct.tf([12], [1, 3, 3, 1]), df.DeadZone(0.5), {}),
    (lambda w: np.exp(-1j * w) / (1j * w + 1), df.Relay(M=1.0), {"omega": (0.1, 100)}),
    (lambda w: 8 * np.exp(-0.5j * w) / (1j * w + 1) ** 2, df.Backlash(h=0.1), {"omega": (0.1, 100)}),
]


@pytest.mark.parametrize("k", range(len(PROBLEMS)))
def test_loeb_agrees_with_graphical_rule_for_amplitude_only_N(k):
    G, N, windows = PROBLEMS[k]
    cycles = df.predict_limit_cycles(G, N, **windows)
    assert len(cycles) >= 1
    for c in cycles:
        assert c.stability in ("stable", "unstable")
        assert graphical_stability(G, N, c.amplitude, c.frequency) == c.stable


def test_graphical_rule_needs_amplitude_only_N():
    class FD(df.Saturation):
        frequency_dependent = True

    with pytest.raises(ValueError, match="amplitude-only"):
        graphical_stability(ct.tf([1], [1, 1]), FD(1.0), 1.0, 1.0)
