"""Exact periodic orbits of a sampled-data (digital) loop with a static element: a finite-dimensional map.

The loop of a discrete-time plant G(z) = C (zI - A)^{-1} B (strictly proper: D = 0; ``control.sample_system(G, dt)``
for a continuous plant behind a zero-order hold) and a static element y = f(x) fed with x = -c (the paper's sign
convention, reference 0) is the map

    s[k+1] = A s[k] + B f(x[k]),     x[k] = -C s[k].

A periodic orbit of period P samples is a fixed point of F^P. Two exact methods:

- Piecewise-constant f (quantizer, relay without hysteresis, a user's staircase): the output sequence y_0..y_{P-1}
  fixes the orbit. When I - A^P is invertible, x_k = -sum_j g[(k - 1 - j) mod P] y_j with the periodic impulse
  response g[d] = C (I - A^P)^{-1} A^d B (d = 0..P-1), and the orbit exists exactly when every x_k lies in the
  input interval of its output level y_k. :func:`discrete_orbits` enumerates all output sequences by branch and
  bound (a partial sequence is pruned when, whatever the unassigned outputs are, some assigned x_k cannot reach
  its level's interval) and keeps the self-consistent ones, checked with the element's own f: **every** orbit of
  period <= ``max_period`` whose input stays within |x| <= ``bound`` is found (up to a rotation of the sequence),
  unless a work bound is hit, which the result says (``complete`` False, ``message``). For the quantizer a
  lattice search replaces it (:func:`discrete_orbits`, ``method``): the integer points of the rounding band
  |((I - H) n)_k| <= 1/2, each coordinate's range from two linear programs, complete without a bound on |x|. Its map Jacobian is A^P
  (f' = 0 between levels): the multipliers are the eigenvalues of A^P, and an orbit is stable when they lie
  inside the unit circle and no x_k sits on a switching level (``margin`` > 0).
- Other static f (saturation, cubic, ...): :func:`shoot_discrete` solves s = F^P(s) by Newton's method with the
  Jacobian prod_k (A - B f'(x_k) C).

Results give the period in samples, the harmonic m that dominates x (the orbit's frequency is 2 pi m / (P dt)),
the amplitude of that harmonic (what the describing function predicts) and the multipliers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._checks import in_closed_interval, positive
from ..describing.interop import as_element
from ..describing.time_model import OUT_OF_RANGE, PiecewiseAffine, Smooth

__all__ = ["DiscreteOrbit", "DiscreteOrbits", "discrete_orbits", "discrete_system", "shoot_discrete",
           "fundamental", "iterate", "is_discrete", "discrete_cycle", "sample_delayed"]

MAX_NODES = 300_000       # default bound on partial sequences examined per period
_SINGULAR = 1e-10         # I - A^P with a singular value below this (relative) is singular
_TIE = 1e-12              # relative tolerance of the interval tests of the pruning (the final check uses f)


@dataclass(frozen=True, repr=False)
class DiscreteOrbit:
    """One periodic orbit of a sampled loop (x = element input samples, y = its output samples).

    Attributes
    ----------
    period : int
        Samples per period P.
    harmonic : int
        The harmonic m (1..P//2) of largest amplitude in x: the orbit oscillates m times per P samples (0 for a
        constant orbit).
    frequency : float
        2 pi m / (P dt) (rad/s); 0 for a constant orbit.
    amplitude : float
        Amplitude of that harmonic of x (the DF's A; at m = P/2, the Nyquist frequency, the amplitude of the
        alternating samples).
    x, y : ndarray
        One period of samples, starting from the canonical rotation of the output sequence.
    state : ndarray
        Plant state s[0].
    multipliers : ndarray
        Eigenvalues of the Jacobian of F^P, by decreasing modulus (no trivial multiplier: this is a map).
    stable : bool
        All multipliers strictly inside the unit circle (and, for a piecewise-constant element, ``margin`` > 0).
    margin : float or None
        Piecewise-constant element: smallest distance of an x_k to a switching level (input unit); None otherwise.
    dt : float
        Sampling period (s).
    method : str
    """

    period: int
    harmonic: int
    frequency: float
    amplitude: float
    x: np.ndarray
    y: np.ndarray
    state: np.ndarray
    multipliers: np.ndarray
    stable: bool
    margin: float | None
    dt: float
    method: str

    @property
    def largest_multiplier(self) -> float:
        """Largest modulus of the multipliers."""
        return float(np.max(np.abs(self.multipliers), initial=0.0))

    def __repr__(self) -> str:
        kind = "stable" if self.stable else "unstable"
        margin = "" if self.margin is None else f", margin {self.margin:.3g}"
        return (f"DiscreteOrbit(period {self.period} samples, harmonic {self.harmonic}, amplitude "
                f"{self.amplitude:.6g}, frequency {self.frequency:.6g} rad/s, {kind} (largest |multiplier| "
                f"{self.largest_multiplier:.3g}){margin}; y = {np.array2string(self.y, precision=4, threshold=12)})")


@dataclass(repr=False)
class DiscreteOrbits:
    """All periodic orbits found by :func:`discrete_orbits`, sorted by period then amplitude.

    Attributes
    ----------
    orbits : list of DiscreteOrbit
    max_period : int
        Periods 1..max_period were searched.
    bound : float
        Orbits whose input stays within |x| <= bound were searched (inf: the element has finitely many levels).
    complete : bool
        True when every period was searched to the end: then every periodic orbit of period <= max_period within
        the bound is in ``orbits``. False when a work bound was hit or a period was skipped (``message`` says which
        and how to raise the bound).
    message : str
    nodes : int
        Partial sequences examined.
    """

    orbits: list
    max_period: int
    bound: float
    complete: bool
    message: str
    nodes: int = 0
    skipped: dict = field(default_factory=dict)

    def __iter__(self):
        return iter(self.orbits)

    def __len__(self) -> int:
        return len(self.orbits)

    def __getitem__(self, i):
        return self.orbits[i]

    def oscillating(self) -> list:
        """The orbits that are not constant (period > 1 and a non-zero fundamental)."""
        return [o for o in self.orbits if o.harmonic > 0 and o.amplitude > 0]

    def __repr__(self) -> str:
        head = (f"{len(self.orbits)} periodic orbit(s) of period <= {self.max_period} samples with |x| <= "
                f"{self.bound:g}; {'complete' if self.complete else 'INCOMPLETE: ' + self.message}")
        rows = [f"  P={o.period:<3d} m={o.harmonic:<2d} A={o.amplitude:<10.5g} w={o.frequency:<10.5g} "
                f"{'stable' if o.stable else 'unstable'}  y={np.array2string(o.y, precision=3, threshold=10)}"
                for o in self.orbits[:30]]
        more = [f"  ... {len(self.orbits) - 30} more"] if len(self.orbits) > 30 else []
        return "\n".join([head] + rows + more)


def discrete_system(G, what: str = "discrete_orbits"):
    """(A, B, C, dt) of a strictly proper SISO discrete-time python-control tf/ss G (``ValueError`` otherwise)."""
    import control as ct

    G = getattr(G, "lti", G)
    if not isinstance(G, (ct.TransferFunction, ct.StateSpace)):
        raise ValueError(f"G must be a python-control tf or ss system for {what}, got {type(G).__name__}")
    dt = G.dt
    if dt is True or dt in (0, None) or not (isinstance(dt, (int, float, np.floating)) and dt > 0):
        raise ValueError(f"G must be a discrete-time system with a numeric sampling period for {what}; got dt={dt!r} "
                         "(control.sample_system(G, dt) discretises a continuous plant behind a zero-order hold)")
    sys = ct.ss(G)
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise ValueError(f"G must be SISO for {what}, got {sys.ninputs} inputs and {sys.noutputs} outputs")
    D = float(np.asarray(sys.D, float)[0, 0])
    if D != 0:
        raise ValueError(f"G must be strictly proper (D = 0) for {what}: a direct feedthrough closes an algebraic "
                         f"loop through the element within one sample; got D = {D!r}")
    return (np.asarray(sys.A, float), np.asarray(sys.B, float)[:, 0], np.asarray(sys.C, float)[0], float(dt))


def sample_delayed(G, dt: float):
    """A continuous plant with a pure delay behind a zero-order hold of period dt, as a discrete python-control
    ss system: the exact sampled map of :func:`dfloop.hybrid.delay_sampled.delayed_sampled_system`.

    Its state is (s, y_{k-m-1}, ..., y_{k-1}): the plant state and the m + 1 held values still pending in the
    delay line (T = m dt + r, 0 <= r < dt), so the periodic orbits :func:`discrete_orbits`,
    :func:`shoot_discrete` and :func:`discrete_cycle` find on it are those of the digital loop with the delay, and
    their multipliers include the pending values. A delay of k whole samples gives G(z) z^-k; T = 0 gives
    ``control.sample_system(G, dt)`` (zero-order hold), with one extra state (a pole at 0) that a delay adds.

    Parameters
    ----------
    G : :class:`~dfloop.solve.delay.DelayedSystem`, or a continuous python-control tf or ss (T = 0)
        Strictly proper, SISO.
    dt : float
        The sampling period (s), > 0.

    Returns
    -------
    control.StateSpace
        Discrete-time, sampling period dt, strictly proper.
    """
    import control as ct

    from .delay import split_delay
    from .delay_sampled import delayed_sampled_system
    from .loop import plant_matrices

    dt = positive("dt", dt)
    free, T = split_delay(G)
    if getattr(free, "dt", 0) not in (0, None):
        raise ValueError(f"G must be a continuous-time plant for sample_delayed, got dt={free.dt!r}")
    A, B, C = plant_matrices(free, what="sample_delayed")
    Ad, Bd, Cd = delayed_sampled_system(A, B, C, T, dt)
    return ct.ss(Ad, Bd[:, None], Cd[None, :], np.zeros((1, 1)), dt)


def iterate(A, B, C, f, s0, steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run the map from state s0: returns (x, y, s) for k = 0..steps-1 (s[k] the state before sample k)."""
    s = np.asarray(s0, float).copy()
    xs, ys, ss = np.empty(steps), np.empty(steps), np.empty((steps, s.size))
    for k in range(steps):
        x = -float(C @ s)
        y = float(f(np.array([x]))[0])
        xs[k], ys[k], ss[k] = x, y, s
        s = A @ s + B * y
    return xs, ys, ss


