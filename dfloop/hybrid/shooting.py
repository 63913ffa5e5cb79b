"""The one periodic-orbit finder: multiple shooting with the monodromy (saltation matrices included) as Jacobian.

For any exact loop model of :mod:`dfloop.hybrid` (piecewise affine, smooth, impact), Newton's method solves

    phi_{T/m}(z_i) - z_{i+1} = 0  (i = 0..m-1, z_m = z_0),      f(z_0) . (z_0 - z_0^k) = 0,

in the nodes z_i and the period T (the last row keeps the correction orthogonal to the flow). Nodes start on
the predicted sinusoidal orbit (``settle_periods`` = 0: right for unstable cycles, which a flow leaves) or on a
flow settled for some periods from it (then the period is detected on the settled motion: the spacing of the
upward crossings of x through its mean, times the number k <= MAX_RETURNS of crossings after which the state
recurs, so period-k orbits such as those after a period doubling are shot whole). The first node lies
in the middle of the longest segment between switches, so small corrections never move a switch across a node.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..harmonics import upward_crossings
from .loop import Flow, HybridError
from .model import start_on_prediction

__all__ = ["Orbit", "ShootingError", "periodic_orbit", "newton_orbit", "homotopy_orbit", "node_count", "middle_halves", "detect_period", "forced_orbit"]

LINE_SEARCH = 8    # step halvings per Newton iteration
NODE_GROWTH = 2.0  # a node interval lets a perturbation grow by at most e^2 at the loop's fastest rate ...
MAX_NODES = 64     # ... with at most this many nodes per period
HOMOTOPY_STEP = 0.25         # first step in the homotopy parameter lam (0: the start, 1: the true orbit)
HOMOTOPY_MIN_STEP = 1.0 / 512
HOMOTOPY_CORRECTIONS = 4     # Newton corrections per homotopy step
HOMOTOPY_TOL = 1e-6          # |H| relative to the nodes' size that ends a correction
HOMOTOPY_SOLVES = 120        # bound on the corrections of one homotopy (each: one flow per node)
FLOOR = 1e-9       # a residual below this that stops decreasing is the rounding floor: accepted
PERIOD_STEP = 2.0  # a Newton step may change the period by at most this factor (a larger one is damped)
_DETECT_PERIODS = 8   # settled periods over which the period is detected
DIVERGED = 1e6        # |x| beyond this many predicted amplitudes while settling: the motion diverges
_PLAUSIBLE = math.log(8.0)   # a detected period within a factor 8 of the predicted one is used
MAX_RETURNS = 4       # crossings per period looked for on the settled motion (period-k orbits, k <= 4)
_RECUR = 1e-2         # relative state distance below which the settled motion has recurred (crossing times are
                      # interpolated between 64 samples per period: their states agree to ~1e-3, not to rounding)


class ShootingError(RuntimeError):
    """No periodic orbit was found; ``residual`` and ``iterations`` say how far Newton got."""

    def __init__(self, message: str, residual: float = math.inf, iterations: int = 0):
        super().__init__(message)
        self.residual, self.iterations = residual, iterations


@dataclass
class Orbit:
    """A converged periodic orbit: start state ``z`` and ``mode``, ``period`` (s), the ``flow`` over one period
    from there (with its monodromy), the final relative ``residual``, the Newton ``iterations``, and ``returns``:
    the oscillations (upward crossings of x through its mean) per period, k > 1 for a period-k orbit."""

    z: np.ndarray
    mode: object
    period: float
    flow: Flow
    residual: float
    iterations: int
    returns: int = 1
    path: str = "newton"   # "newton": Newton from the start nodes; "homotopy": the Newton homotopy from them


def detect_period(t: np.ndarray, x: np.ndarray) -> float | None:
    """Mean spacing (s) of the upward crossings of x through its mean level; None with fewer than 2 crossings."""
    tc = upward_crossings(t, x, float(np.mean(x)))
    return float((tc[-1] - tc[0]) / (tc.size - 1)) if tc.size >= 2 else None


def periodic_orbit(loop, N, amplitude: float, frequency: float, *, tol: float, max_iterations: int,
                   settle_periods: float, nodes: int, max_events: int, bias: float = 0.0,
                   homotopy: bool = True) -> Orbit:
    """Periodic orbit of ``loop`` near the predicted cycle (amplitude, frequency) by multiple shooting.

    Parameters
    ----------
    loop : exact loop model
        From :func:`dfloop.hybrid.loop_model` (``loop.exact`` True).
    N : DescribingFunction
        The element (its DF sets the harmonic-balance start).
    amplitude, frequency : float
        The prediction (element input units, rad/s).
    tol : float
        Newton stops when the relative defect is <= tol.
    max_iterations : int
        Bound on Newton iterations (each: one flow per node, at most 8 line-search flows).
    settle_periods : float
        Periods flowed from the prediction before shooting (0: nodes on the predicted sinusoid).
    nodes : int
        Shooting nodes per period.
    max_events : int
        Bound on the events of one flow.
    bias : float
        Mean of the predicted input, x ~ bias + amplitude sin(frequency t) (a loop with a constant input).
    homotopy : bool
        When Newton from nodes on the predicted orbit (``settle_periods`` 0) fails, follow the Newton homotopy
        from them (:func:`homotopy_orbit`) before raising.

    Raises
    ------
    ShootingError
        With the reason (flow failure, no convergence, singular Jacobian, no decreasing step).
    """
    T = 2.0 * math.pi / frequency
    m = node_count(loop, T, nodes)
    returns = 1
    try:
        if settle_periods > 0:
            zs, modes, T, c, returns = _settled_nodes(loop, N, amplitude, frequency, settle_periods, m, max_events,
                                                      bias)
            return newton_orbit(loop, zs, modes, T, c, tol=tol, max_iterations=max_iterations,
                                max_events=max_events, returns=returns)
        # nodes on the predicted sinusoidal orbit itself (right for unstable cycles, which a flow leaves)
        zs, modes, c = _predicted_nodes(loop, N, amplitude, frequency, m, max_events, bias)
    except HybridError as exc:
        raise ShootingError(f"the flow from the predicted orbit failed: {exc}") from None
    first = None
    for shift in (0.0, 0.5):   # Newton's basin depends on where the nodes sit: a second set half a node later
        try:
            if shift:
                zs_s, modes_s, c_s = _predicted_nodes(loop, N, amplitude, frequency, m, max_events, bias, shift)
            else:
                zs_s, modes_s, c_s = zs, modes, c
            return newton_orbit(loop, zs_s, modes_s, T, c_s, tol=tol, max_iterations=max_iterations,
                                max_events=max_events)
        except HybridError:
            continue
        except ShootingError as exc:
            first = first or exc
    if not homotopy:
        raise first
    try:   # Newton from the predicted orbit stalled: follow the Newton homotopy from it before giving up
        return homotopy_orbit(loop, zs, modes, T, c, tol=tol, max_iterations=max_iterations, max_events=max_events)
    except ShootingError as exc:
        raise ShootingError(f"{first}; the homotopy from the predicted orbit: {exc}", first.residual,
                            first.iterations) from None


def node_count(loop, period: float, nodes: int) -> int:
    """Shooting nodes for an orbit of ``period`` (s): at least ``nodes``, and enough that no node interval lets a
    perturbation grow by more than e^``NODE_GROWTH`` at the loop's fastest growth rate (``loop.growth_rate``: the
    largest real part among the eigenvalues of its modes; a Floquet-like bound of the orbit's own growth), at
    most ``MAX_NODES``. A strongly unstable orbit (a one-period flow from near it diverges) is then shot on
    intervals over which Newton's linearisation holds."""
    rate = float(getattr(loop, "growth_rate", 0.0))
    need = math.ceil(rate * period / NODE_GROWTH) if rate > 0.0 else 1
    return int(min(max(nodes, need), max(nodes, MAX_NODES)))


