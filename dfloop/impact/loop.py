"""The paper's two-mass impact element inside a feedback loop, on the exact linear-mode engine.

Loop of the paper's Fig. 1: the element's input is the force on M2, x = -c, its output is x1, and the linear
part closes the loop, c = G x1 (G a python-control tf or ss, state s: s' = A s + B x1, c = C s + D x1). Between
events the masses, the optional effects and the plant form one linear system of z = [x1, v1, d, u, s, 1]
(d: gap from the wall of the last impact, u = v2 - v1), so the closed loop runs on the same compiled engine as
the forced element (:mod:`dfloop.impact._engine`): flows by matrix exponential, impacts (eqs. 8a/8b), chatter
cut into sticking and separation located to rounding, no integrator tolerance anywhere.

:func:`simulate_impact_loop` samples a run for :func:`dfloop.verify.verify_cycle`; :func:`impact_loop_orbit`
finds the periodic orbit by Newton shooting on the impact map, with its Floquet multipliers from the
monodromy matrix, saltation (jump) matrices of the impacts included.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import _checks
from .._blas import single_threaded_blas
from . import _effects_core as core
from . import _engine
from ._effects_core import D, IMPACT_A, IMPACT_B, SEPARATION, U, V1, X1
from .kernel import DEFAULT_CHATTER_TOL

__all__ = ["simulate_impact_loop", "impact_loop_orbit", "ImpactLoopOrbit"]

_DIVERGED = 1e6            # a state beyond this many times its starting scale stops a run as divergent
_EVENTS_PER_PERIOD = 2000  # default event bound per requested period (chatter makes ~100)


def _plant_matrices(G):
    import control as ct

    from ..solve.plant import as_plant

    lti = as_plant(G).lti
    if lti is None or isinstance(lti, ct.FrequencyResponseData):
        raise ValueError("G must be a python-control tf or ss system for time-domain verification")
    sys = ct.ss(lti)
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise ValueError(f"G must be SISO, got {sys.ninputs} inputs and {sys.noutputs} outputs")
    if not sys.isctime():
        raise ValueError("G must be a continuous-time system")
    return tuple(np.asarray(m, float) for m in (sys.A, sys.B[:, 0], sys.C[0], sys.D[0, 0]))


class _Loop:
    """The closed loop's engine system, the output rows and the scales of its state."""

    def __init__(self, G, element, chatter_tol, force_scale, frequency):
        from .effects import effect_terms

        self.element = element
        self.Ap, self.Bp, self.Cp, self.Dp = _plant_matrices(G)
        self.nc = nc = self.Ap.shape[0]
        n = 5 + nc
        force2 = np.zeros(n)                      # force on M2 = -c = -(C s + D x1)
        force2[X1] = -self.Dp
        force2[4:4 + nc] = -self.Cp
        extra = np.zeros((nc, n))
        extra[:, X1] = self.Bp
        extra[:, 4:4 + nc] = self.Ap
        c, k, friction = effect_terms(element.effects)
        self.system = _engine.LinearModeSystem(element.m1, element.m2, element.h, element.restitution, force2,
                                               extra, damping=c, stiffness=k, friction=friction,
                                               extra_scales=(2.0 * math.pi / frequency,))
        self.v_stick = chatter_tol * max(element.h * frequency, force_scale / (element.m2 * frequency))
        self.x_row = force2                       # element input x (N) as a row over z
        self.n = n

    def start_state(self, amplitude, frequency):
        """Masses at rest, gap centred; plant in its harmonic-balance state for x = amplitude sin(w t)."""
        x1_phasor = complex(self.element(amplitude, frequency)) * amplitude
        s0 = (np.linalg.solve(1j * frequency * np.eye(self.nc) - self.Ap, self.Bp) * x1_phasor).imag
        h = self.element.h
        return np.concatenate([[0.0, 0.0, 0.5 * h, 0.0], s0, [1.0]])

    def limit(self, z, amplitude):
        scale = max(float(np.max(np.abs(z[:-1]))), self.element.h, amplitude)
        return _DIVERGED * scale


