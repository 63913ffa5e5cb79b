"""An independent reference for the roots of 1 + G(jw) N(A, w) = 0, written apart from dfloop.solve.

It uses no code of the solver (no grids, windings, Levenberg-Marquardt, candidate cells): only 1-D reductions,
dense scans and scipy's brentq.

- Amplitude-only N(A): split the amplitude range into pieces on which |N| is strictly monotone (dense scan,
  extrema located by bounded scalar minimisation). On each piece the magnitude condition |G(jw)| |N(A)| = 1
  has at most one solution A(w) for each w; the phase condition h(w) = arg(-G(jw) N(A(w))) = 0 is then a
  1-D problem in w: sign changes of h on a dense scan of w (excluding the wrap at +-pi), each refined by
  brentq with A(w) itself solved by brentq.
- N(F, w) = G_lin(jw) N_s(|G_lin(jw)| F) (LinearThenStatic, MassBacklash): the same loop is the amplitude-only
  problem in X = |G_lin| F with the plant G G_lin and the element N_s; F = X / |G_lin(jw)|.

The scans are chosen from what is known about G independently: frequency points clustered around every pole
and zero (width ~ the real part) and, for a delay T, steps of w T below 0.05 rad.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq, minimize_scalar

__all__ = ["frequency_scan", "amplitude_roots", "composite_roots", "match"]


def frequency_scan(w_lo, w_hi, poles=(), zeros=(), delay=0.0, n=20000):
    """Dense scan of [w_lo, w_hi] (rad/s): log-spaced, clustered around poles/zeros, fine enough for a delay."""
    pts = [np.geomspace(w_lo, w_hi, n)]
    t = np.concatenate([-np.geomspace(1e-4, 1e4, 400), [0.0], np.geomspace(1e-4, 1e4, 400)])
    for r in list(poles) + list(zeros):
        r = complex(r)
        if abs(r) == 0:
            continue
        width = max(abs(r.real), 1e-14 * abs(r))
        pts.append(abs(r.imag) + width * t)
        pts.append(abs(r) + width * t)
    if delay > 0:
        pts.append(np.arange(w_lo, w_hi, 0.05 / delay))
    w = np.unique(np.concatenate(pts))
    return w[(w >= w_lo) & (w <= w_hi)]


def _pieces(Nmag, A):
    """Pieces [A_i, A_j] of strictly monotone |N| > 0 from a dense scan A (sorted), extrema refined."""
    m = Nmag(A)
    ends = []
    dm = np.diff(m)
    d = np.sign(np.where(np.abs(dm) <= 1e-12 * np.maximum(m[1:], m[:-1]), 0.0, dm))  # rounding noise is flat
    for k in range(1, d.size):
        if d[k] != d[k - 1] and d[k] != 0 and d[k - 1] != 0:  # an extremum between A[k-1] and A[k+1]
            s = 1.0 if d[k - 1] > 0 else -1.0
            r = minimize_scalar(lambda x: -s * Nmag(np.array([np.exp(x)]))[0], bounds=(np.log(A[k - 1]), np.log(A[k + 1])),
                                method="bounded", options={"xatol": 1e-13})
            ends.append(float(np.exp(r.x)))
    cuts = [A[0]] + ends + [A[-1]]
    out = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        inside = A[(A > lo) & (A < hi)]
        grid = np.concatenate([[lo], inside, [hi]])
        mg = Nmag(grid)
        ok = mg > 0
        if ok.sum() < 2:
            continue
        grid, mg = grid[ok], mg[ok]
        if np.all(np.diff(mg) > 0) or np.all(np.diff(mg) < 0):
            out.append((grid, mg))
        else:  # flat or noisy: keep the strictly monotone runs
            inc = np.diff(mg) > 0 if mg[-1] > mg[0] else np.diff(mg) < 0
            start = None
            for k, good in enumerate(list(inc) + [False]):
                if good and start is None:
                    start = k
                elif not good and start is not None:
                    if k - start >= 1:
                        out.append((grid[start:k + 1], mg[start:k + 1]))
                    start = None
    return out


def amplitude_roots(G, N, w_scan, A_scan):
    """Roots (A, w) of 1 + G(jw) N(A) = 0 with A within [A_scan[0], A_scan[-1]] and w within the scan.

    G: vectorised w -> G(jw); N: vectorised A -> N(A) (amplitude-only); both complex.
    """
    Nmag = lambda A: np.abs(N(A))  # noqa: E731
    g = G(w_scan)
    gm = np.abs(g)
    roots = []
    A_scan = np.asarray(A_scan, float)
    n_scan = N(A_scan)
    if np.all(np.abs(n_scan.imag) <= 1e-14 * np.abs(n_scan)):  # real N: phase crossovers first, then A
        return _real_roots(G, N, w_scan, A_scan)
    for grid, mg in _pieces(Nmag, np.asarray(A_scan, float)):
        inc = mg[-1] > mg[0]
        lo_m, hi_m = (mg[0], mg[-1]) if inc else (mg[-1], mg[0])
        target = 1.0 / gm
        ok = (target > lo_m) & (target < hi_m)
        if not ok.any():
            continue
        la, lm = np.log(grid), np.log(mg)
        if not inc:
            la, lm = la[::-1], lm[::-1]
        A_w = np.full(w_scan.size, np.nan)
        A_w[ok] = np.exp(np.interp(np.log(target[ok]), lm, la))

        def A_of(w, g_abs):
            t = 1.0 / g_abs
            f = lambda x: np.log(Nmag(np.array([np.exp(x)]))[0]) - np.log(t)  # noqa: E731
            return float(np.exp(brentq(f, np.log(grid[0]), np.log(grid[-1]), xtol=1e-15, rtol=1e-15)))

        # the scan reads arg N interpolated (in ln A) from the piece's own samples: N may cost ms per amplitude
        ph = np.unwrap(np.angle(N(grid)))
        h = np.full(w_scan.size, np.nan)
        h[ok] = np.angle(-g[ok] * np.exp(1j * np.interp(np.log(A_w[ok]), np.log(grid), ph)))
        idx = np.flatnonzero(ok[:-1] & ok[1:] & (np.sign(h[:-1]) != np.sign(h[1:]))
                             & (np.abs(h[:-1]) < 1.0) & (np.abs(h[1:]) < 1.0))

        def h_exact(w):
            gg = G(np.array([w]))[0]
            A = A_of(w, abs(gg))
            return float(np.angle(-gg * N(np.array([A]))[0]))

        seen = set()
        for k in idx:
            # the interpolated phase only says where to look: bracket with the exact phase at nearby scan points
            ks = [j for j in range(k - 3, k + 5) if 0 <= j < w_scan.size and ok[j]]
            hs = []
            for j in ks:
                try:
                    hs.append(h_exact(w_scan[j]))
                except ValueError:  # the magnitude root left the piece at an end
                    hs.append(np.nan)
            for (j0, h0), (j1, h1) in zip(zip(ks, hs), zip(ks[1:], hs[1:])):
                if j1 != j0 + 1 or (j0 in seen) or not (abs(h0) < 1.0 and abs(h1) < 1.0) or np.sign(h0) == np.sign(h1):
                    continue
                seen.add(j0)
                w = brentq(h_exact, w_scan[j0], w_scan[j1], xtol=1e-15 * w_scan[j0], rtol=1e-15)
                roots.append((A_of(w, abs(G(np.array([w]))[0])), float(w)))
    return sorted(roots, key=lambda r: (r[1], r[0]))


def _real_roots(G, N, w_scan, A_scan):
    """Real N: G(jw) must be real, Im G = 0 (brentq on the scan), then N(A) = -1/G(w) on each monotone piece."""
    g = G(w_scan)
    roots = []
    im = g.imag
    for k in np.flatnonzero(np.sign(im[:-1]) != np.sign(im[1:])):
        if abs(g[k].imag) > abs(g[k].real) or abs(g[k + 1].imag) > abs(g[k + 1].real):
            continue  # a sign change of Im G through a pole or far from the real axis
        w = brentq(lambda x: G(np.array([x]))[0].imag, w_scan[k], w_scan[k + 1], xtol=1e-15 * w_scan[k], rtol=1e-15)
        gw = G(np.array([w]))[0].real
        target = -1.0 / gw
        f = lambda x: N(np.array([np.exp(x)]))[0].real - target  # noqa: E731
        vals = N(A_scan).real - target
        idx = np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)
        for j in idx:
            roots.append((float(np.exp(brentq(f, np.log(A_scan[j]), np.log(A_scan[j + 1]), xtol=1e-15, rtol=1e-15))),
                          float(w)))
    return sorted(roots, key=lambda r: (r[1], r[0]))


def composite_roots(G, G_lin, N_s, w_scan, X_scan, F_window):
    """Roots (F, w) of 1 + G(jw) G_lin(jw) N_s(|G_lin(jw)| F) = 0 (F within F_window) from the amplitude-only
    problem in X = |G_lin| F with the plant G G_lin."""
    GG = lambda w: G(w) * G_lin(w)  # noqa: E731
    out = []
    for X, w in amplitude_roots(GG, N_s, w_scan, X_scan):
        F = X / abs(G_lin(np.array([w]))[0])
        if F_window[0] <= F <= F_window[1]:
            out.append((F, w))
    return out


def match(reference, found, rtol=1e-6):
    """(misses, extras): reference roots with no found root within rtol (relative, A and w), and vice versa."""
    def close(p, q):
        return abs(p[0] / q[0] - 1) <= rtol and abs(p[1] / q[1] - 1) <= rtol

    misses = [r for r in reference if not any(close(r, f) for f in found)]
    extras = [f for f in found if not any(close(r, f) for r in reference)]
    return misses, extras
