"""The compiled engine's shortcuts give bit for bit the numbers of the plain evaluations they replace.

Each shortcut of :mod:`dfloop.impact._effects_core` (sparse products, Taylor terms with zeros left undivided,
Horner over the kept terms only, bisection signs from the leading terms) is checked against the plain algorithm
written out here with dense loops and full evaluations: equality is exact (same bytes), not to a tolerance.
"""
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dfloop.impact import _effects_core as core
from dfloop.impact.effects import CoulombFriction, LoadSpring, ViscousDamping, open_loop_system
from dfloop.impact.model import ImpactParameters

T = core.TAYLOR_TERMS
_EFFECTS = [(), (ViscousDamping(3.0),), (LoadSpring(200.0),), (CoulombFriction(5.0, "m2"),),
            (CoulombFriction(8.0, "m1"), ViscousDamping(1.0), LoadSpring(50.0))]


def _system(effects_index, w):
    return open_loop_system(ImpactParameters(1.0, 1.3, 0.1, 0.6, 40.0, w), _EFFECTS[effects_index])


def _plain_taylor(A, z, span):
    """The plain series: dense products, every term divided by k, truncated as the engine documents."""
    n = z.size
    terms = np.zeros((T, n))
    terms[0] = z
    size = max(abs(v) for v in z)
    small, power = 0, 1.0
    for k in range(1, T):
        if small >= 2:
            return terms, k
        for i in range(n):
            acc = 0.0
            for q in range(n):
                acc += A[i, q] * terms[k - 1, q]
            terms[k, i] = acc
        big = 0.0
        for i in range(n):
            terms[k, i] /= k
            big = max(big, abs(terms[k, i]))
        power *= span
        small = small + 1 if span > 0.0 and big * power <= 1e-30 * size else 0
    return terms, T


def _plain_horner(c, s):
    acc = c[-1]
    for k in range(c.size - 2, -1, -1):
        acc = acc * s + c[k]
    return acc


def _plain_refine(c, derivative, lo, hi, flo):
    """The root refinement with a full evaluation at every iteration (the reference of ``core.refine``)."""
    m = c.size
    s = 0.5 * (lo + hi)
    for it in range(core.REFINE_ITERATIONS):
        if hi - lo <= 4e-16 * max(hi, 1e-300):
            break
        fs, ds = core._pval2(c, m, s, derivative)
        if fs == 0.0:
            return s
        if (fs > 0) == (flo > 0):
            lo, flo = s, fs
        else:
            hi = s
        if it < core.NEWTON_STEPS and ds != 0.0:
            s_new = s - fs / ds
            if abs(s_new - s) <= 2e-16 * max(abs(s), 1e-300):
                step = 4e-16 * max(abs(s_new), 1e-300)
                for probe in (s_new - step, s_new + step):
                    if lo < probe < hi:
                        fp = core._pval(c, m, probe, derivative)
                        if fp == 0.0:
                            return probe
                        if (fp > 0) == (flo > 0):
                            lo, flo = probe, fp
                        else:
                            hi = probe
                s_new = 0.5 * (lo + hi)
            elif not (lo < s_new < hi):
                s_new = 0.5 * (lo + hi)
        else:
            s_new = 0.5 * (lo + hi)
        s = s_new
    return hi


_state = st.lists(st.floats(-2.0, 2.0), min_size=4, max_size=4)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, len(_EFFECTS) - 1), st.floats(3.0, 60.0), st.integers(0, 8), _state, st.floats(0.05, 1.0))
def test_sparse_products_and_taylor_terms_equal_the_dense_ones_bit_for_bit(effect, w, slot, head, fraction):
    sysm = _system(effect, w)
    slot = [s for s in range(core.N_SLOTS) if sysm.valid[s]][slot % int(sysm.valid.sum())]
    A = sysm.mats[slot]
    phase = 7.0 * fraction
    z = np.array(head + [math.cos(phase), math.sin(phase), 1.0])
    z[core.D] *= 1e-7                      # a gap near the wall, as after a chatter bounce
    ptr, col, val, mag = core._sparse(A)
    out, dense = np.empty(z.size), np.empty(z.size)
    core._spmv(ptr, col, val, z, out)
    core._matvec(A, z, dense)
    assert out.tobytes() == dense.tobytes()
    core._spmv(ptr, col, mag, np.abs(z), out)
    core._matvec(np.abs(A), np.abs(z), dense)
    assert out.tobytes() == dense.tobytes()
    for span in (0.0, fraction * sysm.dt):
        terms = np.empty((T, z.size))
        m = core._taylor_into(ptr, col, val, z, terms, span)
        plain, plain_m = _plain_taylor(A, z, span)
        assert m == plain_m and terms.tobytes() == plain.tobytes()
        # Horner over the kept terms equals Horner over all of them (zeros beyond m)
        got = np.empty(z.size)
        core._poly_into(terms, m, fraction * sysm.dt, got)
        full = np.array([_plain_horner(terms[:, i], fraction * sysm.dt) for i in range(z.size)])
        assert got.tobytes() == full.tobytes()