def _validated(element, amplitude, frequency, periods):
    if not all(hasattr(element, a) for a in ("m1", "m2", "h", "restitution", "effects")):
        raise ValueError(f"element must be a DynamicBacklash, got {element!r}")
    A0, w = _checks.positive("amplitude", amplitude), _checks.positive("frequency", frequency)
    periods = _checks.positive("periods", periods)
    return A0, w, periods


@single_threaded_blas
def simulate_impact_loop(G, element, amplitude: float, frequency: float, *, periods: float = 80,
                         steps_per_period: int = 400, max_events: int | None = None,
                         chatter_tol: float = DEFAULT_CHATTER_TOL):
    """Simulate the loop around a :class:`~dfloop.impact.dynamic_backlash.DynamicBacklash` element exactly.

    Parameters
    ----------
    G : python-control tf or ss
        The rest of the loop, from x1 (m) to c (N); the force on M2 is -c.
    element : DynamicBacklash
        Masses, clearance, restitution and optional effects are taken from it.
    amplitude, frequency : float
        Force amplitude (N) and frequency (rad/s) of the cycle to start from: the plant starts in the state
        it would have if the force were exactly ``amplitude`` sin(``frequency`` t) and x1 had the DF's
        fundamental; the masses start at rest with the gap centred (the model's initial state).
    periods, steps_per_period : float, int
        Length of the run in periods of ``frequency`` and the uniform sampling of the returned signals.
    max_events : int, optional
        Bound on the number of events (impacts, separations); default 2000 per period. Reaching it raises
        :class:`dfloop.impact.kernel.EventLimitError`, which says how to raise it.
    chatter_tol : float
        Relative post-impact speed (of max(h w, amplitude/(M2 w))) below which a converging chatter sticks.

    Returns
    -------
    dfloop.verify.LoopSimulation
        Uniform samples of the element input x = -c (N) and output y = x1 (m); ``diverged`` when a state grew
        beyond 1e6 times its starting scale (the run stops there).
    """
    from ..verify import LoopSimulation

    A0, w, periods = _validated(element, amplitude, frequency, periods)
    if int(steps_per_period) < 20:
        raise ValueError(f"steps_per_period must be >= 20, got {steps_per_period}")
    chatter_tol = _checks.positive("chatter_tol", chatter_tol)
    period = 2 * math.pi / w
    max_events = _event_bound(max_events, periods)
    loop = _Loop(G, element, chatter_tol, A0, w)
    z = loop.start_state(A0, w)
    run = _engine.run(loop.system, z, periods * period, loop.v_stick, max_events, limit=loop.limit(z, A0),
                      what=f"closed loop ({periods:g} periods of {w:g} rad/s; max_events of simulate_impact_loop)")
    grid = np.arange(0.0, run.t_end, period / int(steps_per_period))
    zs = run.states(grid)
    return LoopSimulation(grid, zs @ loop.x_row, zs[:, X1], run.diverged,
                          method="exact linear-mode engine (events located to rounding)")


def _event_bound(max_events, periods):
    if max_events is None:
        return int(max(10_000, _EVENTS_PER_PERIOD * periods))
    if int(max_events) < 1:
        raise ValueError(f"max_events must be >= 1, got {max_events}")
    return int(max_events)


