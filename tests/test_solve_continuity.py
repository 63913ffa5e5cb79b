"""Roots of a continuous N next to the edge of its dead band, under a sharp resonance (issue 17, item 2).

A lead-lag then a backlash (``LinearThenStatic``) or the mass-backlash behind a resonance of damping ~1e-6: |G| is
1e8..1e10 there, so the roots need |N| ~ 1e-10 and lie within ~1e-11 (relative) of the edge of the element's dead
band, where N rises from 0. These were missed silently (a derivative step straddling the edge) or reported as
"jump crossings" although N is continuous. The references are the independent 1-D reductions of
tests/df_reference.py (brentq on dense scans, written apart from the solver).
"""
from __future__ import annotations

import warnings

import control as ct
import numpy as np
import pytest

import dfloop as df
import fuzz_loops as fl
import df_reference as ref
from dfloop.solve import roots


def _resonance(K: float, zeta: float, wn: float, p: float):
    """K wn^2 p / ((s^2 + 2 zeta wn s + wn^2)(s + p)) and its poles."""
    poles = np.array([complex(-zeta * wn, wn * np.sqrt(1 - zeta ** 2)), complex(-zeta * wn, -wn * np.sqrt(1 - zeta ** 2)),
                      -p])
    return ct.tf([K * wn ** 2 * p], np.real(np.poly(poles))), poles


# (plant parameters, lead-lag (num, den), clearance h, omega window, amplitude window): on the solver before this
# fix, the first was missed silently, the other two were reported as jump crossings with no cycle
CASES = [
    ((170.0, 5e-7, 0.55, 4.0), ([1.36, 1], [1.1, 1]), 0.019, None, None),
    ((3.0e5 / (1.6554 ** 2 * 0.4595), 3.4e-7, 1.6554, 0.4595), ([0.465, 1], [0.23, 1]), 0.0206, (1.6, 24.0),
     (0.0046, 0.18)),
    ((1.0e5 / (0.6359 ** 2 * 0.3445), 5.4e-6, 0.6359, 0.3445), ([8.63, 1], [0.195, 1]), 0.0457, None, None),
]


@pytest.mark.parametrize("plant, lead, h, omega, amplitude", CASES)
def test_lead_lag_backlash_root_at_the_dead_band_edge_is_found(plant, lead, h, omega, amplitude):
    G, poles = _resonance(*plant)
    N = df.LinearThenStatic(ct.tf(*lead), df.Backlash(h))
    assert N.continuous
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # neither a jump crossing nor an unresolved winding may be reported
        cyc = df.predict_limit_cycles(G, N, omega=omega, amplitude=amplitude)
    want = fl.reference_roots(G, poles, [], 0.0, N, "linear_then_static", cyc.omega_window, amplitude)
    assert len(want) == 1
    A, w = want[0]
    lo = float(N.amplitude_domain(np.array([w]))[0][0])
    assert A / lo - 1 < 1e-8  # the root really lies next to the dead-band edge
    assert abs(complex(G(1j * w))) > 1e7
    misses, extras = ref.match(want, [(c.amplitude, c.frequency) for c in cyc])
    assert misses == [] and extras == []
    assert cyc.jump_crossings == [] and cyc.grid_report.uncertified == ()


def test_mass_backlash_root_at_the_play_edge_is_found():
    """The mass-backlash behind a resonance of damping 5e-6 with two more real poles: two roots, one within 1e-9
    of the play edge (|G| = 1.4e9), with the default windows (missed by the solver before this fix)."""
    out = fl.run_case(4, default_windows=True, kind="mass_backlash_resonance")
    assert out["error"] is None and out["n_reference"] == 2
    assert out["misses"] == [] and out["extras"] == [] and out["bad_residual"] == []
    N, found = out["N"], out["result"]
    edge = [c for c in found if c.amplitude / float(N.amplitude_domain(np.array([c.frequency]))[0][0]) - 1 < 1e-8]
    assert len(edge) == 1 and abs(edge[0].G) > 1e9
    assert found.jump_crossings == [] and found.grid_report.uncertified == ()


def test_a_winding_without_a_refined_root_is_reported_not_dropped(monkeypatch):
    """With every refinement failing (a stand-in for any root the refinement cannot reach), the winding of
    16 / (s + 1)^3 around a saturation is not dropped: a warning names the place and GridReport.uncertified holds
    its frequency (the phase crossover of G at w = sqrt(3), where the cycle lies)."""
    def failing(res, a, v, box, tol, certified=False):
        a, v = np.array(a, float), np.array(v, float)
        return a, v, np.zeros(a.size, bool)

    monkeypatch.setattr(roots, "refine", failing)
    monkeypatch.setenv("DFLOOP_COMPILED", "0")  # the Python driver's reporting (the compiled one hands such loops to it)
    G, N = ct.tf([16], [1, 3, 3, 1]), df.Saturation(1.0)
    with pytest.warns(UserWarning, match="winds around 0 but no root could be refined"):
        cyc = df.predict_limit_cycles(G, N, omega=(0.5, 5.0), amplitude=(1.1, 20.0))
    assert len(cyc) == 0
    assert any(a <= np.sqrt(3) <= b for a, b in cyc.grid_report.uncertified)
    assert "not certified" in str(cyc.grid_report)


@pytest.mark.parametrize("element, continuous", [
    (df.Saturation(1.0), True), (df.Backlash(0.5), True), (df.Relay(1.0), True), (df.Relay(1.0, dead_zone=0.3), True),
    (df.Relay(1.0, hysteresis=0.2), False), (df.Quantizer(0.1), True),
    (df.LinearThenStatic(ct.tf([1, 1], [0.5, 1]), df.Relay(1.0, hysteresis=0.2)), False),
    (df.MassBacklash(1.0, 1.0, 0.1), True)])
def test_continuity_is_stated_per_element(element, continuous):
    """The stated continuity matches N across the domain's lower edge: the change of a continuous N over
    [lo (1 - t), lo (1 + t)] vanishes with t (like sqrt t for a dead-zone relay), a jump's does not (the hysteresis
    relay jumps from 0 to 4M/(pi A) e^(-j asin(a/A)))."""
    assert element.continuous is continuous
    w = np.array([1.0])
    lo = float(np.ravel((element.amplitude_domain(w) if element.frequency_dependent else element.amplitude_domain())[0])[0])
    lo = lo if lo > 0 else 1.0

    def change(t):
        A = lo * np.array([1 - t, 1 + t])
        n = element(A, 1.0) if element.frequency_dependent else element(A)
        return abs(n[1] - n[0])

    assert bool(change(1e-14) < 1e-3 * change(1e-6)) is continuous
