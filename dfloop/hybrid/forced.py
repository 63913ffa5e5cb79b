"""The exact forced response: periodic orbits of the loop driven by r = R sin(w t), at the forcing period.

The forcing is an exosystem appended to the plant: p = sin(w t), q = cos(w t) with p' = w q, q' = -w p, and the
element's input x = R p - c (c the plant's output). The driven loop is then an ordinary loop model of
:func:`dfloop.hybrid.loop_model` (exact for piecewise-affine elements, DOP853 for smooth ones), and its periodic
orbits at the forcing period T = 2 pi / w are found by :func:`dfloop.hybrid.shooting.forced_orbit` (multiple
shooting, fixed period, the forcing's phase not an unknown), started on the DF's forced solution
x = A sin(w t + phi), phi the phase of R / (1 + G(jw) N(A)). Stability: the orbit's Floquet multipliers (the
monodromy over T restricted to the plant and element states), all inside the unit circle.

When shooting from the DF start fails, the loop is run ``RUN_PERIODS`` forcing periods from it and sampled once
per forcing period (the stroboscopic map): samples that repeat with period k >= 2 mark a subharmonic response of
order k (its orbit has period k T); samples that settle to one point are shot from (a period-T orbit after all);
samples that neither settle nor repeat mark a quasi-periodic (or chaotic) response. No orbit at the forcing
period is then reported, with what was seen.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .dde import DDELoop
from .delay import split_delay
from .forced_delay import forced_dde_orbit
from .loop import HybridError
from .model import HISTORY_SAMPLES, loop_model
from .shooting import ShootingError, forced_orbit

__all__ = ["ExactForcedPoint", "ExactForcedResponse", "exact_forced_point", "exact_forced_response", "RUN_PERIODS"]

RUN_PERIODS = 400        # forcing periods run from the DF start when shooting fails
_SETTLE = 60             # forcing periods flowed before the second shooting attempt
_REPEAT = 1e-6           # stroboscopic samples equal to this (relative) repeat
_MAX_ORDER = 8           # subharmonic orders looked for


@dataclass(frozen=True, repr=False)
class ExactForcedPoint:
    """The exact response of the driven loop next to one DF forced solution.

    Attributes
    ----------
    omega : float
        Forcing frequency (rad/s).
    predicted : float
        The DF's amplitude A of the element's input.
    kind : str
        ``"periodic"`` (an orbit at the forcing period), ``"subharmonic"`` (the motion repeats every ``order``
        forcing periods), ``"not periodic"`` (quasi-periodic or chaotic within the run) or ``"failed"`` (the loop
        cannot be run, ``message`` says why).
    amplitude : float or None
        Amplitude of the fundamental (at the forcing frequency) of the element's input on the orbit.
    output_amplitude : float or None
        Same for the plant's output.
    multipliers : ndarray or None
        Floquet multipliers (plant and element states), by decreasing modulus.
    stable : bool or None
        All multipliers inside the unit circle.
    order : int or None
        The subharmonic's order.
    observed : str or None
        When no stable orbit at the forcing period was found: what a run of ``RUN_PERIODS`` forcing periods from
        the DF solution does (``"subharmonic"``, ``"not periodic"``, ``"divergence"``, ``"periodic"`` (settles
        on another orbit at the forcing period), ``"failed"``); None otherwise.
    message : str
        How the orbit was found, or what was seen instead.
    residual : float
        Shooting residual (relative), inf without an orbit.
    """

    omega: float
    predicted: float
    kind: str
    amplitude: float | None = None
    output_amplitude: float | None = None
    multipliers: np.ndarray | None = None
    stable: bool | None = None
    order: int | None = None
    observed: str | None = None
    message: str = ""
    residual: float = math.inf
    extra: dict = field(default_factory=dict, compare=False)

    @property
    def periodic(self) -> bool:
        return self.kind == "periodic"

    @property
    def amplitude_error(self) -> float | None:
        """(predicted - exact) / exact, None without an orbit."""
        return None if not self.periodic else (self.predicted - self.amplitude) / self.amplitude

    def to_dict(self) -> dict:
        """Plain data keyed by the attribute names (multipliers as a list of complex)."""
        from ..export import plain

        names = ("omega", "predicted", "kind", "amplitude", "output_amplitude", "multipliers", "stable", "order",
                 "observed", "message", "residual", "amplitude_error")
        return {n: plain(getattr(self, n)) for n in names}

    def __repr__(self) -> str:
        if self.periodic:
            return (f"ExactForcedPoint(omega={self.omega:.6g} rad/s, amplitude={self.amplitude:.8g}, "
                    f"{'stable' if self.stable else 'unstable'} (max |multiplier| "
                    f"{float(np.max(np.abs(self.multipliers))):.4g}); DF amplitude {self.predicted:.6g} "
                    f"({100 * self.amplitude_error:+.3g} %))")
        what = f"subharmonic of order {self.order}" if self.kind == "subharmonic" else self.kind
        return f"ExactForcedPoint(omega={self.omega:.6g} rad/s, {what}: {self.message})"


def _driven(G, N, R: float, w: float, scale: float):
    """The loop model of G driven by R sin(w t), and the indices of its free states."""
    import control as ct

    from .loop import plant_matrices

    A, B, C = plant_matrices(G, what="the exact forced response")
    n = A.shape[0]
    Aa = np.zeros((n + 2, n + 2))
    Aa[:n, :n] = A
    Aa[n, n + 1], Aa[n + 1, n] = w, -w
    Ba = np.append(B, [0.0, 0.0])[:, None]
    Ca = np.append(C, [-R, 0.0])[None, :]
    loop = loop_model(ct.ss(Aa, Ba, Ca, 0.0), N, scale, w, what="the exact forced response")
    free = np.array([i for i in range(loop.size - 1) if i not in (n, n + 1)])
    return loop, free, n


def _start(loop, G, N, R, w, A_pred, n, t):
    """(z, mode) at time t of the DF's forced solution x = Im(E e^{jwt}), E = R / (1 + G(jw) N(A))."""
    Am, Bm = loop.plant
    A, B = Am[:n, :n], Bm[:n]
    nv = complex(N(A_pred, w) if N.frequency_dependent else N(A_pred))
    Gw = complex((-loop.x_row[:n]) @ np.linalg.solve(1j * w * np.eye(n) - A, B))
    E = R / (1 + Gw * nv)
    X = np.linalg.solve(1j * w * np.eye(n) - A, B) * nv * E
    s0 = np.concatenate([(X * np.exp(1j * w * t)).imag, [math.sin(w * t), math.cos(w * t)]])
    T = 2 * math.pi / w
    tt = t + T * (np.arange(HISTORY_SAMPLES) / HISTORY_SAMPLES - 1.0)
    return loop.start(s0, (E * np.exp(1j * w * tt)).imag)