def fundamental(x: np.ndarray, dt: float) -> tuple[int, float, float]:
    """(m, amplitude, frequency) of the largest harmonic m = 1..P//2 of one period of samples x."""
    P = x.size
    if P < 2:
        return 0, 0.0, 0.0
    X = np.fft.rfft(x) / P
    mags = np.abs(X[1:P // 2 + 1]) * 2.0
    if P % 2 == 0:
        mags[-1] *= 0.5        # the Nyquist bin is not doubled
    m = int(np.argmax(mags)) + 1
    if mags[m - 1] <= 1e-14 * max(np.max(np.abs(x)), 1e-300):
        return 0, 0.0, 0.0
    return m, float(mags[m - 1]), 2.0 * math.pi * m / (P * dt)


def _levels(N, bound: float | None):
    """Output levels and their input intervals [lo, hi] of a static piecewise-constant element, clipped to
    |x| <= bound, from its time model; the element's own f (``response``) for the final check."""
    scale = bound / 32.0 if bound is not None and math.isfinite(bound) else 1.0
    try:
        tm = N.time_model(scale)
    except NotImplementedError:
        tm = None
    if not isinstance(tm, PiecewiseAffine) or tm.n_states != 0 or any(
            m.gx != 0 or m.ge != 0 or any(g.cxd != 0 or g.ce != 0 for g in m.guards) for m in tm.modes):
        return None
    lo, hi, out, unbounded = [], [], [], False
    for m in tm.modes:
        a, b = -math.inf, math.inf
        for g in m.guards:
            if g.target == OUT_OF_RANGE:
                unbounded = True
            if g.cx > 0:
                a = max(a, -g.c1 / g.cx)
            elif g.cx < 0:
                b = min(b, -g.c1 / g.cx)
        lo.append(a), hi.append(b), out.append(float(m.g1))
    lo, hi, out = np.array(lo), np.array(hi), np.array(out)
    order = np.argsort(lo)
    lo, hi, out = lo[order], hi[order], out[order]
    if np.any(hi[:-1] > lo[1:] + 1e-12 * np.maximum(1.0, np.abs(lo[1:]))):
        raise ValueError(f"N: {type(N).__name__} has overlapping modes (hysteresis: its output depends on its past), "
                         "not a static element; discrete_orbits handles static piecewise-constant elements")
    if unbounded:
        if bound is None:
            raise ValueError(f"bound is required for {type(N).__name__}: it has infinitely many levels; give the "
                             "largest |x| (element input) of the orbits to search, e.g. bound=10 * step")
        inner = np.isfinite(lo) & np.isfinite(hi)
        lo, hi, out = lo[inner], hi[inner], out[inner]     # the out-of-range pieces of the model
    b = math.inf if bound is None else bound
    keep = (hi >= -b) & (lo <= b)
    lo, hi, out = np.maximum(lo[keep], -b), np.minimum(hi[keep], b), out[keep]
    return lo, hi, out, tm.response


def _periodic_gain(A, B, C, P: int):
    """g[d] = C (I - A^P)^{-1} A^d B, d = 0..P-1, and A^P; None when I - A^P is singular."""
    n = A.shape[0]
    powers = [np.eye(n)]
    for _ in range(P):
        powers.append(A @ powers[-1])
    M = np.eye(n) - powers[P]
    sv = np.linalg.svd(M, compute_uv=False)
    if sv[-1] <= _SINGULAR * max(sv[0], 1.0):
        return None, powers[P]
    left = np.linalg.solve(M.T, C)          # C (I - A^P)^{-1}
    g = np.array([left @ powers[d] @ B for d in range(P)])
    return g, powers[P]


def _search_period(H, lo, hi, v, P, max_nodes):
    """All symbol sequences (levels indices) of length P, first symbol minimal, consistent with x = H y.

    Returns (list of index arrays, nodes examined, hit) where hit says the frontier exceeded max_nodes."""
    L = v.size
    found, nodes = [], 0
    scale = max(1.0, float(np.max(np.abs(v))) * float(np.max(np.abs(H))) * P)
    tie = _TIE * scale
    for s0 in range(L):
        allowed = np.arange(s0, L)
        ylo, yhi = float(v[allowed].min()), float(v[allowed].max())
        lo_all, hi_all = float(lo[allowed].min()), float(hi[allowed].max())
        # suffix bounds: rest[m][k] = range of sum_{j >= m} H[k, j] y_j, y_j in [ylo, yhi]
        t_lo, t_hi = np.minimum(H * ylo, H * yhi), np.maximum(H * ylo, H * yhi)
        rest_lo = np.concatenate([np.cumsum(t_lo[:, ::-1], axis=1)[:, ::-1], np.zeros((P, 1))], axis=1)
        rest_hi = np.concatenate([np.cumsum(t_hi[:, ::-1], axis=1)[:, ::-1], np.zeros((P, 1))], axis=1)
        seqs = np.full((1, 1), s0, dtype=np.int32)
        E = H[:, 0][None, :] * v[s0]
        for m in range(1, P + 1):
            nodes += seqs.shape[0]
            if nodes > max_nodes:
                return found, nodes, True
            # feasibility of rows with m symbols assigned
            e_lo, e_hi = E + rest_lo[:, m], E + rest_hi[:, m]
            ok = np.ones(seqs.shape[0], bool)
            for k in range(m):
                sk = seqs[:, k]
                ok &= (e_lo[:, k] <= hi[sk] + tie) & (e_hi[:, k] >= lo[sk] - tie)
            if m < P:
                ok &= np.all((e_lo[:, m:] <= hi_all + tie) & (e_hi[:, m:] >= lo_all - tie), axis=1)
            seqs, E = seqs[ok], E[ok]
            if seqs.shape[0] == 0 or m == P:
                break
            n_next = allowed.size
            seqs = np.concatenate([np.repeat(seqs, n_next, axis=0),
                                   np.tile(allowed, seqs.shape[0])[:, None].astype(np.int32)], axis=1)
            E = np.repeat(E, n_next, axis=0) + H[:, m][None, :] * v[seqs[:, m]][:, None]
        if m == P:
            found.extend(list(seqs))
    return found, nodes, False


def _lattice_search(H, step: float, bound: float | None, max_nodes: int):
    """Every integer vector n with |((I - H) n)_k| <= 1/2 (and |(H n)_k| <= bound / step): the output sequences
    y = step n of a quantizer's periodic orbits (y - x = step n - H step n is the rounding error, at most step/2).

    Depth-first over n_0, n_1, ... (consecutive samples, which the circulant H couples most): at each node two
    linear programs give the exact range of the next coordinate over the relaxed polytope (the constraints with
    the assigned coordinates fixed), and every integer in it is a child. The relaxation holds every integer
    solution, so nothing is pruned that could be an orbit. Returns (list of integer arrays, linear programs
    solved, why the search stopped early or None)."""
    from scipy.optimize import linprog

    P = H.shape[0]
    rows, lo, hi = [np.eye(P) - H], [np.full(P, -0.5)], [np.full(P, 0.5)]
    if bound is not None and math.isfinite(bound):
        rows.append(H)
        lo.append(np.full(P, -bound / step))
        hi.append(np.full(P, bound / step))
    M, lo, hi = np.vstack(rows), np.concatenate(lo), np.concatenate(hi)
    slack = 1e-9 * (1.0 + np.abs(M).sum(axis=1))          # ties are resolved by the exact check of f
    found, lps = [], 0
    stack = [np.zeros(0, dtype=np.int64)]
    while stack:
        fixed = stack.pop()
        m = fixed.size
        if m == P:
            found.append(fixed)
            continue
        shift = M[:, :m] @ fixed
        A_ub = np.vstack([M[:, m:], -M[:, m:]])
        b_ub = np.concatenate([hi - shift + slack, -(lo - shift - slack)])
        ends = []
        for sign in (1.0, -1.0):
            c = np.zeros(P - m)
            c[0] = sign
            lps += 1
            if lps > max_nodes:
                return found, lps, f"more than max_nodes={max_nodes} linear programs; raise max_nodes"
            res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * (P - m), method="highs")
            if res.status == 2:                               # infeasible: no orbit below this node
                break
            if res.status != 0:
                return found, lps, f"a linear program of the search failed ({res.message})"
            ends.append(sign * res.fun)
        if len(ends) < 2:
            continue
        first, last = math.ceil(ends[0] - 1e-7), math.floor(ends[1] + 1e-7)
        stack.extend(np.append(fixed, v) for v in range(last, first - 1, -1))
    return found, lps, None


def _canonical(seq: np.ndarray) -> tuple | None:
    """The smallest rotation of seq, or None when seq repeats a shorter period."""
    P = seq.size
    for d in range(1, P):
        if P % d == 0 and np.array_equal(seq, np.roll(seq, d)):
            return None
    return min(tuple(np.roll(seq, -r).tolist()) for r in range(P))


def discrete_orbits(G, N, *, max_period: int = 20, bound: float | None = None,
                    max_nodes: int = MAX_NODES, periods=None, method: str = "auto") -> DiscreteOrbits:
    """Every periodic orbit of period <= ``max_period`` samples of a digital loop with a piecewise-constant element.

    Parameters
    ----------
    G : python-control tf or ss, discrete time (``dt`` > 0), strictly proper
        From the element's output y to c (x = -c); e.g. ``control.sample_system(G, dt)`` for a continuous plant
        behind a zero-order hold, times a digital controller C(z).
    N : DescribingFunction
        A static piecewise-constant element (``Quantizer``, ``Relay`` without hysteresis, ...).
    max_period : int
        Largest period searched (samples), in [1, 200].
    bound : float, optional
        Orbits whose element input stays within |x| <= bound are searched (required by the level-by-level search
        for an element with infinitely many levels; the quantizer's lattice search needs none: the rounding bounds
        every orbit, unless I - H is singular for a period, which is then skipped with a message asking for one).
    max_nodes : int
        Work bound per period (>= 1): partial sequences examined (level-by-level search) or linear programs solved
        (lattice search). When it is hit, the period is left incomplete and the result says so. The level search's
        work grows with the number of levels within the bound and with the length of G's memory; the lattice
        search's with the volume 1 / |det(I - H)| of the rounding band (large near the periods where the loop with
        a unit gain would resonate): for 5.6/(s+1)^3 at dt = 0.2 s with a quantizer of step 0.05, 476 linear
        programs for all periods 1..16 and 17738 for periods 18..20 (``benchmarks/bench_digital.py``).
    periods : iterable of int, optional
        Search only these periods (each in [1, max_period]); default 1..max_period.
    method : {"auto", "lattice", "intervals"}
        "lattice": the quantizer's output sequences y = step n are the integer points n of the band
        |((I - H) n)_k| <= 1/2 (x = H y, |y - x| <= step/2), enumerated depth-first with the exact range of each
        next coordinate from two linear programs over the band with the earlier ones fixed (a relaxation: complete).
        "intervals": the level-by-level branch and bound of the module notes. "auto": for a
        :class:`~dfloop.describing.static.Quantizer` without ``bound`` the lattice search; with a bound the level
        search, and the lattice search for each period where the level search hits ``max_nodes``; other elements:
        intervals.

    Returns
    -------
    DiscreteOrbits
        ``complete`` True when the search is exhaustive (see the module notes). Periods where I - A^P is singular
        (G has a pole on the unit circle at a P-th root of unity: orbits are not isolated) are listed in
        ``skipped`` and make the result incomplete.
    """
    A, B, C, dt = discrete_system(G)
    N = as_element(N)
    P_max = int(in_closed_interval("max_period", max_period, 1, 200))
    if bound is not None:
        bound = positive("bound", bound)
    max_nodes = int(in_closed_interval("max_nodes", max_nodes, 1, 10**9))
    from ..describing.static import Quantizer

    if method not in ("auto", "lattice", "intervals"):
        raise ValueError(f"method must be 'auto', 'lattice' or 'intervals'; got {method!r}")
    quantizer = isinstance(N, Quantizer)
    if method == "lattice" and not quantizer:
        raise ValueError(f"method='lattice' is for the Quantizer (a band |f(x) - x| <= step/2); got "
                         f"{type(N).__name__}")
    # auto: a quantizer without a bound goes to the lattice search; with a bound the level search runs first
    # (fast on short memories) and a period where it hits max_nodes is searched again by the lattice search
    lattice_only = quantizer and (method == "lattice" or (method == "auto" and bound is None))
    fallback = quantizer and method == "auto" and bound is not None
    if quantizer:
        step = N.step
    if lattice_only:
        f = N.output
    else:
        parts = _levels(N, bound)
        if parts is None:
            raise ValueError(f"N: {type(N).__name__} is not a static piecewise-constant element; use shoot_discrete "
                             "for the periodic orbits of a digital loop with another static element")
        lo, hi, v, f = parts
    orbits, seen, skipped, nodes_total = [], set(), {}, 0
    if periods is None:
        periods = range(1, P_max + 1)
    else:
        periods = sorted({int(in_closed_interval("periods", p, 1, P_max)) for p in periods})
    for P in periods:
        g, AP = _periodic_gain(A, B, C, P)
        if g is None:
            skipped[P] = "I - A^P is singular (a pole of G on the unit circle at a P-th root of unity)"
            continue
        k = np.arange(P)
        H = -g[(k[:, None] - 1 - k[None, :]) % P]
        lattice = lattice_only
        if not lattice:
            seqs, nodes, hit = _search_period(H, lo, hi, v, P, max_nodes)
            nodes_total += nodes
            if hit and fallback:
                lattice = True
            elif hit:
                skipped[P] = f"the search examined more than max_nodes={max_nodes} partial sequences; raise max_nodes"
        if lattice:
            if bound is None and np.linalg.cond(np.eye(P) - H) > 1e12:
                skipped[P] = ("I - H is singular (the loop with a unit gain in place of the quantizer has an orbit of "
                              "this period: the rounding does not bound the orbits); give bound")
                continue
            seqs, nodes, why = _lattice_search(H, step, bound, max_nodes)
            nodes_total += nodes
            if why is not None:
                skipped[P] = why
        mu = np.linalg.eigvals(AP)
        mu = mu[np.argsort(-np.abs(mu))]
        for seq in seqs:
            key = _canonical(np.asarray(seq))
            if key is None or key in seen:
                continue
            idx = np.array(key)
            y = step * idx.astype(float) if lattice else v[idx]
            x = H @ y
            if not np.array_equal(np.asarray(f(x), float), y) or np.any(np.abs(x) > (bound or math.inf)):
                continue       # a tie on a switching level resolved the other way by f, or out of the bound
            seen.add(key)
            if lattice:
                margin = float(np.min(0.5 * step - np.abs(x - y)))
            else:
                edges = np.concatenate([lo[idx][:, None], hi[idx][:, None]], axis=1)
                inner = np.abs(x[:, None] - edges)
                inner = inner[np.isfinite(edges) & (np.abs(edges) < (bound or math.inf))]
                margin = float(inner.min()) if inner.size else math.inf
            s0 = np.linalg.solve(np.eye(A.shape[0]) - AP, sum(np.linalg.matrix_power(A, P - 1 - j) @ B * y[j]
                                                              for j in range(P)))
            m, amp, w = fundamental(x, dt)
            orbits.append(DiscreteOrbit(P, m, w, amp, x, y, s0, mu, bool(np.all(np.abs(mu) < 1) and margin > 0),
                                        margin, dt, "lattice enumeration of the rounding band (exact)" if lattice
                                        else "enumeration of output sequences (exact)"))
    orbits.sort(key=lambda o: (o.period, o.amplitude))
    complete = not skipped
    by_reason = {}
    for P, why in skipped.items():
        by_reason.setdefault(why, []).append(P)
    message = "every period searched to the end" if complete else "; ".join(
        f"period{'s' if len(Ps) > 1 else ''} {', '.join(map(str, Ps))}: {why}" for why, Ps in by_reason.items())
    return DiscreteOrbits(orbits, P_max, math.inf if bound is None else bound, complete, message, nodes_total, skipped)


def _slope(N, amplitude: float):
    """f and f' of a static element (time model: piecewise affine or smooth)."""
    tm = N.time_model(amplitude)
    if isinstance(tm, Smooth):
        f = tm.f
        if tm.slope is not None:
            return f, tm.slope
        h = 1e-6 * max(amplitude, 1e-300)
        return f, lambda x: (np.asarray(f(x + h)) - np.asarray(f(x - h))) / (2 * h)
    if isinstance(tm, PiecewiseAffine) and tm.n_states == 0:
        lo = np.array([max([-g.c1 / g.cx for g in m.guards if g.cx > 0], default=-math.inf) for m in tm.modes])
        gx = np.array([m.gx for m in tm.modes], float)
        order = np.argsort(lo)
        lo, gx = lo[order], gx[order]

        def slope(x):
            i = np.clip(np.searchsorted(lo, np.asarray(x, float), side="right") - 1, 0, gx.size - 1)
            return gx[i]

        return tm.response, slope
    raise ValueError(f"N: {type(N).__name__} is not a static element with a time model (piecewise affine or "
                     "smooth); shoot_discrete needs f and its slope")


def shoot_discrete(G, N, period: int, amplitude: float, frequency: float, *, tol: float = 1e-12,
                   max_iterations: int = 50, phases: int = 4) -> DiscreteOrbit | None:
    """The periodic orbit of ``period`` samples near the sinusoid x = amplitude sin(frequency t), by Newton's
    method on s = F^P(s) (Jacobian prod_k (A - B f'(x_k) C)), from the discrete harmonic-balance state.

    The samples of the predicted sinusoid can sit at any phase (with few samples per period, different phases
    lead to different orbits): Newton starts from ``phases`` phases spread over one sample (and from phase 0), and
    the converged orbit whose amplitude is nearest the prediction is returned.

    Parameters
    ----------
    G : discrete-time python-control tf or ss (strictly proper)
    N : DescribingFunction (static: piecewise affine or smooth time model)
    period : int
        P, samples per period (>= 1).
    amplitude, frequency : float
        The predicted cycle (input unit, rad/s) giving the start.
    tol : float
        |F^P(s) - s| <= tol (1 + |s|).
    max_iterations : int
        Bound on Newton steps per start.
    phases : int
        Start phases tried (>= 1).

    Returns
    -------
    DiscreteOrbit or None
        None when Newton converged from no start (no orbit of that period near the prediction).
    """
    A, B, C, dt = discrete_system(G, "shoot_discrete")
    N = as_element(N)
    P = int(in_closed_interval("period", period, 1, 10**6))
    amplitude, frequency = positive("amplitude", amplitude), positive("frequency", frequency)
    max_iterations = int(in_closed_interval("max_iterations", max_iterations, 1, 10_000))
    phases = int(in_closed_interval("phases", phases, 1, 1000))
    f, df = _slope(N, amplitude)
    n = A.shape[0]
    X = np.linalg.solve(np.exp(1j * frequency * dt) * np.eye(n) - A, B) * complex(N(amplitude)) * amplitude
    best = None
    for phi in np.concatenate([[0.0], (np.arange(phases) + 0.5) / phases * frequency * dt]):
        o = _newton_map(A, B, C, dt, f, df, (X * np.exp(1j * phi)).imag.copy(), P, tol, max_iterations)
        if o is not None and o.harmonic > 0 and (
                best is None or abs(math.log(o.amplitude / amplitude)) < abs(math.log(best.amplitude / amplitude))):
            best = o
    return best


def _newton_map(A, B, C, dt, f, df, s, P, tol, max_iterations):
    n = A.shape[0]

    def jacobian(xs):
        J = np.eye(n)
        for k in range(P):
            J = (A - np.outer(B, C) * float(np.asarray(df(np.array([xs[k]])))[0])) @ J
        return J

    for it in range(max_iterations + 1):
        xs, ys, ss = iterate(A, B, C, f, s, P)
        r = A @ ss[-1] + B * ys[-1] - s
        if not np.all(np.isfinite(r)):
            return None
        if np.linalg.norm(r) <= tol * (1.0 + np.linalg.norm(s)):
            break
        if it == max_iterations:
            return None
        try:
            s = s - np.linalg.solve(jacobian(xs) - np.eye(n), r)
        except np.linalg.LinAlgError:
            return None
    mu = np.linalg.eigvals(jacobian(xs))
    mu = mu[np.argsort(-np.abs(mu))]
    m, amp, w = fundamental(xs, dt)
    return DiscreteOrbit(P, m, w, amp, xs, ys, s, mu, bool(np.all(np.abs(mu) < 1)), None, dt,
                         f"Newton on the {P}-fold map ({it} iterations)")


def is_discrete(G) -> bool:
    """True for a python-control system (or a dfloop Plant carrying one) with a sampling period dt > 0."""
    dt = getattr(getattr(G, "lti", G), "dt", None)
    return dt is not None and dt is not False and dt != 0


def _settled_orbit(A, B, C, dt, N, f, amplitude, frequency, lo, hi, v, max_samples: int):
    """The orbit a run from the discrete harmonic-balance state settles on (piecewise-constant element), made
    exact by solving the periodic equations for its output sequence; None when the run does not settle."""
    n = A.shape[0]
    X = np.linalg.solve(np.exp(1j * frequency * dt) * np.eye(n) - A, B) * complex(N(amplitude)) * amplitude
    xs, ys, _ = iterate(A, B, C, f, X.imag.copy(), max_samples)
    tail = ys[max_samples // 2:]
    for P in range(1, min(200, tail.size // 3) + 1):
        if np.array_equal(tail[P:], tail[:-P]):
            seq = tail[-P:]
            g, AP = _periodic_gain(A, B, C, P)
            if g is None:
                return None
            k = np.arange(P)
            x = -g[(k[:, None] - 1 - k[None, :]) % P] @ seq
            if not np.array_equal(np.asarray(f(x), float), seq):
                return None
            mu = np.linalg.eigvals(AP)
            s0 = np.linalg.solve(np.eye(n) - AP, sum(np.linalg.matrix_power(A, P - 1 - j) @ B * seq[j]
                                                    for j in range(P)))
            m, amp, w = fundamental(x, dt)
            margin = float(np.min(np.abs(np.concatenate([x - lo[np.searchsorted(lo, x, side="right") - 1],
                                                          hi[np.searchsorted(lo, x, side="right") - 1] - x]))))
            return DiscreteOrbit(P, m, w, amp, x, seq, s0, mu[np.argsort(-np.abs(mu))],
                                 bool(np.all(np.abs(mu) < 1) and margin > 0), margin, dt,
                                 "run from the prediction until the outputs repeat, then the periodic equations (exact)")
    return None


def discrete_cycle(G, N, amplitude: float, frequency: float, *, max_deviation: float = 0.5,
                   max_nodes: int = 50_000, stability: str | None = None):
    """The exact orbit of a digital loop nearest a predicted cycle (amplitude, frequency), or a message.

    Piecewise-constant element: the orbit a run from the prediction settles on (made exact by the periodic
    equations of its output sequence) when it lies within ``max_deviation``, else every orbit of period within a
    factor 1.5 of P0 = 2 pi / (frequency dt) samples (:func:`discrete_orbits`, ``max_nodes`` per period: an
    incomplete search is said in the message). A prediction whose ``stability`` is "unstable" skips the run (it
    would settle on a stable orbit, not the predicted one). Other static elements:
    :func:`shoot_discrete` at periods round(P0) - 1 .. round(P0) + 1. The orbit whose dominant harmonic is nearest
    the prediction in log(amplitude) and log(frequency) is returned, if within ``max_deviation``.

    Returns
    -------
    (DiscreteOrbit or None, str)
        The orbit and what was done (or why none was found).
    """
    A, B, C, dt = discrete_system(G, "exact_cycle")
    N = as_element(N)
    P0 = 2.0 * math.pi / (frequency * dt)

    def deviation(o):
        return max(abs(math.log(o.amplitude / amplitude)), abs(math.log(o.frequency / frequency)))

    bound = 8.0 * amplitude
    try:
        parts = _levels(N, bound)
    except ValueError:
        parts = None
    found, note = [], ""
    if parts is not None:
        lo, hi, v, f = parts
        if stability != "unstable":
            o = _settled_orbit(A, B, C, dt, N, f, amplitude, frequency, lo, hi, v, 20 * int(P0 + 2) + 400)
            if o is not None and o.harmonic > 0 and deviation(o) <= max_deviation:
                return o, "the orbit a run from the prediction settles on (stable; other orbits not enumerated)"
        periods = range(max(2, int(P0 / 1.5)), min(200, int(math.ceil(P0 * 1.5))) + 1)
        res = discrete_orbits(G, N, max_period=max(periods), bound=bound, max_nodes=max_nodes, periods=periods,
                              method="intervals")
        found = res.oscillating()
        note = (f"every orbit of period {periods.start}..{periods.stop - 1} samples with |x| <= {bound:.4g} "
                f"searched{'' if res.complete else ' (INCOMPLETE: ' + res.message + ')'}")
    else:
        for P in range(max(1, int(round(P0)) - 1), int(round(P0)) + 2):
            o = shoot_discrete(G, N, P, amplitude, frequency)
            if o is not None and o.harmonic > 0:
                found.append(o)
        note = f"Newton on the P-fold map, P = {max(1, int(round(P0)) - 1)}..{int(round(P0)) + 1} samples"
    if not found:
        return None, f"no periodic orbit near the prediction ({note})"
    best = min(found, key=deviation)
    if deviation(best) > max_deviation:
        return None, (f"the nearest orbit (period {best.period} samples, A={best.amplitude:.6g}, w={best.frequency:.6g} "
                      f"rad/s) is farther from the prediction than max_deviation={max_deviation:g} ({note})")
    return best, note
