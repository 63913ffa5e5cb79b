"""``predict_limit_cycles``: all roots of 1 + G(jw) N(A, w) = 0 in an (A, w) window, with stability."""
from __future__ import annotations

import dataclasses
import functools
import math
import warnings

import numpy as np

from .._checks import finite, integer_at_least, memory_limit, window as checked_window
from ..describing.base import DescribingFunction
from ..describing.interop import as_element
from ..describing.static import StaticElement
from ._kernels import candidate_cells
from .compiled import (driver_parts, driver_wanted, enabled as compiled_enabled, mode as compiled_mode, residual_for,
                       run_batch, run_driver)
from .grid import FD_MIN_WIDTH, STEP, check_memory, clog, largest_step, resolve_plant, resolve_sampled
from .plant import as_plant
from .result import DeferredReport, GridReport, JumpCrossing, LimitCycle, LimitCycles, assembled
from .roots import (JUMP_BOX, OuterProduct, Residual, accepted, dominant_steps, find_roots, greedy_unique,
                    unresolved_boxes)
from .stability import MARGINAL_TOL, classify

__all__ = ["predict_limit_cycles", "predict_chunk"]

_MAX_REFINE_ROUNDS = 30
_MAX_GRID = 1_000_000  # points per axis of the initial grid
_MIN_LOG_STEP = 1e-6  # grid intervals narrower than this (in ln A or ln w) are not split further
_FD_ROWS = 16  # amplitudes (frequencies) at which a frequency-dependent N is resolved along w (A)
_PHASE_STEP = np.pi / 3  # max turn of arg(G N) between neighbours (frequency-dependent N)
_NEAR_UNIT = math.log(20.0)  # "near 1": 1/20 <= |G N| <= 20


def _grid_size(grid, frequency_dependent: bool, limit: int | None = None) -> tuple[int, int]:
    """(n_amplitudes, n_frequencies) of ``grid``, checked (``limit``: the memory bound in bytes, when already read)."""
    if type(grid) is tuple and len(grid) == 2:  # the common case (two plain ints in range): no conversions
        na, nw = grid
        if type(na) is int and type(nw) is int and 2 <= na <= _MAX_GRID and 2 <= nw <= _MAX_GRID:
            check_memory(na, nw, frequency_dependent, limit)
            return na, nw
    try:
        pair = tuple(grid)
    except TypeError:
        pair = ()
    if len(pair) != 2 or any(isinstance(x, (str, bytes)) for x in pair):
        raise ValueError(f"grid must be a pair (n_amplitudes, n_frequencies); got {grid!r}")
    na, nw = (integer_at_least(f"grid[{i}] ({what})", x, 2) for i, (x, what) in
              enumerate(zip(pair, ("amplitudes", "frequencies"))))  # 2.5, inf, NaN, True: a ValueError
    if na > _MAX_GRID or nw > _MAX_GRID:
        raise ValueError(f"grid sizes must lie in [2, {_MAX_GRID}]; got {grid!r}")
    check_memory(na, nw, frequency_dependent, limit)
    return na, nw


def _amplitude_domain(N, v: np.ndarray) -> tuple[float, float, float]:
    """(smallest lower end, largest upper end, largest lower end) of N's amplitude domain over the nodes v."""
    if N.frequency_dependent:
        lo, hi = N.amplitude_domain(np.exp(v))
    else:
        lo, hi = N.amplitude_domain()
    return float(np.min(lo)), float(np.max(hi)), float(np.max(lo))


_REACH_GRID = np.logspace(-300, 300, 12001)  # amplitudes searched for the limit arguments (0.05 decades)