def _point(loop, orbit, free, R, w, A_pred, how) -> ExactForcedPoint:
    T = orbit.period
    X1 = 2j * complex(loop.fourier(orbit.flow, T, w, 1)[0])   # x ~ Im(X1 e^{jwt})
    M = orbit.flow.monodromy[np.ix_(free, free)]
    mu = np.linalg.eigvals(M)
    mu = mu[np.argsort(-np.abs(mu))]
    return ExactForcedPoint(w, A_pred, "periodic", amplitude=float(abs(X1)), output_amplitude=float(abs(R - X1)),
                            multipliers=mu, stable=bool(np.all(np.abs(mu) < 1.0)),
                            message=f"{how}: converged in {orbit.iterations} Newton iteration(s), residual "
                                    f"{orbit.residual:.1e}", residual=orbit.residual,
                            extra={"z0": orbit.z, "mode0": orbit.mode})


def exact_forced_point(G, N, R: float, omega: float, amplitude: float, *, nodes: int = 8, tol: float = 1e-10,
                       max_iterations: int = 40, max_events: int = 10_000, observe: bool = True) -> ExactForcedPoint:
    """The exact orbit of the loop driven by R sin(w t) at the forcing period, near the DF solution ``amplitude``.

    Parameters
    ----------
    G : python-control tf or ss, or ``delayed(G, T)``
        Strictly proper SISO plant. With a pure delay the element must be static (sloped pieces or smooth):
        the orbit is the delay equation's at the forcing period (:mod:`dfloop.hybrid.forced_delay`; its error
        estimate in ``extra``), and no run is made when it is not found (``kind`` "failed", the reason in
        ``message``).
    N : DescribingFunction
        The element (with a piecewise-affine or smooth time model).
    R, omega : float
        Forcing amplitude (element input units) and frequency (rad/s), > 0.
    amplitude : float
        The DF's amplitude A of the element's input at this frequency (the start), > 0.
    nodes : int
        Shooting nodes per forcing period.
    tol, max_iterations, max_events
        As for :func:`dfloop.exact_cycle`.
    observe : bool
        When the orbit found at the forcing period is unstable, also run the loop from the DF solution to say
        what the motion does instead (``observed``; default). False skips that run for unstable orbits (it
        always runs when no orbit is found).

    Returns
    -------
    ExactForcedPoint
        ``kind`` says whether an orbit at the forcing period was found (then its amplitude and multipliers),
        or a subharmonic / not periodic response was seen instead (module notes).

    Raises
    ------
    ValueError
        Bad R, omega, amplitude or nodes (naming it), or a plant/element the driven loop cannot run.
    """
    from .._checks import flag, in_closed_interval, scale

    R, w, A0 = scale("R", R), scale("omega", omega), scale("amplitude", amplitude)
    m = int(in_closed_interval("nodes", nodes, 1, 1000))
    if split_delay(G)[1] > 0:
        return _delayed_point(G, N, R, w, A0, max_iterations)
    T = 2 * math.pi / w
    loop, free, n = _driven(G, N, R, w, A0 + R)
    if not loop.exact:
        raise ValueError(f"N: {type(N).__name__} has no exact time model here ({loop.method})")
    options = dict(tol=tol, max_iterations=max_iterations, max_events=max_events)
    point, first = None, ""
    try:
        starts = [_start(loop, G, N, R, w, A0, n, i * T / m) for i in range(m)]
        orbit = forced_orbit(loop, [z for z, _ in starts], [mo for _, mo in starts], T, free, **options)
        point = _point(loop, orbit, free, R, w, A0, "shot from the DF solution")
        if point.stable or not flag("observe", observe):
            return point
    except (ShootingError, HybridError) as exc:
        first = f"; shooting from the DF solution: {exc}"
    seen = _observe(loop, G, N, R, w, A0, n, m, free, options)
    if point is not None:   # an unstable orbit at the forcing period: say what the motion near it does instead
        return dataclasses.replace(point, observed=seen["observed"], order=seen.get("order"),
                                   message=f"{point.message}; unstable: {seen['words']}")
    if "orbit" in seen:
        return seen["orbit"]
    kind = {"subharmonic": "subharmonic", "failed": "failed"}.get(seen["observed"], "not periodic")
    return ExactForcedPoint(w, A0, kind, order=seen.get("order"), observed=seen["observed"],
                            message=f"{seen['words']}{first}")


