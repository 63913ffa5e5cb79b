"""The true periodic orbit behind a predicted limit cycle: shooting, Floquet multipliers, DF errors.

:func:`exact_cycle` starts from a prediction (a :class:`~dfloop.solve.result.LimitCycle` or an (amplitude,
frequency) pair), runs the loop of the paper's Fig. 1 (reference 0, x = -c, c = G y) on the exact hybrid engine
(:mod:`dfloop.hybrid`, built from the element's time model by :func:`dfloop.hybrid.loop_model`: matrix
exponentials between switches located to rounding level; the exact impact engine for the dynamic backlash;
DOP853 for smooth elements) and solves the periodicity condition by Newton's method
(:func:`dfloop.hybrid.periodic_orbit`, the one shooting routine for every loop) on (z0, T):

    phi_T(z0) - z0 = 0,      f(z0_k) . (z0 - z0_k) = 0     (the correction is orthogonal to the flow),

with the monodromy (saltation matrices at every switch included) as Jacobian. The start point lies in the middle
of the longest segment between switches, so small corrections never move a switch across t = 0 or t = T.
The Floquet multipliers are the eigenvalues of the converged monodromy; one is the trivial multiplier 1 of the
autonomous flow, and the cycle is stable when all others lie inside the unit circle.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ._blas import single_threaded_blas
from ._checks import integer_at_least, positive, scale
from .describing.interop import as_element
from .solve.engines import register_exact_engine

__all__ = ["ExactCycle", "exact_cycle", "table_certificate"]

_SAMPLES = 512


@dataclass(frozen=True, repr=False)
class ExactCycle:
    """The periodic orbit found by :func:`exact_cycle` (or why none was found).

    Attributes
    ----------
    success : bool
        True only for an orbit converged to ``residual`` <= the requested tolerance. When False, ``message``
        says why and the orbit fields are None: a half-converged orbit is never returned.
    message : str
        What happened (convergence, or the reason of the failure).
    amplitude : float or None
        Amplitude of the fundamental of the element's input x (N's input unit), the quantity the DF predicts.
    frequency, period : float or None
        Angular frequency (rad/s) and period (s) of the orbit.
    t, x, y : ndarray or None
        One period sampled uniformly from t = 0, the time origin chosen so that x's fundamental is
        ``amplitude`` sin(``frequency`` t): element input x and output y.
    switching_times : ndarray or None
        The exact event instants in [0, period), in the same time frame: switches of a piecewise-affine element;
        impacts, separations and friction stops of the dynamic backlash; none for a smooth element.
    harmonics : ndarray or None
        Complex amplitudes X_k of x, k = 1..K (x = mean + sum_k Im(X_k exp(j k w t))); ``harmonics[0]`` is real
        and equal to ``amplitude``.
    multipliers : ndarray or None
        Floquet multipliers (eigenvalues of the monodromy, saltation matrices included), by decreasing modulus.
    stable : bool or None
        All multipliers but the trivial one (closest to 1) strictly inside the unit circle.
    amplitude_error, frequency_error : float or None
        Relative errors of the prediction, (predicted - exact) / exact. For a period-k orbit (``extra["returns"]``
        = k > 1: it repeats only after k oscillations, as after a period doubling) the exact values are those of
        the orbit's k-th harmonic, the oscillation the DF describes; ``frequency`` and ``amplitude`` stay those
        of the orbit's own fundamental (period ``period``).
    predicted : (float, float)
        The predicted (amplitude, frequency) the search started from.
    method : str
        How the orbit was computed (exact hybrid flow, DOP853, impact engine).
    residual : float
        Final |phi_T(z0) - z0| relative to |z0| (inf when no Newton step was taken).
    iterations : int
        Newton iterations used.
    mean : float or None
        Mean of x over the orbit (its bias; 0 up to rounding for a symmetric loop without constant input).
    extra : dict
        Engine details: ``z0`` (augmented state [plant state, element state, 1] at the shooting start, which is
        not the waveform's t = 0, in the loop model's own well-conditioned realisation), ``mode0`` (the element's
        mode there), for re-running the flow; ``plant_state`` (the plant part of ``z0`` in the realisation
        :func:`dfloop.hybrid.plant_matrices` gives, python-control's own up to a diagonal balancing); ``returns``
        (oscillations per period: 1, or k for a period-k orbit found on the settled motion); ``path`` (how
        Newton reached the orbit: ``"newton"`` from the start, or ``"homotopy"``, the Newton homotopy from the
        predicted orbit, :func:`dfloop.hybrid.shooting.homotopy_orbit`). On the
        exact delay flow: ``s0`` (plant state), ``mode0``, ``u0`` (plant input), ``queue0`` (pending switches
        [instant (s), level] of the delay line), ``section`` (the switch the return map starts on) and ``delay``;
        after a failed search that was globalised, ``outcome`` and ``motions`` (:mod:`dfloop.hybrid.globalise`), and
        ``edge`` when the boundary between the motions' fates was followed (:mod:`dfloop.hybrid.edge`).
    """

    success: bool
    message: str
    predicted: tuple
    method: str
    amplitude: float | None = None
    frequency: float | None = None
    period: float | None = None
    t: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    switching_times: np.ndarray | None = None
    harmonics: np.ndarray | None = None
    multipliers: np.ndarray | None = None
    stable: bool | None = None
    amplitude_error: float | None = None
    frequency_error: float | None = None
    residual: float = math.inf
    iterations: int = 0
    extra: dict = field(default_factory=dict)
    mean: float | None = None

    @property
    def distortion(self) -> float | None:
        """RMS of x's harmonics k >= 2 relative to its fundamental (None without an orbit)."""
        if self.harmonics is None:
            return None
        return float(np.sqrt(np.sum(np.abs(self.harmonics[1:]) ** 2)) / abs(self.harmonics[0]))

    @property
    def largest_multiplier(self) -> float | None:
        """Largest modulus among the non-trivial multipliers (None without an orbit)."""
        if self.multipliers is None:
            return None
        mu = self.multipliers if self.extra.get("map") else _nontrivial(self.multipliers)  # a map has no trivial one
        return float(np.max(np.abs(mu), initial=0.0))

    def to_dict(self) -> dict:
        """Plain data keyed by the attribute names (arrays as lists, complex harmonics and multipliers as
        Python complex; ``extra`` left out), plus ``distortion`` and ``largest_multiplier``."""
        from .export import plain

        names = ("success", "message", "predicted", "method", "amplitude", "frequency", "period", "t", "x", "y",
                 "switching_times", "harmonics", "multipliers", "stable", "amplitude_error", "frequency_error",
                 "residual", "iterations", "distortion", "largest_multiplier", "mean")
        return {name: plain(getattr(self, name)) for name in names}

    def to_csv(self, path) -> None:
        """Write the orbit's period, one row per sample: ``t`` (s), ``x`` and ``y`` (ValueError without an orbit)."""
        from .export import write_csv

        if not self.success:
            raise ValueError(f"this ExactCycle has no orbit to write ({self.message})")
        write_csv(path, ({"t": t, "x": x, "y": y} for t, x, y in zip(self.t.tolist(), self.x.tolist(),
                                                                      self.y.tolist())))

    def plot(self, ax=None, *, unit: str = ""):
        """Draw x over one period with the switching (or impact) instants:
        :func:`dfloop.plot.orbit.plot_exact_cycle` (``unit``: x's unit for the axis label). Returns a
        :class:`control.ControlPlot`; ``ValueError`` without an orbit or for an ``ax`` that is not an Axes."""
        from .plot.orbit import plot_exact_cycle

        return plot_exact_cycle(self, ax, unit=unit)

    def __repr__(self) -> str:
        A0, w0 = self.predicted
        if not self.success:
            return (f"ExactCycle(not found: {self.message}; predicted amplitude={A0:.6g}, frequency={w0:.6g} rad/s; "
                    f"{self.method})")
        shifted = self.mean is not None and abs(self.mean) > 1e-9 * self.amplitude
        return (f"ExactCycle({f'mean={self.mean:.8g}, ' if shifted else ''}amplitude={self.amplitude:.8g}, "
                f"frequency={self.frequency:.8g} rad/s, "
                f"{'stable' if self.stable else 'unstable'} (largest non-trivial |multiplier| "
                f"{self.largest_multiplier:.4g}); DF error: amplitude {100 * self.amplitude_error:+.3g} %, "
                f"frequency {100 * self.frequency_error:+.3g} %; {self.switching_times.size} switches/period, "
                f"residual {self.residual:.1e}; {self.method})")


def _plant_state(loop, z: np.ndarray) -> np.ndarray:
    """The plant part of an augmented state z in the coordinates of ``plant_matrices(G)`` (python-control's
    realisation of G, diagonally balanced when badly scaled), not the flow's own (``loop.basis``)."""
    s = np.asarray(z, float)[:loop.n]
    basis = getattr(loop, "basis", None)
    return s.copy() if basis is None else basis @ s


def _nontrivial(mu: np.ndarray) -> np.ndarray:
    """The multipliers without the trivial one (the one closest to 1)."""
    if mu.size == 0:
        return mu
    return np.delete(mu, int(np.argmin(np.abs(mu - 1.0))))


def cycle_argument(cycle, name: str = "cycle") -> tuple[float, float]:
    """(amplitude, frequency) from a LimitCycle or a pair; ``ValueError`` naming ``name`` otherwise."""
    if cycle is None:
        raise ValueError(f"{name} must be a LimitCycle or an (amplitude, frequency) pair, got None")
    if hasattr(cycle, "amplitude") and hasattr(cycle, "frequency"):
        A0, w0 = cycle.amplitude, cycle.frequency
    else:
        try:
            pair = tuple(cycle)
        except TypeError:
            raise ValueError(f"{name} must be a LimitCycle or an (amplitude, frequency) pair, "
                             f"got {type(cycle).__name__}") from None
        if len(pair) != 2 or any(hasattr(p, "amplitude") or np.ndim(p) != 0 for p in pair):
            raise ValueError(f"{name} must be one LimitCycle or one (amplitude, frequency) pair, got "
                             f"{type(cycle).__name__} of {len(pair)} items (pass one cycle, e.g. cycles[0])")
        A0, w0 = pair
    return scale(f"{name} amplitude", A0), scale(f"{name} frequency", w0)


def _failure(message, predicted, method, residual=math.inf, iterations=0, extra=None) -> ExactCycle:
    return ExactCycle(False, message, predicted, method, residual=residual, iterations=iterations,
                      extra=extra or {})


@single_threaded_blas
def exact_cycle(G, N, cycle, *, harmonics: int = 15, samples: int = _SAMPLES, tol: float = 1e-11,
                max_iterations: int = 40, settle_periods: float | None = None, max_events: int = 10_000,
                max_deviation: float | None = None, nodes: int = 8, globalise: bool = True, r0: float = 0.0,
                load: float = 0.0, bias: float | None = None) -> ExactCycle:
    """Find the true periodic orbit near a predicted limit cycle, its Floquet multipliers and the DF's errors.

    Parameters
    ----------
    G : python-control tf or ss, or ``delayed(G, T)``
        SISO plant (from the element's output y to c; x = -c), strictly proper (except around a dynamic
        backlash, whose output x1 is a state); with a pure delay (:func:`dfloop.solve.delay.delayed`) a
        piecewise-constant element (relays, quantizer) runs on the exact delay flow
        (:mod:`dfloop.hybrid.delay`: Newton on the return map to a switch), other static elements and elements with
        memory (backlash) on the discretised delay equation (:mod:`dfloop.hybrid.dde`,
        :mod:`dfloop.hybrid.dde_memory`, error estimate in ``extra``), impact elements raise ``ValueError``.
    N : DescribingFunction
        The element; its ``time_model`` decides the engine (:func:`dfloop.hybrid.loop_model`): piecewise-affine
        elements (relays, saturation, dead zone, backlash, quantizer, ...) run on the exact hybrid engine, a
        :class:`dfloop.impact.DynamicBacklash` on the exact impact engine, smooth static elements on DOP853
        (said in ``method``). An element known only through an operator raises ``ValueError``.
    cycle : LimitCycle or (amplitude, frequency)
        The prediction to start from (amplitude of x's fundamental, rad/s).
    harmonics : int
        Number of harmonics of x to report (>= 1).
    samples : int
        Samples of the returned waveform over one period (>= 16).
    tol : float
        Newton stops when |phi_T(z0) - z0| <= tol |z0| (relative), in [1e-14, 1e-4].
    max_iterations : int
        Bound on Newton iterations (each is one flow over a period plus at most 8 line-search flows).
    settle_periods : float or None
        Periods flowed from the harmonic-balance start before shooting, in [0, 1000] (the period is then
        detected on the settled motion). With 0 the shooting starts on the predicted sinusoidal orbit itself
        (right for unstable cycles, which a flow leaves); a few periods help a stable cycle that the DF places
        poorly. None (default): the loop model's own choice, 0 except for the dynamic backlash (200: the masses'
        motion is not set by the prediction). With a pure delay it is used by the delay equation of a static
        element (saturation, dead zone, friction, smooth elements: Newton then starts from the motion settled
        after that many periods, the default 0 on the prediction), and not by the exact delay flow (its start is
        the exact periodic response to the delayed output of the predicted sinusoid), the delay equation with
        memory (backlash) or with impacts.
    max_events : int
        Bound on switches (impacts) per flow, >= 1 (a flow reaching it fails with a message that says so).
    nodes : int
        Multiple-shooting nodes per period (1: single shooting). Several nodes keep Newton's corrections
        small on strongly unstable cycles, whose flow leaves the prediction within a period. Not used on the
        exact delay flow (Newton on the return map to one switch).
    max_deviation : float or None
        An orbit whose amplitude or frequency differs from the prediction by more than this in log scale
        (0.5: a factor 1.65) is reported as another orbit (``success`` False, its numbers in the message).
        None (default): 0.5, except for an orbit that is this prediction's own although farther (no other DF
        prediction of the loop is nearer to it and its stability agrees: docs/exact.md), which is returned
        with its distance in the message.
    globalise : bool
        When shooting from the prediction fails, look further before answering (default; see Returns). False
        answers from the shooting alone (its failure is then "not checked", never "no orbit"): for callers that
        try many seeds themselves, such as a design chart's exact samples.
    r0, load : float
        A constant input (:mod:`dfloop.solve.bias`): reference r0 at the summing junction (x = r0 - c) and a load
        added to the element's output before the plant (piecewise-affine and smooth elements, no delay).
    bias : float or None
        The predicted mean of x (the orbit sought is x ~ bias + A sin(w t)); None takes ``cycle.bias`` (a
        :class:`~dfloop.solve.bias.BiasedCycle`), else 0. The shooting starts on that biased orbit, so unstable
        biased cycles are found as stable ones (``settle_periods`` 0).

    Returns
    -------
    ExactCycle
        ``success`` False (with the reason) when no orbit was found near the prediction. Never a false "no
        orbit": when shooting from the prediction fails, the loop is globalised (:mod:`dfloop.hybrid.globalise`:
        fewer nodes, runs from three starts on the exact flow, shooting from every oscillation seen), and a "no
        orbit" answer says where the motions went (``extra["outcome"]``, ``extra["motions"]``).
    """
    from ._checks import flag, in_closed_interval
    from .impact._effects_core import admissible, propagate, rows_on_zero, scan_steps
    from .progress import announce_compile

    announce_compile("exact_cycle", 20, admissible, propagate, rows_on_zero, scan_steps)  # bench_startup.py
    N = as_element(N)
    A0, w0 = cycle_argument(cycle)
    predicted = (A0, w0)
    from ._checks import finite

    r0, load = finite("r0", r0), finite("load", load)
    bias = finite("bias", getattr(cycle, "bias", 0.0) if bias is None else bias)
    constant = dict(r0=r0, load=load, bias=bias)
    harmonics = int(in_closed_interval("harmonics", harmonics, 1, 1000))
    samples = int(in_closed_interval("samples", samples, 16, 10**7))
    tol = in_closed_interval("tol", tol, 1e-14, 1e-4)
    max_iterations = int(in_closed_interval("max_iterations", max_iterations, 1, 10_000))
    if settle_periods is not None:
        settle_periods = in_closed_interval("settle_periods", settle_periods, 0.0, 1000.0)
    counterpart = max_deviation is None          # the default: a misplaced cycle's own orbit is still returned
    max_deviation = 0.5 if counterpart else positive("max_deviation", max_deviation)
    max_events = integer_at_least("max_events", max_events, 1)  # 2.5 is refused, not truncated
    max_events = int(in_closed_interval("max_events", max_events, 1, 10**9))
    m = int(in_closed_interval("nodes", nodes, 1, 1000))
    globalise = flag("globalise", globalise)

    from .hybrid.discrete import is_discrete

    if is_discrete(G):   # a digital loop: a finite-dimensional map (dfloop.hybrid.discrete)
        return _discrete_result(G, N, predicted, harmonics, max_deviation, getattr(cycle, "stability", None))

    from .hybrid.globalise import inside_search

    if globalise and not inside_search():   # the caller's own call, not a shooting the globalisation started
        out = _exact_cycle(G, N, cycle, predicted, harmonics, samples, tol, max_iterations, settle_periods,
                           max_events, max_deviation, nodes, m, globalise, constant, counterpart)
        cert = table_certificate(G, N, A0, w0)
        if cert is not None:     # a tabulated N: certified at the point of use (the verdict reads it)
            out = dataclasses.replace(out, extra={**out.extra, "table": cert})
        return out
    return _exact_cycle(G, N, cycle, predicted, harmonics, samples, tol, max_iterations, settle_periods, max_events,
                        max_deviation, nodes, m, globalise, constant, counterpart)


def _exact_cycle(G, N, cycle, predicted, harmonics, samples, tol, max_iterations, settle_periods, max_events,
                 max_deviation, nodes, m, globalise, constant, counterpart) -> ExactCycle:
    from .hybrid import ShootingError, delay_orbit, loop_model, periodic_orbit
    from .hybrid.globalise import homotopy_allowed, shoot_or_globalise

    A0, w0 = predicted
    r0, load, bias = constant["r0"], constant["load"], constant["bias"]
    # no false "no orbit": the whole search below runs inside the globalisation wrapper, which globalises a failure
    options = dict(harmonics=harmonics, samples=samples, tol=tol, max_iterations=max_iterations,
                   settle_periods=settle_periods, max_events=max_events, max_deviation=max_deviation, nodes=nodes,
                   **constant)
    outer = None if not globalise else shoot_or_globalise(
        G, N, predicted, lambda c, **kw: exact_cycle(G, N, c, **{**options, **kw}), max_deviation, constant,
        finish=lambda loop, orbit: _result(loop, orbit, predicted, harmonics, samples), counterpart=counterpart)
    if outer is not None:
        return outer
    loop = loop_model(G, N, A0 + abs(bias), w0, what="exact_cycle", r0=r0, load=load)
    if loop.delay > 0:   # a pure delay: Newton on the return map of the exact delay flow (dfloop.hybrid.delay)
        out = delay_orbit(loop, A0, w0, tol=tol, max_iterations=max_iterations, harmonics=harmonics,
                          samples=samples, max_events=max_events, max_deviation=max_deviation, bias=bias,
                          settle_periods=settle_periods or 0.0)
        if "another_orbit" in out.get("extra", {}):   # the orbit Newton found instead, for the globalisation
            out["extra"]["another_orbit"] = ExactCycle(**out["extra"]["another_orbit"])
        return ExactCycle(**out)
    if not loop.exact:
        raise ValueError(f"N: {type(N).__name__} is known only through a sampled operator ({loop.method}): "
                         "exact_cycle needs an exact time model (piecewise affine, smooth or impact; implement "
                         "time_model(), see dfloop.describing.time_model)")
    try:
        orbit = periodic_orbit(loop, N, A0, w0, tol=tol, max_iterations=max_iterations,
                               settle_periods=loop.settle_periods if settle_periods is None else settle_periods,
                               nodes=m, max_events=max_events, bias=bias, homotopy=homotopy_allowed())
    except ShootingError as exc:
        return _failure(str(exc), predicted, loop.method, exc.residual, exc.iterations)
    out = _result(loop, orbit, predicted, harmonics, samples)
    if not out.amplitude > 1e-12 * A0:
        return _failure(f"the motion settles to rest (fundamental amplitude {out.amplitude:.3g} of x): no "
                        "periodic orbit near the prediction", predicted, loop.method, orbit.residual, orbit.iterations)
    k = out.extra["returns"]        # a period-k orbit is compared with the prediction through its k-th harmonic
    deviation = max(abs(math.log(abs(out.harmonics[k - 1]) / A0)), abs(math.log(k * out.frequency / w0)))
    if deviation > max_deviation:
        return _failure(f"Newton converged to another orbit (A={out.amplitude:.6g}, w={out.frequency:.6g} rad/s, "
                        f"{'stable' if out.stable else 'unstable'}), farther from the prediction than max_deviation "
                        f"= {max_deviation:g} in log(A) or log(w): the predicted cycle may not exist as a true "
                        "orbit; raise max_deviation to accept it", predicted, loop.method, orbit.residual,
                        orbit.iterations, extra={"another_orbit": out})
    return out


def table_certificate(G, N, A: float, w: float) -> dict | None:
    """The certificate of a tabulated N at the cycle (A, w) of the loop with plant G (any plant exact_cycle
    accepts, a pure delay included): :func:`dfloop.impact.certificate.table_certificate`."""
    from .hybrid.delay import split_delay
    from .impact.certificate import table_certificate as certify

    free, delay = split_delay(G)
    free = getattr(free, "lti", None) or free          # a dfloop Plant carries its python-control system
    return certify(lambda om: complex(free(1j * om)) * complex(np.exp(-1j * om * delay)), N, A, w)


def _discrete_result(G, N, predicted, harmonics: int, max_deviation: float, stability=None) -> ExactCycle:
    """The ExactCycle of a digital loop: the orbit of the map nearest the prediction (its P samples as t, x, y;
    ``extra``: ``map`` True, ``samples_per_period`` P, ``harmonic`` m, ``orbit`` the DiscreteOrbit)."""
    from .hybrid.discrete import discrete_cycle

    A0, w0 = predicted
    orbit, note = discrete_cycle(G, N, A0, w0, max_deviation=max_deviation, stability=stability)
    method = f"digital loop (exact map): {note}"
    if orbit is None:
        return _failure(note, predicted, method)
    P, m, dt = orbit.period, orbit.harmonic, orbit.dt
    X = 2.0 * np.fft.fft(orbit.x) / P
    k = np.arange(1, harmonics + 1) * m
    Xk = np.where(k <= P // 2, X[np.minimum(k, P - 1)], 0.0) * 1j   # x ~ Im(X_k e^{j k m 2 pi n / P})
    if P % 2 == 0:
        Xk = np.where(k == P // 2, Xk / 2, Xk)
    phase = float(np.angle(Xk[0]))
    Xk = Xk * np.exp(-1j * np.arange(1, harmonics + 1) * phase)
    Xk[0] = abs(Xk[0])
    return ExactCycle(True, f"periodic orbit of {P} samples (harmonic {m}); {orbit.method}", predicted, method,
                      amplitude=orbit.amplitude, frequency=orbit.frequency, period=P * dt / m, t=np.arange(P) * dt,
                      x=orbit.x, y=orbit.y, switching_times=np.empty(0), harmonics=Xk, multipliers=orbit.multipliers,
                      stable=orbit.stable, amplitude_error=(A0 - orbit.amplitude) / orbit.amplitude,
                      frequency_error=(w0 - orbit.frequency) / orbit.frequency, residual=0.0, iterations=0,
                      extra={"map": True, "samples_per_period": P, "harmonic": m, "orbit": orbit})


def _result(loop, orbit, predicted, harmonics: int, samples: int) -> ExactCycle:
    """The ExactCycle of a converged orbit: harmonics of x from the exact Fourier integrals of the flow, the time
    origin moved so that x's fundamental is A sin(w t), waveform, events and multipliers."""
    fl, T = orbit.flow, orbit.period
    w = 2.0 * math.pi / T
    nx = loop.size - 1
    X = 2j * loop.fourier(fl, T, w, harmonics)                     # x ~ Im(X_k e^{jkwt})
    mean = float(loop.fourier(fl, T, 0.0, 1)[0].real) if hasattr(loop, "r0") else None   # k = 0: the mean
    phase = float(np.angle(X[0]))
    shift = phase / w                                              # new time t' = t + shift
    k = np.arange(1, harmonics + 1)
    X = X * np.exp(-1j * k * phase)
    X[0] = abs(X[0])
    t_new = np.arange(samples) * (T / samples)
    x, y = loop.signals(fl, np.mod(t_new - shift, T))
    switches = np.sort(np.mod(fl.event_times + shift, T))
    mu = np.linalg.eigvals(fl.monodromy[:nx, :nx])
    mu = mu[np.argsort(-np.abs(mu))]
    stable = bool(np.all(np.abs(_nontrivial(mu)) < 1.0))
    A_exact = float(X[0].real)
    A0, w0 = predicted
    if not A_exact > 0 and orbit.returns == 1:   # a loop at rest: no oscillation (exact_cycle reports it)
        return ExactCycle(False, "rest", predicted, loop.method, amplitude=A_exact)
    trivial = float(np.min(np.abs(mu - 1.0)))
    msg = f"converged in {orbit.iterations} Newton iteration(s), residual {orbit.residual:.1e}"
    k = orbit.returns
    if k > 1:   # the DF's oscillation is the k-th harmonic of the orbit: its errors are measured there
        A_dom = float(abs(X[k - 1]))
        msg = (f"period-{k} orbit: it repeats after {k} oscillations of {k * w:.6g} rad/s (the predicted "
               f"oscillation; period {T:.6g} s, dominant amplitude {A_dom:.6g}); " + msg)
    else:
        A_dom = A_exact
    if orbit.residual > 1e-11:
        msg += " (the rounding floor of the switch times)"
    if trivial > 1e-6:
        msg += f"; the trivial multiplier is off 1 by {trivial:.1e} (multipliers less accurate)"
    return ExactCycle(True, msg, predicted, loop.method, amplitude=A_exact, frequency=w, period=T, t=t_new, x=x,
                      y=y, switching_times=switches, harmonics=X, multipliers=mu, stable=stable,
                      amplitude_error=(A0 - A_dom) / A_dom, frequency_error=(w0 - k * w) / (k * w),
                      residual=orbit.residual, iterations=orbit.iterations,
                      extra={"z0": orbit.z, "mode0": orbit.mode, "returns": k, "plant_state": _plant_state(loop, orbit.z),
                             "path": orbit.path},
                      mean=float(np.mean(x)) if mean is None else mean)


def _not_checked(message: str, predicted: tuple) -> ExactCycle:
    return ExactCycle(False, message, predicted, "none", extra={"outcome": "not checked"})


register_exact_engine(exact_cycle, _not_checked)
