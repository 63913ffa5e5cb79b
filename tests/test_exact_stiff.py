"""exact_cycle on high-order and stiff plants (order up to 12: Pade chains, lightly damped modes down to zeta = 1e-4,
real poles 1e4 apart), against Tsypkin's exact conditions for a relay with hysteresis (closed form, no simulation):
the symmetric orbit of half period tau has s(0) = -(I + e^{A tau})^{-1} int_0^tau e^{Ar} dr B M, switches where
x(0) = -C s(0) reaches the threshold a, and the fundamental of x has amplitude (4M/pi)|G(jw)|."""
import math

import control as ct
import numpy as np
import pytest
from scipy.linalg import expm, matrix_balance
from scipy.optimize import brentq

import dfloop as df

M, HYST = 1.0, 0.05


def tsypkin_x0(G, tau):
    """x(0) of the symmetric periodic response to the square wave +M on [0, tau), -M on [tau, 2 tau)."""
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    A, (d, _) = matrix_balance(A, permute=False, separate=True)   # the companion form of a Pade-10 chain has
    B, C = B / d, C * d                                             # entries up to 1e15: balance it first
    n = A.shape[0]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n], big[:n, n] = A, B
    E = expm(big * tau)
    s0 = -np.linalg.solve(np.eye(n) + E[:n, :n], E[:n, n] * M)
    return float(-C @ s0)


def plants():
    rng = np.random.default_rng(16)
    out = []
    # Pade chain of order 10 around a double lag: order 12
    num, den = ct.pade(0.5, 10)
    out.append(("pade-10 chain", ct.tf(num, den) * ct.tf([1.0], [1.0, 2.0, 1.0])))
    # real poles 1e4 apart (a fast actuator): stiff
    out.append(("poles 1e4 apart", ct.tf([10.0], [1.0, 1.0, 0.0]) * ct.tf([1.0], [1e-4, 1.0]) * ct.tf([1.0], [1.0, 1.0])))
    # a lightly damped mode (zeta = 1e-4) above the cycle, with a Pade chain: order 10
    num, den = ct.pade(0.3, 6)
    out.append(("zeta 1e-4 mode + pade-6", ct.tf([4.0], [1.0, 1.0, 1.0]) * ct.tf([25.0], [1.0, 2e-4 * 5.0, 25.0])
                * ct.tf(num, den)))
    # random order-12 plants: a Pade chain, a lightly damped mode, spread real poles
    for _ in range(2):
        order = int(rng.integers(4, 7))
        num, den = ct.pade(float(rng.uniform(0.1, 1.0)), order)
        wn, zeta = float(rng.uniform(4.0, 10.0)), float(10 ** rng.uniform(-4, -2))
        poles = 10 ** rng.uniform(-1.0, 2.0, 12 - order - 2 - 2)
        G = ct.tf(num, den) * ct.tf([wn ** 2], [1.0, 2 * zeta * wn, wn ** 2]) * ct.tf([3.0], [1.0, 1.0, 0.0])
        for p in poles:
            G = G * ct.tf([1.0], [1.0 / p, 1.0])
        out.append((f"random order {ct.ss(G).nstates}", G))
    return out


@pytest.mark.parametrize("name,G", plants(), ids=lambda v: v if isinstance(v, str) else "")
def test_high_order_and_stiff_relay_orbits_satisfy_tsypkins_conditions(name, G):
    N = df.Relay(M, hysteresis=HYST)
    cycles = df.predict_limit_cycles(G, N)
    assert len(cycles) >= 1
    c = cycles[0]
    e = df.exact_cycle(G, N, c)
    assert e.success, e.message
    tau = e.period / 2
    assert e.switching_times.size == 2                       # the symmetric, unimodal orbit
    # the half period is a root of Tsypkin's switching condition x(0) = a, and the root in a +-5 % bracket is it
    root = brentq(lambda t: tsypkin_x0(G, t) - HYST, 0.95 * tau, 1.05 * tau, xtol=1e-15)
    assert tau == pytest.approx(root, rel=1e-9)
    w = e.frequency
    assert e.amplitude == pytest.approx(4 * M / math.pi * abs(complex(G(1j * w))), rel=1e-9)