def _delayed_point(G, N, R: float, w: float, A0: float, max_iterations: int) -> ExactForcedPoint:
    """The forced response of a delayed plant: the delay equation at the forcing period
    (:mod:`dfloop.hybrid.forced_delay`), for static elements (sloped pieces or smooth)."""
    loop = loop_model(G, N, A0 + R, w, what="the exact forced response")
    if not isinstance(loop, DDELoop):
        raise ValueError(f"G: a pure delay in the exact forced response is supported for static elements with "
                         f"sloped pieces or smooth ones (saturation, dead zone, cubic stiffness, ...), not for "
                         f"{type(N).__name__} ({loop.method}); use delayed(G, T).pade(n) for an approximation")
    out = forced_dde_orbit(loop, lambda a: N(a), R, w, A0, max_iterations=max_iterations)
    if not out["success"]:
        return ExactForcedPoint(w, A0, "failed", observed="failed",
                                message=f"no orbit at the forcing period found from the DF solution: {out['message']}")
    X1 = out["X1"]
    mu = out["multipliers"]
    return ExactForcedPoint(w, A0, "periodic", amplitude=float(abs(X1)), output_amplitude=float(abs(R - X1)),
                            multipliers=mu, stable=out["stable"], message=out["message"], residual=out["residual"],
                            extra={k: out[k] for k in ("nodes", "error_estimate", "target_met", "multipliers_coarse")})


def _observe(loop, G, N, R, w, A0, n, m, free, options) -> dict:
    """Run RUN_PERIODS forcing periods from the DF solution and classify the stroboscopic samples."""
    T = 2 * math.pi / w
    max_events = options["max_events"]
    try:
        z, mode = _start(loop, G, N, R, w, A0, n, 0.0)
        bound = 1e6 * (A0 + R + float(np.max(np.abs(z[free]))))
        samples = []
        for p in range(RUN_PERIODS):
            fl = loop.flow(z, mode, T, max_events=max_events)
            z, mode = fl.z, fl.mode
            samples.append(z[free].copy())
            if not np.all(np.isfinite(z)) or float(np.max(np.abs(z[free]))) > bound:
                return {"observed": "divergence", "words": f"the driven motion diverges (forcing period {p + 1})"}
            if p == _SETTLE - 1:   # shoot from the settled motion: a stable orbit the DF start missed
                try:
                    zs, ms, zi, mi = [], [], z.copy(), mode
                    for _ in range(m):
                        zs.append(zi)
                        ms.append(mi)
                        fl_i = loop.flow(zi, mi, T / m, max_events=max_events)
                        zi, mi = fl_i.z, fl_i.mode
                    orbit = _point(loop, forced_orbit(loop, zs, ms, T, free, **options), free, R, w, A0,
                                   f"shot after settling {_SETTLE} forcing periods")
                    if orbit.stable:
                        return {"observed": "periodic", "orbit": orbit,
                                "words": f"the motion settles on a stable orbit at the forcing period, amplitude "
                                         f"{orbit.amplitude:.6g}"}
                except (ShootingError, HybridError):
                    pass
    except HybridError as exc:
        return {"observed": "failed", "words": f"the driven loop cannot be run: {exc}"}
    S = np.array(samples[-4 * _MAX_ORDER:])
    size = max(float(np.max(np.abs(S))), 1e-300)
    for k in range(1, _MAX_ORDER + 1):
        if float(np.max(np.abs(S[k:] - S[:-k]))) <= _REPEAT * size:
            if k == 1:
                return {"observed": "failed", "words": "the motion settles to a period-T motion but shooting from "
                                                      "it did not converge"}
            return {"observed": "subharmonic", "order": k,
                    "words": f"the motion run {RUN_PERIODS} forcing periods from the DF solution repeats every {k} "
                             f"forcing periods (subharmonic of order {k})"}
    spread = float(np.max(np.abs(S - S.mean(axis=0)))) / size
    return {"observed": "not periodic",
            "words": f"the motion run {RUN_PERIODS} forcing periods from the DF solution neither settles nor "
                     f"repeats within {_MAX_ORDER} forcing periods (stroboscopic spread {spread:.2g}: quasi-periodic "
                     "or chaotic)"}


