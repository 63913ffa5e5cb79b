"""The quantizer's lattice enumeration (discrete_orbits, method 'lattice') against brute force, on a slow plant
sampled: 5.6/(s+1)^3 behind a zero-order hold at dt = 0.6 s, quantizer step 0.05, with orbits of 8 samples (four)
and boxes of up to 7^8 candidate sequences for the brute force."""
import math

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.hybrid.discrete import discrete_orbits, discrete_system

G = 5.6 * ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), 0.6)
Q = df.Quantizer(0.05)


def _brute_force(P):
    """Every output sequence y = 0.05 n of period P that the loop reproduces, y = Q(x) with x_k = sum_j h[k - j] y_j
    over the periodic impulse response h (from a long run of the map, written here), for n in the box where the
    rounding error bound puts every orbit: |n_j| <= sum_k |((I - H)^{-1})_jk| / 2 (x = H y, |y - x| <= step/2)."""
    A, B, C, _ = discrete_system(G)
    # periodic impulse response: the response at sample k to a unit input repeated every P samples, summed to 1e-15
    h = np.zeros(P)
    s = B.copy()
    for i in range(1, 4000):
        h[i % P] += -float(C @ s)              # x = -c, the input applied at sample 0 appears from sample 1
        s = A @ s
    H = np.array([[h[(k - j) % P] for j in range(P)] for k in range(P)])
    reach = 0.5 * np.abs(np.linalg.inv(np.eye(P) - H)).sum(axis=1)
    r = int(math.floor(reach.max() + 0.5))
    hits, base, total = [], 2 * r + 1, (2 * r + 1) ** P
    for start in range(0, total, 500_000):
        idx = np.arange(start, min(start + 500_000, total))
        cands = ((idx[:, None] // base ** np.arange(P)) % base - r) * 0.05     # every n in the box, by digits
        x = cands @ H.T
        hits += list(cands[np.all(np.asarray(Q.output(x.ravel())).reshape(x.shape) == cands, axis=1)])
    orbits = set()
    for y in hits:
        n = tuple(np.rint(y / 0.05).astype(int))
        if any(P % d == 0 and n == n[d:] + n[:d] for d in range(1, P)):
            continue                           # a shorter period repeated
        orbits.add(min(n[i:] + n[:i] for i in range(P)))
    return orbits


def test_lattice_enumeration_equals_brute_force():
    res = discrete_orbits(G, Q, max_period=8)
    assert res.complete, res.message
    for P in range(1, 9):
        got = {tuple(np.rint(o.y / 0.05).astype(int)) for o in res if o.period == P}
        assert got == _brute_force(P), P
    assert {o.period for o in res.oscillating()} == {8} and len(res.oscillating()) == 4


def test_lattice_needs_no_bound_and_refuses_other_elements():
    with pytest.raises(ValueError, match="method='lattice' is for the Quantizer"):
        discrete_orbits(G, df.Relay(1.0), method="lattice")
    # 1/z: the loop with a unit gain has the period-2 orbit x = (1, -1) t for every t: the rounding bounds nothing
    res = discrete_orbits(ct.tf([1.0], [1.0, 0.0], 1.0), Q, max_period=2)
    assert not res.complete and "give bound" in res.message and list(res.skipped) == [2]
    bounded = discrete_orbits(ct.tf([1.0], [1.0, 0.0], 1.0), Q, max_period=2, bound=0.12)
    # with the bound: x_{k+1} = -Q(x_k)... every n with y = 0.05 n, x = -y of the other sample: (n, -n), |n| <= 2
    assert bounded.complete and sorted(o.y.max() for o in bounded if o.period == 2) == pytest.approx([0.05, 0.1])


def test_auto_falls_back_to_the_lattice_where_the_level_search_gives_up():
    """With a bound, 'auto' runs the level search first; at period 8 it exceeds 2000 nodes, the lattice search takes
    over and the result is complete and equal to the lattice search's own."""
    levels_only = discrete_orbits(G, Q, max_period=8, periods=[8], bound=0.3, max_nodes=2000, method="intervals")
    assert not levels_only.complete
    auto = discrete_orbits(G, Q, max_period=8, periods=[8], bound=0.3, max_nodes=2000)
    lattice = discrete_orbits(G, Q, max_period=8, periods=[8], bound=0.3, method="lattice")
    assert auto.complete and len(auto.oscillating()) == 4
    assert [tuple(o.y) for o in auto] == [tuple(o.y) for o in lattice]