# ---------------------------------------------------------------------------------------------------- orbits
@dataclass(frozen=True, repr=False)
class ImpactLoopOrbit:
    """A periodic orbit of the closed loop around the dynamic backlash, found by shooting on the impact map.

    Attributes
    ----------
    success : bool
        True when Newton converged to a periodic orbit (residual below the tolerance).
    message : str
        What was found, or why not (no impacts, divergence, no period up to ``max_period_multiple``, Newton
        failure): never a half-converged orbit.
    period : float
        Period T (s) of the orbit (nan when not found).
    period_multiple : int
        Returns to the Poincare section per period (1: a simple cycle; k: period-k orbit of the impact map).
    t, x, y : ndarray
        Dense times over one period from the section (s), element input x = -c (force on M2, N), x1 (m).
    event_times : ndarray
        Impact instants within the period (s from the section).
    multipliers : ndarray
        Non-trivial Floquet multipliers (eigenvalues of the Jacobian of the k-fold impact map; the monodromy
        includes the saltation matrices of every impact). Zeros come from sticking (states absorbed).
    stable : bool
        All multipliers inside the unit circle.
    method : str
        How the orbit was computed.
    residual, iterations : float, int
        Scaled residual of the k-fold impact map at the orbit, and the Newton steps taken.
    section_state, section_side : ndarray, int
        Post-impact state [x1, v1, u, plant states] at the section (t = 0) and its wall (0 = A, 1 = B).
    """

    success: bool
    message: str
    period: float
    period_multiple: int
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    event_times: np.ndarray
    multipliers: np.ndarray
    stable: bool
    method: str
    residual: float = math.nan
    iterations: int = 0
    section_state: np.ndarray = field(default_factory=lambda: np.zeros(0))
    section_side: int = -1

    @property
    def frequency(self) -> float:
        """Fundamental frequency 2 pi / T (rad/s)."""
        return 2.0 * math.pi / self.period if self.success else math.nan

    def to_dict(self) -> dict:
        """Plain data keyed by the attribute names (arrays as lists, multipliers as Python complex), plus
        ``frequency``."""
        from ..export import plain

        names = ("success", "message", "period", "frequency", "period_multiple", "t", "x", "y", "event_times",
                 "multipliers", "stable", "method", "residual", "iterations", "section_state", "section_side")
        return {name: plain(getattr(self, name)) for name in names}

    def to_csv(self, path) -> None:
        """Write the orbit's period, one row per sample: ``t`` (s), ``x`` (N), ``y`` (m); ValueError without one."""
        from ..export import write_csv

        if not self.success:
            raise ValueError(f"this ImpactLoopOrbit has no orbit to write ({self.message})")
        write_csv(path, ({"t": t, "x": x, "y": y} for t, x, y in zip(self.t.tolist(), self.x.tolist(),
                                                                      self.y.tolist())))

    def __repr__(self) -> str:
        if not self.success:
            return f"ImpactLoopOrbit(failed: {self.message})"
        mu = np.max(np.abs(self.multipliers)) if self.multipliers.size else 0.0
        return (f"ImpactLoopOrbit(period={self.period:.6g} s (frequency={self.frequency:.6g} rad/s), "
                f"period_multiple={self.period_multiple}, {self.event_times.size} impacts per period, "
                f"peak |x| {np.max(np.abs(self.x)):.4g} N, stable={self.stable} (largest |multiplier| {mu:.3g}), "
                f"residual={self.residual:.1e}, iterations={self.iterations})")


_METHOD = ("Newton shooting on the impact map of the exact linear-mode engine (matrix-exponential flows, "
           "events located to rounding); monodromy with saltation matrices")


def _failed(message: str, k: int = 0) -> ImpactLoopOrbit:
    empty = np.zeros(0)
    return ImpactLoopOrbit(False, message, math.nan, k, empty, empty, empty, empty, empty, False, _METHOD)


