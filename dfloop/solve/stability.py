"""Stability of a predicted limit cycle: the Loeb criterion and the classical graphical rule.

Loeb (docs/design.md section 1): with R = 1 + G(jw) N(A, w) = U + jV, a cycle at (A0, w0) is stable iff
U_A V_w - U_w V_A > 0. This is the sign of the Jacobian of (A, w) -> (U, V), i.e. the local degree.
Near-zero determinants (tangent / double roots) are reported as marginal instead of guessed.
"""
from __future__ import annotations

import numpy as np

from .roots import Residual

__all__ = ["loeb", "graphical_stability", "MARGINAL_TOL"]

MARGINAL_TOL = 1e-4
"""Conditioning 2 |det J| / |J|_F^2 (log coordinates) below which a cycle is called marginal."""


def loeb(res: Residual, a: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Loeb determinant U_A V_w - U_w V_A in natural units (per unit amplitude, per rad/s) and its
    conditioning 2 det J / |J|_F^2 in log coordinates a = ln A, v = ln w (= 2 s1 s2 / (s1^2 + s2^2)
    with s1, s2 the singular values of J; signed, in [-1, 1]), at log-coordinate points (a, v).
    """
    ra, rv = res.jacobian(np.asarray(a, float), np.asarray(v, float))
    det_log = ra.real * rv.imag - rv.real * ra.imag
    scale = 0.5 * (np.abs(ra) ** 2 + np.abs(rv) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(scale > 0, det_log / np.where(scale > 0, scale, 1.0), 0.0)
    return det_log / (np.exp(a) * np.exp(v)), cond


def graphical_stability(G, N, amplitude: float, frequency: float, step: float = 1e-6) -> bool:
    """Classical rule for amplitude-only N: the cycle is stable iff, at the intersection, the -1/N locus
    (increasing amplitude) leaves the region encircled by the Nyquist plot of G (increasing frequency),
    i.e. iff cross(dG/dw, d(-1/N)/dA) > 0 with cross(p, q) = Re p Im q - Im p Re q.

    ``G`` is a :class:`~dfloop.solve.plant.Plant` or anything :func:`as_plant` accepts.
    """
    from .plant import as_plant

    if N.frequency_dependent:
        raise ValueError("N must be amplitude-only for the graphical rule")
    g = as_plant(G)
    w, A = float(frequency), float(amplitude)
    dg = (g(np.array([w * (1 + step)])) - g(np.array([w * (1 - step)])))[0] / (2 * w * step)
    locus = -1.0 / N(np.array([A * (1 - step), A * (1 + step)]))
    dl = (locus[1] - locus[0]) / (2 * A * step)
    return bool(dg.real * dl.imag - dg.imag * dl.real > 0)
