"""Numeric describing function of any static function or rate-independent hysteretic operator.

The input x = A sin(theta) is split into monotone branches (one for a static function, rising and falling
for a hysteretic operator). On a branch the output is a piecewise-smooth function g(theta); the switching
instants (jumps of g or of its slope) are located, not sampled: user-supplied breakpoints are mapped to
phases exactly (theta = asin(b / A)), and any others are detected on a sampling grid by high-order finite
differences and then bisected to machine precision in theta. Each smooth piece is integrated with
Gauss-Legendre quadrature (spectral convergence; pieces are halved adaptively until two levels agree),
giving the fundamental

    N(A) = (1 / (pi A)) [ int g sin(theta) dtheta + j int g cos(theta) dtheta ]   over one period.
"""
from __future__ import annotations

import copy
from typing import Callable

import numpy as np

from .._checks import amplitude_array, flag, in_closed_interval, integer_at_least, real_array, show, text
from ..errors import DfloopError
from ..progress import progress_bar
from .base import DescribingFunction
from .static import StaticElement
from .time_model import Sampled, fresh_copy, static_model

__all__ = ["NumericDF"]

_EPS = np.finfo(float).eps
_DIFF_ORDER = 6  # order of the finite differences that flag non-smooth cells
_FLAG_RATIO = 50.0  # a cell is flagged when its difference exceeds this multiple of its neighbours' median
_MAX_HALVINGS = 80  # bound on bisection steps (machine precision is reached in about 55)
_WINDOW = 2 * _DIFF_ORDER + 1
_SUB_SAMPLES = 32  # detection grid inside a bracket, on each side of the singularity found there
_MAX_NESTING = 3  # levels of that nested search
_MAX_LEVELS = 64  # bound on adaptive halvings of a quadrature piece
_MAX_PIECES = 8192  # bound on pieces under refinement per branch
_MAX_NODES = 1024  # Gauss-Legendre nodes per piece (building the rule is O(nodes^3))
_MAX_SAMPLES = 2**16  # detection cells per branch (or samples per period for method="sampled")
_CHUNK_VALUES = 2**21  # amplitudes are evaluated in chunks of about this many samples (work arrays stay small)
_HYSTERETIC_CHUNK = 8  # amplitudes per chunk for an operator (a Python loop: ~5-25 ms per amplitude)
_A_RANGE = (1e-250, 1e250)  # amplitudes computed: below, A sin t underflows; above, element arithmetic overflows


def _median_filter(d: np.ndarray) -> np.ndarray:
    """Running median over the last axis (window _WINDOW, edges padded by reflection)."""
    half = _WINDOW // 2
    padded = np.pad(d, [(0, 0), (half, half)], mode="reflect")
    windows = np.lib.stride_tricks.sliding_window_view(padded, _WINDOW, axis=-1)
    return np.median(windows, axis=-1)


def _flag_brackets(grid: np.ndarray, g: np.ndarray):
    """Brackets (row, theta_lo, theta_hi) each containing one jump or kink of g, from samples on ``grid``.

    A singularity inside a cell makes the _DIFF_ORDER-th differences of every stencil covering that cell
    stand out from their neighbours (smooth parts give O(h^p)); the intersection of a run of flagged
    stencils, widened by one sample on each side, brackets it.
    """
    p = _DIFF_ORDER
    d = np.abs(np.diff(g, n=p, axis=-1))
    scale = np.max(np.abs(g), axis=-1, keepdims=True)
    noise = (2.0**p) * 64.0 * _EPS * scale
    flagged = (d > _FLAG_RATIO * _median_filter(d)) & (d > noise)
    edges = np.diff(flagged.astype(np.int8), axis=-1, prepend=0, append=0)
    rows, starts = np.nonzero(edges == 1)
    _, ends = np.nonzero(edges == -1)
    ends = ends - 1  # last flagged stencil of each run
    lo_idx = ends - 1
    hi_idx = starts + p + 1
    merged = lo_idx >= hi_idx  # two singularities within one stencil: bracket the union
    lo_idx = np.where(merged, starts - 1, lo_idx)
    hi_idx = np.where(merged, ends + p + 1, hi_idx)
    last = grid.shape[-1] - 1
    lo_idx = np.clip(lo_idx, 0, last)
    hi_idx = np.clip(hi_idx, 0, last)
    return rows, grid[rows, lo_idx], grid[rows, hi_idx]