class _ImpactMap:
    """Poincare map of the closed loop: post-impact states on ``side`` that follow a flight from elsewhere.

    Section states are reduced to xi = z without d (0 on the section) and the constant 1.
    """

    def __init__(self, loop: _Loop, side: int, period_guess: float, max_events: int, limit: float):
        self.loop, self.side, self.T, self.max_events, self.limit = loop, side, period_guess, max_events, limit
        n = loop.n
        self.keep = np.array([i for i in range(n) if i not in (D, n - 1)])

    def full(self, xi):
        z = np.zeros(self.loop.n)
        z[self.keep] = xi
        z[-1] = 1.0
        return z

    def section_indices(self, run):
        """Segments that start on the section: impacts on ``side`` whose previous impact/separation was not."""
        cause = run.cause
        want = IMPACT_A if self.side == 0 else IMPACT_B
        out = []
        prev = -1
        for i, c in enumerate(cause):
            if c in (IMPACT_A, IMPACT_B, SEPARATION):
                if c == want and prev != want:
                    out.append(i)
                prev = c
        return np.array(out, dtype=np.int64)

    def run(self, xi, returns: int):
        """Run from section state xi until ``returns`` further section crossings (bounded extensions)."""
        loop = self.loop
        z = self.full(xi)
        horizon = 1.5 * returns * self.T
        for _ in range(6):
            run = _engine.run(loop.system, z, horizon, loop.v_stick, self.max_events, ref=self.side,
                              limit=self.limit, what="orbit shooting (max_events of impact_loop_orbit)")
            if run.diverged:
                return None, None
            idx = self.section_indices(run)
            idx = idx[idx > 0]
            if idx.size >= returns:
                return run, int(idx[returns - 1])
            horizon *= 2.0
        return None, None

    def map_and_jacobian(self, xi, returns: int):
        """(P^k(xi), its Jacobian, return time, run, end segment) or None when the returns are not reached."""
        run, end = self.run(xi, returns)
        if run is None:
            return None
        Phi = _monodromy(self.loop, run, end)
        z_end = run.z0[end]
        slot = run.slot[end]
        f_plus = self.loop.system.mats[slot] @ z_end
        n = self.loop.n
        proj = np.eye(n)
        if abs(f_plus[D]) > 0.0:
            proj -= np.outer(f_plus, np.eye(n)[D]) / f_plus[D]   # slide along the flow back onto d = 0
        J = (proj @ Phi)[np.ix_(self.keep, self.keep)]
        return z_end[self.keep], J, run.t0[end], run, end


def _reset_matrix(loop: _Loop, run, i: int) -> np.ndarray:
    """Jacobian of the state jump at the event that starts segment i (impact law, chatter settle, stop)."""
    sysm = loop.system
    n = loop.n
    J = np.eye(n)
    c = run.cause[i]
    M = sysm.m1 + sysm.m2
    if c in (IMPACT_A, IMPACT_B):
        if run.z0[i, U] == 0.0 and run.vel[i, 0] != run.vel[i, 1]:   # plastic settle of a converged chatter
            J[V1, U] = sysm.m2 / M
            J[U, U] = 0.0
        else:
            J[V1, U] = (1.0 + sysm.eps) * sysm.m2 / M
            J[U, U] = -sysm.eps
    elif c == core.GROUND_EVENT and sysm.friction is not None:
        pre_v = run.vel[i, 0] if sysm.friction[1] == 0 else run.vel[i, 1]
        post_v = run.vel[i, 2] if sysm.friction[1] == 0 else run.vel[i, 3]
        if pre_v != 0.0 and post_v == 0.0:      # the friction mass stopped: its speed is reset to 0
            if run.slot[i] // 3 != 0:
                J[V1, :], J[U, :] = 0.0, 0.0
            elif sysm.friction[1] == 0:
                J[U, V1], J[V1, :] = 1.0, 0.0
            else:
                J[U, :] = 0.0
                J[U, V1] = -1.0
    return J


def _monodromy(loop: _Loop, run, end: int) -> np.ndarray:
    """d z(t0[end]+) / d z(t0[0]) along the run: flows exp(A tau) and saltation matrices at every event."""
    sysm = loop.system
    n = loop.n
    Phi = np.eye(n)
    for i in range(end):
        A = sysm.mats[run.slot[i]]
        tau = run.t0[i + 1] - run.t0[i]
        Phi = core.expm_taylor(A * tau) @ Phi
        # saltation at the event that starts segment i + 1
        z_minus = _segment_end_state(run, i)
        f_minus = A @ z_minus
        J = _reset_matrix(loop, run, i + 1)
        z_plus = run.z0[i + 1]
        f_plus = sysm.mats[run.slot[i + 1]] @ z_plus
        r = _event_row(loop, run, i)
        rf = r @ f_minus
        S = J
        if rf != 0.0:
            S = J + np.outer(f_plus - J @ f_minus, r) / rf
        Phi = S @ Phi
    return Phi


