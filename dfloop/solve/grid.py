"""The solver's grid, chosen from G and N themselves so that no root can fall between samples.

Every grid axis is refined until the complex logarithm of the factor it carries (G along ln w, an
amplitude-only N along ln A) changes by at most ``STEP`` within each interval. Each interval then carries
a bound ``eps`` on |ln f(x) - ln f(x_left)| for all x in it, and a grid cell (i, j) can hold a root of
1 + G N only if ln(N_i G_j) lies within eps_a[i] + eps_v[j] of j pi (mod 2 pi j): every other cell is
excluded by that certificate, so its winding number is exactly 0 (see ``_kernels.candidate_cells``).

- Rational G (tf, ss): the bound is certified, from the poles and zeros: an upper bound within a few % of the exact
  variation (:meth:`Plant.log_variation`), in rational arithmetic (:func:`_interval_bound`).
- Callable or frd G, and N along A: sampled. Each interval is checked at its midpoint and at its golden
  section point; it is split while the path through either point is longer than ``STEP``. A phase that
  turns by 2 pi k (+ a little) between two samples can wrap to small steps at both check points (a relay
  around e^{-s}/(s + 1) on [0.1, 1e5] rad/s had intervals of 34 and 42 turns pass), so along omega the
  slope |d ln G / d ln w| is also sampled (a second sample 1e-7 after each) and the interval's bound is
  at least its width times the largest slope at its four samples: a turn of 2 pi k shows in the slope
  whatever k. Only a feature narrower than the samples with small slopes at all four can still hide; an
  interval that stays above ``STEP`` at the smallest width is reported (``GridReport.uncertified``).
"""
from __future__ import annotations

from typing import Callable

import math

import numpy as np

from .._checks import memory_limit
from .plant import Plant

__all__ = ["hypot", "wrap_phase", "STEP", "FD_MIN_WIDTH", "MONOTONE_WIDTH", "BYTES_PER_POINT", "ANGLE_ROUNDING",
           "SUM_ROUNDING", "TERM_ROUNDING", "TAN_OK", "resolve_plant", "resolve_sampled", "node_terms", "allpass_pairs", "ALLPASS_MISMATCH",
           "chord_deviation", "chord_gap", "check_memory", "clog", "largest_step"]

STEP = 0.35
"""Largest change of the complex log of G (or N) allowed within one grid interval (|d ln| = |d ln|f|| + phase)."""
_GOLDEN = 0.3819660112501051
_SLOPE_H = 1e-7  # log step of the slope samples (relative 1e-7 in w): |d ln G/d ln w| up to ~1e7 is seen
MONOTONE_WIDTH = 1e-9  # intervals are split for monotonicity down to this width (relative)
_MAX_ROUNDS = 64  # halvings of an interval; with the minimum width below, never reached on finite windows
_MIN_WIDTH = 1e-13  # intervals narrower than this (log units, relative to 1 + |x|) are not split (a jump)
FD_MIN_WIDTH = 1e-6  # the same for a frequency-dependent N, whose jumps move with the amplitude
_MAX_POINTS = 2_000_000  # nodes per axis
BYTES_PER_POINT = {False: 80, True: 160}
"""Upper bounds on the solver's peak memory per grid point (bytes), for an amplitude-only N (False) and a
frequency-dependent N (True). Measured peaks (tracemalloc, tests/test_memory_bounds.py): under 16 and ~129:
the amplitude-only solver reads the loop product at the candidate cells only (``roots.OuterProduct``), so its
peak scales with them and with the roots, and the bound leaves room for grids where many more cells are
candidates; a frequency-dependent one works on the whole tensor grid (G N, 1 + G N, phases, refinement masks,
windings, tangent seeds)."""


def check_memory(na: int, nv: int, frequency_dependent: bool = False, limit: int | None = None) -> None:
    """Raise ValueError, before anything is allocated, when the work arrays of an na x nv grid exceed the
    memory bound (``limit`` in bytes when already read, else :func:`~dfloop._checks.memory_limit`); the message
    gives the estimate and the knobs."""
    need = BYTES_PER_POINT[bool(frequency_dependent)] * na * nv
    limit = memory_limit() if limit is None else limit
    if need > limit:
        kind = "a frequency-dependent" if frequency_dependent else "an amplitude-only"
        raise ValueError(f"grid of {na} x {nv} points would need {need / 1024 ** 3:.1f} GiB of memory (estimate: "
                         f"{BYTES_PER_POINT[bool(frequency_dependent)]} bytes per point for {kind} N; limit "
                         f"{limit / 1024 ** 3:.3g} GiB); reduce grid=, narrow the omega/amplitude window, or raise "
                         "the limit with the environment variable DFLOOP_MEMORY_LIMIT (GiB)")