def _bisect(evaluate, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray, tol: float) -> np.ndarray:
    """Locate one jump or kink of g in each bracket [lo, hi] to within ``tol`` (vectorised over brackets).

    Each step samples the bracket at 9 equispaced points (5 reused, 4 new) and keeps whichever of the
    three half-width windows [0, 4], [2, 6], [4, 8] (in eighths) has the largest 4th difference: a jump
    keeps its size there, a kink shrinks like the width, smooth curvature like its 4th power, so the
    choice stays right even where g is strongly curved. A kink closer than a quarter-width to the
    midpoint is strictly inside the centred window. When no window shows more than rounding noise the
    singularity (a kink, then) is at the bracket's centre to well within the integration tolerance.
    """
    frac = np.linspace(0.0, 1.0, 9)
    l, r = lo.astype(float).copy(), hi.astype(float).copy()
    g = evaluate(rows, l[:, None] + (r - l)[:, None] * frac)
    coeffs = np.array([1.0, -4.0, 6.0, -4.0, 1.0])
    for _ in range(_MAX_HALVINGS):
        active = (r - l) > tol
        if not np.any(active):
            return 0.5 * (l + r)
        ia = np.nonzero(active)[0]
        ga = g[ia]
        windows = np.stack([ga[:, 0:5], ga[:, 2:7], ga[:, 4:9]], axis=1)  # (k, 3, 5)
        d4 = np.abs(windows @ coeffs)
        noise = 256.0 * _EPS * np.max(np.abs(ga), axis=1)
        best = np.argmax(d4, axis=1)
        quiet = np.max(d4, axis=1) <= noise
        best = np.where(quiet, 1, best)
        new_l = l[ia] + (r[ia] - l[ia]) * (best / 4.0)
        new_r = new_l + 0.5 * (r[ia] - l[ia])
        kept = np.take_along_axis(windows, best[:, None, None], axis=1)[:, 0, :]  # points 0, 2, 4, 6, 8
        mids = new_l[:, None] + (new_r - new_l)[:, None] * frac[1::2]
        g_mid = evaluate(rows[ia], mids)
        g_new = np.empty_like(ga)
        g_new[:, 0::2], g_new[:, 1::2] = kept, g_mid
        g[ia] = g_new
        l[ia], r[ia] = new_l, new_r
        done = ia[quiet]
        l[done] = r[done] = 0.5 * (l[done] + r[done])
    raise RuntimeError(f"switching-instant bisection hit its bound of {_MAX_HALVINGS} halvings")


def _locate(evaluate, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray, samples: int, tol: float, depth: int):
    """Switching phases of g on the intervals [lo, hi] (one per entry of ``rows``): (rows, phases).

    Detects on a grid of ``samples`` cells, bisects each bracket, then looks again inside each bracket on
    both sides of what it found (a finer grid), so that singularities closer than a grid cell are found
    too; ``depth`` bounds this nesting.
    """
    grid = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, samples + 1)
    k, b_lo, b_hi = _flag_brackets(grid, evaluate(rows, grid))
    if k.size == 0:
        return rows[:0], lo[:0]
    found = _bisect(evaluate, rows[k], b_lo, b_hi, tol)
    out_rows, out_phases = [rows[k]], [found]
    if depth > 0:
        margin = 4.0 * tol
        sub_lo = np.concatenate([b_lo, found + margin])
        sub_hi = np.concatenate([found - margin, b_hi])
        keep = (sub_hi - sub_lo) > 64.0 * margin
        if np.any(keep):
            sub_rows = np.concatenate([rows[k], rows[k]])[keep]
            r2, p2 = _locate(evaluate, sub_rows, sub_lo[keep], sub_hi[keep], _SUB_SAMPLES, tol, depth - 1)
            out_rows.append(r2)
            out_phases.append(p2)
    return np.concatenate(out_rows), np.concatenate(out_phases)


