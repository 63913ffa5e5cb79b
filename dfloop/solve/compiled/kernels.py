"""numba kernels of the compiled pipeline: rational G (with a pure delay), closed-form static N, and the
Levenberg-Marquardt refinement of :func:`dfloop.solve.roots.refine`, point by point.

Every kernel evaluates the same floating-point expressions, in the same order, as the numpy code it replaces
(``Plant`` for tf/ss and delayed plants, the ``_evaluate`` of the static elements, ``Residual._evaluate_slopes``,
``roots.refine``, ``roots.at_rounding_level``, ``roots.residual_bound``), including numpy's complex division
(Smith's algorithm, a reciprocal times) and its Horner order; the elementary functions (exp, log, atan2, sqrt)
come from the platform's libm here and possibly from numpy's SIMD versions there, so values agree to a few
units in the last place (tests/test_compiled.py compares both paths on many loops).

One specialisation per kernel (``cache=True``; the argument types never vary): all elements go through one
dispatcher on a kind code and a parameter array, all plants through one set of coefficient arrays, so nothing is
specialised per loop.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kinds import BACKLASH, CUBIC, DEADZONE, RELAY, SATURATION

_SERIES = np.array([math.comb(2 * n, n) / 4.0**n * 2.0 / (2 * n + 3) for n in range(16)])
_TWO_PI_INV = 2.0 / np.pi
_FOUR_PI_INV = 4.0 / np.pi
_PI = np.pi
_EPS = float(np.finfo(float).eps)
_FD_STEP = 1e-6
_POLISH = 1e-4
_MAX_LM_ITER = 100

_OPTS = dict(cache=True, nogil=True, error_model="numpy")


@njit(**_OPTS)
def cdiv(a, b):
    """a / b as numpy computes it (Smith's algorithm with a reciprocal)."""
    br, bi = b.real, b.imag
    if abs(br) >= abs(bi):
        if br == 0.0 and bi == 0.0:
            return complex(a.real / abs(br), a.imag / abs(br))
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        return complex((a.real + a.imag * rat) * scl, (a.imag - a.real * rat) * scl)
    rat = br / bi
    scl = 1.0 / (bi + br * rat)
    return complex((a.real * rat + a.imag) * scl, (a.imag * rat - a.real) * scl)


@njit(**_OPTS)
def cabs(z):
    return math.hypot(z.real, z.imag)


@njit(**_OPTS)
def _clip(x, lo, hi):
    return min(max(x, lo), hi)


@njit(**_OPTS)
def _asin_minus(t, c):
    tc = _clip(t, 0.0, 1.0)
    if tc < 0.25:
        t2 = tc * tc
        y = _SERIES[15]
        for i in range(14, -1, -1):
            y = _SERIES[i] + y * t2
        return y * t2 * tc
    return math.atan2(tc, c) - tc * c


@njit(**_OPTS)
def _f(u):
    c = math.sqrt((1.0 - u) * (1.0 + u))
    return _TWO_PI_INV * (math.atan2(u, c) + u * c)


@njit(**_OPTS)
def _one_minus_ratio(level, A):
    if math.isinf(A):
        return 1.0
    return (A - level) / A


@njit(**_OPTS)
def element(kind, p, A):
    """N(A) of a static element (kind code, parameters) at a finite amplitude A > 0."""
    if kind == SATURATION:  # p = (limit, k)
        r = p[0] / A
        if r >= 1.0:
            return complex(p[1], 0.0)
        return complex(p[1] * _f(_clip(r, 0.0, 1.0)), 0.0)
    if kind == DEADZONE:  # p = (delta, k)
        r = p[0] / A
        if r >= 1.0:
            return 0j
        rc = _clip(r, 0.0, 1.0)
        if rc < 0.5:
            return complex(p[1] * (1.0 - _f(rc)), 0.0)
        gap = _clip(_one_minus_ratio(p[0], A), 0.0, 1.0)
        return complex(_TWO_PI_INV * p[1] * _asin_minus(math.sqrt(gap * (1.0 + rc)), rc), 0.0)
    if kind == RELAY:  # p = (M, hysteresis, on, off)
        M, hyst, on, off = p[0], p[1], p[2], p[3]
        if on != 0.0 and A <= on:
            return 0j
        c_on, c_off = _clip(on / A, -1.0, 1.0), _clip(off / A, -1.0, 1.0)
        gap_on = _clip(_one_minus_ratio(on, A), 0.0, 2.0)
        gap_off = _clip(_one_minus_ratio(off, A), 0.0, 2.0)
        re = _TWO_PI_INV * (M / A) * (math.sqrt(gap_on * (1.0 + c_on)) + math.sqrt(gap_off * (1.0 + c_off)))
        im = 0.0 if hyst == 0.0 else -_FOUR_PI_INV * ((M / A) * (hyst / A))
        return complex(re, im)
    if kind == BACKLASH:  # p = (h, k, h / 2)
        h, k = p[0], p[1]
        r = h / A
        if r >= 2.0:
            return 0j
        rc = _clip(r, 0.0, 2.0)
        u = _one_minus_ratio(h, A)
        s = _clip(2.0 * _one_minus_ratio(p[2], A), 0.0, 2.0)
        t = math.sqrt(rc * s)
        phi = _asin_minus(t, abs(_clip(u, -1.0, 1.0)))
        re = k * (1.0 - phi / _PI) if rc <= 1.0 else k * phi / _PI
        return complex(re, -(k / _PI) * rc * s)
    if kind == CUBIC:  # p = (k1, 0.75 k3)
        return complex(p[0] + p[1] * A * A, 0.0)
    # PRELOAD, FRICTION: p = (slope, level)
    return complex(p[0] + _FOUR_PI_INV * (p[1] / A), 0.0)


@njit(**_OPTS)
def _polyval(c, s):
    y = 0j
    for k in range(c.size):
        y = y * s + c[k]
    return y


@njit(**_OPTS)
def plant(num, den, delay, w):
    """G(jw) = num(jw) / den(jw) e^{-jwT} as :class:`~dfloop.solve.plant.Plant` evaluates it."""
    s = complex(0.0, w)
    g = cdiv(_polyval(num, s), _polyval(den, s))
    if delay != 0.0:
        x = -w * delay
        g = g * complex(math.cos(x), math.sin(x))
    return g


@njit(**_OPTS)
def log_slope(zeros, poles, delay, w):
    """d ln G / d ln w (Plant.log_slope)."""
    s = complex(0.0, w)
    return (_sum_ratios(s, zeros) - _sum_ratios(s, poles)) - complex(0.0, w * delay)


@njit(**_OPTS)
def _sum_ratios(s, roots):
    """sum_k s / (s - r_k) in numpy's order for a reduction: the first term plus the sum of the others
    (pairwise in blocks of 8 beyond 8 terms: there the order differs from numpy's by rounding only)."""
    if roots.size == 0:
        return 0j
    rest = complex(-0.0, -0.0)
    for k in range(1, roots.size):
        rest = rest + cdiv(s, s - roots[k])
    return cdiv(s, s - roots[0]) + rest


@njit(**_OPTS)
def fd_step(a, ln_lo, ln_hi):
    """The central-difference step of N along a (Residual._fd_steps): _FD_STEP, shrunk to a quarter of the
    distance to the edges (ln_lo, ln_hi) of N's amplitude domain, at least 64 rounding units of a."""
    gap = min(a - ln_lo, ln_hi - a)
    if math.isnan(gap):
        gap = math.inf
    return _clip(0.25 * gap, 64 * rounding(a), _FD_STEP)


@njit(**_OPTS)
def _n_slope(kind, p, A, h):
    """dN/da by the central difference of step h (log units), as numpy divides by 2h: times 1 / (2h)."""
    return (element(kind, p, A * math.exp(h)) - element(kind, p, A * math.exp(-h))) * (1.0 / (2 * h))


@njit(**_OPTS)
def slopes_at(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, a, v):
    """(P, dP/da, dP/dv, G, N) at one point (a, v) in log coordinates (Residual._evaluate_slopes)."""
    A, w = math.exp(a), math.exp(v)
    g = plant(num, den, delay, w)
    g_v = g * log_slope(zeros, poles, delay, w)
    n = element(kind, p, A)
    n_a = _n_slope(kind, p, A, fd_step(a, ln_lo, ln_hi))
    return g * n, g * n_a, g_v * n, g, n


@njit(**_OPTS)
def rounding(x):
    """Rounding unit of a log coordinate (roots._rounding)."""
    ax = abs(x)
    return max(np.nextafter(ax, np.inf) - ax, _EPS)


@njit(**_OPTS)
def at_rounding_level(P, P_a, P_v, a, v):
    r = 1.0 + P
    det = P_a.real * P_v.imag - P_v.real * P_a.imag
    da = (P_v.imag * r.real - P_v.real * r.imag) / det
    dv = (P_a.real * r.imag - P_a.imag * r.real) / det
    jav = P_a.real * P_v.real + P_a.imag * P_v.imag
    ka, kv = abs(jav / cabs(P_a) ** 2), abs(jav / cabs(P_v) ** 2)
    ua, uv = 8 * rounding(a), 8 * rounding(v)
    if not math.isfinite(ka):
        ka = 0.0
    if not math.isfinite(kv):
        kv = 0.0
    return (abs(da) <= ua + ka * uv) and (abs(dv) <= uv + kv * ua)


@njit(**_OPTS)
def accepted(P, P_a, P_v, a, v, tol):
    bound = max(tol * (1 + cabs(P)), 32 * (cabs(P_a) * rounding(a) + cabs(P_v) * rounding(v)))
    return cabs(1.0 + P) <= bound


@njit(**_OPTS)
def evaluate_slopes(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, a, A, w):
    """Residual._evaluate_slopes at log amplitudes a (A = e^a) and frequencies w (arrays): P, P_a, P_v, G, N."""
    k = A.size
    out = np.empty((5, k), np.complex128)
    for i in range(k):
        g = plant(num, den, delay, w[i])
        g_v = g * log_slope(zeros, poles, delay, w[i])
        n = element(kind, p, A[i])
        n_a = _n_slope(kind, p, A[i], fd_step(a[i], ln_lo, ln_hi))
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i] = g * n, g * n_a, g_v * n, g, n
    return out


