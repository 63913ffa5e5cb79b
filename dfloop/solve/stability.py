"""Stability of a predicted limit cycle: the Loeb criterion and the classical graphical rule.

Loeb (docs/design.md section 1): with R = 1 + G(jw) N(A, w) = U + jV, a cycle at (A0, w0) is stable iff
U_A V_w - U_w V_A > 0. This is the sign of the Jacobian of (A, w) -> (U, V), i.e. the local degree.
Tangent / double roots are reported as marginal instead of guessed. The marginal test is scale-free: it uses
the sine of the angle between dR/d(ln A) and dR/d(ln w) (the angle at which the Nyquist curve of G crosses
the -1/N locus), which does not change when A, w, G or N are rescaled, nor with the damping of the plant.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .._checks import in_closed_interval, scale
from ..describing.interop import as_element
from .roots import Residual

__all__ = ["loeb", "classify", "label_roots", "graphical_stability", "MARGINAL_TOL"]

MARGINAL_TOL = 1e-4
"""|sin| of the crossing angle, det J / (|R_a| |R_w|), below which a cycle is called marginal."""


def loeb(res: Residual, a: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Loeb determinant U_A V_w - U_w V_A in natural units (per unit amplitude, per rad/s) and its
    conditioning det J / (|R_a| |R_v|) at log-coordinate points (a, v): the signed sine of the angle
    between the two columns of J (a = ln A, v = ln w), in [-1, 1], invariant under any rescaling of
    A, w, G and N, and 0 for a tangent (double) root.
    """
    a, v = np.asarray(a, float), np.asarray(v, float)
    return _loeb_from(a, v, *res.jacobian(a, v))


def _loeb_from(a, v, ra, rv):
    det_log = ra.real * rv.imag - rv.real * ra.imag
    scale = np.abs(ra) * np.abs(rv)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(scale > 0, det_log / np.where(scale > 0, scale, 1.0), 0.0)
    return det_log / (np.exp(a) * np.exp(v)), cond


def classify(res: Residual, a: np.ndarray, v: np.ndarray, marginal_tol: float = MARGINAL_TOL):
    """Loeb determinant, conditioning and label ("stable", "unstable", "marginal") of roots (a, v).

    The one marginal test of dfloop (:func:`label_roots` on the residual's slopes); see there.
    """
    return label_roots(res.slopes, a, v, marginal_tol)


def label_roots(slopes: Callable, a, v, marginal_tol: float = MARGINAL_TOL):
    """Loeb determinant, conditioning and label of roots (a, v) of R = 1 + P, given P's slopes.

    Shared by :func:`~dfloop.predict_limit_cycles` and :func:`~dfloop.continuation.sweep`, so that the two
    call a root marginal by the same rule.

    A root is marginal when its Loeb sign is not decided: the crossing angle's sine, det J / (|R_a| |R_w|),
    is below ``marginal_tol``, or the sign of the determinant changes within the root's position uncertainty
    (4 |R| / s_min(J) in log units along the Jacobian's weakest direction, which is how far the true
    root may lie; a tangent (double) root is found at a distance of that order, with a determinant of
    either sign). Both tests are invariant under rescaling A, w, G and N.

    Parameters
    ----------
    slopes : callable
        ``slopes(a, v) -> (P, dP/da, dP/dv)`` at 1-D arrays of log coordinates a = ln A, v = ln w
        (e.g. :meth:`dfloop.solve.roots.Residual.slopes`).
    a, v : array_like
        The roots, log coordinates (ln of N's input unit, ln rad/s).
    marginal_tol : float
        Bound on the crossing angle's sine below which a root is marginal.

    Returns
    -------
    det, cond : ndarray
        Loeb determinant in natural units (per unit amplitude, per rad/s) and the signed sine of the
        crossing angle.
    label : ndarray of str
        ``"stable"``, ``"unstable"`` or ``"marginal"``.
    """
    a, v = np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(v, float))
    P, ra, rv = slopes(a, v)
    det, cond = _loeb_from(a, v, ra, rv)
    jaa, jvv, jav = np.abs(ra) ** 2, np.abs(rv) ** 2, (ra.conj() * rv).real
    half_tr, dj = (jaa + jvv) / 2, jaa * jvv - jav ** 2
    s_min = np.sqrt(np.maximum(half_tr - np.sqrt(np.maximum(half_tr ** 2 - dj, 0)), 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        dx = np.minimum(np.where(s_min > 0, 4 * np.abs(1 + P) / s_min, np.inf), 1e-2)
    # weakest direction: eigenvector of J^T J for the smaller eigenvalue s_min^2
    ea, ev = jav, s_min ** 2 - jaa
    norm = np.hypot(ea, ev)
    flat = norm == 0
    ea, ev = np.where(flat, np.where(jaa <= jvv, 1.0, 0.0), ea), np.where(flat, np.where(jaa <= jvv, 0.0, 1.0), ev)
    norm = np.hypot(ea, ev)
    ea, ev = ea / norm, ev / norm
    k = a.size
    ap, vp = np.concatenate([a + dx * ea, a - dx * ea]), np.concatenate([v + dx * ev, v - dx * ev])
    d_pm, _ = _loeb_from(ap, vp, *slopes(ap, vp)[1:])
    d_plus, d_minus = d_pm[:k], d_pm[k:]
    undecided = (np.sign(d_plus) != np.sign(det)) | (np.sign(d_minus) != np.sign(det))
    label = np.where((np.abs(cond) < marginal_tol) | undecided, "marginal", np.where(det > 0, "stable", "unstable"))
    return det, cond, label


def graphical_stability(G, N, amplitude: float, frequency: float, step: float = 1e-6) -> bool:
    """Classical rule for amplitude-only N: the cycle is stable iff, at the intersection, the -1/N locus
    (increasing amplitude) leaves the region encircled by the Nyquist plot of G (increasing frequency),
    i.e. iff cross(dG/dw, d(-1/N)/dA) > 0 with cross(p, q) = Re p Im q - Im p Re q.

    ``G`` is a :class:`~dfloop.solve.plant.Plant` or anything :func:`as_plant` accepts; ``step`` is the
    relative step of the central differences in w and A, in [1e-12, 0.5] (w (1 - step) and A (1 - step) stay
    positive).
    """
    from .plant import as_plant

    N = as_element(N)
    if N.frequency_dependent:
        raise ValueError("N must be amplitude-only for the graphical rule")
    g = as_plant(G)
    w, A = scale("frequency", frequency), scale("amplitude", amplitude)
    step = in_closed_interval("step", step, 1e-12, 0.5)
    dg = (g(np.array([w * (1 + step)])) - g(np.array([w * (1 - step)])))[0] / (2 * w * step)
    locus = -1.0 / N(np.array([A * (1 - step), A * (1 + step)]))
    dl = (locus[1] - locus[0]) / (2 * A * step)
    return bool(dg.real * dl.imag - dg.imag * dl.real > 0)