def _taylor_like(data, m, scale, root):
    """Coefficients shaped like r.A^k z / k! over a step of 1 (|c_k| ~ scale^k / k!), zero from m on, with a
    root of the polynomial near ``root``."""
    c = np.zeros(T)
    for k in range(1, m):
        c[k] = data.draw(st.floats(-1.0, 1.0)) * scale ** k / math.factorial(k)
    c[1] = math.copysign(max(abs(c[1]), 1e-3), c[1])
    c[0] = -sum(c[k] * root ** k for k in range(1, m))
    return c


@settings(max_examples=60, deadline=None)
@given(st.data(), st.integers(6, T), st.floats(0.1, 3.0), st.floats(1.0, 12.0), st.booleans())
def test_refine_with_certified_signs_equals_refine_with_full_evaluations(data, m, scale, depth, derivative):
    """Roots from 1e-12 to 0.1 of the step (chatter flights are 1e-9 of it): same bracket, same returned root."""
    c = _taylor_like(data, m, scale, 10.0 ** -depth)
    lo, hi = 0.0, 1.0
    flo = core._pval(c, m, lo, derivative)
    fhi = core._pval(c, m, hi, derivative)
    if flo == 0.0 or (flo > 0) == (fhi > 0):
        hi = 2.0 * 10.0 ** -depth          # bracket the constructed root itself
        fhi = core._pval(c, m, hi, derivative)
    if flo == 0.0 or (flo > 0) == (fhi > 0):
        return                             # no sign change to refine (a derivative without one here)
    got = core.refine(c, m, derivative, lo, hi, flo)
    ref = _plain_refine(c[:m].copy() if m < T else c, derivative, lo, hi, flo)
    assert got == ref
    assert (core._pval(c, m, got, derivative) > 0) != (flo > 0) or core._pval(c, m, got, derivative) == 0.0


def _terms_at(c, m, derivative, hi):
    """|terms| of the polynomial (or of its derivative) at s = hi, exactly summable with math.fsum."""
    if derivative:
        return [abs(k * c[k]) * hi ** (k - 1) for k in range(1, m)]
    return [abs(c[k]) * hi ** k for k in range(m)]


@settings(max_examples=80, deadline=None)
@given(st.data(), st.integers(6, T), st.floats(0.1, 3.0), st.floats(1.0, 12.0), st.floats(-15.0, 0.0),
       st.booleans())
def test_certain_sign_agrees_with_the_full_evaluation(data, m, scale, depth, offset, derivative):
    """Whenever the leading K terms decide the sign (any K, with the tail bound of the dropped terms on [0, hi]),
    it is the sign of the full Horner value, which is not 0; far from the root they do decide."""
    root = 10.0 ** -depth
    c = _taylor_like(data, m, scale, root)
    hi = 4.0 * root
    first = 1 if derivative else 0
    K = data.draw(st.integers(first + 1, m - 1))
    terms = _terms_at(c, m, derivative, hi)
    tail = math.fsum(terms[K - first:])
    decided = 0
    for s in (root * (1.0 + 10.0 ** offset), root * (1.0 - 10.0 ** offset), 0.5 * hi, hi, 0.3 * root):
        s = min(max(s, 0.0), hi)
        sign = core._certain_sign(c, s, derivative, K, tail)
        full = core._pval(c, m, s, derivative)
        if sign != 0.0:
            decided += 1
            assert full != 0.0 and (full > 0) == (sign > 0)
        if tail <= 1e-16 * math.fsum(terms) and abs(full) > 1e-12 * math.fsum(_terms_at(c, m, derivative, s)):
            assert sign != 0.0
    # the engine's choice of K: the dropped terms are bounded by its tail, and that tail is negligible
    K, tail = core._cheap_terms(c, m, derivative, hi, np.empty(m))
    assert math.fsum(terms[K - first:]) <= tail * (1 + 1e-12) <= 1e-16 * math.fsum(terms) * (1 + 1e-12) + 1e-299


def test_pval_over_kept_terms_equals_the_full_sum():
    rng = np.random.default_rng(3)
    for m in (3, 7, 19, T - 1, T):
        c = np.zeros(T)
        c[:m] = rng.normal(size=m) / np.array([math.factorial(k) for k in range(m)])
        for s in (0.0, 1e-9, 0.37, 1.0):
            for derivative in (False, True):
                full = _plain_horner(c, s) if not derivative else _plain_horner(
                    np.array([k * c[k] for k in range(1, T)]), s)
                assert core._pval(c, m, s, derivative) == full
                assert core._pval2(c, m, s, derivative)[0] == full