def _segment_end_state(run, i: int) -> np.ndarray:
    """State at the end of segment i, before the event (in the segment's own wall reference)."""
    sysm = run.system
    s = run.slot[i]
    tau = np.array([run.t0[i + 1] - run.t0[i]])
    return core.propagate(sysm.mats[s], sysm.exps[s], run.z0[i], tau, sysm.dt)[0]


def _event_row(loop: _Loop, run, i: int) -> np.ndarray:
    """The constraint row whose zero crossing ended segment i (the event surface's normal)."""
    sysm = loop.system
    s, ref = run.slot[i], run.ref[i]
    c = run.cause[i + 1]
    kinds = sysm.kinds[s, :sysm.nrows[s]]
    want = {IMPACT_A: core.HIT_A, IMPACT_B: core.HIT_B, SEPARATION: core.SEPARATE}.get(int(c))
    if want is None:   # ground event: the stop or slip row closest to zero at the segment end
        z_end = _segment_end_state(run, i)
        vals = np.abs(sysm.rows[s, ref, :sysm.nrows[s]] @ z_end)
        cand = [j for j in range(kinds.size) if kinds[j] in (core.STOP, core.SLIP)]
        j = min(cand, key=lambda jj: vals[jj]) if cand else int(np.argmin(vals))
    else:
        j = int(np.flatnonzero(kinds == want)[0])
    return sysm.rows[s, ref, j]


@single_threaded_blas
def impact_loop_orbit(G, element, amplitude: float, frequency: float, *, max_period_multiple: int = 4,
                      transient_periods: float = 200, tol: float = 1e-10, max_iterations: int = 30,
                      samples: int = 400, max_events: int | None = None,
                      chatter_tol: float = DEFAULT_CHATTER_TOL) -> ImpactLoopOrbit:
    """Periodic orbit of the loop around a dynamic backlash near a predicted cycle, with its Floquet multipliers.

    The loop is run from the prediction's harmonic-balance state (as :func:`simulate_impact_loop`) for
    ``transient_periods``; then, on the Poincare section of impacts on one side after a flight from elsewhere,
    the smallest k <= ``max_period_multiple`` with a k-periodic point is sought by Newton shooting on the k-fold
    impact map (Jacobian from the exact monodromy with saltation matrices; damped, at most ``max_iterations``).

    Parameters
    ----------
    G : python-control tf or ss
        From x1 (m) to c (N); the force on M2 is -c.
    element : DynamicBacklash
    amplitude, frequency : float
        The predicted cycle (force amplitude N, rad/s) to start from.
    max_period_multiple : int
        Largest number of section returns per period tried.
    transient_periods : float
        Periods of ``frequency`` run before shooting.
    tol : float
        Convergence: the k-fold map's residual, relative to the section state's scale (per component).
    samples : int
        Dense samples over one period of the result.

    Returns
    -------
    ImpactLoopOrbit
        ``success`` False with the reason when no orbit is found (chaotic or quasi-periodic response,
        divergence, no impacts, Newton failure).
    """
    A0, w, transient_periods = _validated(element, amplitude, frequency, transient_periods)
    kmax = int(max_period_multiple)
    if kmax < 1:
        raise ValueError(f"max_period_multiple must be >= 1, got {max_period_multiple}")
    tol = _checks.positive("tol", tol)
    if int(max_iterations) < 1 or int(samples) < 2:
        raise ValueError(f"max_iterations must be >= 1 and samples >= 2, got {max_iterations}, {samples}")
    chatter_tol = _checks.positive("chatter_tol", chatter_tol)
    period = 2 * math.pi / w
    max_events = _event_bound(max_events, transient_periods + 4 * kmax)
    loop = _Loop(G, element, chatter_tol, A0, w)
    z = loop.start_state(A0, w)
    limit = loop.limit(z, A0)
    run = _engine.run(loop.system, z, transient_periods * period, loop.v_stick, max_events, limit=limit,
                      record_from=0.5 * transient_periods * period,
                      what="orbit transient (max_events of impact_loop_orbit)")
    if run.diverged:
        return _failed(f"the loop diverges from the predicted cycle (states beyond {limit:.3g} at "
                       f"t = {run.t_end:.4g} s)")
    best = None
    for side in (1, 0):
        pm = _ImpactMap(loop, side, period, max_events, limit)
        idx = pm.section_indices(run)
        if idx.size >= 2 * kmax + 2 and (best is None or idx.size > best[1].size):
            best = (pm, idx)
    if best is None:
        return _failed("too few impacts after the transient to define an impact map (the loop rests, sticks "
                       "for good, or touches one wall only rarely)")
    pm, idx = best
    states = run.z0[idx][:, pm.keep]
    times = run.t0[idx]
    scale = np.max(np.abs(states), axis=0) + 1e-9 * (np.max(np.abs(states)) + 1e-300)
    pm.T = float(np.median(np.diff(times)))
    reasons = []
    for k in range(1, kmax + 1):
        pm.T = float(np.median(times[k:] - times[:-k])) / k
        result = _newton(pm, states[-1], k, scale, tol, int(max_iterations))
        if isinstance(result, str):
            reasons.append(f"k={k}: {result}")
            continue
        xi, J, T, orbit_run, end, residual, iterations = result
        if k > 1 and _divides(pm, xi, k, scale, tol):
            reasons.append(f"k={k}: converged to a lower-period orbit")
            continue
        return _orbit_result(loop, pm, xi, J, T, orbit_run, end, k, residual, iterations, int(samples))
    return _failed("no periodic orbit up to period multiple "
                   f"{kmax} near the response (chaotic or quasi-periodic?): " + "; ".join(reasons), kmax)


