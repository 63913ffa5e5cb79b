"""A closed-loop run of a digital loop: the exact map s_{k+1} = A s_k + B f(x_k), x_k = -C s_k, sample by sample.

A discrete-time plant (python-control, dt > 0; a continuous plant behind a zero-order hold, with or without a
delay: :func:`dfloop.hybrid.discrete.sample_delayed`) around a static element is a map, not a flow, so the
continuous engines cannot run it. :func:`discrete_simulation` iterates the map from the discrete harmonic-balance
state of a predicted cycle (the plant state whose samples are the predicted sinusoid's, the element replaced by its
DF), which is what :func:`dfloop.verify_cycle` runs from inside and outside a prediction. Exact: no step, no
interpolation; x and y are the samples.
"""
from __future__ import annotations

import math

import numpy as np

from ..describing.interop import as_element
from ..describing.time_model import PiecewiseAffine, Smooth
from .discrete import discrete_system, iterate
from .run import LoopSimulation

__all__ = ["discrete_simulation"]

METHOD = "digital loop: the exact map, one sample per step"


def _static_map(N, amplitude: float):
    """The element's static map f (vectorised), or ValueError naming N for an element with memory."""
    try:
        tm = N.time_model(amplitude)
    except NotImplementedError:
        tm = None
    if isinstance(tm, Smooth):
        return tm.f
    if isinstance(tm, PiecewiseAffine) and tm.n_states == 0 and all(m.ge == 0 and m.de == 0 for m in tm.modes):
        bounds = []
        for m in tm.modes:
            lo = max((-g.c1 / g.cx for g in m.guards if g.cx > 0), default=-math.inf)
            hi = min((-g.c1 / g.cx for g in m.guards if g.cx < 0), default=math.inf)
            bounds.append((lo, hi))
        bounds.sort()
        if all(a[1] <= b[0] + 1e-12 * max(1.0, abs(b[0])) for a, b in zip(bounds[:-1], bounds[1:])):   # no overlap
            return tm.response
    raise ValueError(f"N: {type(N).__name__} is not a static element (its output depends on its past, or it has "
                     "no time model): a run of a digital loop needs a static piecewise-affine or smooth element")


def discrete_simulation(G, N, amplitude: float, frequency: float, periods: float, *, r0: float = 0.0,
                        load: float = 0.0, bias: float = 0.0, diverge: float = 1e6) -> LoopSimulation:
    """Run the digital loop from the predicted cycle x_k = amplitude sin(frequency k dt).

    Parameters
    ----------
    G : discrete-time python-control tf or ss (strictly proper)
        The sampled loop (e.g. a scene's controller * plant behind the hold).
    N : DescribingFunction
        A static element (piecewise affine without memory, or smooth).
    amplitude, frequency : float
        The start (element input units, rad/s): the plant state is the discrete harmonic-balance state
        X = (e^{jw dt} I - A)^{-1} B N(amplitude) amplitude, s_0 = Im X.
    periods : float
        Length of the run in periods 2 pi / frequency (at least one sample).
    r0, load, bias : float
        Must be 0 (no constant input on a digital loop: ``ValueError`` naming the parameter).
    diverge : float
        The run stops when |x| exceeds ``diverge`` times the amplitude (``diverged`` is then True).

    Returns
    -------
    LoopSimulation
        t = k dt (s), the samples x_k and y_k.
    """
    for name, value in (("r0", r0), ("load", load), ("bias", bias)):
        if value != 0.0:
            raise ValueError(f"{name} must be 0 for a run of a digital loop (no constant input on a sampled loop), "
                             f"got {value!r}")
    A, B, C, dt = discrete_system(G, "simulate_loop")
    N = as_element(N)
    f = _static_map(N, amplitude)
    n = A.shape[0]
    X = np.linalg.solve(np.exp(1j * frequency * dt) * np.eye(n) - A, B) * complex(N(amplitude)) * amplitude
    steps = max(1, int(math.ceil(periods * 2.0 * math.pi / (frequency * dt))))
    s, xs, ys, done = X.imag.copy(), [], [], 0
    limit = diverge * amplitude
    diverged = False
    while done < steps and not diverged:   # blocks, so a divergent run stops early
        k = min(1024, steps - done)
        x, y, S = iterate(A, B, C, f, s, k)
        big = np.flatnonzero(~(np.abs(x) <= limit))
        if big.size:
            x, y, diverged = x[:big[0] + 1], y[:big[0] + 1], True
        xs.append(x), ys.append(y)
        s = A @ S[-1] + B * y[-1]
        done += k
    x, y = np.concatenate(xs), np.concatenate(ys)
    return LoopSimulation(np.arange(x.size) * dt, x, y, diverged, METHOD)
