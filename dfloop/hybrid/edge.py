"""Edge tracking: the motion on the boundary between two basins, and the unstable orbit it may settle on.

When the motions started inside a predicted (unstable) cycle go one way (rest, a smaller cycle) and those
started outside another (divergence, a larger cycle), the boundary between the two basins runs between the
starts, and an unstable periodic orbit, if one exists there, lies on it. Edge tracking (Skufca, Yorke &
Eckhardt 2006; Schneider, Eckhardt & Yorke 2007) follows the boundary:

1. bisect the start amplitude factor f between a start whose fate is the inside one and a start whose fate is
   the outside one (each trial's fate decided by running it on the loop's exact flow, :meth:`flow` of the loop
   model) until the two starts are closer than ``EDGE_EPS`` (relative to the size of the predicted state);
2. run the pair forward (``CHUNKS`` steps per predicted period) until they are farther apart than
   ``EDGE_DELTA``; their last common states bracket the boundary again: bisect on the segment between them;
3. repeat, following the motion that stays on the boundary, for at most ``periods`` predicted periods
   (``EDGE_PERIODS`` by default: raise it with ``edge_track(..., periods=)``, or the module constant for
   :func:`dfloop.exact_cycle`).

The fate of a trial is decided on ``a``, half the spread of x over the last two predicted periods: the inside
fate "rest" when ``a`` < ``REST`` times the predicted amplitude, "divergence" when the flow passes ``LIMIT``
times it, a cycle when ``a`` stays within ``MATCH`` of that cycle's own spread for 3 windows; a trial that
reaches neither fate within ``FATE_PERIODS`` periods ends the tracking ("undecided").

The boundary motion ends as one of (``EdgeTrack.outcome``):

- ``"orbit"``: it becomes periodic (its upward crossings of the mean and its spreads repeat to ``PERIODIC``);
  multiple shooting (:func:`dfloop.hybrid.shooting.newton_orbit`) from nodes on one period of it converges:
  the unstable orbit on the boundary (``EdgeTrack.orbit``);
- ``"rest"``: its oscillation falls below ``EDGE_REST`` of the predicted amplitude (the boundary itself
  leads to rest: a continuum of rests such as a backlash's play); ``x_rest`` says where the inside member of
  the pair comes to rest (the element input x itself, not its deviation from a mean);
- ``"not periodic"``: the bound was reached without periodicity (chaotic or slowly drifting);
- ``"periodic, shooting failed"``, ``"undecided"``, ``"failed"`` (the flow cannot follow the pair):
  inconclusive, with the reason.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .._blas import single_threaded_blas
from ..harmonics import upward_crossings
from .loop import HybridError
from .model import start_on_prediction
from .shooting import ShootingError, middle_halves, newton_orbit, node_count

__all__ = ["EdgeTrack", "edge_track", "EDGE_PERIODS", "FATE_PERIODS"]

EDGE_PERIODS = 100     # predicted periods followed on the boundary (the bound of the tracking)
FATE_PERIODS = 200     # predicted periods a trial may run before its fate counts as undecided
MAX_TRIALS = 3000      # bound on the trial runs of one tracking
CHUNKS = 8             # steps per predicted period while the pair advances
SAMPLES = 64           # samples of x per predicted period (times the oscillations seen in it, <= 16 times)
EDGE_EPS = 1e-7        # bisection ends when the pair is this close (relative to the predicted state's size)
EDGE_DELTA = 1e-4      # the pair has separated when this far apart
REST = 1e-6            # a trial's oscillation below this fraction of the predicted amplitude: rest
EDGE_REST = 1e-3       # the boundary motion's oscillation below this fraction: the boundary leads to rest
LIMIT = 1e3            # |x| beyond this many predicted amplitudes: divergence
MATCH = 0.02           # a trial within this relative spread of a cycle's (3 windows running) has reached it
SETTLED = 1e-3         # a bracket's own cycle: its spread steady to this (relative) for 5 windows
PERIODIC = 2e-2        # relative spread of the boundary motion's last oscillation periods and spreads below
                       # which it looks periodic: shooting from it then decides
_SHOTS = 6             # shootings tried from a periodic-looking boundary motion (one per 2 periods at most)


@dataclass
class EdgeTrack:
    """What edge tracking found on the boundary between two basins (see the module notes).

    ``outcome``: ``"orbit"``, ``"rest"``, ``"not periodic"``, ``"periodic, shooting failed"``, ``"undecided"`` or
    ``"failed"``; ``message``: the evidence in words; ``orbit``: the :class:`~dfloop.hybrid.shooting.Orbit`
    (``"orbit"`` only); ``time``: how long (s) the boundary motion was followed, ``periods`` that in predicted
    periods; ``trials``: trial runs (bisections) used; ``flow_periods``: predicted periods flowed in all (the
    cost); ``seconds``: wall time; ``inside``, ``outside``: the fates bracketing the boundary; ``amplitude``,
    ``frequency``: the boundary motion's last spread of x (half its range) and oscillation frequency (rad/s, or
    None); ``x_rest``: where x comes to rest (``"rest"``, ``"slow"``); ``boundary``: the
    start amplitude factor where the first bisection (along the starts on the scaled predicted orbit) put the
    boundary (its inside end), or None; ``times``, ``x``: the boundary motion's samples.
    """

    outcome: str
    message: str
    orbit: object = None
    time: float = 0.0
    periods: float = 0.0
    trials: int = 0
    flow_periods: float = 0.0
    seconds: float = 0.0
    inside: str = ""
    outside: str = ""
    amplitude: float | None = None
    frequency: float | None = None
    x_rest: float | None = None
    boundary: float | None = None
    times: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False)
    x: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False)

    def __repr__(self) -> str:
        return (f"EdgeTrack({self.outcome}: {self.message}; {self.periods:.3g} periods on the boundary, "
                f"{self.trials} trials, {self.seconds:.3g} s)")

    def to_dict(self) -> dict:
        """Plain data (the orbit and the samples left out)."""
        return {"outcome": self.outcome, "message": self.message, "time": self.time, "periods": self.periods,
                "trials": self.trials, "flow_periods": self.flow_periods, "seconds": self.seconds,
                "inside": self.inside, "outside": self.outside, "amplitude": self.amplitude,
                "frequency": self.frequency, "x_rest": self.x_rest, "boundary": self.boundary}


class _Stop(Exception):
    """Tracking ends: an outcome and its words."""

    def __init__(self, outcome: str, message: str):
        super().__init__(message)
        self.outcome, self.message = outcome, message


class _Tracker:
    def __init__(self, loop, A0, w0, periods, tol, max_iterations, max_events, nodes, max_trials):
        self.loop, self.A0, self.w0 = loop, A0, w0
        self.P = 2.0 * math.pi / w0
        self.periods, self.tol, self.max_iterations = periods, tol, max_iterations
        self.max_events, self.nodes, self.max_trials = max_events, nodes, max_trials
        self.nx = loop.size - 1
        self.limit = LIMIT * A0
        self.trials, self.flowed = 0, 0.0
        self.targets = {}                 # "inside" / "outside" -> (kind, spread)

    # ------------------------------------------------------------------------------------------ flows

    def flow(self, z, mode, span):
        kw = {"limit": self.limit} if getattr(self.loop, "bounded", False) else {}
        fl = self.loop.flow(z, mode, span, max_events=self.max_events, **kw)
        self.flowed += span / self.P
        return fl

    def x_of(self, fl, span, count):
        count = min(count * max(1, len(fl.events) // 2), 16 * count)   # >= ~64 samples per oscillation
        tk = np.arange(count) * (span / count)
        if getattr(fl, "stopped", None) is not None:
            tk = tk[tk <= fl.stopped]
        return tk, self.loop.signals(fl, tk)[0]

    def diverged(self, fl, x) -> bool:
        return (getattr(fl, "stopped", None) is not None or not np.all(np.isfinite(fl.z))
                or not np.all(np.isfinite(x)) or np.max(np.abs(x), initial=0.0) > self.limit)

    def run(self, z, mode, settle: bool, horizon: int = FATE_PERIODS):
        """Run from (z, mode) period by period until a fate: ("rest" | "divergence" | "cycle", spread). With
        ``settle`` any steady cycle counts (a bracket's own fate); otherwise only the two bracket fates do."""
        prev, streak, last = None, 0, None
        for p in range(horizon):
            fl = self.flow(z, mode, self.P)
            _, x = self.x_of(fl, self.P, SAMPLES)
            if self.diverged(fl, x):
                return "divergence", math.inf
            window = x if prev is None else np.concatenate([prev, x])
            a = 0.5 * float(np.ptp(window))
            prev, z, mode = x, fl.z, fl.mode
            if p == 1:
                self.first_a = a
            self.last_a = a
            self.used = p + 1
            if a < REST * self.A0:
                return "rest", a
            if settle:
                streak = streak + 1 if last is not None and abs(a / last - 1.0) < SETTLED else 0
                if streak >= 5:
                    return "cycle", a
            else:
                hit = [k for k, (kind, ref) in self.targets.items() if kind == "cycle" and abs(a / ref - 1.0) < MATCH]
                streak = streak + 1 if hit else 0
                if streak >= 3:
                    return "cycle", self.targets[hit[0]][1]
            last = a
        return None, last

    def fate(self, z, mode, quick: bool = False) -> str:
        """"inside" or "outside" (the bracket whose fate the run from (z, mode) reaches). ``quick``: "inside" only
        for a start at rest from the start (within 2 periods), "outside" for any other."""
        if self.trials >= self.max_trials:
            raise _Stop("undecided", f"the bound of {self.max_trials} trial runs was reached (raise max_trials)")
        self.trials += 1
        try:
            if quick:
                kind, _ = self.run(z, mode, settle=False, horizon=2)
                self.still = kind == "rest"
                return "inside" if self.still else "outside"
            kind, a = self.run(z, mode, settle=False)
        except HybridError as exc:
            raise _Stop("failed", f"a trial run cannot be followed on the exact flow: {exc}") from None
        self.still = kind == "rest" and self.used <= 2
        for side, (k, ref) in self.targets.items():
            if k == kind and (kind != "cycle" or ref == a):
                return side
        raise _Stop("undecided", f"a trial run reached neither fate within {FATE_PERIODS} predicted periods "
                                 f"({'spread ' + format(a, '.4g') if a is not None else 'no measure'}); raise "
                                 "dfloop.hybrid.edge.FATE_PERIODS")

    # -------------------------------------------------------------------------------------- bisection

    def distance(self, za, zb) -> float:
        return float(np.linalg.norm(np.asarray(za)[:self.nx] - np.asarray(zb)[:self.nx])) / self.scale

    def bisect(self, point, still: bool = False):
        """Bisect the path ``point(lam)`` (lam 0: inside fate, 1: outside) to EDGE_EPS; (inside, outside) ends.
        ``still``: point(0) is at rest from its start (an equilibrium)."""
        a, b = 0.0, 1.0
        self.lam = a
        za, zb = point(a), point(b)
        crept = None
        for _ in range(60):
            if self.distance(za[0], zb[0]) <= EDGE_EPS:
                break
            mid = 0.5 * (a + b)
            zm = point(mid)
            try:
                side = self.fate(*zm, quick=crept is not None)
            except _Stop as stop:
                if stop.outcome != "undecided" or not still:
                    raise
                side, crept = "outside", (self.first_a, self.last_a)   # next to rest: creeps, does not rest
            if side == "inside":
                a, za, still = mid, zm, self.still
                self.lam = a
            else:
                b, zb = mid, zm
        if crept is not None:   # then bisected on "at rest from the start" (2 periods a trial)
            raise self.slow(za, zb, crept)
        return za, zb

    def slow(self, za, zb, crept) -> _Stop:
        """The boundary at a rest state: the inside end of the bracket is at rest from its start (an equilibrium),
        and a start between it and the outside end creeps for the whole trial run."""
        if self.first is not None:
            self.boundary = self.first[0] + self.lam * (self.first[1] - self.first[0])
        x_rest = float(self.loop.x(za[0]))
        d = self.distance(za[0], zb[0])
        self.x_rest = x_rest
        return _Stop("slow", f"the boundary runs through rest: the inside starts are at rest from the start (their "
                             f"spread of x below {REST:g} of the predicted amplitude within 2 periods: a continuum of "
                             f"rests) up to one at x = {x_rest:.6g}, the start {d:.2g} "
                             f"(relative) beyond it moves, and the starts between that and the outside start creep away "
                             f"from rest (one neither rests nor leaves within {FATE_PERIODS} predicted periods = "
                             f"{FATE_PERIODS * self.P:.4g} s: spread of x {crept[0]:.3g} in its first periods, "
                             f"{crept[1]:.3g} at the end)")

    def segment(self, za, zb):
        """The linear path between two states (the mode of the nearer end, made admissible)."""
        def point(lam):
            z = (1.0 - lam) * za[0] + lam * zb[0]
            return self.loop.admissible_mode(z, za[1] if lam <= 0.5 else zb[1])
        return point

    # ------------------------------------------------------------------------------------------ track

    def track(self, f_in, f_out, N, bias):
        loop, A0, w0 = self.loop, self.A0, self.w0

        def start(f):
            return loop.admissible_mode(*start_on_prediction(loop, N, f * A0, w0, bias=bias))

        z_in, z_out = start(f_in), start(f_out)
        self.scale = max(float(np.linalg.norm(start(1.0)[0][:self.nx])), 1e-300)
        for side, z in (("inside", z_in), ("outside", z_out)):
            kind, a = self.run(*z, settle=True)
            if kind is None:
                raise _Stop("undecided", f"the {side} start (A={A0 * (f_in if side == 'inside' else f_out):.4g}) "
                                         f"settles within {FATE_PERIODS} predicted periods on neither rest, "
                                         "divergence nor a cycle")
            self.targets[side] = (kind, a)
            if side == "inside":
                still = kind == "rest" and self.used <= 2
        if self.targets["inside"] == self.targets["outside"] or (
                self.targets["inside"][0] == self.targets["outside"][0] == "cycle"
                and abs(self.targets["inside"][1] / self.targets["outside"][1] - 1.0) < MATCH):
            raise _Stop("undecided", f"the starts at {f_in:g} and {f_out:g} times the prediction have the same fate "
                                     f"({self.targets['inside'][0]}): no boundary between them")
        self.first = (f_in, f_out)
        pair = self.bisect(lambda lam: start(f_in + lam * (f_out - f_in)), still)
        self.first = None
        self.boundary = f_in + self.lam * (f_out - f_in)
        h = self.P / CHUNKS
        t_edge = 0.0
        ts, xs = [], []
        shots, next_shot = 0, 2.0 * self.P
        while t_edge < self.periods * self.P:
            (za, ma), (zb, mb) = pair
            fresh = (za, ma)                   # the boundary state right after a bisection
            steps = 0
            while t_edge < self.periods * self.P:
                fa, fb = self.flow(za, ma, h), self.flow(zb, mb, h)
                if self.distance(fa.z, fb.z) > EDGE_DELTA or not np.all(np.isfinite(fb.z)):
                    break
                tk, x = self.x_of(fa, h, SAMPLES // CHUNKS)
                ts.append(t_edge + tk)
                xs.append(x)
                t_edge += h
                steps += 1
                za, ma, zb, mb = fa.z, fa.mode, fb.z, fb.mode
            if steps == 0:
                h *= 0.5
                if h < self.P / 1024:
                    raise _Stop("failed", "the pair separates within 1/1024 of a period of the bisection: the "
                                          "boundary cannot be followed at EDGE_EPS (rounding)")
            else:
                t, x = np.concatenate(ts), np.concatenate(xs)
                self.edge = (t, x)
                self.rest_check(t, x, (za, ma))
                if shots < _SHOTS and t_edge >= next_shot:
                    found = self.periodic(t, x, fresh)
                    if found is not None:
                        shots += 1
                        next_shot = t_edge + 2.0 * self.P
                        if found is not False:
                            return found
            pair = self.bisect(self.segment((za, ma), (zb, mb)))
        t, x = self.edge
        tail = x[t > t[-1] - 2.0 * self.P]
        if shots:
            raise _Stop("periodic, shooting failed", f"the boundary motion looks periodic but none of {shots} "
                        "shootings from it converged")
        raise _Stop("not periodic", f"the boundary motion is not periodic within {self.periods:g} predicted periods "
                                    f"({t_edge:.4g} s; spread of x {0.5 * np.ptp(tail):.4g} at the end; raise "
                                    "periods / dfloop.hybrid.edge.EDGE_PERIODS)")

    def rest_check(self, t, x, state):
        tail = x[t > t[-1] - 2.0 * self.P]
        if t[-1] < 2.0 * self.P or 0.5 * np.ptp(tail) >= EDGE_REST * self.A0:
            return
        kind, _ = self.run(*state, settle=True)        # the inside member, on to its own rest
        fl = self.flow(*state, self.P)
        x_rest = self.x_rest = float(self.loop.signals(fl, np.array([self.P]))[0][0])
        raise _Stop("rest", f"the boundary motion comes to rest: its oscillation falls below {EDGE_REST:g} of the "
                            f"predicted amplitude after {t[-1]:.4g} s ({t[-1] / self.P:.3g} predicted periods) and the "
                            f"inside member of the pair rests at x = {x_rest:.6g} ({kind} within the run)")

    def periodic(self, t, x, fresh):
        """None when the boundary motion does not look periodic yet; False when it does but the shooting
        failed; the EdgeTrack outcome ("orbit") when it converged."""
        window = t > t[-1] - 6.0 * self.P
        tw, xw = t[window], x[window]
        tc = upward_crossings(tw, xw, float(np.mean(xw)))
        if tc.size < 4:
            return None
        gaps = np.diff(tc)[-3:]
        spreads = [np.ptp(xw[(tw >= a) & (tw < b)]) for a, b in zip(tc[-4:-1], tc[-3:])]
        if np.ptp(gaps) > PERIODIC * np.mean(gaps) or np.ptp(spreads) > PERIODIC * np.mean(spreads):
            return None
        T = float(np.mean(gaps))
        try:
            orbit = self.shoot(fresh, T)
        except (ShootingError, HybridError):
            return False
        return orbit

    def shoot(self, fresh, T):
        """Multiple shooting from nodes on one period of the motion from the fresh boundary state."""
        loop = self.loop
        fl = loop.flow(fresh[0], fresh[1], T, max_events=self.max_events)
        starts = np.clip(fl.t0, 0.0, T)
        ends = np.append(fl.t0[1:], T)
        k = int(np.argmax(ends - starts))
        t_mid = 0.5 * (starts[k] + ends[k])
        z1, m1 = loop.admissible_mode(loop.states(fl, np.array([t_mid]))[0], int(fl.modes[k]))
        fl = loop.flow(z1, m1, T, max_events=self.max_events)
        m = node_count(loop, T, self.nodes)
        t = np.arange(m) * (T / m)
        if loop.switching and fl.t0.size > 1:    # each node within the middle half of its segment
            t = np.unique(middle_halves(t, np.append(fl.t0, T)))
        seg = np.clip(np.searchsorted(fl.t0, t, side="right") - 1, 0, fl.t0.size - 1)
        zs, modes = list(loop.states(fl, t)), [int(fl.modes[i]) for i in seg]
        c = np.diff(np.append(t, T)) / T
        return newton_orbit(loop, zs, modes, T, c, tol=self.tol, max_iterations=self.max_iterations,
                            max_events=self.max_events)


@single_threaded_blas
def edge_track(loop, N, amplitude: float, frequency: float, inside: float, outside: float, *, bias: float = 0.0,
               periods: float = EDGE_PERIODS, tol: float = 1e-11, max_iterations: int = 40,
               max_events: int = 100_000, nodes: int = 8, max_trials: int = MAX_TRIALS) -> EdgeTrack:
    """Follow the boundary between the basins of the motions started on the predicted orbit scaled by ``inside``
    and by ``outside`` (see the module notes).

    Parameters
    ----------
    loop : exact loop model
        From :func:`dfloop.hybrid.loop_model` without a delay (``loop.exact`` True, ``loop.delay`` 0).
    N : DescribingFunction
        The element (its DF sets the harmonic-balance starts).
    amplitude, frequency : float
        The prediction (element input units, rad/s); every scale (rest, divergence, the bound) is relative to it.
    inside, outside : float
        Start amplitude factors with different fates (e.g. 0.7: rests, 1.0: diverges), > 0 and different.
    bias : float
        Mean of the predicted input (a loop with a constant input).
    periods : float
        Bound: predicted periods followed on the boundary, > 0.
    tol, max_iterations, max_events, nodes
        For the shooting from a periodic boundary motion (as in :func:`dfloop.exact_cycle`); ``max_events`` also
        bounds the events of each flow.
    max_trials : int
        Bound on the trial runs (bisections), >= 1.

    Returns
    -------
    EdgeTrack
        Never raises for a loop that cannot be followed: the outcome says so.
    """
    for name, v in (("inside", inside), ("outside", outside), ("periods", periods), ("amplitude", amplitude),
                    ("frequency", frequency)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive finite number; got {v!r}")
    if inside == outside:
        raise ValueError(f"inside and outside must differ; got {inside!r} for both")
    if getattr(loop, "delay", 0.0) > 0 or not getattr(loop, "exact", False):
        raise ValueError("loop must be an exact loop model without a delay (edge tracking runs on its flow; the "
                         "delay engines keep their state in a history)")
    tr = _Tracker(loop, float(amplitude), float(frequency), float(periods), tol, max_iterations, max_events, nodes,
                  max_trials)
    began = time.perf_counter()
    outcome, message, orbit = None, "", None
    try:
        found = tr.track(float(inside), float(outside), N, bias)
        outcome, orbit = "orbit", found
        message = (f"the boundary motion becomes periodic (period {found.period:.6g} s); multiple shooting from it "
                   f"converged (residual {found.residual:.1e})")
    except _Stop as stop:
        outcome, message = stop.outcome, stop.message
    except HybridError as exc:
        outcome, message = "failed", f"the boundary cannot be followed on the exact flow: {exc}"
    t, x = getattr(tr, "edge", (np.empty(0), np.empty(0)))
    amp = freq = None
    if t.size:
        tail = t > t[-1] - 2.0 * tr.P
        amp = float(0.5 * np.ptp(x[tail]))
        tc = upward_crossings(t[tail], x[tail], float(np.mean(x[tail])))
        freq = float(2.0 * math.pi * (tc.size - 1) / (tc[-1] - tc[0])) if tc.size >= 2 else None
    x_rest = getattr(tr, "x_rest", None) if outcome in ("rest", "slow") else None
    targets = {k: (v[0] if v[0] != "cycle" else f"cycle (spread {v[1]:.4g})") for k, v in tr.targets.items()}
    return EdgeTrack(outcome, message, orbit, float(t[-1]) if t.size else 0.0,
                     float(t[-1] / tr.P) if t.size else 0.0, tr.trials, tr.flowed, time.perf_counter() - began,
                     targets.get("inside", ""), targets.get("outside", ""), amp, freq, x_rest,
                     getattr(tr, "boundary", None), t, x)