def clog(f: np.ndarray) -> np.ndarray:
    """Complex logarithm ln|f| + j arg f (-inf real part where f = 0)."""
    with np.errstate(divide="ignore"):
        return np.log(np.abs(f)) + 1j * np.angle(f)


def hypot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``np.hypot(x, y)``, as sqrt(x^2 + y^2) where max(|x|, |y|) lies in (1e-150, 1e150): no square overflows or
    loses the larger term there, and the result is within two ulp of hypot's (the grids' bounds sum logs and angles,
    and carry margins far larger); hypot itself elsewhere (inf, NaN, extreme values). The compiled driver computes
    the same expression (``driver._hypot``), so both get the same bits, at a fraction of hypot's cost."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        big = np.maximum(np.abs(x), np.abs(y))
        return np.where((big > 1e-150) & (big < 1e150), np.sqrt(x * x + y * y), np.hypot(x, y))


def wrap_phase(d: np.ndarray) -> np.ndarray:
    """A phase difference d (rad) wrapped into [-pi, pi] by one turn: exact where |d| <= 2 pi (a difference of two
    angles: d -+ 2 pi is exact there, by Sterbenz's lemma, so both drivers get the same bits), and
    ``np.angle(np.exp(1j d))`` elsewhere (NaN stays NaN, an infinite d gives NaN)."""
    d = np.asarray(d, float)
    with np.errstate(invalid="ignore"):
        out = np.where(d > np.pi, d - 2 * np.pi, np.where(d < -np.pi, d + 2 * np.pi, d))
        far = ~(np.abs(d) <= 2 * np.pi) & ~np.isnan(d)
        if far.any():
            out[far] = np.angle(np.exp(1j * d[far]))
    return out


def _dlog(l1: np.ndarray, l0: np.ndarray) -> np.ndarray:
    """|ln f1 - ln f0| with the phase difference wrapped to [-pi, pi] (:func:`wrap_phase`); inf when one side is
    0, 0 when both."""
    with np.errstate(invalid="ignore"):
        dre = l1.real - l0.real
        d = hypot(np.where(np.isnan(dre), 0.0, dre), wrap_phase(l1.imag - l0.imag))
    return d


def _too_many(n: int, name: str) -> None:
    if n > _MAX_POINTS:
        raise RuntimeError(f"resolving {name} needs more than {_MAX_POINTS} grid points; narrow the window "
                           f"(the factor turns faster than the grid can follow)")


def _slope(l0: np.ndarray, lh: np.ndarray) -> np.ndarray:
    """|d ln f / dx| from ln f at x and at x + _SLOPE_H (wrapped phase step; 0 where f = 0 at both)."""
    return _dlog(lh, l0) / _SLOPE_H


def _non_monotone(ls: list) -> np.ndarray:
    """Whether ln|f| or arg f, sampled at increasing points (list of complex-log arrays), turns back (steps
    below 1e-10 are rounding, not a turn)."""
    out = np.zeros(ls[0].shape, bool)
    for k, part in enumerate((np.real, np.imag)):
        with np.errstate(invalid="ignore"):  # ln 0 - ln 0 (a dead band) is NaN: neither up nor down
            steps = [part(b) - part(a) for a, b in zip(ls[:-1], ls[1:])]
        if k == 1:
            steps = [wrap_phase(d) for d in steps]
        with np.errstate(invalid="ignore"):
            up = np.any([d > 1e-10 for d in steps], axis=0)
            down = np.any([d < -1e-10 for d in steps], axis=0)
        out |= up & down
    return out