def _newton(pm: _ImpactMap, xi, k, scale, tol, max_iterations):
    """Damped Newton on P^k(xi) - xi = 0 (scaled); a tuple when converged, else the reason (str)."""
    out = pm.map_and_jacobian(xi, k)
    if out is None:
        return "the impact map does not return (divergence or no further impacts)"
    for it in range(max_iterations + 1):
        p, J, T, run, end = out
        res = (p - xi) / scale
        norm = float(np.max(np.abs(res)))
        if norm <= tol:
            return xi, J, T, run, end, norm, it
        if it == max_iterations:
            break
        Js = (J - np.eye(xi.size)) / scale[:, None] * scale[None, :]
        try:
            step = -np.linalg.solve(Js, res) * scale
        except np.linalg.LinAlgError:
            return "singular shooting Jacobian"
        lam = 1.0
        for _ in range(12):
            trial = pm.map_and_jacobian(xi + lam * step, k)
            if trial is not None and float(np.max(np.abs((trial[0] - xi - lam * step) / scale))) < norm:
                break
            lam *= 0.5
        else:
            return f"Newton stalled at residual {norm:.2e}"
        xi = xi + lam * step
        out = trial
    return f"no convergence in {max_iterations} Newton iterations (residual {norm:.2e})"


def _divides(pm, xi, k, scale, tol):
    """True when xi is already periodic with a divisor of k (a lower-period orbit found again)."""
    for d in range(1, k):
        if k % d == 0:
            out = pm.map_and_jacobian(xi, d)
            if out is not None and float(np.max(np.abs((out[0] - xi) / scale))) <= 100 * tol:
                return True
    return False


def _orbit_result(loop, pm, xi, J, T, run, end, k, residual, iterations, samples) -> ImpactLoopOrbit:
    multipliers = np.linalg.eigvals(J)
    multipliers = multipliers[np.argsort(-np.abs(multipliers))]
    t = np.linspace(0.0, T, samples, endpoint=False)  # one period, without its endpoint
    zs = run.states(np.minimum(t, run.t_end))
    imp = (run.cause[:end] == IMPACT_A) | (run.cause[:end] == IMPACT_B)
    imp[0] = True
    events = run.t0[:end][imp]
    stable = bool(np.all(np.abs(multipliers) < 1.0))
    return ImpactLoopOrbit(True, f"period-{k} orbit of the impact map on side {'AB'[pm.side]} "
                           f"(residual {residual:.1e} after {iterations} Newton steps)", float(T), k, t,
                           zs @ loop.x_row, zs[:, X1], events, multipliers, stable, _METHOD, residual,
                           iterations, xi.copy(), pm.side)