def _gauss_legendre(evaluate, rows, a, b, xi, w):
    """Gauss-Legendre integrals of g sin and g cos over the pieces [a, b] (one per entry of rows), and
    the rounding floor of those sums: g is perturbed by the input's rounding, eps |x| |dg/dx| with
    x = A sin t, i.e. eps |tan t| |dg/dt| (estimated from neighbouring nodes), plus eps |g|."""
    half, mid = 0.5 * (b - a), 0.5 * (a + b)
    theta = mid[:, None] + half[:, None] * xi
    g = evaluate(rows, theta)
    wg = half[:, None] * w * g
    slope = np.zeros_like(g)
    if xi.size > 2:  # at interior nodes, the smaller one-sided slope: a jump between nodes does not count
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.nan_to_num(np.abs(np.diff(g, axis=1) / np.diff(theta, axis=1)), posinf=0.0)
        slope[:, 1:-1] = np.minimum(d[:, :-1], d[:, 1:])
    floor = np.sum(half[:, None] * w * _EPS * (np.abs(g) + np.abs(np.tan(theta)) * slope), axis=1)
    return np.sum(wg * np.sin(theta), axis=1), np.sum(wg * np.cos(theta), axis=1), floor


def _adaptive_pieces(evaluate, R: int, rows, a, b, nodes: int, rtol: float):
    """Sum over pieces of int g sin and int g cos per row, each piece halved until its two halves agree
    with the whole to ``rtol`` times the row's int |g| sin-and-cos weighted sum, or to the rounding floor
    of the integrand (smooth pieces pass at once, a missed jump costs one halving per bit). Returns
    (I_sin, I_cos, error bound) per row."""
    xi, w = np.polynomial.legendre.leggauss(nodes)
    c_sin, c_cos, _ = _gauss_legendre(evaluate, rows, a, b, xi, w)
    scale = np.bincount(rows, np.abs(c_sin) + np.abs(c_cos), minlength=R)
    tol = rtol * scale[rows] + np.finfo(float).tiny
    i_sin, i_cos, err = np.zeros(R), np.zeros(R), np.zeros(R)
    for _ in range(_MAX_LEVELS):
        m = 0.5 * (a + b)
        l_sin, l_cos, l_floor = _gauss_legendre(evaluate, rows, a, m, xi, w)
        r_sin, r_cos, r_floor = _gauss_legendre(evaluate, rows, m, b, xi, w)
        f_sin, f_cos = l_sin + r_sin, l_cos + r_cos
        diff = np.abs(f_sin - c_sin) + np.abs(f_cos - c_cos)
        ok = diff <= np.maximum(tol, 16.0 * (l_floor + r_floor))
        np.add.at(i_sin, rows[ok], f_sin[ok])
        np.add.at(i_cos, rows[ok], f_cos[ok])
        np.add.at(err, rows[ok], diff[ok])
        if np.all(ok):
            return i_sin, i_cos, err
        bad = ~ok
        if np.max(np.bincount(rows[bad], minlength=R)) > _MAX_PIECES // 2:
            raise RuntimeError(
                f"adaptive quadrature exceeded its bound of {_MAX_PIECES} pieces per branch "
                "(noisy output or many unresolved jumps: supply breakpoints or raise rtol)"
            )
        rows, tol = np.repeat(rows[bad], 2), np.repeat(tol[bad], 2)
        a, b = np.stack([a[bad], m[bad]], 1).ravel(), np.stack([m[bad], b[bad]], 1).ravel()
        c_sin = np.stack([l_sin[bad], r_sin[bad]], 1).ravel()
        c_cos = np.stack([l_cos[bad], r_cos[bad]], 1).ravel()
    raise RuntimeError(
        f"adaptive quadrature hit its bound of {_MAX_LEVELS} halvings (unresolved jumps: supply breakpoints)"
    )


