"""Exact periodic orbits of digital loops (dfloop.hybrid.discrete) against closed forms and direct iteration."""
import math

import control as ct
import numpy as np
import pytest

from dfloop import Quantizer, Relay, Saturation, exact_cycle, predict_limit_cycles
from dfloop.hybrid.discrete import discrete_orbits, shoot_discrete


def _canon(seq):
    seq = tuple(seq)
    P = len(seq)
    for d in range(1, P):               # reduce to the primitive period
        if P % d == 0 and seq == seq[d:] + seq[:d]:
            seq = seq[:d]
            break
    return min(seq[r:] + seq[:r] for r in range(len(seq)))


def _simulate(a_list, b_list, c_list, f, s0, steps):
    """x[k+1] = A x + B f(-C x), written out independently of the package (scalar loops)."""
    A, B, C = np.asarray(a_list, float), np.asarray(b_list, float), np.asarray(c_list, float)
    s = np.asarray(s0, float)
    ys = []
    for _ in range(steps):
        y = f(-C @ s)
        ys.append(y)
        s = A @ s + B * y
    return np.array(ys)


def _rounding(x):
    return math.copysign(math.floor(abs(x) + 0.5), x)


@pytest.mark.parametrize("a", [-0.85, -0.6, 0.7, 0.8])
def test_first_order_rounding_loop_closed_form(a):
    """s[k+1] = Q(a s[k]) (G(z) = -a/z, x = a s): constant orbits s = n and (a < 0) period-2 orbits s = +-n exist
    exactly for the integers n with |a| n > n - 1/2, i.e. n < 1 / (2 (1 - |a|)); nothing else."""
    G = ct.tf([-a], [1.0, 0.0], 1.0)
    res = discrete_orbits(G, Quantizer(1.0), max_period=12, bound=20.0)
    assert res.complete
    n_max = math.ceil(0.5 / (1 - abs(a))) - 1
    if a > 0:
        expect = {(float(n),) for n in range(-n_max, n_max + 1)}
    else:
        expect = {(0.0,)} | {_canon((-float(n), float(n))) for n in range(1, n_max + 1)}
    got = {_canon(o.y) for o in res}
    assert got == expect
    for o in res:
        assert o.stable and np.allclose(o.multipliers, 0.0)
        if o.period == 2:
            assert o.frequency == pytest.approx(math.pi) and o.amplitude == pytest.approx(abs(a) * abs(o.y[0]))


@pytest.mark.parametrize("M", [2, 3, 4, 5])
def test_pure_delay_relay_orbits_are_the_antiperiodic_sequences(M):
    """y[k] = sign(-y[k-M]) (G = z^-M, ideal relay): the orbits are exactly the +-1 sequences with y[k+M] = -y[k]
    (listed by brute force over the 2^M first halves), plus the rest point y = 0 (x = 0 in the dead zone's middle
    level of the three-level relay model)."""
    G = ct.tf([1.0], [1.0] + [0.0] * M, 1.0)
    res = discrete_orbits(G, Relay(1.0, dead_zone=0.5), max_period=2 * M)
    assert res.complete
    expect = {(0.0,)}
    for bits in range(2 ** M):
        half = [1.0 if bits >> i & 1 else -1.0 for i in range(M)]
        expect.add(_canon(half + [-v for v in half]))
    # three-level relay: 0 outputs are consistent too wherever |x| <= 1/2; the +-1 antiperiodic ones are all there
    got = {_canon(o.y) for o in res}
    assert {e for e in expect if 0.0 not in e or e == (0.0,)} <= got
    for o in res:
        assert np.allclose(o.multipliers, 0.0) and o.stable


SQUARE = [  # (M, rho, angle, gain): G = gain / ((z - p)(z - conj p)), p = rho e^{j angle}; square wave consistent
    (2, 0.4970766390395692, 1.4247056380108907, 0.9256033756048327),
    (3, 0.4781314525989169, 0.02227963664022509, 1.3622976120349062),
    (4, 0.6831763403546312, 0.07693973249458672, 1.41222779687529),
    (5, 0.8403286425318996, 0.197034164796739, 0.49611307965338236),
]