def resolve_sampled(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, name: str, step: float = STEP,
                    min_width: float = 1e-13, slopes: bool = False, monotone: bool = False):
    """Refine the sorted nodes x (log units) until ln f is resolved by sampling; see the module notes.

    ``f(exp(x))`` returns an array of shape (len(x),) or (len(x), m) (m functions resolved together;
    eps is then the largest over them). Intervals narrower than ``min_width`` (relative to 1 + |x|),
    and intervals with f = 0 at an end (the edge of a dead band, which no refinement resolves), are not
    split. With ``slopes``, f is also sampled ``_SLOPE_H`` after every sample and the interval's bound is at
    least its width times the largest |d ln f / dx| seen at its samples (a phase that turns by 2 pi k
    between samples shows its slope, whatever k). With ``monotone``, an interval is also split (down to a
    relative width of 1e-9) while its four samples show ln|f| or arg f turning back: then each interval's
    bound (the path through its samples) bounds the change inside it, and a ripple of N (a quantizer's)
    cannot hide a pair of roots in one cell. Returns (nodes, f at nodes, eps per interval, number of
    evaluations, uncertified intervals as an (k, 2) array of their ends in x).
    """
    x = np.asarray(x, float)
    x_end = x[-1]

    def sample(xs):
        if not slopes:
            fx = f(np.exp(xs))
            return fx, clog(fx), None
        xh = np.where(xs + _SLOPE_H > x_end, xs - _SLOPE_H, xs + _SLOPE_H)  # stay inside G's domain (frd)
        fx = f(np.exp(xs))  # two calls: a callable's shape errors then name the user's own nodes
        lx = clog(fx)
        s = _slope(lx, clog(f(np.exp(xh))))
        return fx, lx, (s.max(axis=1) if s.ndim > 1 else s)

    fx, lx, sx = sample(x)
    done_x, done_f, done_eps = [x[:1]], [fx[:1]], [np.empty(0)]
    x0, x1, l0, l1, f1 = x[:-1], x[1:], lx[:-1], lx[1:], fx[1:]
    s0, s1 = (sx[:-1], sx[1:]) if slopes else (None, None)
    n_eval = x.size * (2 if slopes else 1)
    bad_lo, bad_hi = [], []
    for _ in range(_MAX_ROUNDS):
        if x0.size == 0:
            break
        dx = x1 - x0
        xm, xg = x0 + 0.5 * dx, x0 + _GOLDEN * dx
        fs, ls, ss = sample(np.concatenate([xm, xg]))
        n_eval += fs.size * (2 if slopes else 1)
        fm, fg = fs[:x0.size], fs[x0.size:]
        lm, lg = ls[:x0.size], ls[x0.size:]
        m1, m2, g1, g2 = _dlog(lm, l0), _dlog(l1, lm), _dlog(lg, l0), _dlog(l1, lg)
        eps = np.maximum(m1 + m2, g1 + g2)
        if eps.ndim > 1:  # several functions sampled together (rows of a frequency-dependent N)
            eps = eps.max(axis=1)
        if slopes:
            sm = ss[:x0.size]
            with np.errstate(invalid="ignore"):
                lip = dx * np.maximum(np.maximum(s0, s1), np.maximum(sm, ss[x0.size:]))
            eps = np.maximum(eps, np.where(np.isnan(lip), np.inf, lip))
        wide = dx > min_width * (1 + np.abs(x0))
        split = np.isfinite(eps) & (eps > step) & wide
        if monotone:
            turns = _non_monotone([l0, lg, lm, l1])
            if turns.ndim > 1:
                turns = turns.any(axis=1)
            split |= turns & np.isfinite(eps) & (dx > MONOTONE_WIDTH * (1 + np.abs(x0)))
        keep = ~split
        if slopes:  # kept above the step: a discontinuity, or a feature the sampling cannot follow
            stuck = keep & (eps > step)
            bad_lo.append(x0[stuck])
            bad_hi.append(x1[stuck])
        done_x.append(x1[keep])
        done_f.append(f1[keep])
        done_eps.append(eps[keep])
        # split intervals: [x0, xm] and [xm, x1]
        x0, x1 = np.concatenate([x0[split], xm[split]]), np.concatenate([xm[split], x1[split]])
        l0, l1 = np.concatenate([l0[split], lm[split]]), np.concatenate([lm[split], l1[split]])
        f1 = np.concatenate([fm[split], f1[split]])
        if slopes:
            s0, s1 = np.concatenate([s0[split], sm[split]]), np.concatenate([sm[split], s1[split]])
        _too_many(sum(a.size for a in done_x) + x0.size, name)
    else:
        raise RuntimeError(f"resolving {name} did not settle within {_MAX_ROUNDS} halvings")
    bad = (np.column_stack([np.concatenate(bad_lo), np.concatenate(bad_hi)]) if bad_lo
           else np.empty((0, 2)))
    # nodes: the first one plus the right end of every accepted interval; eps follows the right ends
    xs, fs_, es = np.concatenate(done_x), np.concatenate(done_f), np.concatenate(done_eps)
    order = np.argsort(xs[1:], kind="stable") + 1
    return (np.concatenate([xs[:1], xs[order]]), np.concatenate([fs_[:1], fs_[order]]), es[order - 1], n_eval,
            bad[np.argsort(bad[:, 0])])