def _branch_integrals(evaluate, lo, hi, fixed, nodes: int, samples: int, locate: bool, rtol: float):
    """Integrals of g sin(theta) and g cos(theta) over [lo, hi] for each row (one row per branch), and
    an error bound. ``evaluate(rows, theta)`` returns g at theta (shape (len(rows), m)); ``fixed`` holds
    known switching phases per row (shape (R, F); entries outside [lo, hi] are clipped: empty pieces)."""
    R = lo.shape[0]
    cuts = [np.clip(fixed, lo[:, None], hi[:, None])]
    if locate:
        tol = 2.0 * _EPS * float(np.max(hi - lo))
        rows, found = _locate(evaluate, np.arange(R), lo, hi, samples, tol, _MAX_NESTING)
        if rows.size:
            order = np.argsort(rows, kind="stable")
            rows, found = rows[order], found[order]
            rank = np.arange(rows.size) - np.searchsorted(rows, rows)
            located = np.repeat(lo[:, None], int(rank.max()) + 1, axis=1)
            located[rows, rank] = found
            cuts.append(located)
    bounds = np.sort(np.concatenate([lo[:, None], *cuts, hi[:, None]], axis=1), axis=1)
    rows = np.repeat(np.arange(R), bounds.shape[1] - 1)
    return _adaptive_pieces(evaluate, R, rows, bounds[:, :-1].ravel(), bounds[:, 1:].ravel(), nodes, rtol)