def _limit_reach(res: Residual, v: np.ndarray, eps_v: np.ndarray, end: str):
    """The amplitude beyond which (``end="inf"``) or below which (``end="zero"``) no root can lie, by the
    element's :meth:`tail_bound` / :meth:`head_bound`, or None when the element states no bound, or its limit
    there is 0 or infinite (then |N| alone limits the window), or G N(limit) reaches -1 in the window.

    A root at w needs |G(w)| |N - N_lim| >= |1 + G(w) N_lim(w)| (N_lim = N(inf, w) or N(0, w)), so the bound
    must reach r(w) = |1 + G N_lim| / |G| there. r is taken on the frequency nodes refined up to 64-fold, less
    what G can move between the fine nodes (|G(w) - G(w_k)| <= |G(w_k)| (e^eps - 1), eps the resolved bound on
    |d ln G| per interval over the refinement); half of the smallest r is required, for margin.
    """
    N = res.N
    bound = N.tail_bound if end == "inf" else N.head_bound
    if bound(np.ones(1)) is None:
        return None
    A_lim = np.inf if end == "inf" else 0.0
    try:  # a limit of 0 or inf is settled by |N| alone: nothing to compute (checked on the nodes first)
        n0 = N(np.full(v.shape, A_lim), np.exp(v)) if res.frequency_dependent else N(A_lim)
    except ValueError:
        return None
    if not (np.all(np.isfinite(n0)) and np.any(n0)):
        return None
    k = int(np.clip(200_000 // max(v.size, 1), 1, 64))
    t = np.linspace(0.0, 1.0, k, endpoint=False)
    vf = np.concatenate([(v[:-1, None] + np.diff(v)[:, None] * t[None, :]).ravel(), v[-1:]])
    w = np.exp(vf)
    n_lim = N(np.full(w.shape, A_lim), w) if res.frequency_dependent else n0
    g = res.plant(w)
    P = g * n_lim
    if not (np.all(np.isfinite(P)) and np.any(P)):
        return None
    finite_eps = eps_v[np.isfinite(eps_v)]
    slack = math.expm1((float(finite_eps.max()) if finite_eps.size else STEP) / k)
    room = np.abs(1 + P) - np.abs(P) * slack
    if not np.all(room > 0):
        return None
    r = float(np.min(room / (np.abs(g) * (1 + slack))))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        dev = bound(_REACH_GRID)
    if end == "inf":
        ok = np.flatnonzero(dev < 0.5 * r)
        return float(_REACH_GRID[ok[0]]) if ok.size else None
    ok = np.flatnonzero(~(dev < 0.5 * r))
    return float(_REACH_GRID[ok[0] - 1]) if ok.size and ok[0] > 0 else None


def _default_amplitude_window(res: Residual, v: np.ndarray, eps_v: np.ndarray, dom: tuple[float, float, float]):
    """Amplitudes where |G N| = 1 can hold for some w of the window (the only place for roots), within the
    reach of the element's limit arguments (:func:`_limit_reach`; docs/solver.md, "Default windows")."""
    lo, hi, lo_max = dom
    top, bottom = _limit_reach(res, v, eps_v, "inf"), _limit_reach(res, v, eps_v, "zero")
    if lo > 0:
        cand = lo * (1 + np.logspace(-9, 8, 171))
        if top is not None:  # up to the limit argument's reach
            cand = np.concatenate([cand, np.geomspace(lo, max(top, lo * 2), 200)])
        if lo_max > lo:  # a domain that moves with w (MassBacklash: h/2 m w^2): dense from each lower end on
            reach = top if top is not None else lo_max * 1e8
            cand = np.concatenate([cand, np.geomspace(lo, lo_max, 200), np.geomspace(lo_max, max(reach, lo_max * 2), 200)])
    else:
        cand = np.logspace(-30, 30, 601)
    if math.isfinite(hi):
        cand = np.concatenate([cand, hi * (1 - np.logspace(-9, -0.3, 88))])
    if top is not None:
        cand = np.concatenate([cand[cand < top], [top]])
    if bottom is not None:
        cand = np.concatenate([[bottom], cand[cand > bottom]])
    cand = np.unique(cand[(cand > lo) & (cand < hi)])
    if cand.size < 2:  # the limit arguments leave no amplitude of the domain for a root: a token window
        a0 = lo * (1 + 1e-9) if lo > 0 else (hi / 2 if math.isfinite(hi) else 1.0)
        a1 = min(hi * (1 - 1e-9), a0 * 2) if math.isfinite(hi) else a0 * 2
        return (float(a0), float(a1)), "default: no root possible by N's limits (a token window)"
    if res.frequency_dependent:
        sub = v[np.unique(np.linspace(0, v.size - 1, min(v.size, 2000)).astype(int))]
        P = res.grid(np.log(cand), sub)
        if not np.any(P):
            raise ValueError("N is zero everywhere in its amplitude domain: no limit cycle is possible")
        M = np.abs(P)
        band = np.any((M >= 0.5) & (M <= 2.0), axis=1)
        cross = np.any((M[1:] - 1) * (M[:-1] - 1) < 0, axis=1)
        varying = np.any(np.abs(np.diff(P, axis=0)) > 1e-9 * np.abs(P[:-1]), axis=1)
    else:  # |G N| = |N| |G| and |G| takes every value between its extremes over the window
        n = res.N(cand)
        if not np.any(n):
            raise ValueError("N is zero everywhere in its amplitude domain: no limit cycle is possible")
        g = np.abs(res.plant(np.exp(v)))
        g_lo, g_hi = g.min(), g.max()
        m = np.abs(n)
        band = (m * g_lo <= 2.0) & (m * g_hi >= 0.5)
        cross = (np.minimum(m[1:], m[:-1]) * g_lo <= 1.0) & (np.maximum(m[1:], m[:-1]) * g_hi >= 1.0)
        varying = np.abs(np.diff(n)) > 1e-9 * np.abs(n[:-1])
    rows = np.zeros(cand.size, bool)
    rows[:-1] |= (band[:-1] | cross) & varying
    rows[1:] |= (band[1:] | cross) & varying
    idx = np.flatnonzero(rows)
    limits = "; no root beyond A=%.3g by N's limit" % top if top is not None else ""
    limits += "; no root below A=%.3g by N's limit" % bottom if bottom is not None else ""
    if idx.size == 0:
        return (float(cand[0]), float(cand[-1])), f"default: N's amplitude domain (|G N| never reaches 1){limits}"
    i0, i1 = max(idx[0] - 2, 0), min(idx[-1] + 2, cand.size - 1)
    return ((float(cand[i0]), float(cand[i1])),
            f"default: where |G N| can reach 1 within N's amplitude domain{limits}")


_MAX_BREAKPOINTS = 200_000


def _breakpoints(N, A_lo: float, A_hi: float) -> np.ndarray:
    """The amplitudes inside (A_lo, A_hi) where a static element's f or its slope jumps (where N has a kink);
    empty for other elements or when there are more than ``_MAX_BREAKPOINTS`` (then sampling alone follows N)."""
    if not isinstance(N, StaticElement):
        return np.empty(0)
    step = getattr(N, "step", None)  # a quantizer: count its thresholds before asking for them
    if step is not None and A_hi / step > _MAX_BREAKPOINTS:
        return np.empty(0)
    bp = np.asarray(N.breakpoints(A_hi), float)
    return bp[(bp > A_lo) & (bp < A_hi)]


def _split_mask(P: np.ndarray, axis: int, x: np.ndarray) -> np.ndarray:
    """Intervals along ``axis`` where arg(G N) turns fast while |G N| is near 1 (jumps of N excepted)."""
    Pt = P if axis == 0 else P.T
    P0, P1 = Pt[:-1], Pt[1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        near = np.abs(np.log(np.abs(Pt))) < _NEAR_UNIT
        dph = np.where((P0 == 0) | (P1 == 0), 0.0, np.abs(np.angle(P1 * P0.conj())))
    # a full turn of R = 1 + G N between two samples would be invisible to the winding count;
    # entries where N = 0 (dead band) are skipped, and so are jumps of N, which no refinement resolves
    # (the winding machinery of roots.py handles them at a bounded resolution)
    bad = (near[:-1] | near[1:]) & (dph > _PHASE_STEP)
    cols = np.flatnonzero(bad.any(axis=0))
    if cols.size:
        bad[:, cols] &= ~dominant_steps(Pt[:, cols])
    return np.any(bad, axis=1) & (np.diff(x) > _MIN_LOG_STEP)


def _resolve_grid(res: Residual, a: np.ndarray, v: np.ndarray):
    """Refine a tensor grid whose v axis already resolves G, for a frequency-dependent N: G N sampled
    on the grid, intervals split where arg(G N) turns fast while |G N| is near 1 (bounded)."""
    for _ in range(_MAX_REFINE_ROUNDS):
        P = res.grid(a, v)
        split_a, split_v = _split_mask(P, 0, a), _split_mask(P, 1, v)
        if not (split_a.any() or split_v.any()):
            return a, v, P
        a = np.sort(np.concatenate([a, (a[:-1] + a[1:])[split_a] / 2]))
        v = np.sort(np.concatenate([v, (v[:-1] + v[1:])[split_v] / 2]))
        check_memory(a.size, v.size, True)
    raise RuntimeError(f"grid refinement did not settle within max_rounds={_MAX_REFINE_ROUNDS}")


def predict_limit_cycles(G, N, *, omega=None, amplitude=None, grid=(64, 256), tol: float = 1e-10,
                         marginal_tol: float = MARGINAL_TOL, exact: bool = False) -> LimitCycles:
    """Predict the limit cycles of the loop of the paper's Fig. 1 by the describing-function method.

    Solves 1 + G(jw) N(A, w) = 0 for all (A, w) in the window, refines each root to
    |1 + G N| <= tol (1 + |G N|) (or to the rounding of ln A, ln w where the root is steeper than that
    allows), and classifies it by the Loeb criterion. The grid is chosen from G and N themselves so
    that no root can fall between samples (docs/solver.md).

    Parameters
    ----------
    G : python-control tf, ss or frd (SISO), or callable
        The linear part (proper, not zero); a callable gets an array of frequencies (rad/s) and returns
        G(j omega) of the same shape, finite.
    N : DescribingFunction, python-control nonlinearity or static function
        The nonlinear element, amplitude-only or frequency-dependent. python-control's nonlinearity objects
        and plain functions f(x) are converted by :func:`dfloop.as_element`.
    omega : (float, float), optional
        Frequency window in rad/s. Default: two decades beyond the plant's poles and zeros, or the
        frd's own grid. Required for a callable G.
    amplitude : (float, float), optional
        Amplitude window (N's input unit). Default: the part of N's amplitude domain where |G N| can
        reach 1 for some frequency of the window. Clipped to N's amplitude domain.
    grid : (int, int)
        Initial log-spaced grid (amplitudes, frequencies). Each axis is then refined until ln G (along
        ln w; exactly from the poles and zeros for tf/ss, by sampling with an aliasing check otherwise)
        and ln N (along ln A) change by at most ``grid.STEP`` per interval; see ``.grid_report``.
    tol : float
        Residual tolerance relative to 1 + |G N|, in (0, 1e-3).
    marginal_tol : float
        Cycles whose crossing-angle sine (``loeb_conditioning``) is below this, or whose Loeb sign changes
        within their position uncertainty, are reported as marginal. In [0, 1).
    exact : bool
        Also find the true periodic orbit near each prediction (:func:`dfloop.exact_cycle`, attached as
        ``cycle.exact``). Every cycle carries ``cycle.confidence`` (cheap) whatever this says.

    Returns
    -------
    LimitCycles
        List of :class:`LimitCycle` sorted by frequency, with the windows used, the grid size, a
        :class:`GridReport` (``.grid_report``: how the grid was chosen) and ``jump_crossings``: places
        where G(jw) passes through the gap of a jump of -1/N (a winding of 1 + G N that comes from a
        discontinuity of N, not from a root; a warning names them). Roots where ``N.validity`` is False
        are kept with ``valid=False``.

    Raises
    ------
    ContinuumError
        (a ValueError) when 1 + G N = 0 along a whole curve (G lies on -1/N there); it names the
        amplitude and frequency ranges.
    ValueError
        For bad input: improper or zero G, a callable G of wrong shape or non-finite values, windows,
        grid sizes beyond memory, NaN or out-of-range tolerances.
    RuntimeError
        When a work bound is reached (the message says which window to narrow).

    Notes
    -----
    Discontinuities of N (regime jumps of a tabulated DF, N = 0 beyond a limit frequency) are resolved
    to a bounded size only: grid steps of G N that dominate their neighbours are not refined, edge
    bisection stops at 1e-9 (relative), and a winding box that shrinks to 1e-7 (relative) next to a
    discontinuity without a refinable root is a jump crossing. Roots are accepted only at a small
    residual, which a jump cannot fake.
    """
    N = as_element(N)
    if not isinstance(exact, (bool, np.bool_)):
        raise ValueError(f"exact must be True or False; got {exact!r}")
    if not (type(tol) is float and 0 < tol < 1e-3):  # a plain float in range passes as it is
        tol = finite("tol", tol)
        if not (0 < tol < 1e-3):
            raise ValueError(f"tol must lie in (0, 1e-3); got {tol}")
    if not (type(marginal_tol) is float and 0 <= marginal_tol < 1):
        marginal_tol = finite("marginal_tol", marginal_tol)
        if not (0 <= marginal_tol < 1):
            raise ValueError(f"marginal_tol must lie in [0, 1); got {marginal_tol}")
    limit = memory_limit()
    na, nw = _grid_size(grid, N.frequency_dependent, limit)
    if not exact:  # the common case end to end in one compiled call (solve/compiled/driver.py), where it applies
        result = _compiled_driver(G, N, omega, amplitude, na, nw, tol, marginal_tol, limit)
        if result is not None:
            return result
    plant = as_plant(G)
    res = residual_for(plant, N)  # compiled where G and N have compiled forms (solve/compiled)

    if omega is None:
        if plant.default_window is None:
            raise ValueError("omega window is required when G is a callable (no poles/zeros to choose it from)")
        w_lo, w_hi = plant.default_window
        w_src = _omega_window_reason(plant)
    else:
        w_lo, w_hi = checked_window("omega", omega)
        w_src = "given"
    if w_lo < plant.domain[0] * (1 - 1e-12) or w_hi > plant.domain[1] * (1 + 1e-12):
        raise ValueError(f"omega window ({w_lo:g}, {w_hi:g}) leaves the plant's frequency range {plant.domain}")
    plant(np.array([w_lo, w_hi]))  # input check before any work: NaN, a pole on the axis or overflow at the ends
    v_lo, v_hi = math.log(w_lo), math.log(w_hi)
    v = np.linspace(v_lo, v_hi, nw)
    if not plant.exact:  # rational plants need no hints: their grid is placed from the poles and zeros
        features = plant.feature_frequencies[(plant.feature_frequencies > w_lo) & (plant.feature_frequencies < w_hi)]
        v = np.unique(np.concatenate([v, np.log(features)]))
    v, g, eps_v, n_eval, uncertified = resolve_plant(plant, v)
    if not np.any(g):
        raise ValueError(f"G is zero at every frequency of the window ({w_lo:g}, {w_hi:g}) rad/s: no loop")

    dom = _amplitude_domain(N, v)
    if amplitude is None:
        # every node of G's resolved grid (|G| changes by at most a factor e^STEP between them, well inside
        # the band 1/2..2 used), so a narrow resonance peak is seen; a frequency-dependent N on a subset
        (A_lo, A_hi), a_src = _default_amplitude_window(res, v, eps_v, dom)
    else:
        A_lo, A_hi = checked_window("amplitude", amplitude)
        a_src = "given"
        dom = dom[:2]
        if A_lo <= dom[0]:
            A_lo, a_src = dom[0] * (1 + 1e-9), "given, clipped to N's amplitude domain"
        if A_hi >= dom[1]:
            A_hi, a_src = dom[1] * (1 - 1e-9), "given, clipped to N's amplitude domain"
        if A_lo >= A_hi:
            raise ValueError(f"amplitude window {tuple(amplitude)} lies outside N's amplitude domain {dom}")
    a = np.linspace(math.log(A_lo), math.log(A_hi), na)

    if res.frequency_dependent:
        # N turns along w too (a delay inside N): resolve G N along w at _FD_ROWS initial amplitudes, then
        # N along A at _FD_ROWS frequencies, then refine the tensor grid near |G N| = 1
        A0 = np.exp(a[np.unique(np.linspace(0, a.size - 1, min(a.size, _FD_ROWS)).astype(int))])
        v, _, eps_v, n_gn, _ = resolve_sampled(lambda w: res.plant(w)[:, None] * res._n(A0[None, :], w[:, None]),
                                               v, "G N along omega", min_width=FD_MIN_WIDTH, slopes=True)
        w_sub = np.exp(v[np.unique(np.linspace(0, v.size - 1, min(v.size, _FD_ROWS)).astype(int))])
        a, _, eps_a, n_n, _ = resolve_sampled(lambda A: res._n(A[:, None], w_sub[None, :]), a,
                                              "N along the amplitude", min_width=FD_MIN_WIDTH)
        n_eval += n_gn * A0.size + n_n * w_sub.size
        check_memory(a.size, v.size, True)
        a, v, P = _resolve_grid(res, a, v)
        cells, a_rule, n_cand, n = None, f"sampled at {w_sub.size} frequencies, then 2-D near |G N| = 1", None, None
    else:
        bp = _breakpoints(N, A_lo, A_hi)
        if bp.size:  # kinks of N (a quantizer's thresholds) as nodes: N is smooth between them
            a = np.unique(np.concatenate([a, np.log(bp)]))
        a, n, eps_a, n_n, _ = resolve_sampled(lambda A: res._n(A, None), a, "N along the amplitude", monotone=True)
        n_eval += n_n
        check_memory(a.size, v.size, False)
        P = OuterProduct(n, g)  # read at the candidate cells only: no na x nv array
        cells = candidate_cells(clog(n), eps_a, clog(g), eps_v)
        a_rule, n_cand = "sampled", int(cells[0].size)
    if not (np.any(n) if not res.frequency_dependent else np.any(P)):
        raise ValueError("N is zero everywhere in the amplitude window: no limit cycle is possible")
    w_rule = f"sampled (G N at {A0.size} amplitudes)" if res.frequency_dependent else (
        "exact" if plant.exact else "sampled")
    report = GridReport(shape=(a.size, v.size), frequency_rule=w_rule,
                        amplitude_rule=a_rule, max_step_frequency=largest_step(eps_v),
                        max_step_amplitude=largest_step(eps_a),
                        n_jumps=int(np.count_nonzero(eps_v > STEP) + np.count_nonzero(eps_a > STEP)),
                        candidate_cells=n_cand, n_evaluations=int(n_eval),
                        uncertified=tuple((float(np.exp(lo)), float(np.exp(hi))) for lo, hi in uncertified))
    window = (a[0], a[-1], v[0], v[-1])
    ra, rv, jumps = find_roots(res, a, v, P, tol, cells, None if res.frequency_dependent else (eps_a, eps_v))
    cycles, rejected = _build(res, ra, rv, window, marginal_tol, tol)
    report = dataclasses.replace(report, rejected=rejected)
    lost = unresolved_boxes(res, ra, rv)
    if lost:  # 1 + G N winds there but no root could be refined: say where (never silently dropped)
        warnings.warn(f"{len(lost)} place(s) where 1 + G N winds around 0 but no root could be refined: " + "; ".join(
            f"A in [{b[0]:.6g}, {b[1]:.6g}], omega in [{b[2]:.6g}, {b[3]:.6g}] rad/s" for b in lost[:3])
            + " (see .grid_report.uncertified)", stacklevel=2)
        report = dataclasses.replace(report, uncertified=report.uncertified + tuple(b[2:] for b in lost))
    crossings = _jump_crossings(res, jumps)
    if crossings:
        where = "; ".join(f"A={c.amplitude:.4g}, omega={c.frequency:.4g} rad/s" for c in crossings[:5])
        warnings.warn(f"{len(crossings)} jump crossing(s): G(jw) passes through the gap of a jump of -1/N at "
                      f"{where}{' ...' if len(crossings) > 5 else ''}; no limit cycle of the DF equation there "
                      "(see .jump_crossings)", stacklevel=2)
    cycles = _open_loop_label(plant, _attach_confidence(G, N, cycles, exact))
    result = LimitCycles(cycles, (A_lo, A_hi), (w_lo, w_hi), {"amplitude": a_src, "omega": w_src},
                         (a.size, v.size), res.n_points, crossings, report)
    result.plant, result.element = G, N
    return result


_LABELS = ("stable", "unstable", "marginal")  # the driver's label codes


def _driver_inputs(G, N, omega, amplitude, mode: str | None = None):
    """(parts, windows (w_lo, w_hi, A_lo, A_hi), amplitude source) of the loop for the compiled driver
    (solve/compiled/driver.py; NaN windows: the defaults), or None where it does not apply (``mode``: the value
    of ``DFLOOP_COMPILED`` when already read)."""
    parts = driver_parts(G, N, mode)
    if parts is None:
        return None
    w_lo = w_hi = A_lo = A_hi = math.nan
    if omega is not None:
        w_lo, w_hi = checked_window("omega", omega)
    a_src = None
    if amplitude is not None:
        A_lo, A_hi = checked_window("amplitude", amplitude)
        a_src = "given"
        dom = parts[1][5:7]
        if A_lo <= dom[0]:
            A_lo, a_src = dom[0] * (1 + 1e-9), "given, clipped to N's amplitude domain"
        if A_hi >= dom[1]:
            A_hi, a_src = dom[1] * (1 - 1e-9), "given, clipped to N's amplitude domain"
        if A_lo >= A_hi:
            return None  # the Python path says why
    return parts, (w_lo, w_hi, A_lo, A_hi), a_src


def _compiled_driver(G, N, omega, amplitude, na: int, nw: int, tol: float, marginal_tol: float, limit: int):
    """The result of the compiled driver where it applies and finishes; None otherwise (then the Python driver
    runs: the same algorithm, every branch). ``limit``: the memory bound in bytes."""
    mode = compiled_mode()  # the environment, read once for the call
    inputs = _driver_inputs(G, N, omega, amplitude, mode)
    if inputs is None or not driver_wanted(mode):
        return None
    parts, windows, a_src = inputs
    raw = run_driver(*parts, *windows, na, nw, tol, marginal_tol, limit)
    if raw[0] != 0:
        return None
    return _driver_result(G, N, raw[1], raw[2], raw[3], omega is not None, a_src)


def predict_chunk(loops, *, omega=None, amplitude=None, grid=(64, 256), tol: float = 1e-10,
                  marginal_tol: float = MARGINAL_TOL, exact: bool = False, errors=None) -> list:
    """:func:`predict_limit_cycles` for each loop (G, N) of ``loops``, with the same options: the loops the
    compiled driver applies to run in one call of it, shared among threads over the cores (:func:`.compiled.run_batch`),
    the others, and those it leaves to the Python driver, one by one. The results are the ones of
    ``predict_limit_cycles(G, N, ...)`` for each loop (the same code computes them).

    ``errors(index, exc)``, when given, is called for a loop that raises (and its result is None); by default
    the exception propagates.
    """
    loops = list(loops)
    out: list = [None] * len(loops)
    fast, where = [], []
    opts = dict(omega=omega, amplitude=amplitude, grid=grid, tol=tol, marginal_tol=marginal_tol, exact=exact)
    mode = compiled_mode()
    if not exact and isinstance(exact, (bool, np.bool_)) and compiled_enabled(mode):
        tol_c, mtol_c = finite("tol", tol), finite("marginal_tol", marginal_tol)
        if 0 < tol_c < 1e-3 and 0 <= mtol_c < 1:
            try:
                na, nw = _grid_size(grid, False)
            except ValueError:
                na = None
            for k, (G, N) in enumerate(loops):
                if na is None:
                    break
                try:
                    N = as_element(N)
                    inputs = _driver_inputs(G, N, omega, amplitude, mode)
                except ValueError:
                    inputs = None
                if inputs is not None:
                    fast.append((k, G, N, inputs))
    if fast:
        raw = run_batch([f[3][0] for f in fast], [f[3][1] for f in fast], na, nw, tol_c, mtol_c)
        status, fl, it, rows, count = raw
        for q, (k, G, N, inputs) in enumerate(fast):
            if status[q] == 0:
                out[k] = _driver_result(G, N, fl[q], it[q], rows[q, :count[q]], omega is not None, inputs[2])
                where.append(k)
    done = set(where)
    for k, (G, N) in enumerate(loops):
        if k in done:
            continue
        try:
            out[k] = predict_limit_cycles(G, N, **opts)
        except Exception as exc:  # noqa: BLE001 - handed to the caller's handler, or re-raised
            if errors is None:
                raise
            errors(k, exc)
    return out


@functools.lru_cache(maxsize=256)
def _default_omega_source(mag_lo: float, mag_hi: float) -> str:
    """How the default frequency window was chosen, from the smallest and largest |pole/zero| (remembered: a
    plant's text is the same every call)."""
    if not math.isfinite(mag_lo):
        return "default: G has no pole or zero off the origin: 0.01-100 rad/s"
    at = f"{mag_lo:.3g}" if f"{mag_lo:.3g}" == f"{mag_hi:.3g}" else f"{mag_lo:.3g}..{mag_hi:.3g}"
    return f"default: 2 decades beyond G's poles/zeros at {at} rad/s, where G's phase and slope have settled"


def _driver_result(G, N, fl, it, rows, w_given: bool, a_src) -> LimitCycles:
    """LimitCycles from the compiled driver's output (floats fl, ints it, root rows; see driver._drive)."""
    A_lo, A_hi, w_lo, w_hi, top, bottom, step_v, step_a, mag_lo, mag_hi = fl.tolist()
    case, n_a, n_v, n_jumps, n_cand, n_eval, n_points, rejected, real_unstable = it.tolist()
    if a_src is None:
        limits = "; no root beyond A=%.3g by N's limit" % top if top == top else ""
        limits += "; no root below A=%.3g by N's limit" % bottom if bottom == bottom else ""
        a_src = (f"default: where |G N| can reach 1 within N's amplitude domain{limits}" if case == 0 else
                 f"default: N's amplitude domain (|G N| never reaches 1){limits}")
    w_src = "given" if w_given else _default_omega_source(mag_lo, mag_hi)
    cycles = []
    for A, w, det, cond, label, r, rel, g, n, edge in rows.tolist():
        A, w, label = A.real, w.real, _LABELS[int(label.real)]
        if edge.real:
            warnings.warn(f"limit cycle at A={A:.6g}, omega={w:.6g} rad/s lies on the edge of the search "
                          "window; widen the window to confirm it", stacklevel=4)
        if real_unstable and label == "stable":
            label = LOEB_ONLY
        cycles.append(assembled(LimitCycle, amplitude=A, frequency=w, stability=label, residual=r.real,
                                relative_residual=rel.real, loeb_determinant=det.real, loeb_conditioning=cond.real,
                                G=g, N=n, on_edge=bool(edge.real),
                                _confidence=functools.partial(_confidence, G, N, A, w)))
    report = DeferredReport(((n_a, n_v), step_v, step_a, n_jumps, n_cand, n_eval, rejected))
    result = LimitCycles(cycles, (A_lo, A_hi), (w_lo, w_hi), {"amplitude": a_src, "omega": w_src}, (n_a, n_v),
                         n_points, (), report)
    result.plant, result.element = G, N
    return result


LOEB_ONLY = "loeb-stable only"
"""The label of a Loeb-stable cycle of a loop whose plant has unstable real (non-oscillatory) poles."""


def _open_loop_label(plant, cycles: list[LimitCycle]) -> list[LimitCycle]:
    """Relabel Loeb-stable cycles of a plant with unstable real poles.

    The Loeb criterion sees perturbations of the oscillation's amplitude and frequency only; a real open-loop
    pole in the right half-plane is a non-oscillatory mode (a drift, a bias) it cannot see, and such loops can
    diverge from both sides of a Loeb-stable cycle. Their "stable" becomes ``LOEB_ONLY`` unless the exact orbit
    (``exact=True``) was found: then its Floquet multipliers decide ("stable" or "unstable"). Callable and frd
    plants have no known poles: their labels are the Loeb criterion's.
    """
    if plant.roots is None or not cycles:
        return cycles
    poles = plant.roots[1]
    if not np.any((poles.real > 0) & (np.abs(poles.imag) <= 1e-9 * np.abs(poles))):
        return cycles
    out = []
    for c in cycles:
        if c.stability == "stable":
            ex = c.exact
            label = (("stable" if ex.stable else "unstable") if ex is not None and ex.success else LOEB_ONLY)
            c = dataclasses.replace(c, stability=label)
        out.append(c)
    return out


def _attach_confidence(G, N, cycles: list[LimitCycle], exact: bool) -> list[LimitCycle]:
    """Every cycle with its confidence (computed on first access) and, when asked, its exact orbit."""
    from .engines import exact_engine

    def checked(c):   # a loop without an exact engine: the cycle is "not checked", with the reason
        exact_cycle, not_checked = exact_engine()
        try:
            return exact_cycle(G, N, c)
        except ValueError as exc:
            return not_checked(f"not checked: {exc}", (c.amplitude, c.frequency))

    return [dataclasses.replace(c, _confidence=functools.partial(_confidence, G, N, c.amplitude, c.frequency),
                                exact=checked(c) if exact else None) for c in cycles]


def _confidence(G, N, amplitude: float, frequency: float):
    """cycle_confidence, or an unavailable Confidence that says why it could not be computed."""
    from .confidence import cycle_confidence, unavailable

    try:
        return cycle_confidence(G, N, amplitude, frequency)
    except ValueError as exc:
        return unavailable(str(exc))


def _jump_crossings(res: Residual, jumps: np.ndarray) -> list[JumpCrossing]:
    """JumpCrossing objects from rows (a, v, winding) of :func:`find_roots`; N on each side of the jump
    is read at the corners (+-JUMP_BOX / 2 in log units) with the smallest and largest arg(1 + G N)."""
    out = []
    h = JUMP_BOX / 2
    for a, v, wind in jumps:
        ca, cv = a + np.array([-h, h, h, -h]), v + np.array([-h, -h, h, h])
        A, w = np.exp(ca), np.exp(cv)
        n = res.N(A, w) if res.frequency_dependent else res.N(A)
        g = res.plant(w)
        ph = np.angle((1 + g * n) / (1 + g[0] * n[0]))
        lo, hi = int(np.argmin(ph)), int(np.argmax(ph))
        out.append(JumpCrossing(amplitude=float(np.exp(a)), frequency=float(np.exp(v)), resolution=JUMP_BOX,
                                winding=int(wind), G=complex(res.plant(np.array([np.exp(v)]))[0]),
                                N_sides=(complex(n[lo]), complex(n[hi]))))
    return out


def _build(res: Residual, ra, rv, bounds, marginal_tol, tol) -> tuple[list[LimitCycle], int]:
    """The LimitCycle objects of refined roots (ra, rv), and how many points failed the residual bound.

    Every returned cycle satisfies :func:`roots.residual_bound` (checked here, centrally, on fresh values of
    G and N, whatever path found it); a point that does not is dropped and counted (``GridReport.rejected``).
    """
    if ra.size == 0:
        return [], 0
    P, P_a, P_v = res.slopes(ra, rv)
    good = accepted(P, P_a, P_v, ra, rv, tol)
    rejected = int(np.count_nonzero(~good))
    ra, rv = ra[good], rv[good]
    if ra.size == 0:
        return [], rejected
    det, cond, label = classify(res, ra, rv, marginal_tol)
    # a double root may be reached from several seeds: merge marginal roots closer than 1e-4 (log units)
    keep = np.ones(ra.size, bool)
    marg = np.flatnonzero(label == "marginal")
    if marg.size > 1:
        keep[marg] = False
        keep[marg[greedy_unique(ra[marg], rv[marg], 0.5e-4)]] = True
    ra, rv, det, cond, label = ra[keep], rv[keep], det[keep], cond[keep], label[keep]
    A, w = np.exp(ra), np.exp(rv)
    g, n = res.factors(ra, rv)
    wf = w if res.frequency_dependent else None
    own = type(res.N)
    # the protocol's defaults (finite means valid, closed forms are exact) need no second evaluation of N
    valid = np.broadcast_to(np.isfinite(n) if own.validity is DescribingFunction.validity
                            else res.N.validity(A, wf), A.shape)
    err = np.broadcast_to(np.zeros(A.shape) if own.error_estimate is DescribingFunction.error_estimate
                          else res.N.error_estimate(A, wf), A.shape)
    err = np.where(np.isnan(err), np.inf, err)  # an element without an estimate: unknown, not NaN
    a_lo, a_hi, v_lo, v_hi = bounds
    edge_tol = 1e-9
    on_edge = ((np.abs(ra - a_lo) <= edge_tol) | (np.abs(ra - a_hi) <= edge_tol)
               | (np.abs(rv - v_lo) <= edge_tol) | (np.abs(rv - v_hi) <= edge_tol))
    out = []
    for k in np.lexsort((A, np.round(rv, 10))):  # by frequency; equal ones (to 1e-10) by amplitude
        if on_edge[k]:
            warnings.warn(f"limit cycle at A={A[k]:.6g}, omega={w[k]:.6g} rad/s lies on the edge of the search "
                          "window; widen the window to confirm it", stacklevel=3)
        r = 1 + g[k] * n[k]
        values = (A[k], w[k], det[k], cond[k], abs(r))
        if not all(math.isfinite(x) for x in values):
            raise RuntimeError(f"non-finite value in a refined root at A={A[k]}, omega={w[k]}")
        out.append(LimitCycle(amplitude=float(A[k]), frequency=float(w[k]), stability=str(label[k]),
                              residual=float(abs(r)), relative_residual=float(abs(r) / (1 + abs(g[k] * n[k]))),
                              loeb_determinant=float(det[k]), loeb_conditioning=float(cond[k]), G=complex(g[k]),
                              N=complex(n[k]), on_edge=bool(on_edge[k]), valid=bool(valid[k]),
                              n_error=float(err[k])))
    return out, rejected


def _omega_window_reason(plant) -> str:
    """Why the default frequency window ends where it does (for the header of the result)."""
    if plant.domain[0] != 0:
        return "default: the frd's grid"
    if not plant.exact:
        return "default: from the plant's poles/zeros"
    mag = np.abs(np.concatenate(plant.roots))
    mag = mag[np.isfinite(mag) & (mag > 0)]
    if mag.size == 0:
        return "default: G has no pole or zero off the origin: 0.01-100 rad/s"
    at = f"{mag.min():.3g}" if f"{mag.min():.3g}" == f"{mag.max():.3g}" else f"{mag.min():.3g}..{mag.max():.3g}"
    return f"default: 2 decades beyond G's poles/zeros at {at} rad/s, where G's phase and slope have settled"
