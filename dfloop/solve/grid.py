"""The solver's grid, chosen from G and N themselves so that no root can fall between samples.

Every grid axis is refined until the complex logarithm of the factor it carries (G along ln w, an
amplitude-only N along ln A) changes by at most ``STEP`` within each interval. Each interval then carries
a bound ``eps`` on |ln f(x) - ln f(x_left)| for all x in it, and a grid cell (i, j) can hold a root of
1 + G N only if ln(N_i G_j) lies within eps_a[i] + eps_v[j] of j pi (mod 2 pi j): every other cell is
excluded by that certificate, so its winding number is exactly 0 (see ``_kernels.candidate_cells``).

- Rational G (tf, ss): the bound is exact, from the poles and zeros (:meth:`Plant.log_variation`).
- Callable or frd G, and N along A: sampled. Each interval is checked at its midpoint and at its golden
  section point; it is split while the path through either point is longer than ``STEP``. This is the
  aliasing check: a phase that turns by 2 pi k (+ a little) between two samples shows half-steps of
  pi k, which wrap to a small step when k is even, but golden-section steps of 2 pi k 0.382.., which do
  not wrap to a small step for any k below ~10 (and for no k at all twice in a row as the interval is
  halved). The bound is the longer of the two paths.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .._checks import memory_limit
from .plant import Plant

__all__ = ["STEP", "FD_MIN_WIDTH", "BYTES_PER_POINT", "resolve_plant", "resolve_sampled", "check_memory", "clog",
           "largest_step"]

STEP = 0.35
"""Largest change of the complex log of G (or N) allowed within one grid interval (|d ln| = |d ln|f|| + phase)."""
_GOLDEN = 0.3819660112501051
_MAX_ROUNDS = 64  # halvings of an interval; with the minimum width below, never reached on finite windows
_MIN_WIDTH = 1e-13  # intervals narrower than this (log units, relative to 1 + |x|) are not split (a jump)
FD_MIN_WIDTH = 1e-6  # the same for a frequency-dependent N, whose jumps move with the amplitude
_MAX_POINTS = 2_000_000  # nodes per axis
BYTES_PER_POINT = {False: 48, True: 160}
"""Upper bounds on the solver's peak memory per grid point (bytes), for an amplitude-only N (False) and a
frequency-dependent N (True). Measured peaks (tracemalloc, tests/test_memory_bounds.py): ~23 and ~129: the
amplitude-only solver works on the candidate cells and the products of two vectors, a frequency-dependent one
on the whole tensor grid (G N, 1 + G N, phases, refinement masks, windings, tangent seeds)."""


def check_memory(na: int, nv: int, frequency_dependent: bool = False) -> None:
    """Raise ValueError, before anything is allocated, when the work arrays of an na x nv grid exceed the
    memory bound; the message gives the estimate and the knobs."""
    need = BYTES_PER_POINT[bool(frequency_dependent)] * na * nv
    limit = memory_limit()
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


def _dlog(l1: np.ndarray, l0: np.ndarray) -> np.ndarray:
    """|ln f1 - ln f0| with the phase difference wrapped to (-pi, pi]; inf when one side is 0, 0 when both."""
    with np.errstate(invalid="ignore"):
        dre = l1.real - l0.real
        dim = np.angle(np.exp(1j * (l1.imag - l0.imag)))
        d = np.hypot(np.where(np.isnan(dre), 0.0, dre), dim)
    return d


def _too_many(n: int, name: str) -> None:
    if n > _MAX_POINTS:
        raise RuntimeError(f"resolving {name} needs more than {_MAX_POINTS} grid points; narrow the window "
                           f"(the factor turns faster than the grid can follow)")


def resolve_sampled(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, name: str, step: float = STEP,
                    min_width: float = 1e-13):
    """Refine the sorted nodes x (log units) until ln f is resolved by sampling; see the module notes.

    ``f(exp(x))`` returns an array of shape (len(x),) or (len(x), m) (m functions resolved together;
    eps is then the largest over them). Intervals narrower than ``min_width`` (relative to 1 + |x|),
    and intervals with f = 0 at an end (the edge of a dead band, which no refinement resolves), are not
    split. Returns (nodes, f at nodes, eps per interval, number of evaluations).
    """
    x = np.asarray(x, float)
    fx = f(np.exp(x))
    lx = clog(fx)
    done_x, done_f, done_eps = [x[:1]], [fx[:1]], [np.empty(0)]
    x0, x1, l0, l1, f1 = x[:-1], x[1:], lx[:-1], lx[1:], fx[1:]
    n_eval = x.size
    for _ in range(_MAX_ROUNDS):
        if x0.size == 0:
            break
        dx = x1 - x0
        xm, xg = x0 + 0.5 * dx, x0 + _GOLDEN * dx
        fs = f(np.exp(np.concatenate([xm, xg])))
        n_eval += fs.size
        fm, fg = fs[:x0.size], fs[x0.size:]
        lm, lg = clog(fm), clog(fg)
        m1, m2, g1, g2 = _dlog(lm, l0), _dlog(l1, lm), _dlog(lg, l0), _dlog(l1, lg)
        eps = np.maximum(m1 + m2, g1 + g2)
        if eps.ndim > 1:  # several functions sampled together (rows of a frequency-dependent N)
            eps = eps.max(axis=1)
        split = np.isfinite(eps) & (eps > step) & (dx > min_width * (1 + np.abs(x0)))
        keep = ~split
        done_x.append(x1[keep])
        done_f.append(f1[keep])
        done_eps.append(eps[keep])
        # split intervals: [x0, xm] and [xm, x1]
        x0, x1 = np.concatenate([x0[split], xm[split]]), np.concatenate([xm[split], x1[split]])
        l0, l1 = np.concatenate([l0[split], lm[split]]), np.concatenate([lm[split], l1[split]])
        f1 = np.concatenate([fm[split], f1[split]])
        _too_many(sum(a.size for a in done_x) + x0.size, name)
    else:
        raise RuntimeError(f"resolving {name} did not settle within {_MAX_ROUNDS} halvings")
    # nodes: the first one plus the right end of every accepted interval; eps follows the right ends
    xs, fs_, es = np.concatenate(done_x), np.concatenate(done_f), np.concatenate(done_eps)
    order = np.argsort(xs[1:], kind="stable") + 1
    return np.concatenate([xs[:1], xs[order]]), np.concatenate([fs_[:1], fs_[order]]), es[order - 1], n_eval


def resolve_plant(plant: Plant, v: np.ndarray, step: float = STEP):
    """Frequency nodes (ln w) resolving G: exact bound for rational G, sampled otherwise.

    Returns (nodes, G at nodes, eps per interval, number of evaluations of G).
    """
    if not plant.exact:
        return resolve_sampled(plant, v, "G along omega", step)
    v = np.asarray(v, float)
    done_x, done_eps = [v[:1]], [np.empty(0)]
    x0, x1 = v[:-1], v[1:]
    for _ in range(_MAX_ROUNDS):
        if x0.size == 0:
            break
        eps = plant.log_variation(np.exp(x0), np.exp(x1))
        split = (eps > step) & (x1 - x0 > _MIN_WIDTH * (1 + np.abs(x0)))
        done_x.append(x1[~split])
        done_eps.append(eps[~split])
        xm = 0.5 * (x0[split] + x1[split])
        x0, x1 = np.concatenate([x0[split], xm]), np.concatenate([xm, x1[split]])
        _too_many(sum(a.size for a in done_x) + x0.size, "G along omega")
    else:
        raise RuntimeError(f"resolving G did not settle within {_MAX_ROUNDS} halvings")
    xs, es = np.concatenate(done_x), np.concatenate(done_eps)
    order = np.argsort(xs[1:], kind="stable") + 1
    nodes = np.concatenate([xs[:1], xs[order]])
    return nodes, plant(np.exp(nodes)), es[order - 1], nodes.size


def largest_step(eps: np.ndarray, step: float = STEP) -> float:
    """The largest interval bound among the resolved intervals (those left above ``step`` are jumps)."""
    ok = eps[eps <= step]
    return float(ok.max()) if ok.size else 0.0
