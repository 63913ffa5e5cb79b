"""Closed-form pieces of the paper's two-mass motion, written in local time (JIT-compiled, also plain Python).

A flight starts at phase ``phi0 = w t0`` (mod 2 pi); ``theta = w s`` is the local phase after ``s`` seconds.
The forcing enters through

    shape(theta)  = cos(phi0) (1 - cos theta) + sin(phi0) (sin theta - theta)
    dshape(theta) = cos(phi0) sin theta - sin(phi0) (1 - cos theta)

so that a body of mass m driven by F cos(w t) moves as x0 + v0 s + F/(m w^2) shape, v0 + F/(m w) dshape.
Both are evaluated without cancellation for small theta (docs/design.md section 2: local time).
"""
from __future__ import annotations

import math

from numba import njit

TWO_PI = 2.0 * math.pi


@njit(cache=True, nogil=True)
def one_minus_cos(theta):
    """1 - cos(theta) without cancellation."""
    h = math.sin(0.5 * theta)
    return 2.0 * h * h


@njit(cache=True, nogil=True)
def sin_minus_x(theta):
    """sin(theta) - theta without cancellation (Taylor series for |theta| < 1)."""
    if abs(theta) >= 1.0:
        return math.sin(theta) - theta
    t2 = theta * theta
    term = -theta * t2 / 6.0
    total = term
    for k in range(2, 12):
        term *= -t2 / ((2 * k) * (2 * k + 1))
        total += term
    return total


@njit(cache=True, nogil=True)
def shape(c0, s0, theta):
    """cos(phi0)(1 - cos theta) + sin(phi0)(sin theta - theta)."""
    return c0 * one_minus_cos(theta) + s0 * sin_minus_x(theta)


@njit(cache=True, nogil=True)
def dshape(c0, s0, theta):
    """cos(phi0) sin theta - sin(phi0)(1 - cos theta): d(shape)/d(theta)."""
    return c0 * math.sin(theta) - s0 * one_minus_cos(theta)


@njit(cache=True, nogil=True)
def wrap_phase(phi):
    """phi reduced to [0, 2 pi)."""
    r = phi - TWO_PI * math.floor(phi / TWO_PI)
    if r >= TWO_PI:
        r -= TWO_PI
    return r
