"""The true periodic orbit behind a predicted limit cycle: shooting, Floquet multipliers, DF errors.

:func:`exact_cycle` starts from a prediction (a :class:`~dfloop.solve.result.LimitCycle` or an (amplitude,
frequency) pair), runs the loop of the paper's Fig. 1 (reference 0, x = -c, c = G y) on the exact hybrid engine
(:mod:`dfloop.hybrid`: matrix exponentials between switches located to rounding level; DOP853 for elements that
are not piecewise linear) and solves the periodicity condition by Newton's method on (z0, T):

    phi_T(z0) - z0 = 0,      f(z0_k) . (z0 - z0_k) = 0     (the correction is orthogonal to the flow),

with the monodromy (saltation matrices at every switch included) as Jacobian. The start point lies in the middle
of the longest segment between switches, so small corrections never move a switch across t = 0 or t = T.
The Floquet multipliers are the eigenvalues of the converged monodromy; one is the trivial multiplier 1 of the
autonomous flow, and the cycle is stable when all others lie inside the unit circle.

A loop around a :class:`dfloop.impact.DynamicBacklash` is delegated to
:func:`dfloop.impact.loop.impact_loop_orbit` (the exact impact engine) and wrapped in the same result.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._blas import single_threaded_blas
from ._checks import integer_at_least, positive, scale
from .describing.interop import as_element

__all__ = ["ExactCycle", "exact_cycle"]

_SAMPLES = 512
_HISTORY = 256      # samples of the predicted sinusoid that set the element's state (relay branch, play)
_LINE_SEARCH = 8    # step halvings per Newton iteration
_FLOOR = 1e-9       # a residual below this that stops decreasing is the rounding floor: accepted


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
        The exact switching (or impact) instants in [0, period), in the same time frame.
    harmonics : ndarray or None
        Complex amplitudes X_k of x, k = 1..K (x = mean + sum_k Im(X_k exp(j k w t))); ``harmonics[0]`` is real
        and equal to ``amplitude``.
    multipliers : ndarray or None
        Floquet multipliers (eigenvalues of the monodromy, saltation matrices included), by decreasing modulus.
    stable : bool or None
        All multipliers but the trivial one (closest to 1) strictly inside the unit circle.
    amplitude_error, frequency_error : float or None
        Relative errors of the prediction, (predicted - exact) / exact.
    predicted : (float, float)
        The predicted (amplitude, frequency) the search started from.
    method : str
        How the orbit was computed (exact hybrid flow, DOP853, impact engine).
    residual : float
        Final |phi_T(z0) - z0| relative to |z0| (inf when no Newton step was taken).
    iterations : int
        Newton iterations used.
    extra : dict
        Engine details: ``z0`` (augmented state [plant state, element state, 1] at the shooting start, which is
        not the waveform's t = 0) and ``mode0`` (the element's mode there), for re-running the flow.
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
        return float(np.max(np.abs(_nontrivial(self.multipliers)), initial=0.0))

    def plot(self, ax=None, *, unit: str = ""):
        """Draw the element input x over one period with the exact switching (or impact) instants marked.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Where to draw (a new figure's axes by default).
        unit : str
            The unit of x (the element's ``input_unit``, e.g. ``"m"``) for the axis label.

        Returns
        -------
        matplotlib Axes
            ``ax.lines[0]`` is the waveform (``t``, ``x``), ``ax.lines[1]`` the switching instants
            (``switching_times`` and x there, interpolated on the periodic waveform).

        Raises
        ------
        ValueError
            For an ExactCycle without an orbit (``success`` False; the message says why), or an ``ax`` that is
            not a matplotlib Axes.
        """
        from .plot._labels import TIME, axes_or_new, legend, quantity

        if not self.success:
            raise ValueError(f"this ExactCycle has no orbit to plot ({self.message})")
        ax = axes_or_new(ax)
        ax.plot(self.t, self.x, color="C0", label="x(t), exact orbit")
        ts = self.switching_times
        ax.plot(ts, np.interp(ts, self.t, self.x, period=self.period), ls="none", marker="o", ms=5, mfc="none",
                mec="C3", label="switching / impact instants")
        ax.axhline(0.0, color="0.8", lw=0.5)
        ax.set_xlim(0.0, self.period)
        ax.set_xlabel(TIME)
        ax.set_ylabel(quantity("Element input x", unit))
        ax.set_title(f"Exact orbit: A={self.amplitude:.4g}, ω={self.frequency:.4g} rad/s, "
                     f"{'stable' if self.stable else 'unstable'}", fontsize=9)
        legend(ax, fontsize=8)
        return ax

    def __repr__(self) -> str:
        A0, w0 = self.predicted
        if not self.success:
            return f"ExactCycle(no orbit: {self.message}; predicted A={A0:.6g}, w={w0:.6g} rad/s; {self.method})"
        return (f"ExactCycle(A={self.amplitude:.8g}, omega={self.frequency:.8g} rad/s, "
                f"{'stable' if self.stable else 'unstable'} (largest non-trivial |multiplier| "
                f"{self.largest_multiplier:.4g}); DF error: A {100 * self.amplitude_error:+.3g} %, "
                f"omega {100 * self.frequency_error:+.3g} %; {self.switching_times.size} switches/period, "
                f"residual {self.residual:.1e}; {self.method})")


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


def _harmonic_balance_state(G_matrices, N, A0: float, w: float, t: float = 0.0) -> np.ndarray:
    """Plant state at time t of the sinusoidal orbit x = A0 sin(w t) that the DF assumes."""
    A, B, _ = G_matrices
    n_val = complex(N(A0, w) if N.frequency_dependent else N(A0))
    X = np.linalg.solve(1j * w * np.eye(A.shape[0]) - A, B) * n_val * A0
    return (X * np.exp(1j * w * t)).imag.copy()


def _failure(message, predicted, method, residual=math.inf, iterations=0) -> ExactCycle:
    return ExactCycle(False, message, predicted, method, residual=residual, iterations=iterations)


@single_threaded_blas
def exact_cycle(G, N, cycle, *, harmonics: int = 15, samples: int = _SAMPLES, tol: float = 1e-11,
                max_iterations: int = 40, settle_periods: float = 0.0, max_events: int = 10_000,
                max_deviation: float = 0.5, nodes: int = 8) -> ExactCycle:
    """Find the true periodic orbit near a predicted limit cycle, its Floquet multipliers and the DF's errors.

    Parameters
    ----------
    G : python-control tf or ss
        Strictly proper SISO plant (from the element's output y to c; x = -c).
    N : DescribingFunction
        The element: piecewise-linear elements (relays, saturation, dead zone, backlash, quantizer, ...) run on
        the exact hybrid engine, other static elements on DOP853 (said in ``method``), a
        :class:`dfloop.impact.DynamicBacklash` on the exact impact engine.
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
    settle_periods : float
        Periods flowed from the harmonic-balance start before shooting, in [0, 1000]. With 0 (default) the
        shooting starts on the predicted sinusoidal orbit itself (right for unstable cycles, which a flow
        leaves); a few periods help a stable cycle that the DF places poorly.
    max_events : int
        Bound on switches per flow (a flow reaching it fails with a message that says so).
    nodes : int
        Multiple-shooting nodes per period (1: single shooting). Several nodes keep Newton's corrections
        small on strongly unstable cycles, whose flow leaves the prediction within a period.
    max_deviation : float
        An orbit whose amplitude or frequency differs from the prediction by more than this in log scale
        (0.5: a factor 1.65) is reported as another orbit (``success`` False, its numbers in the message).

    Returns
    -------
    ExactCycle
        ``success`` False (with the reason) when no orbit was found near the prediction.
    """
    from ._checks import in_closed_interval
    from .hybrid import HybridError, loop_model, plant_matrices

    N = as_element(N)
    A0, w0 = cycle_argument(cycle)
    predicted = (A0, w0)
    harmonics = int(in_closed_interval("harmonics", harmonics, 1, 1000))
    samples = int(in_closed_interval("samples", samples, 16, 10**7))
    tol = in_closed_interval("tol", tol, 1e-14, 1e-4)
    max_iterations = int(in_closed_interval("max_iterations", max_iterations, 1, 10_000))
    settle_periods = in_closed_interval("settle_periods", settle_periods, 0.0, 1000.0)
    max_deviation = positive("max_deviation", max_deviation)
    max_events = integer_at_least("max_events", max_events, 1)

    from .impact import DynamicBacklash
    if isinstance(N, DynamicBacklash):
        return _impact_orbit(G, N, A0, w0)

    plant = plant_matrices(G, what="exact_cycle")
    loop, method = loop_model(G, N, A0, w0)
    if loop is None:
        raise ValueError(f"N: {method}; exact_cycle needs a piecewise-linear or static element "
                         "(or a DynamicBacklash)")
    T = 2.0 * math.pi / w0
    m = int(in_closed_interval("nodes", nodes, 1, 1000))
    try:
        if settle_periods > 0:
            z, mode = loop.start(_harmonic_balance_state(plant, N, A0, w0), _history(A0, w0, 0.0))
            fl = loop.flow(z, mode, settle_periods * T, max_events=max_events)
            z, mode, t_first = _section_point(loop, fl, settle_periods * T, T, time=True)
            fl = loop.flow(z, mode, T, max_events=max_events)
            zs, modes = _nodes_on_flow(loop, fl, m, T)
        else:   # nodes on the predicted sinusoidal orbit itself (right for unstable cycles, which a flow leaves)
            z, mode = loop.start(_harmonic_balance_state(plant, N, A0, w0), _history(A0, w0, 0.0))
            fl = loop.flow(z, mode, T, max_events=max_events)
            _, _, t_first = _section_point(loop, fl, T, T, time=True)
            zs, modes = [], []
            for i in range(m):
                ti = t_first + i * T / m
                zi, mi = loop.start(_harmonic_balance_state(plant, N, A0, w0, ti), _history(A0, w0, ti))
                zi, mi = loop.admissible_mode(zi, mi)
                zs.append(zi)
                modes.append(mi)
    except HybridError as exc:
        return _failure(f"the flow from the predicted orbit failed: {exc}", predicted, method)

    nx = loop.size - 1
    residual, it = math.inf, 0
    for it in range(1, max_iterations + 1):
        try:
            flows = [loop.flow(zs[i], modes[i], T / m, monodromy=True, max_events=max_events) for i in range(m)]
        except HybridError as exc:
            return _failure(f"Newton iteration {it}: {exc}", predicted, method, residual, it)
        previous = residual
        residual = _defect(flows, zs, nx)
        consistent = all(flows[i].mode == modes[(i + 1) % m] for i in range(m))
        if consistent and (residual <= tol or (residual <= _FLOOR and residual > 0.5 * previous)):
            break   # converged, or stalled at the rounding floor of the switch times (quadratic convergence ended)
        if it == max_iterations:
            return _failure(f"Newton did not converge in max_iterations = {max_iterations} (residual "
                            f"{residual:.2e} > tol = {tol:g}): no periodic orbit near the prediction, or a "
                            "chaotic / quasi-periodic response; raise max_iterations or start elsewhere",
                            predicted, method, residual, it)
        J, F = _shooting_system(loop, flows, zs, modes, m, nx)
        try:
            delta = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            return _failure(f"singular shooting Jacobian at iteration {it} (a multiplier equal to 1 besides "
                            "the trivial one: a marginal or non-isolated orbit)", predicted, method, residual, it)
        found = _line_search(loop, zs, flows, T, delta, residual, m, nx, max_events)
        if found is None:
            return _failure(f"Newton iteration {it}: no step reduces the residual {residual:.2e} (no periodic "
                            "orbit near the prediction, or a chaotic / quasi-periodic response)", predicted, method,
                            residual, it)
        zs, modes, T = found
    try:
        fl = loop.flow(zs[0], modes[0], T, monodromy=True, max_events=max_events)
    except HybridError as exc:
        return _failure(f"the converged orbit cannot be followed over one period: {exc}", predicted, method,
                        residual, it)
    z, mode = zs[0], modes[0]
    out = _result(loop, fl, z, mode, T, predicted, method, residual, it, harmonics, samples)
    deviation = max(abs(math.log(out.amplitude / A0)), abs(math.log(out.frequency / w0)))
    if deviation > max_deviation:
        return _failure(f"Newton converged to another orbit (A={out.amplitude:.6g}, w={out.frequency:.6g} rad/s, "
                        f"{'stable' if out.stable else 'unstable'}), farther from the prediction than max_deviation "
                        f"= {max_deviation:g} in log(A) or log(w): the predicted cycle may not exist as a true "
                        "orbit; raise max_deviation to accept it", predicted, method, residual, it)
    return out


def _section_point(loop, fl, t_end: float, T: float, time: bool = False):
    """State, mode (and time) at the middle of the longest segment between switches in the last period of a
    flow (segments that wrap around t_end - T count whole when the flow's mode at both ends is the same)."""
    starts = np.clip(fl.t0, t_end - T, t_end)
    ends = np.clip(np.append(fl.t0[1:], t_end), t_end - T, t_end)
    lengths = ends - starts
    k = int(np.argmax(lengths))
    t_mid = 0.5 * (starts[k] + ends[k])
    out = (loop.states(fl, t_mid)[0], int(fl.modes[k]))
    return out + (t_mid,) if time else out


def _history(A0: float, w0: float, t: float) -> np.ndarray:
    """Samples of the predicted input A0 sin(w0 t') over the period before time t (sets the element's state)."""
    T = 2.0 * math.pi / w0
    return A0 * np.sin(w0 * (t + T * (np.arange(_HISTORY) / _HISTORY - 1.0)))


def _nodes_on_flow(loop, fl, m: int, T: float):
    """m equally spaced states of a flow over [0, T] and their modes."""
    t = np.arange(m) * (T / m)
    seg = np.clip(np.searchsorted(fl.t0, t, side="right") - 1, 0, fl.t0.size - 1)
    return list(loop.states(fl, t)), [int(fl.modes[k]) for k in seg]


def _defect(flows, zs, nx) -> float:
    """Relative size of the shooting defects phi(z_i) - z_{i+1}."""
    m = len(zs)
    d = np.concatenate([flows[i].z[:nx] - zs[(i + 1) % m][:nx] for i in range(m)])
    scale = max(float(np.linalg.norm(np.concatenate([z[:nx] for z in zs]))), 1e-300)
    return float(np.linalg.norm(d)) / scale


def _shooting_system(loop, flows, zs, modes, m, nx):
    """Jacobian and defects of multiple shooting in (z_0..z_{m-1}, T); last row: correction orthogonal to
    the flow at z_0."""
    n = m * nx + 1
    J = np.zeros((n, n))
    F = np.zeros(n)
    for i in range(m):
        r = slice(i * nx, (i + 1) * nx)
        j = (i + 1) % m
        J[r, r] += flows[i].monodromy[:nx, :nx]
        J[r, j * nx:(j + 1) * nx] -= np.eye(nx)
        J[r, -1] = loop.field(flows[i].z, flows[i].mode)[:nx] / m
        F[r] = flows[i].z[:nx] - zs[j][:nx]
    J[-1, :nx] = loop.field(zs[0], modes[0])[:nx]
    return J, F


def _line_search(loop, zs, flows, T, delta, residual, m, nx, max_events):
    """Damped Newton step (halvings bounded by _LINE_SEARCH) on nodes and period; node modes follow the flows."""
    from .hybrid import HybridError

    step = 1.0
    for _ in range(_LINE_SEARCH + 1):
        T_new = T + step * delta[-1]
        if T_new > 0:
            try:
                # node modes follow the trial flows in turn (a hysteretic element's mode is not a function of
                # the state: a node moved across a switch takes the mode the flow reaching it ends in)
                new_z, new_modes, trial = [], [], []
                for i in range(m):
                    zi = zs[i].copy()
                    zi[:nx] += step * delta[i * nx:(i + 1) * nx]
                    zi, mi = loop.admissible_mode(zi, trial[-1].mode if trial else flows[-1].mode)
                    new_z.append(zi)
                    new_modes.append(mi)
                    trial.append(loop.flow(zi, mi, T_new / m, max_events=max_events))
                if _defect(trial, new_z, nx) < residual or residual < _FLOOR:
                    return new_z, new_modes, T_new
            except HybridError:
                pass
        step *= 0.5
    return None


def _result(loop, fl, z, mode, T, predicted, method, residual, iterations, harmonics, samples) -> ExactCycle:
    w = 2.0 * math.pi / T
    nx = loop.size - 1
    four = loop.fourier(fl, T, w, harmonics) @ loop.x_row          # (1/T) int x e^{-jkwt}
    X = 2j * four                                                  # x ~ Im(X_k e^{jkwt})
    phase = float(np.angle(X[0]))
    shift = phase / w                                              # new time t' = t + shift
    k = np.arange(1, harmonics + 1)
    X = X * np.exp(-1j * k * phase)
    X[0] = abs(X[0])
    t_new = np.arange(samples) * (T / samples)
    t_old = np.mod(t_new - shift, T)
    zs = loop.states(fl, t_old)
    seg = np.clip(np.searchsorted(fl.t0, t_old, side="right") - 1, 0, fl.t0.size - 1)
    x = loop.x(zs)
    y = loop.output(zs, fl.modes[seg])
    switches = np.sort(np.mod(np.array([e[0] for e in fl.events]) + shift, T))
    mu = np.linalg.eigvals(fl.monodromy[:nx, :nx])
    mu = mu[np.argsort(-np.abs(mu))]
    others = _nontrivial(mu)
    stable = bool(np.all(np.abs(others) < 1.0))
    A_exact = float(X[0].real)
    A0, w0 = predicted
    trivial = float(np.min(np.abs(mu - 1.0)))
    msg = f"converged in {iterations} Newton iteration(s), residual {residual:.1e}"
    if residual > 1e-11:
        msg += " (the rounding floor of the switch times)"
    if trivial > 1e-6:
        msg += f"; the trivial multiplier is off 1 by {trivial:.1e} (multipliers less accurate)"
    return ExactCycle(True, msg, predicted, method, amplitude=A_exact, frequency=w, period=T, t=t_new, x=x, y=y,
                      switching_times=switches, harmonics=X, multipliers=mu, stable=stable,
                      amplitude_error=(A0 - A_exact) / A_exact, frequency_error=(w0 - w) / w, residual=residual,
                      iterations=iterations, extra={"z0": z, "mode0": mode})


def _impact_orbit(G, N, A0: float, w0: float) -> ExactCycle:
    """Delegate to the impact engine's orbit finder and wrap its result (dynamic backlash)."""
    from .impact.loop import impact_loop_orbit

    o = impact_loop_orbit(G, N, A0, w0)
    method = getattr(o, "method", "impact engine")
    if not o.success:
        return _failure(o.message, (A0, w0), method)
    T = float(o.period)
    t, x = np.asarray(o.t, float), np.asarray(o.x, float)
    w = 2.0 * math.pi / T
    from .harmonics import fundamental

    A_exact = abs(fundamental(np.append(t, t[0] + T), np.append(x, x[0]), w))
    return ExactCycle(True, o.message, (A0, w0), method, amplitude=A_exact, frequency=w, period=T, t=t, x=x,
                      y=np.asarray(o.y, float), switching_times=np.asarray(o.event_times, float),
                      harmonics=np.array([A_exact + 0j]), multipliers=np.asarray(o.multipliers),
                      stable=bool(o.stable), amplitude_error=(A0 - A_exact) / A_exact,
                      frequency_error=(w0 - w) / w, residual=0.0, iterations=0,
                      extra={"period_multiple": getattr(o, "period_multiple", 1)})