ANGLE_ROUNDING = 4e-15
"""Bound (rad) on the rounding error of one factor's turn where :func:`resolve_plant`'s bound takes it exactly, as
atan2(x h, x^2 + p0 p1) (a root on the imaginary axis, or an interval the factor turns by more than ~1.3 rad on:
see ``TAN_OK``): atan2 is within 4 ulp (numpy's vectorised version; libm's, used by the compiled driver, within
1 ulp) of a value below pi in magnitude, and its arguments' rounding moves it by a few ulp more there; added per
root to the interval bound."""
SUM_ROUNDING = 2.3e-16
"""Relative bound per term on the rounding of the sums of turns and of magnitude changes in :func:`resolve_plant`'s
bound (the sum of n non-negative terms in floating point is within (n - 1) u of the exact sum; 2.3e-16 > 2u)."""
TERM_ROUNDING = 2e-14
"""Relative bound on the rounding of one factor's term in :func:`resolve_plant`'s bound (u = 2^-53 ~ 1.1e-16):
the magnitude term is a product of two quotients of correctly rounded differences and hypotenuses (within ~12 u);
the turn's tangent x h / (x^2 + p0 p1) is within 7 u where p0 p1 >= 0, and within 4 u / ``TAN_OK`` + 3 u (71 u)
where the sum in its denominator cancels down to ``TAN_OK`` of its terms' size. Applied as a factor (1 + 2e-14)."""
TAN_OK = 1.0 / 16
"""The turn of a factor over an interval is bounded by its tangent x h / D (D = x^2 + p0 p1) where
D > TAN_OK (x^2 + |p0 p1|); elsewhere (only where the interval straddles the root's frequency and the factor
turns by more than atan(15) ~ 1.5 rad) it is taken exactly by atan2."""


ALLPASS_MISMATCH = 1e-9
"""Largest distance |z + conj(p)|, relative to |Re p|, at which a zero z and a pole p count as an all-pass pair
(:func:`allpass_pairs`): the mirrored roots of a Pade delay, computed apart, meet this to ~1e-14."""


def allpass_pairs(zeros: np.ndarray, poles: np.ndarray):
    """The all-pass pairs of a rational plant: (paired, slack).

    ``paired`` (bool, zeros then poles) marks each zero z matched with a pole p at its mirror image,
    z = -conj(p) up to ``ALLPASS_MISMATCH`` |Re p| (each zero takes the nearest unmatched pole; a Pade delay's
    zeros mirror its poles). The factor (jw - z) / (jw - p) of a pair has modulus 1 at every w when the mirror
    is exact; with z = -conj(p) + d, its modulus lies within |d| / |Re p| of 1, since
    |jw + conj(p)| = |jw - p| >= |Re p|. So a pair changes ln|G| by at most 2 c, c = -ln(1 - |d| / |Re p|)
    (|d| with a rounding margin), on any interval: ``slack`` is the sum over the pairs, and
    :func:`resolve_plant`'s magnitude bound counts the pairs by it in place of their roots' separate rises and
    falls (their phases as before). Written in scalar arithmetic that numba compiles unchanged, so the compiled
    driver's grid is the same bit for bit.
    """
    nz, n_p = zeros.size, poles.size
    paired = np.zeros(nz + n_p, np.bool_)
    slack = 0.0
    for i in range(nz):
        zr, zi = zeros[i].real, zeros[i].imag
        best, j_best = math.inf, -1
        for j in range(n_p):
            pr, pi_ = poles[j].real, poles[j].imag
            if paired[nz + j] or not (pr != 0 and math.isfinite(pr) and math.isfinite(pi_)):
                continue
            d = math.hypot(zr + pr, zi - pi_)
            if d < best:
                best, j_best = d, j
        if j_best < 0 or not (math.isfinite(zr) and math.isfinite(zi)):
            continue
        pr, pi_ = poles[j_best].real, poles[j_best].imag
        # the distance's own rounding (two sums and a hypot of numbers of these sizes), as a margin
        d = best * (1 + 1e-15) + 1e-15 * (abs(zr) + abs(zi) + abs(pr) + abs(pi_))
        if d <= ALLPASS_MISMATCH * abs(pr):
            paired[i] = paired[nz + j_best] = True
            slack += -2.0 * math.log1p(-d / abs(pr))
    return paired, slack * (1 + 1e-12)