class NumericDF(DescribingFunction):
    """Describing function computed numerically from a static function or a hysteretic operator.

    Parameters
    ----------
    element : callable
        Either a vectorised static function ``y = f(x)`` (numpy in, numpy out), or, with
        ``hysteretic=True``, a stateful rate-independent operator ``op(x) -> y`` at rest (e.g.
        ``Backlash(h).operator()`` or python-control's ``friction_backlash_nonlinearity``); it is
        deep-copied, never mutated. A :class:`StaticElement` is taken as its ``output`` with its
        ``breakpoints``; any other :class:`DescribingFunction` as its ``operator()``.
    hysteretic : bool
        Treat ``element`` as a stateful operator (default: False, True for a non-static DescribingFunction).
    breakpoints : array_like or callable, optional
        Input levels where f or its slope jumps (static functions only); each level b is used as +b and
        -b. A callable is called with the largest amplitude, ``breakpoints(A_max)`` (e.g.
        ``Quantizer.breakpoints``). Worth supplying when there are many (a quantizer at large amplitude).
    nodes : int
        Gauss-Legendre nodes per smooth piece (>= 2).
    samples : int
        Cells of the detection grid per branch (>= 16); for ``method="sampled"`` the samples per period.
    locate : bool, optional
        Detect and bisect switching instants (default: only when no breakpoints are given). Without it,
        only the adaptive halving of pieces resolves unlisted jumps, one halving per bit.
    rtol : float
        Each quadrature piece is halved until its halves agree with it to ``rtol`` times int |y|.
    method : {"pieces", "sampled"}
        ``"pieces"`` (located switching instants, Gauss-Legendre per piece) or ``"sampled"``: plain uniform
        sampling of one period with ``samples`` points and the first DFT bin (the benchmark's baseline).
    input_name, input_unit : str
        Name and unit of the input amplitude.

    Notes
    -----
    Static functions: N = (2 / (pi A)) int_{-pi/2}^{pi/2} f(A sin t) sin t dt (real; any single-valued f,
    odd or not), vectorised over amplitudes. Hysteretic operators, per amplitude (a Python loop: the
    operator is scalar): a warm-up from rest over 3/4 of a period (x from 0 up to A and down to -A), then
    the rising and falling branches; a branch's output at any phase comes from a copy of the state at the
    branch start fed the branch's monotone input (rate independence), so switching instants can be
    bisected. The operator must come back to the same state after the measured period (checked;
    ``ValueError`` otherwise). Limits: a numeric DF has none, so A = 0 and A = inf raise ``ValueError``
    (:class:`dfloop.errors.DfloopError`), as does any A outside [1e-250, 1e250] (there the samples A sin t
    underflow, or the element's arithmetic overflows) and an element whose output is not finite along the
    sinusoid; NaN entries give NaN. Near a dead-band edge
    (A = edge (1 + e)) the DF's relative condition number is ~1/e: the element's own rounding of
    x = A sin t then limits agreement to a few eps / e.
    Measured cost per amplitude on the dev machine (``python benchmarks/bench_numeric_df.py``, 2 shared
    cores, 16 nodes, times vary ~2x between runs): static f with breakpoints ~0.16 ms for 6-7 amplitudes
    per call, 0.009 ms each for 2000 amplitudes in one call; static f with located switching points ~3 ms;
    Python operators 6 ms (backlash) to 22 ms (relay), to 1e-13 relative or better, where uniform sampling
    with 2^16 points reaches 6e-6 (backlash) in ~400 ms.
    """

    def __init__(
        self,
        element: Callable,
        *,
        hysteretic: bool | None = None,
        breakpoints=None,
        nodes: int = 16,
        samples: int = 128,
        locate: bool | None = None,
        rtol: float = 1e-14,
        method: str = "pieces",
        input_name: str = "A",
        input_unit: str = "",
    ):
        hysteretic = flag("hysteretic", hysteretic, none=True)
        if isinstance(element, StaticElement) and not hysteretic:
            breakpoints = element.breakpoints if breakpoints is None else breakpoints
            element = element.output
        elif isinstance(element, DescribingFunction):
            element = element.operator()
            hysteretic = True if hysteretic is None else hysteretic
        if not callable(element):
            raise DfloopError(f"element must be callable, got {element!r} ({type(element).__name__})")
        self.element = element
        self.hysteretic = bool(hysteretic)
        if breakpoints is not None and self.hysteretic:
            raise DfloopError(f"breakpoints apply to static functions only (hysteretic=True given), got "
                              f"breakpoints={breakpoints!r}")
        self.breakpoints = breakpoints
        nodes = integer_at_least("nodes", nodes, 2)
        if nodes > _MAX_NODES:  # the Gauss-Legendre rule costs O(nodes^3) to build: 4096 nodes take ~20 s
            raise DfloopError(f"nodes must be <= {_MAX_NODES} (Gauss-Legendre nodes per piece; pieces are halved "
                              f"adaptively instead), got {nodes!r}")
        samples = integer_at_least("samples", samples, 16)
        if samples > _MAX_SAMPLES:
            raise DfloopError(f"samples must be <= {_MAX_SAMPLES} (cells of the detection grid per branch), got "
                              f"{samples!r}")
        if method not in ("pieces", "sampled"):
            raise DfloopError(f"method must be 'pieces' or 'sampled', got {method!r}")
        self.rtol = in_closed_interval("rtol", rtol, 1e-16, 1e-2)
        if breakpoints is not None and not callable(breakpoints):
            levels = real_array(breakpoints, "breakpoints")
            if not np.all(np.isfinite(levels)):
                raise DfloopError(f"breakpoints must be finite, got {show(breakpoints)}")
        locate = flag("locate", locate, none=True)
        self.locate = breakpoints is None if locate is None else locate
        self.nodes, self.samples, self.method = int(nodes), int(samples), method
        self.input_name, self.input_unit = text("input_name", input_name), text("input_unit", input_unit)

    @property
    def continuous(self) -> bool:
        """Whether N is known to be continuous: for a static f (a bounded f(A sin t) moves its average
        continuously with A); a hysteretic operator may switch on at a non-zero fundamental (a jump)."""
        return not self.hysteretic

    def time_model(self, amplitude: float):
        """A static f: piecewise affine between its breakpoints or smooth; a hysteretic operator with its own
        ``time_model`` (the relay and play operators): that; any other operator:
        :class:`~dfloop.describing.time_model.Sampled` (fixed step)."""
        name = type(self).__name__
        if not self.hysteretic:
            return static_model(self.element, self.breakpoints, name, amplitude)
        own = getattr(self.element, "time_model", None)
        if callable(own):
            return own(amplitude, name)
        return Sampled(name, fresh_copy(self.element))

    # ------------------------------------------------------------------------------------ evaluation

    def _evaluate(self, A, omega):
        return self._compute(A)[0]

    def error_estimate(self, A, omega=None) -> np.ndarray:
        """Bound on |N - exact| from the adaptive quadrature (sum of |halves - whole| over accepted
        pieces, scaled like N); NaN for ``method="sampled"``, which has no estimate."""
        return self._compute(amplitude_array(A, self.input_name))[1]

    def _compute(self, A: np.ndarray):
        n_out = np.full(A.shape, complex(np.nan, np.nan))
        e_out = np.full(A.shape, np.nan)
        ok = ~np.isnan(A)
        a = A[ok]
        lo, hi = _A_RANGE
        outside = (a < lo) | (a > hi)
        if np.any(outside):
            bad = float(a[outside][0])  # a plain float: its repr is the number
            raise DfloopError(
                f"{self.input_name} (amplitude) must lie in [{lo:g}, {hi:g}] for NumericDF, got {bad!r}: a numeric "
                "DF has no limit at 0 or infinity (an analytic element gives it), and beyond this range the "
                f"samples {self.input_name} sin(t) underflow or the element's arithmetic overflows"
            )
        if a.size:
            n, e = self._chunked(a)
            self._finite(np.column_stack([n.real, n.imag, e if self.method == "pieces" else 0 * n.real]), a)
            n_out[ok], e_out[ok] = n, e
        return n_out, e_out

    def _chunked(self, a: np.ndarray):
        """(N, error bound) over the amplitudes ``a``, in chunks: the work arrays of one chunk stay near
        ``_CHUNK_VALUES`` samples whatever the number of amplitudes, and a long computation (an operator over
        many amplitudes: a Python loop) shows progress after a second."""
        compute = self._hysteretic if self.hysteretic else self._static
        size = _HYSTERETIC_CHUNK if self.hysteretic else max(1, _CHUNK_VALUES // (self.samples + 1))
        if a.size <= size:
            return compute(a)
        n, e = np.empty(a.size, complex), np.empty(a.size)
        kind = "hysteretic" if self.hysteretic else "static"
        with progress_bar(f"NumericDF ({kind}): {a.size} amplitudes", a.size) as bar:
            for i in range(0, a.size, size):
                n[i:i + size], e[i:i + size] = compute(a[i:i + size])
                bar.update(min(size, a.size - i))
        return n, e

    def _fixed_phases(self, a: np.ndarray) -> np.ndarray:
        if self.breakpoints is None:
            return np.empty((a.size, 0))
        levels = self.breakpoints(float(a.max())) if callable(self.breakpoints) else self.breakpoints
        levels = np.asarray(levels, dtype=float).ravel()
        if not np.all(np.isfinite(levels)):
            raise DfloopError(f"breakpoints must be finite, got {levels[~np.isfinite(levels)][0]!r}")
        levels = np.concatenate([levels, -levels])
        return np.arcsin(np.clip(levels[None, :] / a[:, None], -1.0, 1.0))

    def _static(self, a: np.ndarray):
        f = self.element

        def evaluate(rows, theta):
            return self._finite(np.asarray(f(a[rows][:, None] * np.sin(theta)), dtype=float).reshape(theta.shape),
                                a[rows])

        if self.method == "sampled":
            theta = 2.0 * np.pi * np.arange(self.samples) / self.samples
            y = evaluate(np.arange(a.size), np.broadcast_to(theta, (a.size, theta.size)))
            return (2.0 * np.mean(y * np.sin(theta), axis=1)) / a, np.full(a.size, np.nan)
        lo, hi = np.full(a.size, -0.5 * np.pi), np.full(a.size, 0.5 * np.pi)
        i_sin, _, err = _branch_integrals(
            evaluate, lo, hi, self._fixed_phases(a), self.nodes, self.samples, self.locate, self.rtol
        )
        return (2.0 / np.pi) * (i_sin / a), (2.0 / np.pi) * (err / a)  # pi a would overflow near 1e308

    def _finite(self, values: np.ndarray, amplitudes: np.ndarray) -> np.ndarray:
        """``values`` (one row per amplitude), raising DfloopError naming the amplitude where one is not finite."""
        bad = ~np.isfinite(values)
        if np.any(bad):
            row = int(np.argwhere(bad)[0][0])
            raise DfloopError(
                f"the element's output is not finite along {self.input_name} sin(t) at {self.input_name} = "
                f"{float(amplitudes[row])!r}: NumericDF needs an element with finite output at that amplitude"
            )
        return values

    def _branch_states(self, A: float):
        """Operator states at the start of the rising (x = -A) and falling (x = +A) branches, after a
        warm-up from rest over 3/4 of a period; checks that one more period reproduces the first."""
        op = copy.deepcopy(self.element)
        n = self.samples
        for t in np.linspace(0.0, 1.5 * np.pi, 3 * n // 4 + 1):  # warm-up: 0 -> A -> -A
            op(A * np.sin(t))
        states = [op]
        for lo in (-0.5 * np.pi, 0.5 * np.pi):
            nxt = copy.deepcopy(states[-1])
            for t in np.linspace(lo, lo + np.pi, n + 1):
                nxt(A * np.sin(t))
            states.append(nxt)
        self._check_periodic(states[0], states[2], A)
        return states[:2]

    def _sampled_operator(self, A: float) -> complex:
        """Baseline: warm-up, then the first DFT bin of ``samples`` uniform samples of one period."""
        op = copy.deepcopy(self.element)
        n = self.samples
        for t in np.linspace(0.0, 2.0 * np.pi, 5 * n // 4 + 1)[: 5 * n // 4]:  # 0 -> A -> -A -> 0
            op(A * np.sin(t))
        theta = 2.0 * np.pi * np.arange(n) / n
        y = np.array([op(A * np.sin(t)) for t in theta])
        return complex(2.0j * np.mean(y * np.exp(-1j * theta)) / A)

    def _hysteretic(self, a: np.ndarray):
        """(N, error bound) for each amplitude: both branches of every amplitude integrated together."""
        if self.method == "sampled":
            return np.array([self._sampled_operator(float(x)) for x in a]), np.full(a.size, np.nan)
        states = [s for x in a for s in self._branch_states(float(x))]  # row 2i: rising, 2i + 1: falling
        amp = np.repeat(a, 2)

        def evaluate(rows, theta):
            vals = np.empty(theta.shape)
            for i, (row, t) in enumerate(zip(rows, theta)):
                x = amp[row] * np.sin(t)
                if np.all(np.diff(t) >= 0):  # monotone along the branch: feed one copy in order
                    c = copy.deepcopy(states[row])
                    vals[i] = [c(v) for v in x]
                else:
                    vals[i] = [copy.deepcopy(states[row])(v) for v in x]
            return self._finite(vals, amp[rows])

        lo = np.tile([-0.5 * np.pi, 0.5 * np.pi], a.size)
        i_sin, i_cos, err = _branch_integrals(
            evaluate, lo, lo + np.pi, np.empty((lo.size, 0)), self.nodes, self.samples, self.locate, self.rtol
        )
        total = (i_sin + 1j * i_cos).reshape(-1, 2).sum(axis=1)
        return (total / a) / np.pi, (err.reshape(-1, 2).sum(axis=1) / a) / np.pi

    def _check_periodic(self, begin, end, A: float) -> None:
        """The state after the measured period must reproduce the rising branch of the period's start."""
        theta = np.linspace(-0.5 * np.pi, 0.5 * np.pi, self.samples + 1)
        b, e = copy.deepcopy(begin), copy.deepcopy(end)
        yb = np.array([b(A * np.sin(t)) for t in theta])
        ye = np.array([e(A * np.sin(t)) for t in theta])
        scale = max(np.max(np.abs(yb)), np.finfo(float).tiny)
        if np.max(np.abs(yb - ye)) > 1e-9 * scale:
            raise DfloopError(
                f"the operator is not periodic after one warm-up period at {self.input_name} = {A}: "
                "it is not a rate-independent hysteresis operator"
            )

    def __repr__(self) -> str:
        kind = "hysteretic" if self.hysteretic else "static"
        return (
            f"NumericDF({self.element!r}, {kind}, method={self.method!r}, nodes={self.nodes}, "
            f"samples={self.samples}, locate={self.locate}, rtol={self.rtol})"
        )
