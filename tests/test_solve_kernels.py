"""The solver's array kernels equal straightforward loops over nodes, edges and cells, bit for bit.

The references below are plain Python loops, written from the kernels' definitions (one node, edge or cell at
a time); the inputs are random, with the edge cases the kernels must treat exactly: phases at exactly +-pi and
0, exact zeros of R, ties in the local-minimum test, NaN and infinite values, empty and one-row grids.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from dfloop.solve._kernels import candidate_cells, edge_steps, nonzero_windings, tangent_seeds

TWO_PI = 2.0 * math.pi


def wrap(d):
    return d - TWO_PI if d > math.pi else (d + TWO_PI if d < -math.pi else d)


def ref_edge_steps(theta, R, split):
    na, nv = R.shape
    ph_a = np.array([[wrap(theta[i + 1, j] - theta[i, j]) for j in range(nv)] for i in range(na - 1)]).reshape(
        na - 1, nv)
    ph_v = np.array([[wrap(theta[i, j + 1] - theta[i, j]) for j in range(nv - 1)] for i in range(na)]).reshape(
        na, nv - 1)

    def zero(i, j):
        return theta[i, j] == 0.0 and R[i, j] == 0.0

    ea = [(i, j) for i in range(na - 1) for j in range(nv)
          if abs(ph_a[i, j]) > split or zero(i, j) or zero(i + 1, j)]
    ev = [(i, j) for i in range(na) for j in range(nv - 1)
          if abs(ph_v[i, j]) > split or zero(i, j) or zero(i, j + 1)]
    return ph_a, ph_v, ea, ev


def ref_windings(ph_a, ph_v):
    out = []
    for i in range(ph_v.shape[0] - 1):
        for j in range(ph_a.shape[1] - 1):
            w = round((ph_a[i, j] + ph_v[i + 1, j] - ph_a[i, j + 1] - ph_v[i, j]) / TWO_PI)
            if w != 0:
                out.append((i, j, w))
    return out


def ref_candidates(ln_n, eps_a, ln_g, eps_v):
    out = []
    for i in range(ln_n.size - 1):
        for j in range(ln_g.size - 1):
            re, e = ln_n[i].real + ln_g[j].real, eps_a[i] + eps_v[j]
            im = wrap(ln_n[i].imag + ln_g[j].imag - math.pi)
            if abs(re) <= e and re * re + im * im <= e * e:
                out.append((i, j))
    return out


def ref_seeds(P, ci, cj, threshold, allowed):
    na, nv = P.shape

    def m(i, j):
        pr, pi = P[i, j].real, P[i, j].imag
        q = pr * pr + pi * pi
        with np.errstate(invalid="ignore"):
            return (q + 2.0 * pr + 1.0) / (1.0 + q)

    cells = set(zip(ci.tolist(), cj.tolist()))
    out = []
    for i in range(na):
        for j in range(nv):
            if not allowed[i, j]:
                continue
            x = m(i, j)
            if x >= threshold or any((i - di, j - dj) in cells for di in range(-1, 3) for dj in range(-1, 3)):
                continue
            nbrs = [m(i + di, j + dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)
                    if (di or dj) and 0 <= i + di < na and 0 <= j + dj < nv]
            if not any(y < x for y in nbrs):
                out.append((i, j, x))
    return out


def same_floats(a, b):
    """Bit-identical (NaN equal to NaN, +0 distinct from -0)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


def random_R(rng, na, nv):
    """Random residual with exact (signed) zeros and phases at exactly pi, -pi and 0 (arg of -1 - 0j is -pi)."""
    R = rng.normal(size=(na, nv)) + 1j * rng.normal(size=(na, nv))
    special = np.array([0.0, -1.0 + 0.0j, complex(-1.0, -0.0), 2.0, complex(0.0, -0.0), complex(-0.0, -0.0),
                        complex(-0.0, 0.0), 1j, -1j])  # arg(-0 - 0j) = -pi, arg(-0 + 0j) = pi: signed zeros
    pick = rng.random((na, nv)) < 0.3
    R[pick] = rng.choice(special, size=int(pick.sum()))
    return R


