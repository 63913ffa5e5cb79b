"""Curves for plots: breaks at jumps (located by bisection, not bridged by a line) and direction arrows."""
from __future__ import annotations

from typing import Callable

import numpy as np

_WINDOW = 9  # neighbours whose smallest step sets the local scale
_SUSPECT_RATIO = 4.0  # a step this many times the local scale is bisected
_MAX_PASSES = 8  # bound on search passes (an interval may hold several jumps: one is found per pass)
_MAX_HALVINGS = 60  # bound on bisection steps per suspect interval (machine resolution comes first)
_JUMP_SHRINK = 1e-6  # a step that keeps this fraction of its size after full bisection is a jump
_ARROW_POINTS = 18.0  # arrow length on screen (points)


def _local_min(d: np.ndarray) -> np.ndarray:
    """Smallest step among each step's neighbours (window _WINDOW): the local scale of a smooth stretch,
    kept small even where several neighbouring steps are jumps (a branch that switches back and forth)."""
    half = _WINDOW // 2
    padded = np.pad(d, half, mode="edge")
    return np.min(np.lib.stride_tricks.sliding_window_view(padded, _WINDOW), axis=-1)


def locate_jumps(f: Callable[[np.ndarray], np.ndarray], t: np.ndarray, z: np.ndarray):
    """Discontinuities of a curve z = f(t) sampled at increasing ``t``.

    Steps much larger than the smallest of their neighbours' are bisected (vectorised over all of them),
    keeping the half with the larger step, until the bracket reaches machine resolution in ``t``: a
    continuous curve's step shrinks to nothing there (it is dropped once below a millionth of its size), a
    jump keeps its size. NaN separators in ``t`` are skipped.

    Returns
    -------
    (index, t_left, z_left, t_right, z_right) : arrays
        For each jump, the sample interval [t[index], t[index + 1]] that holds it and the two sides of the
        final bracket (the curve's one-sided values at the jump, to machine resolution in ``t``).
    """
    finite = np.isfinite(z) & np.isfinite(t)
    ok = finite[:-1] & finite[1:]
    with np.errstate(invalid="ignore"):  # inf - inf between two points outside N's domain
        d = np.where(ok, np.abs(np.diff(z)), 0.0)
        scale = np.maximum(np.abs(z[:-1]), np.abs(z[1:]))  # local: -1/N may run off towards infinity elsewhere
    d_ok = np.where(ok, d, np.inf)  # gaps do not set the local scale
    idx = np.flatnonzero(ok & (d > _SUSPECT_RATIO * _local_min(d_ok)) & (d > 1e-12 * scale))
    lo, hi, zlo, zhi = t[idx].astype(float), t[idx + 1].astype(float), z[idx], z[idx + 1]
    alive = np.ones(idx.size, bool)
    for _ in range(_MAX_HALVINGS):
        mid = 0.5 * (lo + hi)
        with np.errstate(invalid="ignore"):
            alive &= ~(np.abs(zhi - zlo) <= _JUMP_SHRINK * d[idx])  # continuous here: stop refining
        active = alive & (mid > lo) & (mid < hi)
        if not np.any(active):
            break
        zm = np.asarray(f(mid[active]), dtype=complex)
        left = np.abs(zm - zlo[active]) >= np.abs(zhi[active] - zm)
        a = np.flatnonzero(active)
        hi[a[left]], zhi[a[left]] = mid[active][left], zm[left]
        lo[a[~left]], zlo[a[~left]] = mid[active][~left], zm[~left]
    jump = ~(np.isfinite(zlo) & np.isfinite(zhi)) | (np.abs(zhi - zlo) > _JUMP_SHRINK * d[idx])
    return idx[jump], lo[jump], zlo[jump], hi[jump], zhi[jump]


def curve_with_gaps(f: Callable[[np.ndarray], np.ndarray], t) -> tuple[np.ndarray, np.ndarray]:
    """Samples of z = f(t) ready to draw: NaN where z is not finite and a NaN gap at every jump.

    Each side of a jump is drawn up to the jump itself (its located position), so the gap is as narrow as
    the discontinuity and no line segment bridges it.

    Returns
    -------
    (t, z) : numpy.ndarray
        The parameter and complex values, with the inserted points and NaN separators.
    """
    t = np.asarray(t, dtype=float)
    z = np.asarray(f(t), dtype=complex)
    for _ in range(_MAX_PASSES):
        idx, t_l, z_l, t_r, z_r = locate_jumps(f, t, z)
        if not idx.size:
            break
        t = np.insert(t, np.repeat(idx + 1, 3), np.column_stack([t_l, np.full(idx.size, np.nan), t_r]).ravel())
        z = np.insert(z, np.repeat(idx + 1, 3),
                      np.column_stack([z_l, np.full(idx.size, np.nan), z_r]).ravel())
    return t, np.where(np.isfinite(z), z, complex(np.nan, np.nan))


def add_direction_arrow(ax, z: np.ndarray, color, *, gid: str = "dfloop-direction"):
    """An arrow along the drawn curve ``z`` (ordered by the increasing parameter) at its middle visible point.

    Returns the annotation, or None when no stretch of the curve is visible in the current view.
    """
    pts = np.column_stack([z.real, z.imag])
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    visible = np.isfinite(pts).all(axis=1) & (pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1)
    idx = np.flatnonzero(visible)
    if idx.size < 2:
        return None
    screen = ax.transData.transform(np.where(np.isfinite(pts), pts, 0.0))
    length = _ARROW_POINTS * ax.figure.dpi / 72.0
    for i in idx[np.argsort(np.abs(idx - idx[idx.size // 2]))]:  # from the middle outwards
        run = np.arange(i + 1, pts.shape[0])
        run = run[: np.argmax(~visible[run]) if np.any(~visible[run]) else run.size]
        far = run[np.linalg.norm(screen[run] - screen[i], axis=1) >= length]
        if far.size:
            j = far[0]
            return ax.annotate("", xy=tuple(pts[j]), xytext=tuple(pts[i]), gid=gid,
                               arrowprops=dict(arrowstyle="-|>", color=color, lw=1.2, shrinkA=0, shrinkB=0))
    return None