@njit(**_OPTS)
def products(num, den, delay, kind, p, A, w):
    """P = G(w) N(A) at scattered points (arrays of equal size)."""
    out = np.empty(A.size, np.complex128)
    for i in range(A.size):
        out[i] = plant(num, den, delay, w[i]) * element(kind, p, A[i])
    return out


@njit(**_OPTS)
def plant_values(num, den, delay, w):
    out = np.empty(w.size, np.complex128)
    for i in range(w.size):
        out[i] = plant(num, den, delay, w[i])
    return out


@njit(**_OPTS)
def element_values(kind, p, A):
    out = np.empty(A.size, np.complex128)
    for i in range(A.size):
        out[i] = element(kind, p, A[i])
    return out


@njit(**_OPTS)
def refine(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, a, v, a_lo, a_hi, v_lo, v_hi, tol, certified):
    """roots.refine, one point at a time (each point's iteration is independent there too); ``certified`` as
    there (a box known to hold a root accepts a point within the residual bound).

    Returns (a, v, ok), the final (P, P_a, P_v, G, N) per point, shape (5, n), and the number of points at
    which G and N were evaluated (three per evaluation of the slopes, as Residual counts them)."""
    n_pts = a.size
    a, v = a.copy(), v.copy()
    ok = np.zeros(n_pts, np.bool_)
    vals = np.empty((5, n_pts), np.complex128)
    polish = tol * _POLISH
    evaluated = 0
    for i in range(n_pts):
        ai, vi = a[i], v[i]
        P, ra, rv, g, n = slopes_at(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, ai, vi)
        evaluated += 3
        rel = cabs(1.0 + P) / (1 + cabs(P))
        lam = 1e-12
        done = (rel <= polish) or at_rounding_level(P, ra, rv, ai, vi)
        failed = False
        for _ in range(_MAX_LM_ITER):
            if done or failed:
                break
            r = 1.0 + P
            jaa = cabs(ra) ** 2
            jvv = cabs(rv) ** 2
            jav = ra.real * rv.real + ra.imag * rv.imag
            ga = ra.real * r.real + ra.imag * r.imag
            gv = rv.real * r.real + rv.imag * r.imag
            m11, m22 = jaa * (1 + lam), jvv * (1 + lam)
            det = m11 * m22 - jav ** 2
            da = -(m22 * ga - jav * gv) / det
            dv = -(m11 * gv - jav * ga) / det
            ok_step = math.isfinite(da) and math.isfinite(dv)
            if not ok_step:
                da, dv = 0.0, 0.0
            fine_a = abs(da) <= 2 * rounding(ai)
            fine_v = abs(dv) <= 2 * rounding(vi)
            # both from the unmodified steps, as the numpy version's two np.where
            da, dv = ((0.0 if fine_a else (-ga / jaa if fine_v else da)),
                      (0.0 if fine_v else (-gv / jvv if fine_a else dv)))
            if not math.isfinite(da):
                da = 0.0
            if not math.isfinite(dv):
                dv = 0.0
            at = _clip(ai + da, a_lo[i], a_hi[i])
            vt = _clip(vi + dv, v_lo[i], v_hi[i])
            Pt, rat, rvt, gt, nt = slopes_at(num, den, zeros, poles, delay, kind, p, ln_lo, ln_hi, at, vt)
            evaluated += 3
            relt = cabs(1.0 + Pt) / (1 + cabs(Pt))
            better = (relt < rel) and ok_step
            pinned = at == a_lo[i] or at == a_hi[i] or vt == v_lo[i] or vt == v_hi[i]
            small = abs(da) <= 1e-9 * (1 + abs(ai)) and abs(dv) <= 1e-9 * (1 + abs(vi))
            if better and ((relt > (1 - 1e-3) * rel and small) or (pinned and relt > 0.5 * rel)):
                failed = True
            if better:
                ai, vi, P, rel, ra, rv, g, n = at, vt, Pt, relt, rat, rvt, gt, nt
                lam = max(lam / 10, 1e-15)
            else:
                lam *= 100
            done = (rel <= polish) or at_rounding_level(P, ra, rv, ai, vi)
            if lam > 1e8 and not done:
                failed = True
        a[i], v[i] = ai, vi
        ok[i] = accepted(P, ra, rv, ai, vi, tol) and (certified or rel <= tol
                                                      or at_rounding_level(P, ra, rv, ai, vi))
        vals[0, i], vals[1, i], vals[2, i], vals[3, i], vals[4, i] = P, ra, rv, g, n
    return a, v, ok, vals, evaluated