@pytest.mark.parametrize("shape", [(1, 1), (1, 5), (5, 1), (2, 2), (9, 13), (30, 24)])
@pytest.mark.parametrize("seed", range(4))
def test_edge_steps_and_windings_equal_loops(shape, seed):
    rng = np.random.default_rng(seed)
    R = random_R(rng, *shape)
    theta = np.angle(R)
    assert {-math.pi, math.pi} <= set(theta.ravel().tolist()) or min(shape) < 5
    for split in (math.pi / 2, 0.3):
        ph_a, ph_v, ai, aj, vi, vj = edge_steps(theta, R, split)
        r_a, r_v, ea, ev = ref_edge_steps(theta, R, split)
        assert same_floats(ph_a, r_a) and same_floats(ph_v, r_v)
        assert list(zip(ai.tolist(), aj.tolist())) == ea and list(zip(vi.tolist(), vj.tolist())) == ev
        assert ai.dtype == aj.dtype == vi.dtype == vj.dtype == np.int64
        ii, jj, w = nonzero_windings(ph_a, ph_v)
        assert list(zip(ii.tolist(), jj.tolist(), w.tolist())) == ref_windings(ph_a, ph_v)
        assert w.dtype == np.int64


def test_windings_of_a_known_field():
    # R = a + j v around the origin: exactly one cell, the one holding the zero, winds once counter-clockwise
    a, v = np.linspace(-1.05, 0.95, 21), np.linspace(-0.95, 1.05, 21)
    R = a[:, None] + 1j * v[None, :]
    ph_a, ph_v, *_ = edge_steps(np.angle(R), R, math.pi / 2)
    ii, jj, w = nonzero_windings(ph_a, ph_v)
    assert (ii.tolist(), jj.tolist(), w.tolist()) == ([10], [9], [1])
    ii, jj, w = nonzero_windings(*edge_steps(np.angle(np.conj(R)), np.conj(R), math.pi / 2)[:2])
    assert w.tolist() == [-1]


@pytest.mark.parametrize("seed", range(6))
def test_candidate_cells_equal_loops(seed):
    rng = np.random.default_rng(seed)
    na, nv = rng.integers(1, 40, size=2)
    ln_n = rng.normal(scale=0.5, size=na) + 1j * rng.uniform(-math.pi, math.pi, size=na)
    ln_g = rng.normal(scale=0.5, size=nv) + 1j * rng.uniform(-math.pi, math.pi, size=nv)
    ln_n.imag[rng.random(na) < 0.2] = math.pi  # phases at exactly pi and 0: im of the sum at exactly +-pi
    ln_g.imag[rng.random(nv) < 0.2] = 0.0
    ln_n.real[rng.random(na) < 0.2] = 0.0
    eps_a, eps_v = rng.uniform(0, 1.5, size=na - 1), rng.uniform(0, 1.5, size=nv - 1)
    eps_a[rng.random(na - 1) < 0.2] = 0.0
    if seed % 2:  # N = 0 at a node (ln = -inf): its interval's bound is inf; an unbounded frequency interval
        dead = np.flatnonzero(rng.random(na - 1) < 0.15)
        ln_n.real[dead], eps_a[dead] = -np.inf, np.inf
        eps_v[rng.random(nv - 1) < 0.05] = np.inf
    i, j = candidate_cells(ln_n, eps_a, ln_g, eps_v)
    assert list(zip(i.tolist(), j.tolist())) == ref_candidates(ln_n, eps_a, ln_g, eps_v)
    assert i.dtype == j.dtype == np.int64
    # an exact root on a node (ln(N G) = j pi, zero tolerance) is kept
    assert candidate_cells(np.array([0.0, 1.0]) + 1j * np.pi, np.zeros(1), np.zeros(2, complex),
                           np.zeros(1))[0].tolist() == [0]


@pytest.mark.parametrize("seed", range(6))
def test_tangent_seeds_equal_loops(seed):
    rng = np.random.default_rng(seed)
    na, nv = rng.integers(1, 30, size=2)
    # values on a coarse lattice, so that ties between neighbours (equal m) are common
    P = (rng.integers(-4, 3, size=(na, nv)) + 1j * rng.integers(-2, 3, size=(na, nv))) / 2.0
    P[rng.random((na, nv)) < 0.05] = -1.0  # exact roots: m = 0
    P[rng.random((na, nv)) < 0.03] = np.nan
    P[rng.random((na, nv)) < 0.03] = np.inf
    allowed = rng.random((na, nv)) < 0.7
    k = rng.integers(0, 4)
    ci, cj = rng.integers(0, max(na - 1, 1), size=k), rng.integers(0, max(nv - 1, 1), size=k)
    for threshold in (0.1, 0.6):
        ni, nj = (x.astype(np.int64) for x in np.nonzero(allowed))   # the allowed nodes, row-major
        si, sj, sm = tangent_seeds(P, ci.astype(np.int64), cj.astype(np.int64), threshold, ni, nj)
        ref = ref_seeds(P, ci, cj, threshold, allowed)
        assert list(zip(si.tolist(), sj.tolist())) == [(i, j) for i, j, _ in ref]
        assert same_floats(sm, [x for *_, x in ref])
