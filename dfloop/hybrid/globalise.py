"""Never a false "no orbit": what :func:`dfloop.exact_cycle` does when shooting from the prediction fails.

Newton's method converges only near an orbit; a prediction that the describing function places poorly (high
distortion, a Padé chain, a long delay) can leave it stalled although a true, attracting orbit lies close by.
Before answering "no orbit", :func:`shoot_or_globalise`:

0. (in the first shooting) follows the Newton homotopy from the predicted orbit when Newton from it stalls
   (:func:`dfloop.hybrid.shooting.homotopy_orbit`; ``extra["path"]`` says which found the orbit);
1. shoots again from the prediction itself (no settling) with fewer multiple-shooting nodes (1 and 2: a node
   set that straddles a fast switch can stall where single shooting converges);
2. simulates the loop on the exact flow from the prediction and from starts 0.7 and 1.4 times its amplitude
   (``RUN_PERIODS`` predicted periods each) and measures where each motion went: a periodic motion (amplitude,
   frequency, periodicity), rest (anywhere: at x = 0 or off it inside the element's dead band or play, with
   ``x_end`` and the element's output ``y_end`` there), divergence, or a motion not periodic within the run;
3. shoots from every oscillating motion found (after settling on it for 20 more periods).

An orbit found within ``max_deviation`` of the prediction is returned (its message says how it was found). A
"no periodic orbit" answer carries the evidence: ``extra["motions"]`` (one dict per start) and
``extra["outcome"]``, one of ``"another cycle"`` (the motions settle on an exact orbit far from the
prediction; its numbers are in the message), ``"rest"``, ``"divergence"``, ``"not periodic"``, ``"boundary"``
(some motions decay to rest, others diverge: an unstable orbit may lie between them, so no orbit is ruled out),
``"incomplete"`` (some starts could not be followed on the exact flow, e.g. a motion that slides on a switching
surface: the others alone rule nothing out), or ``"shooting failed"`` (a periodic motion was seen but no shooting
from it converged).
"""
from __future__ import annotations

import contextvars
import dataclasses
import math

import numpy as np

from ..harmonics import steady_state
from .delay import DelayError, delay_simulation, split_delay
from .loop import HybridError
from .edge import EDGE_PERIODS, EdgeTrack, edge_track
from .model import loop_model, start_on_prediction

__all__ = ["shoot_or_globalise", "inside_search", "homotopy_allowed", "RUN_PERIODS", "STARTS"]

RUN_PERIODS = 200          # predicted periods per run
STARTS = (1.0, 0.7, 1.4)   # start amplitudes, relative to the prediction
_MEASURE = 10              # periods measured at the end of a run
_PERIODIC = 1e-2           # relative spread of the per-period amplitudes (64 samples per predicted period, so a
                           # coarse measure) below which a motion counts as periodic; shooting then decides
_REST = 1e-6               # |x| below this fraction of the start amplitude: rest
_DIVERGED = 1e6

_INSIDE = contextvars.ContextVar("dfloop_exact_cycle_inside", default=False)
_HOMOTOPY = contextvars.ContextVar("dfloop_exact_cycle_homotopy", default=True)


def homotopy_allowed() -> bool:
    """False in the globalisation's further attempts: the homotopy from the prediction ran in the first one."""
    return _HOMOTOPY.get()


def inside_search() -> bool:
    """True inside a shooting that :func:`shoot_or_globalise` started (its ``exact_cycle`` calls)."""
    return _INSIDE.get()


def shoot_or_globalise(G, N, predicted: tuple, shoot, max_deviation: float, constant: dict | None = None,
                       finish=None, counterpart: bool = False):
    """Run ``shoot(cycle, **options)`` (one :func:`dfloop.exact_cycle` call) and globalise when it fails.

    ``constant``: the loop's constant input and the predicted bias (``r0``, ``load``, ``bias``), for the runs.
    ``finish(loop, orbit)``: the :class:`~dfloop.exact.ExactCycle` of an orbit the edge tracking converged (None:
    no edge tracking).
    ``counterpart``: an orbit farther than ``max_deviation`` is still returned when it is this prediction's own
    (:func:`_counterpart`).

    Returns None when called from inside a shooting started here (the caller then shoots itself), otherwise
    an :class:`~dfloop.exact.ExactCycle`.
    """
    if _INSIDE.get():
        return None
    token = _INSIDE.set(True)
    try:
        first = shoot(predicted)
        if first.success:
            return first
        quiet = _HOMOTOPY.set(False)
        try:
            return _globalise(G, N, predicted, first, shoot, max_deviation, constant or {}, finish, counterpart)
        finally:
            _HOMOTOPY.reset(quiet)
    finally:
        _INSIDE.reset(token)