@pytest.mark.parametrize("M, rho, angle, gain", SQUARE)
def test_second_order_relay_square_wave_closed_form(M, rho, angle, gain):
    """Period 2M square wave of a relay around a second-order G: by partial fractions (residue r at pole p), the
    antiperiodic response is c_k = sum r (1 - 2 p^k + p^M) / ((1 + p^M) (1 - p)), k = 1..M (c_{k+M} = -c_k), and
    the orbit exists when x = -c has the square wave's signs. The enumeration finds it with these x."""
    p = rho * np.exp(1j * angle)
    poles = np.array([p, np.conj(p)])
    res_ = np.array([gain / (poles[0] - poles[1]), gain / (poles[1] - poles[0])])
    c = np.zeros(2 * M)
    for k in range(1, M + 1):
        c[k % (2 * M)] = np.sum(res_ * (1 - 2 * poles ** k + poles ** M) / ((1 + poles ** M) * (1 - poles))).real
    for k in range(1, M):
        c[k + M] = -c[k]
    c[0] = -c[M]
    x_closed = -c
    y_square = np.r_[np.ones(M), -np.ones(M)]
    assert np.all(np.sign(x_closed) == y_square) and np.min(np.abs(x_closed)) > 0.1
    G = ct.tf([gain], np.real(np.poly(poles)), 1.0)
    res = discrete_orbits(G, Relay(1.0, dead_zone=0.05), max_period=2 * M)
    match = [o for o in res if o.period == 2 * M and _canon(o.y) == _canon(y_square)]
    assert len(match) == 1
    o = match[0]
    shift = next(r for r in range(2 * M) if np.array_equal(np.roll(y_square, -r), o.y))
    assert np.allclose(o.x, np.roll(x_closed, -shift), atol=1e-10)
    assert o.frequency == pytest.approx(math.pi / M)


def test_every_orbit_reached_by_direct_iteration_is_enumerated():
    """Random starts of a quantized second-order loop, run by an independent loop: the periodic tail of each run
    (period <= 10) is one of the enumerated orbits."""
    num, den = [0.9, 0.3], [1.0, -0.2, 0.45]
    G = ct.tf(num, den, 1.0)
    res = discrete_orbits(G, Quantizer(1.0), max_period=10, bound=4.0)
    assert res.complete
    known = {_canon(o.y) for o in res}
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    rng = np.random.default_rng(3)
    tails = set()
    for _ in range(60):
        ys = _simulate(A, B, C, _rounding, rng.uniform(-3, 3, 2), 400)
        tail = ys[-48:]
        P = next(P for P in range(1, 11) if np.array_equal(tail[P:], tail[:-P]))
        tails.add(_canon(tuple(tail[-P:])))
    assert tails and tails <= known
    assert any(len(t) > 1 for t in known)


def test_incomplete_search_says_so():
    G = ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), 0.2)
    res = discrete_orbits(G, Relay(1.0, dead_zone=0.05), max_period=16, max_nodes=2000)
    assert not res.complete and "max_nodes=2000" in res.message and "raise max_nodes" in res.message
    with pytest.raises(ValueError, match="bound"):      # the level-by-level search needs a finite set of levels
        discrete_orbits(ct.tf([0.5], [1.0, 0.0], 1.0), Quantizer(1.0), method="intervals")
    with pytest.raises(ValueError, match="hysteresis"):
        discrete_orbits(ct.tf([0.5], [1.0, 0.0], 1.0), Relay(1.0, hysteresis=0.1))
    with pytest.raises(ValueError, match="discrete-time"):
        discrete_orbits(ct.tf([1.0], [1.0, 1.0]), Relay(1.0))


def test_exact_cycle_of_a_zoh_relay_loop_matches_a_long_run():
    """exact_cycle on the discrete loop: period in samples and amplitude agree with an independent long run."""
    G = ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), 0.2)
    N = Relay(1.0, dead_zone=0.05)
    stable = [c for c in predict_limit_cycles(G, N) if c.stability == "stable"][0]
    ex = exact_cycle(G, N, stable)
    assert ex.success and ex.stable and ex.extra["map"]
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    relay = lambda x: 0.0 if abs(x) <= 0.05 else math.copysign(1.0, x)   # noqa: E731
    o = ex.extra["orbit"]
    P = ex.extra["samples_per_period"]
    ys = _simulate(A, B, C, relay, o.state, 10 * P)          # the orbit repeats in an independent run
    assert np.array_equal(ys, np.tile(o.y, 10))
    assert ex.frequency == pytest.approx(2 * math.pi * ex.extra["harmonic"] / (P * 0.2))
    assert abs(ex.amplitude_error) < 0.1 and abs(ex.frequency_error) < 0.05   # the DF is close here


