"""Tangent (double) roots at a fold stay a reported root whatever the grid: a dead-zone relay around
K/(s(s+1)(s+2)) at the fold gain K* = pi d / (2 M |G0(j sqrt 2)|), where the two cycles merge at A* = d sqrt 2,
w* = sqrt 2 (closed form: N's maximum 2M/(pi d) at A = d sqrt 2 meets 1/(K |G0|) at the phase crossover).

Near a double root Re R or Im R stays at rounding level over a region ~sqrt(rounding) wide, which puts zeros on
many box edges; the isolation must report the root (marginal), not run out of boxes, for every grid that the
window choice can produce."""
import math

import control as ct
import numpy as np
import pytest

import dfloop as df

M, D = 1.0, 0.1
G0 = ct.tf([1.0], [1.0, 3.0, 2.0, 0.0])
K_STAR = math.pi * D / (2 * M * (1.0 / 6.0))
A_STAR, W_STAR = D * math.sqrt(2.0), math.sqrt(2.0)


@pytest.mark.parametrize("upper", np.geomspace(20.0, 400.0, 9))
def test_fold_root_is_reported_on_every_grid(upper):
    for K in (K_STAR, K_STAR * (1 + 2e-16), K_STAR * (1 - 2e-16)):
        cycles = df.predict_limit_cycles(K * G0, df.Relay(M=M, dead_zone=D), amplitude=(D * (1 + 1e-9), upper))
        assert 1 <= len(cycles) <= 2          # the merged pair: one tangent root, or two at rounding distance
        for c in cycles:
            assert abs(c.amplitude / A_STAR - 1) < 1e-6 and abs(c.frequency / W_STAR - 1) < 1e-9
            assert c.residual < 1e-9
        if len(cycles) == 1:
            assert cycles[0].stability == "marginal"


def test_no_cycle_just_below_the_fold_and_two_just_above():
    N = df.Relay(M=M, dead_zone=D)
    assert len(df.predict_limit_cycles(K_STAR * (1 - 1e-6) * G0, N)) == 0
    above = df.predict_limit_cycles(K_STAR * (1 + 1e-6) * G0, N)
    assert sorted(c.stability for c in above) == ["stable", "unstable"]