def _simulate(G, N, A: float, w: float, periods: float, r0: float = 0.0, load: float = 0.0, bias: float = 0.0):
    """(t, x, diverged, method, y_end, x_end) of the loop run on its exact flow from the predicted orbit of (A, w),
    or None when the loop has no exact flow (a run that fails part-way returns the part before the failure). With
    a constant input (r0, load) the run starts on x = bias + A sin(w t) and x is returned less its final mean;
    y_end and x_end are the element's output and its input itself (not less any mean) at the end of the run."""
    try:
        loop = loop_model(G, N, A + abs(bias), w, r0=r0, load=load)
    except ValueError:
        return None
    if not loop.exact:
        return None
    if loop.delay > 0:
        try:
            sim = delay_simulation(loop, A, w, periods, 64, diverge=_DIVERGED, bias=bias)
        except DelayError as exc:
            if "left the range" in str(exc):          # the quantizer's modelled range (64 A): a divergence
                return np.array([0.0]), np.array([_DIVERGED * A]), True, str(exc), math.nan, math.nan
            if "never switches" in str(exc):          # the element stays at rest: so does its output
                return np.array([0.0]), np.array([0.0]), False, str(exc), 0.0, math.nan
            return None
        shifted = (r0 or load or bias) and not sim.diverged       # x less its final mean, as below
        x = sim.x - np.mean(sim.x[-max(sim.x.size // 10, 1):]) if shifted else sim.x
        return sim.t, x, sim.diverged, sim.method, float(sim.y[-1]), float(sim.x[-1])
    P = 2.0 * math.pi / w
    ts, xs = [], []
    diverged, y_end = False, math.nan
    try:
        z, mode = start_on_prediction(loop, N, A, w, bias=bias)
        for p in range(int(periods)):
            fl = loop.flow(z, mode, P, max_events=100_000,
                           **({"limit": _DIVERGED * A} if getattr(loop, "bounded", False) else {}))
            tk = np.arange(64) * (P / 64)
            if getattr(fl, "stopped", None) is not None:   # passed the divergence bound within the period
                tk = tk[tk <= fl.stopped]
                diverged = True
            xk, yk = loop.signals(fl, tk)
            y_end = float(yk[-1])
            ts.append(p * P + tk)
            xs.append(xk)
            z, mode = fl.z, fl.mode
            if diverged or not np.all(np.isfinite(xk)) or np.max(np.abs(xk - bias)) > _DIVERGED * A:
                diverged = True
                break
    except HybridError:
        if not ts:
            return None
    x = np.concatenate(xs)
    x_end = float(x[-1])
    if (r0 != 0.0 or load != 0.0 or bias != 0.0) and not diverged:
        x = x - np.mean(x[-max(x.size // 10, 1):])
    return np.concatenate(ts), x, diverged, loop.method, y_end, x_end


def _motion(G, N, A0: float, w0: float, factor: float, constant: dict | None = None) -> dict:
    """Where the motion started on the predicted orbit scaled by ``factor`` went."""
    A = factor * A0
    run = _simulate(G, N, A, w0, RUN_PERIODS, **(constant or {}))
    out = {"start_amplitude": A, "start_frequency": w0, "periods": RUN_PERIODS}
    if run is None:
        return {**out, "outcome": "no simulation"}
    t, x, diverged, _, y_end, x_end = run
    if diverged:
        return {**out, "outcome": "divergence", "amplitude": float(np.max(np.abs(x)))}
    if t.size < 3:          # the element never switches from this start: its output stays at rest
        return {**out, "outcome": "rest", "amplitude": 0.0, "note": run[3]}
    tail = x[t > t[-1] - 0.1 * (t[-1] - t[0])]
    if np.max(np.abs(tail)) < _REST * A:
        return {**out, "outcome": "rest", "amplitude": float(np.max(np.abs(tail))), "x_end": x_end,
                "y_end": y_end}
    if _at_rest(tail, A):   # rest off zero (inside a dead band or play, or an equilibrium of a biased loop)
        return {**out, "outcome": "rest", "amplitude": float(np.ptp(tail) / 2), "x_end": x_end,
                "y_end": y_end}
    st = steady_state(t, x, _MEASURE)
    if not st.oscillating:   # no zero crossing left: at rest, possibly off zero (in a play or dead band)
        return {**out, "outcome": "rest", "amplitude": float(st.amplitude), "x_end": x_end, "y_end": y_end}
    kind = "periodic" if st.periodicity < _PERIODIC else "not periodic"
    return {**out, "outcome": kind, "amplitude": float(st.amplitude), "frequency": float(st.frequency),
            "periodicity": float(st.periodicity)}


def _at_rest(tail: np.ndarray, A: float) -> bool:
    """True when x comes to rest anywhere, not only at 0 (an equilibrium in the element's zero set, e.g. inside a
    dead zone around a plant with an integrator): over the last tenth of the run x either no longer moves (its
    spread below ``_REST`` times the start amplitude) or stays on one side of its end value's sign while its
    spread shrinks (the last quarter of the tail moves less than half as much as the first quarter)."""
    if np.ptp(tail) <= _REST * A:
        return True
    q = max(tail.size // 4, 2)
    one_side = bool(np.all(tail > 0) or np.all(tail < 0))
    return one_side and np.ptp(tail[-q:]) < 0.5 * np.ptp(tail[:q])


def _words(m: dict) -> str:
    start = f"from A={m['start_amplitude']:.4g}"
    k = m["outcome"]
    if k == "periodic":
        return f"{start}: periodic, A={m['amplitude']:.6g}, w={m['frequency']:.6g} rad/s"
    if k == "not periodic":
        return (f"{start}: not periodic within {m['periods']} periods (A~{m['amplitude']:.4g}, "
                f"w~{m['frequency']:.4g} rad/s, amplitude spread {m['periodicity']:.2g})")
    if k == "rest":
        if "note" in m:
            return f"{start}: the element never switches ({m['note']})"
        where = f"{start}: comes to rest at x = {m['x_end']:.4g}"
        if m.get("y_end") == 0.0 and m["x_end"] != 0.0:
            where += " (element output 0 there: inside its dead band or play)"
        return where
    if k == "divergence":
        return f"{start}: diverges (|x| reached {m['amplitude']:.3g})"
    return f"{start}: the loop cannot be simulated here"


def _edge_loop(G, N, predicted, constant):
    A0, w0 = predicted
    return loop_model(G, N, A0 + abs(constant.get("bias", 0.0)), w0, r0=constant.get("r0", 0.0),
                      load=constant.get("load", 0.0))


def _edge_verdict(edge, outcome: str, msg: str) -> tuple[str, str]:
    """The outcome and message once edge tracking has followed the boundary between the starts' fates."""
    if edge.outcome in ("rest", "slow"):
        return "edge rest", (f"no periodic orbit near the prediction: of the motions started on and around it some "
                             f"{edge.inside} and some {edge.outside}, and the boundary between them (edge tracking) "
                             "is rest, not a periodic orbit (see the evidence)")
    if outcome == "boundary":
        return outcome, f"{msg}; edge tracking on that boundary was inconclusive ({edge.outcome})"
    return outcome, msg


def _rebase(found, predicted, how: str):
    """The orbit ``found`` (shot from another start) reported against the original prediction."""
    A0, w0 = predicted
    A, w = found.amplitude, found.frequency
    return dataclasses.replace(found, predicted=predicted, amplitude_error=(A0 - A) / A, frequency_error=(w0 - w) / w,
                               message=f"{found.message}; found by globalisation ({how})",
                               extra={**found.extra, "outcome": "orbit", "globalised": how})


def _bracket(motions: list, others: list) -> tuple | None:
    """(inside, outside) start factors of two neighbouring starts with different fates (rest, divergence, a cycle:
    the orbit shooting found from the motion, or its measured amplitude), or None."""
    def fate(m, orbit):
        if m["outcome"] in ("rest", "divergence"):
            return m["outcome"]
        if m["outcome"] == "periodic":
            return ("cycle", round(math.log((orbit.amplitude if orbit is not None else m["amplitude"])), 1))
        return None

    ranked = sorted(zip(motions, others), key=lambda p: p[0]["start_amplitude"])
    fates = [fate(m, o) for m, o in ranked]
    for (m1, _), (m2, _), f1, f2 in zip(ranked, ranked[1:], fates, fates[1:]):
        if f1 is not None and f2 is not None and f1 != f2:
            return m1["start_amplitude"], m2["start_amplitude"]
    return None


def _edge(G, N, predicted, motions, orbits, constant):
    """The edge tracking between the first two neighbouring starts with different fates: the EdgeTrack, or a
    sentence saying why none ran (None when no two starts differ)."""
    A0, w0 = predicted
    pair = _bracket(motions, orbits)
    if pair is None:
        return None
    if split_delay(G)[1] > 0:
        return "edge tracking between them is not available on the delay engines (their state is a history)"
    try:
        loop = loop_model(G, N, A0 + abs(constant.get("bias", 0.0)), w0, r0=constant.get("r0", 0.0),
                          load=constant.get("load", 0.0))
    except ValueError as exc:
        return f"no loop model to track the boundary on ({exc})"
    if not loop.exact:
        return "edge tracking needs an exact flow"
    return edge_track(loop, N, A0, w0, pair[0] / A0, pair[1] / A0, bias=constant.get("bias", 0.0),
                      periods=EDGE_PERIODS)


def _counterpart(G, N, predicted: tuple, orbit, constant: dict) -> str:
    """Why the exact ``orbit`` the motions from the prediction settle on, though farther than ``max_deviation``, is
    this prediction's own counterpart, or ``""`` when it is not: the DF's predictions of the loop in a window
    around both (:func:`dfloop.predict_limit_cycles`) include this one, with the orbit's stability, and no other
    prediction is nearer to the orbit (in max |ln A|, |ln w|). A DF that misplaces a strongly distorted cycle (a dead
    zone barely exceeded) is then answered with the true orbit and its distance, not with "another cycle"."""
    from ..solve.predict import predict_limit_cycles

    if any(constant.get(k, 0.0) for k in ("r0", "load", "bias")):
        return ""
    (A0, w0), A, w = predicted, orbit.amplitude, orbit.frequency
    try:
        cycles = predict_limit_cycles(G, N, amplitude=(min(A0, A) / 4, 4 * max(A0, A)),
                                      omega=(min(w0, w) / 4, 4 * max(w0, w)))
    except ValueError:
        return ""

    def far(c, a, f):
        return max(abs(math.log(c.amplitude / a)), abs(math.log(c.frequency / f)))
    own = [c for c in cycles if far(c, A0, w0) < 1e-6]
    if not own or own[0].stability != ("stable" if orbit.stable else "unstable"):
        return ""
    nearest = min(far(c, A, w) for c in cycles)
    if far(own[0], A, w) > nearest:
        return ""
    return (f"the orbit is {far(own[0], A, w):.3g} away in log(A) or log(w), beyond max_deviation, but no other "
            f"DF prediction of the loop ({len(cycles)} in A {min(A0, A) / 4:.3g}-{4 * max(A0, A):.3g}, w "
            f"{min(w0, w) / 4:.3g}-{4 * max(w0, w):.3g} rad/s) is nearer to it and its stability agrees: it is "
            "this prediction's orbit, the DF misplaces it")


def _globalise(G, N, predicted, first, shoot, max_deviation, constant, finish=None, counterpart=False):
    A0, w0 = predicted
    near = first.extra.get("another_orbit")     # Newton converged, but farther than max_deviation
    claim = _counterpart(G, N, predicted, near, constant) if counterpart and near is not None else ""
    if claim:
        return _rebase(near, predicted, f"shooting from the prediction converged to it; {claim}")
    tried = [f"shooting from the prediction: {first.message}"]
    delayed = split_delay(G)[1] > 0
    if not delayed:
        for nodes in (1, 2):
            try:
                r = shoot(predicted, nodes=nodes, settle_periods=0.0)
            except ValueError:
                break
            if r.success:
                return _rebase(r, predicted, f"single/multiple shooting with {nodes} node(s) from the prediction")
            tried.append(f"{nodes} node(s): {r.message}")
    motions = [_motion(G, N, A0, w0, f, constant) for f in STARTS]
    others, orbits = [], []
    for m in motions:
        orbits.append(None)
        if m["outcome"] not in ("periodic", "not periodic"):
            continue
        r = None
        for nodes in ((1,) if delayed else (1, 2)):
            try:
                r = shoot((m["amplitude"], m["frequency"]), settle_periods=20.0, nodes=nodes, max_deviation=0.5)
            except ValueError:
                continue
            if r.success:
                break
        if r is None or not r.success:
            continue
        deviation = max(abs(math.log(r.amplitude / A0)), abs(math.log(r.frequency / w0)))
        how = (f"the motion from A={m['start_amplitude']:.4g} settled at A={m['amplitude']:.6g}, "
               f"w={m['frequency']:.6g} rad/s; shooting from there converged")
        if deviation <= max_deviation:
            return _rebase(r, predicted, how)
        others.append((r, how))
        orbits[-1] = r
    if all(m["outcome"] == "no simulation" for m in motions):
        return first      # no time-domain model to globalise with: the first answer stands
    evidence = "; ".join(_words(m) for m in motions)
    edge = _edge(G, N, predicted, motions, orbits, constant) if finish is not None else None
    edge_orbit = None
    if isinstance(edge, EdgeTrack):
        evidence += f"; edge tracking: {edge.message} ({edge.periods:.3g} predicted periods on the boundary, " \
                    f"{edge.trials} trial runs, {edge.seconds:.2g} s)"
        if edge.orbit is not None:
            r = finish(_edge_loop(G, N, predicted, constant), edge.orbit)
            k = r.extra.get("returns", 1) if r.success else 1
            if r.success:
                deviation = max(abs(math.log(abs(r.harmonics[k - 1]) / A0)), abs(math.log(k * r.frequency / w0)))
                how = (f"edge tracking: the motion on the boundary between the starts that "
                       f"{edge.inside} and those that {edge.outside} became periodic; shooting from it converged")
                if deviation <= max_deviation:
                    out = _rebase(r, predicted, how)
                    return dataclasses.replace(out, extra={**out.extra, "edge": edge.to_dict()})
                others.insert(0, (r, how))
                edge_orbit = r
    elif isinstance(edge, str):
        evidence += f"; {edge}"
    if others:
        o, how = others[0]
        claim = _counterpart(G, N, predicted, o, constant) if counterpart else ""
        if claim:
            return _rebase(o, predicted, f"{how}; {claim}")
        outcome = "another cycle"
        where = ("the motion on the boundary between the fates of the starts around it (edge tracking) settles on "
                 "another cycle" if o is edge_orbit else "the motions started on and around it go to another cycle")
        msg = (f"no periodic orbit near the prediction: {where}, "
               f"the exact orbit A={o.amplitude:.6g}, w={o.frequency:.6g} rad/s "
               f"({'stable' if o.stable else 'unstable'}), farther than max_deviation = {max_deviation:g}")
    else:
        kinds = [m["outcome"] for m in motions]
        outcome = ("shooting failed" if "periodic" in kinds else "divergence" if "divergence" in kinds
                   else "not periodic" if "not periodic" in kinds else "rest")
        msg = {"shooting failed": "a periodic motion was seen but no shooting from it converged (raise "
                                  "max_iterations, or check the loop for sliding / grazing motion)",
               "divergence": "no periodic orbit near the prediction: motions started on and around it diverge",
               "not periodic": "no periodic orbit near the prediction found: the motions started on and around "
                               "it are not periodic within the runs (chaotic, quasi-periodic or slowly settling)",
               "rest": "no periodic orbit near the prediction: motions started on and around it decay to rest",
               }[outcome]
        if outcome == "divergence" and "rest" in kinds:
            # a boundary between rest and divergence: an unstable orbit may separate them, so nothing is ruled out
            outcome = "boundary"
            msg = (f"no periodic orbit found near the prediction, but none ruled out: of the motions started on and "
                   f"around it {kinds.count('rest')} decay to rest and {kinds.count('divergence')} diverge, so the "
                   "prediction lies near the boundary between the two, where an unstable orbit may lie (shooting "
                   "did not converge to one)")
        elif outcome in ("rest", "divergence", "not periodic") and "no simulation" in kinds:
            # a start that cannot be followed gives no evidence: the others alone cannot rule an orbit out
            outcome = "incomplete"
            seen = ", ".join(f"{kinds.count(k)} {k}" for k in ("rest", "divergence", "not periodic") if k in kinds)
            msg = (f"no periodic orbit found near the prediction, but none ruled out: {kinds.count('no simulation')} "
                   f"of the {len(kinds)} motions started on and around it could not be followed on the exact flow "
                   f"(the others: {seen})")
        if isinstance(edge, EdgeTrack) and outcome in ("boundary", "another cycle", "rest", "divergence"):
            outcome, msg = _edge_verdict(edge, outcome, msg)
    if isinstance(edge, EdgeTrack) and outcome == "another cycle" and edge.outcome not in ("rest", "slow", "orbit"):
        # some starts go to another cycle, others elsewhere, and the boundary between them was not resolved
        outcome = "boundary"
        msg += (f"; but the motions split between two fates and edge tracking on the boundary between them was "
                f"inconclusive ({edge.outcome}), so an unstable orbit near the prediction is not ruled out")
    elif isinstance(edge, EdgeTrack) and outcome == "another cycle" and edge.outcome != "orbit":
        outcome = "edge rest"
        msg += "; the boundary between the fates of the starts runs through rest, not through a periodic orbit"
    extra = {**first.extra, "outcome": outcome, "motions": motions, "attempts": tried}
    if isinstance(edge, EdgeTrack):
        extra["edge"] = edge.to_dict()
    return dataclasses.replace(first, message=f"{msg}. Evidence: {evidence}. First attempt: {first.message}",
                               extra=extra)