def chord_deviation(zeros: np.ndarray, poles: np.ndarray, delay: float, v0: float, v1: float) -> float:
    """How far j pi - ln G(e^v) can lie from its chord over [v0, v1] (v = ln w, w in rad/s; rational G with the
    given zeros and poles and a pure delay in s): a bound h with |T(v) - L(v)| <= h for every v there, T the
    curve and L the straight line between its values at the ends.

    For a C^2 curve the distance to the chord is at most (v1 - v0)^2 / 8 max |T''| (the linear interpolation's
    error, with its non-negative kernel, holds for complex values too). Each factor ln(j e^v - r) has second
    derivative -j w r / (jw - r)^2, of modulus at most w1 |r| / d^2 on the interval (d the least distance from r
    to the segment [j w0, j w1]); the delay's -j w T has w T <= w1 T. Infinite when a root lies on that segment.
    Scalar arithmetic that numba compiles unchanged (the compiled driver's seed exclusion uses the same source).
    """
    w0, w1 = math.exp(v0), math.exp(v1)
    m = w1 * delay
    for k in range(zeros.size + poles.size):
        r = zeros[k] if k < zeros.size else poles[k - zeros.size]
        x, y = -r.real, r.imag
        if x == 0.0 and y == 0.0:  # a root at the origin: ln(jw) has no curvature in ln w
            continue
        dy = max(w0 - y, 0.0, y - w1)
        d2 = x * x + dy * dy
        if not d2 > 0.0:
            return math.inf
        m += w1 * math.hypot(x, y) / d2
    return (v1 - v0) * (v1 - v0) / 8.0 * m * (1.0 + 1e-9)


def chord_gap(l0: complex, l1: complex, t0: complex, t1: complex, e: float, h: float) -> float:
    """A lower bound (log units, arg modulo 2 pi) on the distance between the rectangle spanned by l0, l1 (ln N at
    the ends of a piece where ln|N| and arg N are monotone and arg N turns by less than pi) and the curve
    j pi - ln G over a piece of G with ends t0, t1, variation bound e (|ln G - ln G(end)| <= e on it) and chord
    deviation h (:func:`chord_deviation`).

    The curve lies within h of the chord [t0, t1] (whose turn, read modulo 2 pi, is the curve's own when
    e < pi / 2; otherwise nothing is claimed: -inf). The separation of the rectangle and the chord along the
    real axis, the imaginary axis and the chord's normal is each a lower bound on their distance; the largest,
    less h, is returned. A sharper companion of the two discs of radius e around t0 and t1 where G turns slowly
    and N's rectangle is flat (a long valley of small |1 + G N|). Scalar arithmetic that numba compiles
    unchanged."""
    if not (e < 0.5 * math.pi and h >= 0.0 and h < math.inf):
        return -math.inf
    two_pi = 2.0 * math.pi
    dy = l1.imag - l0.imag
    dy -= two_pi * math.floor((dy + math.pi) / two_pi)
    yc, hy = l0.imag + 0.5 * dy, 0.5 * abs(dy)
    x0, x1 = min(l0.real, l1.real), max(l0.real, l1.real)
    du = t1.imag - t0.imag
    du -= two_pi * math.floor((du + math.pi) / two_pi)
    off = t0.imag + 0.5 * du - yc  # the chord's copy whose middle lies within pi of the rectangle's
    shift = -two_pi * math.floor((off + math.pi) / two_pi)
    ar, ai, br, bi = t0.real, t0.imag + shift, t1.real, t0.imag + du + shift
    sep = max(x0 - max(ar, br), min(ar, br) - x1, (yc - hy) - max(ai, bi), min(ai, bi) - (yc + hy))
    length = math.hypot(br - ar, bi - ai)
    if length > 0.0:
        nx, ny = -(bi - ai) / length, (br - ar) / length
        s = ar * nx + ai * ny
        c00, c01 = x0 * nx + (yc - hy) * ny, x0 * nx + (yc + hy) * ny
        c10, c11 = x1 * nx + (yc - hy) * ny, x1 * nx + (yc + hy) * ny
        sep = max(sep, min(c00, c01, c10, c11) - s, s - max(c00, c01, c10, c11))
    return sep - h


