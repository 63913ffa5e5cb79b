"""Compiled responses of the relay and play operators to sampled inputs (used by :mod:`dfloop.solve.confidence`).

Same switching rules as :class:`dfloop.describing.static.RelayOperator` and
:class:`dfloop.describing.static.PlayOperator`; one warm-up pass over the samples, then the recorded pass.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def relay_response(x, M, on, off):
    """Relay output for samples x of one period, in the periodic regime (after one warm-up period)."""
    state = 0
    out = np.empty(x.shape[0])
    for rep in range(2):
        for i in range(x.shape[0]):
            v = x[i]
            if state == 1 and v < off:
                state = -1 if v < -on else 0
            elif state == -1 and v > -off:
                state = 1 if v > on else 0
            elif state == 0:
                state = 1 if v > on else (-1 if v < -on else 0)
            out[i] = M * state
    return out


@njit(cache=True)
def play_response(x, h, k):
    """Play-operator output k c for samples x of one period, in the periodic regime (after one warm-up)."""
    c = 0.0
    half = 0.5 * h
    out = np.empty(x.shape[0])
    for rep in range(2):
        for i in range(x.shape[0]):
            v = x[i]
            if v - c > half:
                c = v - half
            elif v - c < -half:
                c = v + half
            out[i] = k * c
    return out