def test_shooting_on_the_map_closed_form_saturation_orbit():
    """G = 1.5 / (z^2 + 0.3), saturation at 1: c[k+2] = -0.3 c[k] + 1.5 sat(-c[k]). A period-4 orbit is antiperiodic
    over 2 samples, c[k+2] = -c[k], so 1.5 sat(u) = 0.7 u for u = -c[k]: u = +-15/7 (saturated). The DF puts the
    cycle at w dt = pi/2 (G(j) = -1.5/0.7 is real), and Newton on the 4-fold map finds x = +-15/7, which an
    independent run repeats."""
    G = ct.tf([1.5], [1.0, 0.0, 0.3], 1.0)
    cycles = predict_limit_cycles(G, Saturation(1.0))
    c = [c for c in cycles if c.stability == "stable"][0]
    assert c.frequency == pytest.approx(math.pi / 2, rel=1e-9)
    o = shoot_discrete(G, Saturation(1.0), 4, c.amplitude, c.frequency)
    assert o is not None and o.period == 4 and o.harmonic == 1
    assert np.allclose(np.abs(o.x), 15 / 7, rtol=1e-12)     # (the phase with samples at 0 gives the orbit
    # (0, u, 0, -u), also exact but farther from the prediction in amplitude: u = 15/7 against sqrt(2) 15/7)
    assert o.amplitude == pytest.approx(math.sqrt(2) * 15 / 7, rel=1e-12)
    assert o.stable and np.allclose(np.abs(o.multipliers), 0.09)     # f' = 0: the Jacobian is A^4, |eig A| = 0.3^(1/2)
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    sat = lambda x: max(-1.0, min(1.0, x))   # noqa: E731
    ys = _simulate(A, B, C, sat, o.state, 20)
    assert np.allclose(ys, np.tile(o.y, 5), atol=1e-12)
    ex = exact_cycle(G, Saturation(1.0), c)
    assert ex.success and ex.amplitude == pytest.approx(o.amplitude) and ex.extra["samples_per_period"] == 4


@pytest.mark.parametrize("seed", [0, 3, 6, 8, 9])
def test_enumeration_equals_brute_force_over_all_sequences(seed):
    """Random first- and second-order loops with a quantizer (5 levels within |x| <= 2.4): the orbits of period
    <= 6 are exactly those a brute force over all 5^P output sequences finds (own periodic solve and check)."""
    rng = np.random.default_rng(seed)
    if seed % 2:
        G = ct.tf([rng.uniform(0.6, 1.2)], [1.0, rng.uniform(-0.3, 0.5)], 1.0)
    else:
        G = ct.tf([rng.uniform(0.5, 1.5), rng.uniform(-0.5, 0.5)], [1.0, rng.uniform(-1.0, 0.2), rng.uniform(0.3, 0.8)], 1.0)
    bound = 2.4
    res = discrete_orbits(G, Quantizer(1.0), max_period=6, bound=bound)
    assert res.complete
    sys = ct.ss(G)
    A, B, C = np.asarray(sys.A), np.asarray(sys.B)[:, 0], np.asarray(sys.C)[0]
    n = A.shape[0]
    levels = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
    expect = set()
    for P in range(1, 7):
        AP = np.linalg.matrix_power(A, P)
        for idx in np.ndindex(*([5] * P)):
            y = levels[list(idx)]
            s = np.linalg.solve(np.eye(n) - AP, sum(np.linalg.matrix_power(A, P - 1 - j) @ B * y[j] for j in range(P)))
            ok = True
            for k in range(P):
                x = -C @ s
                if abs(x) > bound or _rounding(x) != y[k]:
                    ok = False
                    break
                s = A @ s + B * y[k]
            if ok:
                expect.add(_canon(tuple(y)))
    assert {_canon(o.y) for o in res} == expect
    assert any(len(e) > 1 for e in expect)      # these loops have oscillating orbits (periods 2, 3 or 4)


@pytest.mark.parametrize("kwargs, name", [({"max_period": 0}, "max_period"), ({"bound": -1.0}, "bound"),
                                          ({"max_nodes": 0}, "max_nodes"), ({"periods": [0]}, "periods"),
                                          ({"max_period": 4, "periods": [5]}, "periods")])
def test_bad_arguments_name_the_parameter(kwargs, name):
    kwargs = {"bound": 3.0, **kwargs}
    with pytest.raises(ValueError, match=name):
        discrete_orbits(ct.tf([0.8], [1.0, 0.0], 1.0), Quantizer(1.0), **kwargs)
    with pytest.raises(ValueError, match="not a static piecewise-constant"):
        discrete_orbits(ct.tf([0.8], [1.0, 0.0], 1.0), Saturation(1.0))
    with pytest.raises(ValueError, match="strictly proper"):
        discrete_orbits(ct.tf([1.0, 0.0], [1.0, 0.5], 1.0), Quantizer(1.0), bound=3.0)