def node_terms(plant: Plant, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The terms of each factor j nu - r of a rational plant at the frequencies w (rad/s, shape (k,); nu = w, or
    the plant's frequency map of it), for each root r = -x + jy (zeros, then poles): p = nu - y and the modulus
    d = |j nu - r| = hypot(x, p) (:func:`hypot`), two arrays (k, number of roots). :func:`_interval_bound` bounds
    each factor's change over an interval from the terms of its two ends, with no logarithm or arctangent."""
    zeros, poles = plant.roots
    r = np.concatenate([zeros, poles])
    nu = np.asarray(w if plant.frequency_map is None else plant.frequency_map(w), float)[:, None]
    p = nu - r.imag
    return p, hypot(-r.real, p)


def _interval_bound(plant: Plant, nu0, nu1, p0, p1, d0, d1, pairs) -> np.ndarray:
    """An upper bound on :meth:`Plant.log_variation` on the intervals [nu0, nu1] (mapped frequencies, shape (k,))
    from the node terms of their ends (:func:`node_terms`, shapes (k, roots)), in rational arithmetic only.

    For the factor j nu - r = x + j p, p = nu - y, over an interval of width h = nu1 - nu0:

    - its modulus d moves monotonically where the interval does not straddle y (p0 >= 0 or p1 <= 0), by
      |ln(d1 / d0)| = t <= sinh t = (d1^2 - d0^2) / (2 d0 d1) = h |p0 + p1| / (2 d0 d1) in magnitude (rising where
      p0 >= 0); where it straddles y (p0 < 0 < p1) it falls to |x| and rises again, by at most
      sinh(ln(d0 / |x|)) = p0^2 / (2 |x| d0) and p1^2 / (2 |x| d1);
    - its angle turns by atan2(x h, D), D = x^2 + p0 p1, which is at most its tangent x h / D in magnitude where
      D > 0: the bound takes the tangent where D > ``TAN_OK`` (x^2 + |p0 p1|), atan2 itself elsewhere (a root on
      the imaginary axis, or a turn above ~1.5 rad).

    Each factor's change t on an interval of the grid (|d ln G| <= ``STEP`` = 0.35) is at most ``STEP``, where
    sinh t / t <= 1.021 and tan t / t <= 1.043: the bound exceeds the exact variation by at most 4.3 % there (plus
    the rounding margins), by much less where several factors share the step.
    The magnitudes of all-pass pairs (a Pade delay's mirrored roots) are counted by their joint bound (``pairs`` =
    :func:`allpass_pairs` of the plant), not root by root: their moduli cancel. The rounding of every term
    (``TERM_ROUNDING``), of the sums (``SUM_ROUNDING``) and of the exact turns (``ANGLE_ROUNDING``) is added, so
    the bound stays an upper bound. The compiled driver computes the same expressions (IEEE arithmetic and square
    roots, correctly rounded in both), so both get the same bits."""
    zeros, poles = plant.roots
    r = np.concatenate([zeros, poles])
    nr = r.size
    paired, slack = pairs
    sign = np.concatenate([np.ones(zeros.size), -np.ones(poles.size)])
    x = -r.real
    h = (nu1 - nu0)[:, None]
    scale = 1.0 + SUM_ROUNDING * (nr + 1) + TERM_ROUNDING
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ax = np.abs(x)
        inside = (p0 < 0) & (p1 > 0)
        mono = 0.5 * (h / d0) * (np.abs(p1 + p0) / d1)
        rising = p0 >= 0
        up = np.where(inside, 0.5 * (p1 / ax) * (p1 / d1), np.where(rising, mono, 0.0))
        down = np.where(inside, 0.5 * (p0 / ax) * (p0 / d0), np.where(rising, 0.0, mono))
        up, down = np.where(paired, 0.0, up), np.where(paired, 0.0, down)  # all-pass pairs: by the slack
        rise = np.where(sign > 0, up, down).sum(axis=-1) * scale + slack
        fall = np.where(sign > 0, down, up).sum(axis=-1) * scale + slack
        pp = p0 * p1
        xx = x * x
        D = xx + pp
        tangent = D > TAN_OK * (xx + np.abs(pp))
        turn = np.where(tangent, x * h / D, 0.0)
    if not tangent.all():
        far = ~tangent
        turn[far] = np.arctan2(np.broadcast_to(x * h, far.shape)[far], D[far])
    turn = sign * turn
    delay_turn = plant.delay * (nu1 - nu0)
    arg = np.maximum(np.where(turn > 0, turn, 0).sum(axis=-1), -np.where(turn < 0, turn, 0).sum(axis=-1) + delay_turn)
    arg = arg * scale + ANGLE_ROUNDING * nr
    return hypot(arg, np.maximum(rise, fall))


def resolve_plant(plant: Plant, v: np.ndarray, step: float = STEP):
    """Frequency nodes (ln w) resolving G: exact bound for rational G, sampled (with slopes) otherwise.

    For rational G, each interval's bound is an upper bound on :meth:`Plant.log_variation`'s (within a few % of
    it), from terms computed once per node (:func:`node_terms`: nu - y and |jw - r| for each root r = -x + jy) and
    combined per interval in rational arithmetic, with margins for rounding (:func:`_interval_bound`).
    Returns (nodes, G at nodes, eps per interval, number of evaluations of G, uncertified intervals (k, 2)).
    """
    if not plant.exact:
        return resolve_sampled(plant, v, "G along omega", step, slopes=True)
    v = np.asarray(v, float)
    w = np.exp(v)
    tp, td = node_terms(plant, w)
    nu = w if plant.frequency_map is None else np.asarray(plant.frequency_map(w), float)
    tx, tnu, tp, td = [v], [nu], [tp], [td]  # the node table, one block per round
    n_nodes = v.size
    done_i, done_eps = [np.zeros(1, np.int64)], [np.empty(0)]
    i0, i1 = np.arange(v.size - 1), np.arange(1, v.size)  # table indices of the live intervals' ends
    pairs = allpass_pairs(*plant.roots)  # (paired, slack) of the all-pass pairs, once for the plant
    for _ in range(_MAX_ROUNDS):
        if i0.size == 0:
            break
        X, NU, PT, DT = (np.concatenate(t) if len(t) > 1 else t[0] for t in (tx, tnu, tp, td))
        tx, tnu, tp, td = [X], [NU], [PT], [DT]
        x0, x1 = X[i0], X[i1]
        eps = _interval_bound(plant, NU[i0], NU[i1], PT[i0], PT[i1], DT[i0], DT[i1], pairs)
        split = (eps > step) & (x1 - x0 > _MIN_WIDTH * (1 + np.abs(x0)))
        done_i.append(i1[~split])
        done_eps.append(eps[~split])
        xm = 0.5 * (x0[split] + x1[split])
        wm = np.exp(xm)
        pm, dm = node_terms(plant, wm)
        tx.append(xm)
        tnu.append(wm if plant.frequency_map is None else np.asarray(plant.frequency_map(wm), float))
        tp.append(pm)
        td.append(dm)
        im = np.arange(n_nodes, n_nodes + xm.size)
        n_nodes += xm.size
        i0, i1 = np.concatenate([i0[split], im]), np.concatenate([im, i1[split]])
        _too_many(sum(a.size for a in done_i) + i0.size, "G along omega")
    else:
        raise RuntimeError(f"resolving G did not settle within {_MAX_ROUNDS} halvings")
    X = np.concatenate(tx)
    xs, es = X[np.concatenate(done_i)], np.concatenate(done_eps)
    order = np.argsort(xs[1:], kind="stable") + 1
    nodes = np.concatenate([xs[:1], xs[order]])
    return nodes, plant(np.exp(nodes)), es[order - 1], nodes.size, np.empty((0, 2))


def largest_step(eps: np.ndarray, step: float = STEP) -> float:
    """The largest interval bound among the resolved intervals (those left above ``step`` are jumps)."""
    ok = eps[eps <= step]
    return float(ok.max()) if ok.size else 0.0