@dataclass
class ExactForcedResponse:
    """The exact counterpart of every DF forced solution (:func:`exact_forced_response`).

    Attributes
    ----------
    response : ForcedResponse
        The DF forced response it follows.
    points : list of list of ExactForcedPoint
        ``points[k][i]``: the exact response next to ``response.solutions[k][i]`` (frequencies not computed, by
        ``every``, hold an empty list).
    """

    response: object
    points: list

    def flat(self) -> list:
        """All computed points, by frequency."""
        return [p for row in self.points for p in row]

    @property
    def largest_difference(self) -> float | None:
        """Largest |DF - exact| / exact amplitude over the periodic points (None without one)."""
        errs = [abs(p.amplitude_error) for p in self.flat() if p.periodic]
        return max(errs) if errs else None

    def disagreements(self) -> list:
        """Where the DF and the exact response differ in kind: a DF point without an orbit at the forcing period
        (subharmonic, not periodic), or whose stability differs from the exact multipliers'. (DF point, exact)."""
        out = []
        for sols, row in zip(self.response.solutions, self.points):
            for df, ex in zip(sols, row):
                if not ex.periodic or ex.stable != df.stable:
                    out.append((df, ex))
        return out

    def to_dict(self) -> dict:
        """``points``: one dict per computed point (:meth:`ExactForcedPoint.to_dict`), ``largest_difference``."""
        return {"points": [p.to_dict() for p in self.flat()], "largest_difference": self.largest_difference}

    def plot(self, ax=None, **kwargs):
        """The DF forced response with these exact points on top (:func:`dfloop.plot.forced.plot_forced_response`)."""
        from ..plot.forced import plot_forced_response

        return plot_forced_response(self.response, ax=ax, exact=self, **kwargs)

    def __repr__(self) -> str:
        pts = self.flat()
        kinds = {}
        for p in pts:
            key = p.kind if p.kind != "periodic" else ("stable orbit" if p.stable else "unstable orbit")
            kinds[key] = kinds.get(key, 0) + 1
        diff = self.largest_difference
        head = (f"ExactForcedResponse({len(pts)} point(s): " + ", ".join(f"{v} {k}" for k, v in kinds.items())
                + ("" if diff is None else f"; largest DF amplitude error {100 * diff:.3g} %") + ")")
        return "\n".join([head] + [f"  DF {df!r} -> {ex!r}" for df, ex in self.disagreements()])


def exact_forced_response(G, N, response, *, every: int = 1, **options) -> ExactForcedResponse:
    """The exact response next to every DF forced solution of ``response`` (:func:`exact_forced_point` each).

    Parameters
    ----------
    G, N
        The loop of the DF forced response.
    response : ForcedResponse
        From :func:`dfloop.solve.forced.forced_response` (its ``R``, ``omega``, ``solutions``).
    every : int
        Compute every ``every``-th frequency of the grid (>= 1; the others hold empty lists).
    **options
        Passed to :func:`exact_forced_point` (``nodes``, ``tol``, ...).
    """
    from .._checks import integer_at_least

    every = integer_at_least("every", every, 1)
    points = []
    for k, (w, sols) in enumerate(zip(response.omega, response.solutions)):
        points.append([exact_forced_point(G, N, response.R, float(w), p.amplitude, **options) for p in sols]
                      if k % every == 0 else [])
    return ExactForcedResponse(response, points)