def middle_halves(t: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Node times t (s, increasing) with every node but the first moved into the middle half of its segment
    between consecutive switching times ``edges`` (s, increasing, spanning t): a small correction of the orbit then
    never moves a switch across a node."""
    j = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, edges.size - 2)
    margin = 0.25 * (edges[j + 1] - edges[j])
    out = t.copy()
    out[1:] = np.clip(t, edges[j] + margin, edges[j + 1] - margin)[1:]
    return out


def _predicted_nodes(loop, N, amplitude, frequency, m, max_events, bias, shift: float = 0.0):
    """m nodes on the predicted orbit x = bias + A sin(w t): (states, modes, intervals as fractions of T); the
    first node ``shift`` node intervals after the middle of the longest segment.

    Each node flows only its own interval (a strongly unstable orbit's one-period flow diverges); the switches
    those short flows meet place the first node in the middle of the longest segment between switches and move
    every other node into the middle half of its segment, so that small corrections never move a switch across a
    node."""
    T = 2.0 * math.pi / frequency
    t = np.arange(m) * (T / m)
    if loop.switching:
        switches = []
        for ti in t:
            zi, mi = loop.admissible_mode(*start_on_prediction(loop, N, amplitude, frequency, ti, bias))
            fl = loop.flow(zi, mi, T / m, max_events=max_events)
            switches.extend(ti + fl.event_times[fl.event_times > 0.0])
        bounds = np.unique(np.mod(np.asarray(switches, float), T))
        if bounds.size:
            gaps = np.diff(np.append(bounds, bounds[0] + T))
            k = int(np.argmax(gaps))
            t_first = bounds[k] + 0.5 * gaps[k] + shift * T / m
            t = t_first + np.arange(m) * (T / m)
            t = middle_halves(t, np.concatenate([bounds - T, bounds, bounds + T, bounds + 2 * T]))
            t = np.unique(t)
    zs, modes = [], []
    for ti in t:
        zi, mi = loop.admissible_mode(*start_on_prediction(loop, N, amplitude, frequency, ti, bias))
        zs.append(zi)
        modes.append(mi)
    if t.size == m and np.array_equal(t, np.arange(m) * (T / m)):
        return zs, modes, np.full(m, 1.0 / m)   # equal intervals exactly: a batched model flows them in one run
    return zs, modes, np.diff(np.append(t, t[0] + T)) / T


def newton_orbit(loop, zs: list, modes: list, T: float, c: np.ndarray, *, tol: float, max_iterations: int,
                 max_events: int, returns: int = 1) -> Orbit:
    """Multiple shooting by Newton's method from nodes ``zs`` (modes ``modes``; node i flows c_i T) and period T:
    the :class:`Orbit`, or ``ShootingError`` with the reason (see :func:`periodic_orbit`)."""
    m = len(zs)
    zs = [np.array(z, float) for z in zs]
    modes = list(modes)

    nx = loop.size - 1
    residual, it = math.inf, 0
    flows = None           # node flows with monodromy, when the line search already computed them
    for it in range(1, max_iterations + 1):
        try:
            if flows is None:
                flows = loop.flow_many(zs, modes, T * c, monodromy=True, max_events=max_events)
        except HybridError as exc:
            raise ShootingError(f"Newton iteration {it}: {exc}", residual, it) from None
        previous = residual
        residual = _defect(flows, zs, nx)
        consistent = all(flows[i].mode == modes[(i + 1) % m] for i in range(m))
        if consistent and (residual <= tol or (residual <= FLOOR and residual > 0.5 * previous)):
            break   # converged, or stalled at the rounding floor of the switch times (quadratic convergence ended)
        if it == max_iterations:
            raise ShootingError(f"Newton did not converge in max_iterations = {max_iterations} (residual "
                                f"{residual:.2e} > tol = {tol:g}): no periodic orbit near the prediction, or a "
                                "chaotic / quasi-periodic response; raise max_iterations or start elsewhere",
                                residual, it)
        J, F = _shooting_system(loop, flows, zs, modes, c, nx)
        try:
            delta = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            raise ShootingError(f"singular shooting Jacobian at iteration {it} (a multiplier equal to 1 besides "
                                "the trivial one: a marginal or non-isolated orbit)", residual, it) from None
        found = _line_search(loop, zs, flows, T, c, delta, residual, nx, max_events)
        if found is None:
            raise ShootingError(f"Newton iteration {it}: no step reduces the residual {residual:.2e} (no periodic "
                                "orbit near the prediction, or a chaotic / quasi-periodic response)", residual, it)
        zs, modes, T, flows = found
    try:
        fl = loop.join(flows, T, max_events=max_events)
    except HybridError as exc:
        raise ShootingError(f"the converged orbit cannot be followed over one period: {exc}", residual, it) from None
    return Orbit(zs[0], modes[0], T, fl, residual, it, returns)


def homotopy_orbit(loop, zs: list, modes: list, T: float, c: np.ndarray, *, tol: float, max_iterations: int,
                   max_events: int) -> Orbit:
    """Periodic orbit by the Newton (fixed-point) homotopy of the multiple-shooting system from a start u0.

    With F(u) the shooting defects of u = (nodes, period) (:func:`newton_orbit`), the path
    H(u, lam) = F(u) - (1 - lam) F(u0) = 0 starts at u0 for lam = 0 (the predicted orbit solves it) and reaches
    the true periodicity condition F(u) = 0 at lam = 1. It is followed by natural-parameter continuation in lam:
    steps of at first ``HOMOTOPY_STEP``, each corrected by at most ``HOMOTOPY_CORRECTIONS`` Newton iterations
    (halved on failure down to ``HOMOTOPY_MIN_STEP``, doubled after a success), at most ``HOMOTOPY_SOLVES``
    corrections in all. Where a Newton step from u0 only shrinks ||F||, the homotopy keeps F's direction, so it
    follows the orbit's branch through regions where damped Newton stalls (a strongly distorted or strongly
    unstable orbit). At lam = 1 :func:`newton_orbit` converges the orbit with the caller's ``tol``: an orbit from
    the homotopy passes exactly the check an orbit from Newton does (``Orbit.path`` = ``"homotopy"``).

    Raises
    ------
    ShootingError
        The path turns back in lam (a fold), a flow fails, or a bound is hit: with lam reached.
    """
    m = len(zs)
    nx = loop.size - 1
    zs = [np.array(z, float) for z in zs]
    modes = list(modes)
    c = np.asarray(c, float)

    def flows_of(nodes, node_modes, period):
        out, new_modes = [], []
        for i, (zi, mi) in enumerate(zip(nodes, node_modes)):   # modes follow the flows (hysteretic elements)
            mi = mi if i == 0 else out[-1].mode
            zi, mi = loop.admissible_mode(zi, mi)
            nodes[i] = zi
            new_modes.append(mi)
            out.append(loop.flow(zi, mi, period * c[i], monodromy=True, max_events=max_events))
        return out, new_modes

    try:
        flows, modes = flows_of(zs, modes, T)
    except HybridError as exc:
        raise ShootingError(f"the flow from the start failed: {exc}") from None
    F0 = _shooting_system(loop, flows, zs, modes, c, nx)[1]
    scale = max(float(np.linalg.norm(np.concatenate([z[:nx] for z in zs]))), 1e-300)
    lam, step, solves = 0.0, HOMOTOPY_STEP, 0
    while lam < 1.0:
        if solves >= HOMOTOPY_SOLVES:
            raise ShootingError(f"HOMOTOPY_SOLVES = {HOMOTOPY_SOLVES} corrections used at lam = {lam:.3g} (raise "
                                "dfloop.hybrid.shooting.HOMOTOPY_SOLVES to follow the path further)")
        target = min(1.0, lam + step)
        trial_z, trial_modes, trial_T, trial_flows = list(zs), list(modes), T, flows
        ok = False
        try:
            for _ in range(HOMOTOPY_CORRECTIONS):
                solves += 1
                J, F = _shooting_system(loop, trial_flows, trial_z, trial_modes, c, nx)
                H = F - (1.0 - target) * F0
                delta = np.linalg.solve(J, -H)
                trial_T = trial_T + delta[-1]
                if not trial_T > 0.0:
                    break
                trial_z = [z.copy() for z in trial_z]
                for i in range(m):
                    trial_z[i][:nx] += delta[i * nx:(i + 1) * nx]
                trial_flows, trial_modes = flows_of(trial_z, trial_modes, trial_T)
                H = _shooting_system(loop, trial_flows, trial_z, trial_modes, c, nx)[1] - (1.0 - target) * F0
                if np.linalg.norm(H) <= HOMOTOPY_TOL * scale:
                    ok = True
                    break
        except (HybridError, np.linalg.LinAlgError):
            ok = False
        if ok:
            lam, zs, modes, T, flows = target, trial_z, trial_modes, trial_T, trial_flows
            step = min(2.0 * step, 1.0)
        else:
            step *= 0.5
            if step < HOMOTOPY_MIN_STEP:
                raise ShootingError(f"the homotopy path stops at lam = {lam:.4g} (no corrected step down to "
                                    f"{HOMOTOPY_MIN_STEP:g}: a fold of the path or a flow that fails)")
    orbit = newton_orbit(loop, zs, modes, T, c, tol=tol, max_iterations=max_iterations, max_events=max_events)
    return dataclasses.replace(orbit, path="homotopy")


def _settled_nodes(loop, N, amplitude, frequency, settle_periods, m, max_events, bias=0.0):
    """Flow ``settle_periods`` predicted periods (one flow per period), detect the period on the last ones, and
    put the nodes on one period of the settled motion from the middle of its longest segment."""
    T = 2.0 * math.pi / frequency
    z, mode = start_on_prediction(loop, N, amplitude, frequency, bias=bias)
    whole = int(math.floor(settle_periods))
    spans = [T] * whole + ([(settle_periods - whole) * T] if settle_periods > whole else [])
    tail_t, tail_x, tail_flows = [], [], []
    for p, span in enumerate(spans):
        fl = loop.flow(z, mode, span, max_events=max_events)
        tk = np.arange(64) * (span / 64)
        x = loop.signals(fl, tk)[0]
        if p >= len(spans) - _DETECT_PERIODS:
            tail_t.append(p * T + tk)
            tail_x.append(x)
            tail_flows.append((p * T, span, fl))
        z, mode = fl.z, fl.mode
        if not np.all(np.isfinite(z)) or np.max(np.abs(x - bias)) > DIVERGED * amplitude:
            raise HybridError(f"the motion diverged while settling: |x| passed {DIVERGED:g} times the predicted "
                              f"amplitude in period {p + 1} of {settle_periods:g}")
    t_tail, x_tail = np.concatenate(tail_t), np.concatenate(tail_x)
    detected, returns = detect_period(t_tail, x_tail), 1
    if detected is not None:
        returns = _returns_per_period(loop, tail_flows, upward_crossings(t_tail, x_tail, float(np.mean(x_tail))))
    if detected is not None and abs(math.log(detected / T)) < _PLAUSIBLE:
        T = detected * returns        # one oscillation times the oscillations per period
        m *= returns                  # as many nodes per oscillation as a period-1 orbit gets
    else:
        returns = 1
    fl = loop.flow(z, mode, T, max_events=max_events)
    _, mode, t_mid = _section_point(fl, T, T)
    fl = loop.flow(loop.states(fl, t_mid)[0], mode, T, max_events=max_events)
    t = np.arange(m) * (T / m)
    if loop.switching:   # each node away from the switches: within the middle half of its segment
        bounds = np.append(fl.t0, T)
        k = np.clip(np.searchsorted(bounds, t, side="right") - 1, 0, bounds.size - 2)
        margin = 0.25 * (bounds[k + 1] - bounds[k])
        t[1:] = np.clip(t, bounds[k] + margin, bounds[k + 1] - margin)[1:]
        t = np.unique(t)
    seg = np.clip(np.searchsorted(fl.t0, t, side="right") - 1, 0, fl.t0.size - 1)
    return list(loop.states(fl, t)), [int(fl.modes[k]) for k in seg], T, np.diff(np.append(t, T)) / T, returns


def _returns_per_period(loop, tail_flows, crossings: np.ndarray) -> int:
    """Smallest k <= MAX_RETURNS after which the state at the upward crossings recurs (1 if none does, or when
    too few crossings were seen to tell).

    The state at each crossing time comes from the settled flows; k is accepted when every pair of crossings k
    apart is within ``_RECUR`` (relative to the largest state) while some pair one apart is not.
    """
    if crossings.size < 3:
        return 1
    states = []
    for tc in crossings:
        for start, span, fl in tail_flows:
            if start <= tc <= start + span:
                states.append(loop.states(fl, np.array([tc - start]))[0][:loop.size - 1])
                break
    z = np.array(states)
    scale = max(float(np.max(np.abs(z))), 1e-300)

    def spread(k):
        return float(np.max(np.abs(z[k:] - z[:-k]))) / scale

    if spread(1) <= _RECUR:
        return 1
    for k in range(2, min(MAX_RETURNS, z.shape[0] - 2) + 1):
        if spread(k) <= _RECUR:
            return k
    return 1


def _section_point(fl, t_end: float, T: float):
    """Segment index, mode and time of the middle of the longest segment between switches in the last period
    of a flow (segments that wrap around t_end - T count whole)."""
    starts = np.clip(fl.t0, t_end - T, t_end)
    ends = np.clip(np.append(fl.t0[1:], t_end), t_end - T, t_end)
    k = int(np.argmax(ends - starts))
    return k, int(fl.modes[k]), 0.5 * (starts[k] + ends[k])


def _defect(flows, zs, nx) -> float:
    """Relative size of the shooting defects phi(z_i) - z_{i+1}."""
    m = len(zs)
    d = np.concatenate([flows[i].z[:nx] - zs[(i + 1) % m][:nx] for i in range(m)])
    scale = max(float(np.linalg.norm(np.concatenate([z[:nx] for z in zs]))), 1e-300)
    return float(np.linalg.norm(d)) / scale


def _shooting_system(loop, flows, zs, modes, c, nx):
    """Jacobian and defects of multiple shooting in (z_0..z_{m-1}, T), node i flowing c_i T; last row: the
    correction orthogonal to the flow at z_0."""
    m = len(zs)
    n = m * nx + 1
    J = np.zeros((n, n))
    F = np.zeros(n)
    for i in range(m):
        r = slice(i * nx, (i + 1) * nx)
        j = (i + 1) % m
        J[r, r] += flows[i].monodromy[:nx, :nx]
        J[r, j * nx:(j + 1) * nx] -= np.eye(nx)
        J[r, -1] = loop.field(flows[i].z, flows[i].mode)[:nx] * c[i]
        F[r] = flows[i].z[:nx] - zs[j][:nx]
    J[-1, :nx] = loop.field(zs[0], modes[0])[:nx]
    return J, F


def _line_search(loop, zs, flows, T, c, delta, residual, nx, max_events):
    """Damped Newton step (halvings bounded by LINE_SEARCH) on nodes and period; node modes follow the flows.

    Returns (nodes, modes, period, flows): the flows are the trial's own, with monodromy, when the model runs
    all nodes at once (reused by the next iteration), else None."""
    m = len(zs)
    step = 1.0
    for _ in range(LINE_SEARCH + 1):
        T_new = T + step * delta[-1]
        if T / PERIOD_STEP < T_new < T * PERIOD_STEP:   # a step that moves the period by more is not a correction
            try:
                new_z, new_modes, trial = [], [], []
                if loop.batched:   # modes are functions of the state: all nodes at once, with monodromy
                    for i in range(m):
                        zi = zs[i].copy()
                        zi[:nx] += step * delta[i * nx:(i + 1) * nx]
                        zi, mi = loop.admissible_mode(zi, _mode_reaching(flows, i))
                        new_z.append(zi)
                        new_modes.append(mi)
                    trial = loop.flow_many(new_z, new_modes, T_new * c, monodromy=True, max_events=max_events)
                else:
                    # node modes follow the trial flows in turn (a hysteretic element's mode is not a function of
                    # the state: a node moved across a switch takes the mode the flow reaching it ends in)
                    for i in range(m):
                        zi = zs[i].copy()
                        zi[:nx] += step * delta[i * nx:(i + 1) * nx]
                        zi, mi = loop.admissible_mode(zi, trial[-1].mode if trial else flows[-1].mode)
                        new_z.append(zi)
                        new_modes.append(mi)
                        trial.append(loop.flow(zi, mi, T_new * c[i], max_events=max_events))
                if _defect(trial, new_z, nx) < residual or residual < FLOOR:
                    return new_z, new_modes, T_new, (trial if loop.batched else None)
            except HybridError:
                pass
        step *= 0.5
    return None


def _mode_reaching(flows, i: int):
    """The mode the flow reaching node i ends in."""
    return flows[i - 1].mode


def forced_orbit(loop, zs: list, modes: list, period: float, free: np.ndarray, *, tol: float, max_iterations: int,
                 max_events: int) -> Orbit:
    """Periodic orbit of a driven (non-autonomous) loop at the fixed forcing ``period``, by multiple shooting.

    The forcing is part of the loop's state (an exosystem, e.g. sin and cos of the forcing phase), so the loop
    model stays autonomous; only the components ``free`` (plant and element states) are unknowns, the others
    (the forcing's phase, the constant 1) are fixed by time. Newton solves phi_{T/m}(z_i)[free] = z_{i+1}[free]
    (i = 0..m-1, z_m = z_0) with the node flows' monodromies as Jacobian blocks; there is no phase condition and
    the period is not an unknown.

    Parameters
    ----------
    loop : exact loop model
        With the forcing in its state.
    zs, modes : list
        The m nodes' start states (at times i T / m) and modes.
    period : float
        The forcing period T (s).
    free : ndarray of int
        Indices of the unknown components of the state.
    tol, max_iterations, max_events
        As for :func:`periodic_orbit`.

    Returns
    -------
    Orbit
        Its ``flow`` over one period from the first node, with the monodromy (the multipliers are the
        eigenvalues of ``flow.monodromy[free][:, free]``).

    Raises
    ------
    ShootingError
        With the reason (flow failure, no convergence within ``max_iterations``, singular Jacobian, no decreasing
        step): then no orbit at the forcing period was found near the start.
    """
    m = len(zs)
    k = free.size
    tau = period / m
    zs = [np.array(z, float) for z in zs]
    modes = list(modes)

    def flows_of(nodes, node_modes):
        return loop.flow_many(nodes, node_modes, tau, monodromy=True, max_events=max_events)

    def defect(flows, nodes):
        d = np.concatenate([flows[i].z[free] - nodes[(i + 1) % m][free] for i in range(m)])
        scale = max(float(np.linalg.norm(np.concatenate([z[free] for z in nodes]))), 1e-300)
        return float(np.linalg.norm(d)) / scale, d

    residual, it = math.inf, 0
    try:
        flows = flows_of(zs, modes)
    except HybridError as exc:
        raise ShootingError(f"the flow from the start failed: {exc}") from None
    for it in range(1, max_iterations + 1):
        previous = residual
        residual, d = defect(flows, zs)
        consistent = all(flows[i].mode == modes[(i + 1) % m] for i in range(m))
        if consistent and (residual <= tol or (residual <= FLOOR and residual > 0.5 * previous)):
            break
        if it == max_iterations:
            raise ShootingError(f"Newton did not converge in max_iterations = {max_iterations} (residual "
                                f"{residual:.2e} > tol = {tol:g}): no orbit at the forcing period near the start "
                                "(a subharmonic or quasi-periodic response?); raise max_iterations or start elsewhere",
                                residual, it)
        J = np.zeros((m * k, m * k))
        for i in range(m):
            r = slice(i * k, (i + 1) * k)
            J[r, r] = flows[i].monodromy[np.ix_(free, free)]
            j = (i + 1) % m
            J[r, j * k:(j + 1) * k] -= np.eye(k)
        try:
            delta = np.linalg.solve(J, -d)
        except np.linalg.LinAlgError:
            raise ShootingError(f"singular shooting Jacobian at iteration {it} (a multiplier equal to 1: a fold of "
                                "the forced response)", residual, it) from None
        step, found = 1.0, None
        for _ in range(LINE_SEARCH + 1):
            try:
                new_z, new_modes = [], []
                for i in range(m):
                    zi = zs[i].copy()
                    zi[free] += step * delta[i * k:(i + 1) * k]
                    zi, mi = loop.admissible_mode(zi, flows[i - 1].mode)
                    new_z.append(zi)
                    new_modes.append(mi)
                trial = flows_of(new_z, new_modes)
                if defect(trial, new_z)[0] < residual or residual < FLOOR:
                    found = new_z, new_modes, trial
                    break
            except HybridError:
                pass
            step *= 0.5
        if found is None:
            raise ShootingError(f"Newton iteration {it}: no step reduces the residual {residual:.2e} (no orbit at "
                                "the forcing period near the start, or a subharmonic / quasi-periodic response)",
                                residual, it)
        zs, modes, flows = found
    try:
        fl = loop.join(flows, period, max_events=max_events)
    except HybridError as exc:
        raise ShootingError(f"the converged orbit cannot be followed over one period: {exc}", residual, it) from None
    return Orbit(zs[0], modes[0], period, fl, residual, it)
