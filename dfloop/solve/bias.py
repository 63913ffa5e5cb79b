"""Limit cycles with a bias: e(t) ~ B + A sin(w t) in a loop with a constant input r0 at the summing junction.

The dual-input DF balance (docs/bias_forced.md) is

    B + G(0) m(B, A) = r0            (bias equation; m = B N_B is the element's mean output),
    1 + G(jw) N_A(B, A) = 0          (first harmonic),

and with an integrator in G (G(0) infinite) the bias equation becomes m(B, A) = 0: the bias settles where the
element's mean output vanishes, whatever r0 (the plant's output mean then equals r0).

Completeness by construction: the bias equation is solved for B on a grid of amplitudes, every root bracketed by a
sign change on a fine grid of B and bisected to rounding; the roots are numbered in increasing B, and on each
amplitude interval where their number is constant the j-th root B_j(A) defines an amplitude-only DF
N_j(A) = N_A(B_j(A), A), whose cycles :func:`~dfloop.predict_limit_cycles` finds (every root in its window, by the
winding-number argument of the symmetric solver). When m is non-decreasing in B (every monotone element: relays,
saturation, dead zone, backlash) and G(0) >= 0, the bias equation is monotone in B and its roots form one interval:
nothing can be missed. Otherwise a double root of the bias equation (a tangency, no sign change) could be
missed; the result says whether the bias equation was monotone on the grid (``bias_monotone``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize.elementwise import find_root

from .._checks import finite, integer_at_least, window as checked_window
from ..describing.base import DescribingFunction
from ..describing.dual_input import DualInputDF
from ..errors import DfloopError
from .plant import as_plant
from .predict import predict_limit_cycles

__all__ = ["BiasedCycle", "BiasedCycles", "predict_biased_cycles", "static_gain", "biased_confidence"]

_BISECTIONS = 200  # bisection steps on the bias (machine precision is reached in about 60 for any window)
_JUMP = 1e-6  # a sign change of the bias equation is a jump, no root, when |F| there stays above this (relative)


def static_gain(G) -> float:
    """G(0) of a rational plant (python-control tf or ss, or ``delayed(G, T)``: G's, as e^{-sT} is 1 at s = 0):
    ``inf`` (signed by the low-frequency phase) when G has a pole at s = 0 (an integrator).

    Raises
    ------
    ValueError
        For a plant given as a callable or frd (no G(0)): pass ``dc_gain=`` to :func:`predict_biased_cycles`.
    """
    plant = as_plant(G)
    if plant.roots is None:
        raise DfloopError("G(0) is unknown for a callable or frd plant: pass dc_gain= (inf for an integrator)")
    zeros, poles = plant.roots
    if np.any(poles == 0):
        return math.inf
    rational = plant.lti if plant.delay_free is None else plant.delay_free   # a delay's e^{-sT} is 1 at s = 0
    return float(np.real(rational.dcgain()))


@dataclass(frozen=True)
class BiasedCycle:
    """One predicted biased cycle e(t) ~ B + A sin(w t) at the element's input.

    Attributes
    ----------
    bias : float
        B, mean of the element's input (input units).
    amplitude : float
        A, amplitude of the fundamental at the element's input.
    frequency : float
        w in rad/s (``period`` = 2 pi / w, s).
    mean_output : float
        m(B, A), the element's mean output.
    stability : str
        ``"stable"``, ``"unstable"`` or ``"marginal"``: the Loeb criterion on the reduced map A -> N_A(B(A), A)
        (the bias following the amplitude quasi-statically). It ignores the bias dynamics: a cycle it calls stable
        can be unstable through a slow drift of the bias (docs/bias_forced.md, "Limits"); check with a simulation.
    branch : int
        Index of the bias root (in increasing B) at this amplitude.
    residual : float
        |1 + G(jw) N_A(B, A)| at the answer.
    confidence : Confidence or None
        The harmonic distortion the dual-input DF neglects and the estimated errors of (A, w) and of the bias
        (:func:`biased_confidence`; ``bias_error`` absolute, input units).
    exact : ExactCycle or None
        The exact orbit (:func:`dfloop.biased.biased_cycles`); its multipliers then decide the stability.
    """

    bias: float
    amplitude: float
    frequency: float
    mean_output: float
    stability: str
    branch: int
    residual: float
    confidence: object = field(default=None, compare=False)
    exact: object = field(default=None, compare=False)

    @property
    def period(self) -> float:
        """2 pi / frequency (s)."""
        return 2 * math.pi / self.frequency

    @property
    def stable(self) -> bool:
        return self.stability == "stable"

    def to_dict(self) -> dict:
        """Plain data: the attributes (``confidence`` and ``exact`` as their own ``to_dict()``, or None)."""
        out = {k: getattr(self, k) for k in ("bias", "amplitude", "frequency", "mean_output", "stability", "branch",
                                             "residual")}
        for k in ("confidence", "exact"):
            v = getattr(self, k)
            out[k] = None if v is None else v.to_dict()
        return out

    def __repr__(self) -> str:
        text = (f"BiasedCycle(bias={self.bias:.6g}, amplitude={self.amplitude:.6g}, frequency={self.frequency:.6g} "
                f"rad/s, {self.stability}, branch {self.branch}, |1+G N_A|={self.residual:.1e}")
        c = self.confidence
        if c is not None and c.available:
            text += (f"; distortion {100 * c.distortion:.3g} %, est. error A {100 * c.amplitude_error:+.3g} %, "
                     f"w {100 * c.frequency_error:+.3g} %, bias {c.bias_error:+.3g}")
        ex = self.exact
        if ex is not None:
            text += (f"; exact: mean={ex.mean:.8g}, A={ex.amplitude:.8g}, w={ex.frequency:.8g} rad/s, "
                     f"{'stable' if ex.stable else 'unstable'}" if ex.success else f"; exact: {ex.message}")
        return text + ")"


class BiasedCycles(list):
    """The predicted biased cycles (sorted by frequency, then amplitude) and how they were searched.

    Attributes
    ----------
    r0 : float
        The constant input at the summing junction.
    dc_gain : float
        G(0) used (``inf`` for an integrator: bias equation m(B, A) = 0).
    amplitude_window, bias_window, omega_window : (float, float)
        The windows searched (``omega_window`` None when the plant's default was used per branch).
    bias_monotone : bool
        Whether the bias equation was monotone in B on every amplitude of the grid (then its roots form one
        interval and the search is complete); False: a double root of the bias equation could be missed.
    branches : list of (float, float, int)
        Amplitude intervals with a constant number of bias roots, and that number.
    gaps : list of (float, float)
        Amplitude intervals between two grid nodes where the number of bias roots changes (a fold of the bias
        equation, or a root leaving the bias window): not searched (refine ``n_amplitudes`` to shrink them).
    """

    def __init__(self, cycles, r0, dc_gain, amplitude_window, bias_window, omega_window, bias_monotone, branches,
                 gaps=()):
        # by frequency, then amplitude: cycles whose frequencies agree to 9 digits (an integrator's phase crossover
        # fixes w for every amplitude) keep an order that rounding cannot flip
        super().__init__(sorted(cycles, key=lambda c: (float(f"{c.frequency:.9g}"), c.amplitude)))
        self.r0, self.dc_gain = r0, dc_gain
        self.amplitude_window, self.bias_window, self.omega_window = amplitude_window, bias_window, omega_window
        self.bias_monotone, self.branches, self.gaps = bias_monotone, branches, list(gaps)

    def __repr__(self) -> str:
        head = (f"{len(self)} biased cycle(s), r0={self.r0:g}, G(0)={self.dc_gain:g}; amplitude window "
                f"[{self.amplitude_window[0]:.4g}, {self.amplitude_window[1]:.4g}], bias window "
                f"[{self.bias_window[0]:.4g}, {self.bias_window[1]:.4g}]; bias equation "
                + ("monotone in B (complete)" if self.bias_monotone else
                   "not monotone in B (a double bias root could be missed)"))
        if self.gaps:
            head += f"; {len(self.gaps)} amplitude gap(s) not searched (bias root count changes)"
        return "\n".join([head] + [f"  {c!r}" for c in self])


class _BiasEquation:
    """F(B, A) = B + G(0) (m(B, A) + d) - r0, or m(B, A) + d with an integrator (d: the load); its roots in B, numbered in increasing B."""

    def __init__(self, dual: DualInputDF, g0: float, r0: float, load: float, bias_grid: np.ndarray):
        self.dual, self.g0, self.r0, self.load, self.grid = dual, g0, r0, load, bias_grid

    def __call__(self, B, A):
        m = self.dual.mean(B, A) + self.load
        return m if math.isinf(self.g0) else B + self.g0 * m - self.r0

    def brackets(self, A: np.ndarray):
        """F on the bias grid for each amplitude (rows), the sign-change mask (cells) that are roots, and each root.

        A sign change of F across a jump (a relay with hysteresis holding one output when A is below its
        hysteresis: the mean output jumps from -M to +M) is no root: every sign-change cell is bisected and kept
        only if |F| at the converged bracket is below ``_JUMP`` times the row's largest |F|. Returns
        ``(F, change, B)`` with ``B`` the bisected root of each kept cell (NaN elsewhere).
        """
        Bg, Ag = np.meshgrid(self.grid, A)
        F = self(Bg, Ag)
        change = np.sign(F[:, :-1]) * np.sign(F[:, 1:]) <= 0
        change &= ~((F[:, :-1] == 0) & (np.arange(F.shape[1] - 1) > 0))  # a zero on a node counts once
        B = np.full(change.shape, np.nan)
        rows, cells = np.nonzero(change)
        if rows.size:
            # Chandrupatla's bracketing method (interpolation where F is smooth, bisection where it is not: the
            # mean output of a relay with hysteresis jumps), to a bracket of a few ulps of the bias window
            span = float(self.grid[-1] - self.grid[0])
            res = find_root(lambda b, a: self(b, a), (self.grid[cells], self.grid[cells + 1]), args=(A[rows],),
                            tolerances=dict(xatol=4 * np.finfo(float).eps * span, xrtol=4 * np.finfo(float).eps,
                                            fatol=0.0, frtol=0.0), maxiter=_BISECTIONS)
            if not np.all(res.success):
                bad = int(np.argmin(res.success))
                raise DfloopError(f"the bias root at A = {float(A[rows[bad]])!r} did not converge in {_BISECTIONS} "
                                  f"steps")
            scale = np.max(np.abs(F), axis=1)[rows]
            f_lo, f_hi = (np.abs(f) for f in res.f_bracket)
            root = (np.minimum(f_lo, f_hi) <= _JUMP * scale) | (res.f_x == 0)
            change[rows[~root], cells[~root]] = False
            B[rows[root], cells[root]] = res.x[root]
        return F, change, B

    def root(self, A: np.ndarray, j: int) -> np.ndarray:
        """The j-th bias root at each amplitude (bisected to rounding in its grid cell)."""
        _, change, B = self.brackets(A)
        count = change.sum(axis=1)
        if np.any(count <= j):
            raise DfloopError(f"bias branch {j} does not exist at A = {float(A[count <= j][0])!r}")
        cell = np.argmax(np.cumsum(change, axis=1) > j, axis=1)
        return B[np.arange(A.size), cell]


class _BranchDF(DescribingFunction):
    """N_j(A) = N_A(B_j(A), A) on one amplitude interval (the symmetric solver's element for one bias branch)."""

    def __init__(self, equation: _BiasEquation, j: int, lo: float, hi: float):
        self.equation, self.j, self.lo, self.hi = equation, j, lo, hi

    def _evaluate(self, A, omega):
        a = np.asarray(A, float)
        out = np.zeros(a.shape, complex)
        flat = a.ravel()
        ok = np.isfinite(flat) & (flat >= self.lo) & (flat <= self.hi)
        res = out.ravel()
        if np.any(ok):
            B = self.equation.root(flat[ok], self.j)
            res[ok] = self.equation.dual.N_A(B, flat[ok])
        res[np.isnan(flat)] = np.nan
        return res.reshape(a.shape)

    def amplitude_domain(self, omega=None):
        shape = np.shape(omega) if omega is not None else ()
        return np.full(shape, self.lo), np.full(shape, self.hi)


def predict_biased_cycles(G, element, *, r0: float = 0.0, load: float = 0.0, amplitude, bias=None, omega=None, dc_gain=None,
                          n_amplitudes: int = 200, n_bias: int = 400, grid=(64, 256)) -> BiasedCycles:
    """Every biased cycle e ~ B + A sin(w t) of the loop with a constant input r0 (dual-input DF balance).

    Parameters
    ----------
    G : python-control tf or ss, ``delayed(G, T)``, or callable
        The linear part; a callable or frd needs ``dc_gain``. A pure delay enters the first harmonic as
        G(jw) e^{-jwT} and not the bias equation (G(0) is the rational part's).
    element : DescribingFunction, DualInputDF or callable
        The nonlinear element (any element :class:`~dfloop.describing.dual_input.DualInputDF` accepts, symmetric
        or not), or its dual-input DF.
    r0 : float
        Constant input at the summing junction (element input units; e = r0 - y).
    load : float
        Constant added to the element's output (element output units: a load torque, gravity): the plant is driven
        by u = f(e) + load, so the bias equation reads B + G(0) (m + load) = r0 (m + load = 0 with an integrator).
    amplitude : (float, float)
        Amplitude window (0 < lo < hi) of the element's input.
    bias : (float, float), optional
        Bias window searched for B. Default: r0 +/- (|r0| + 4 amplitude[1]) widened by |G(0)| times the largest
        |m| on the amplitude window's grid (finite G(0)); +/- (|r0| + 4 amplitude[1]) with an integrator.
    omega : (float, float), optional
        Frequency window (rad/s); default: the symmetric solver's.
    dc_gain : float, optional
        G(0) (``inf`` for an integrator); default: from the poles and zeros of G.
    n_amplitudes, n_bias : int
        Grid on which the bias roots are counted (amplitudes log-spaced, biases uniform); each root is bisected
        to rounding afterwards.
    grid : (int, int)
        Initial grid of the symmetric solver on each branch.

    Returns
    -------
    BiasedCycles

    Raises
    ------
    ValueError
        Bad windows or sizes (naming the parameter), or an element without a dual-input DF.
    """
    dual = element if isinstance(element, DualInputDF) else DualInputDF(element)
    r0 = finite("r0", r0)
    load = finite("load", load)
    a_lo, a_hi = checked_window("amplitude", amplitude)
    if not a_lo > 0:
        raise DfloopError(f"amplitude window must be positive, got {amplitude!r}")
    n_a = integer_at_least("n_amplitudes", n_amplitudes, 8)
    n_b = integer_at_least("n_bias", n_bias, 8)
    g0 = static_gain(G) if dc_gain is None else float(dc_gain)
    if math.isnan(g0):
        raise DfloopError(f"dc_gain must be a number or inf, got {dc_gain!r}")
    g0 = abs(g0) if math.isinf(g0) else g0
    A = np.geomspace(a_lo, a_hi, n_a)
    if bias is None:
        half = abs(r0) + 4 * a_hi  # with an integrator: a bias beyond the swing plus the element's breakpoints
        if not math.isinf(g0):
            probe = np.linspace(r0 - half, r0 + half, 64)
            Bg, Ag = np.meshgrid(probe, A)
            half += abs(g0) * (float(np.max(np.abs(dual.mean(Bg, Ag)))) + abs(load))
        b_lo, b_hi = (-half, half) if math.isinf(g0) else (r0 - half, r0 + half)
    else:
        b_lo, b_hi = _signed_window(bias)
    equation = _BiasEquation(dual, g0, r0, load, np.linspace(b_lo, b_hi, n_b))
    F, change, _ = equation.brackets(A)
    count = change.sum(axis=1)
    dF = np.diff(F, axis=1)
    slack = 1e-12 * np.max(np.abs(F), axis=1, keepdims=True)  # flat parts (a saturated mean) vary by rounding
    monotone = bool(np.all((dF >= -slack).all(axis=1) | (dF <= slack).all(axis=1)))
    # amplitude intervals with a constant number of bias roots (interval ends: the grid nodes where it holds)
    branches, gaps, start = [], [], 0
    for i in range(1, n_a + 1):
        if i == n_a or count[i] != count[start]:
            if count[start] > 0 and i - 1 > start:
                branches.append((float(A[start]), float(A[i - 1]), int(count[start])))
            if i < n_a:
                gaps.append((float(A[i - 1]), float(A[i])))
            start = i
    cycles = []
    for lo, hi, k in branches:
        for j in range(k):
            found = predict_limit_cycles(G, _BranchDF(equation, j, lo, hi), amplitude=(lo, hi), omega=omega,
                                         grid=grid)
            for c in found:
                a = np.array([c.amplitude])
                B = float(equation.root(a, j)[0])
                conf = biased_confidence(G, dual, B, c.amplitude, c.frequency, r0=r0, load=load, dc_gain=g0)
                cycles.append(BiasedCycle(B, c.amplitude, c.frequency, float(dual.mean(B, c.amplitude)),
                                          c.stability, j, float(c.residual), conf))
    return BiasedCycles(cycles, r0, g0, (a_lo, a_hi), (b_lo, b_hi), omega, monotone, branches, gaps)


def _signed_window(bias) -> tuple[float, float]:
    try:
        lo, hi = (finite("bias", x) for x in bias)
    except TypeError:
        raise DfloopError(f"bias must be a pair (lo, hi), got {bias!r}") from None
    if not lo < hi:
        raise DfloopError(f"bias must satisfy lo < hi, got {bias!r}")
    return lo, hi


_SAMPLES = 2048      # samples of one period for the confidence
_HARMONICS = 15      # harmonics carried through G
_STEP = 1e-6         # relative step of the central differences of the balance's Jacobian


def _response(dual: DualInputDF, scale: float):
    """The element's output over one period of periodic input samples (its periodic regime), or None."""
    if dual.function is not None:
        f = dual.function
        return lambda x: np.asarray(f(x), float)
    if isinstance(dual.element, DescribingFunction):
        try:
            return dual.element.time_model(scale).response
        except NotImplementedError:
            return None
    return None


def biased_confidence(G, element, bias: float, amplitude: float, frequency: float, *, r0: float = 0.0,
                      load: float = 0.0, dc_gain=None, samples: int = _SAMPLES, harmonics: int = _HARMONICS):
    """Harmonic distortion and estimated errors of a biased cycle e ~ B + A sin(w t) (the biased counterpart of
    :func:`dfloop.solve.confidence.cycle_confidence`).

    The element is driven by B + A sin(theta); the harmonics k >= 2 of its output pass through G and give the
    input's distortion d = sqrt(sum |X_k|^2) / A. Driven once more with the distorted input, the element's mean
    output changes by dm and its fundamental gain by dN: the first corrections the harmonics make to the bias
    equation B + G(0) (m + load) = r0 (m + load = 0 with an integrator) and to 1 + G(jw) N_A = 0. Solving the
    balance linearised in (B, A, w) (central differences, relative step 1e-6) gives the estimated errors, as
    one step of a harmonic balance with the bias and K harmonics.

    Parameters
    ----------
    G : python-control tf or ss, ``delayed(G, T)``, or callable (then ``dc_gain`` is needed)
    element : DualInputDF or anything it accepts
    bias, amplitude, frequency : float
        The predicted cycle (input units, rad/s).
    r0, load, dc_gain
        As for :func:`predict_biased_cycles`.
    samples, harmonics : int
        Samples of one period (>= 64) and harmonics carried through G (>= 2).

    Returns
    -------
    Confidence
        ``amplitude_error``, ``frequency_error`` relative, ``bias_error`` absolute (predicted - exact, estimated);
        unavailable (with the reason) for an element without a time-domain response.
    """
    from .._checks import in_closed_interval, scale as positive_scale
    from .confidence import Confidence, plant_harmonics, unavailable

    dual = element if isinstance(element, DualInputDF) else DualInputDF(element)
    B, A, w = finite("bias", bias), positive_scale("amplitude", amplitude), positive_scale("frequency", frequency)
    r0, load = finite("r0", r0), finite("load", load)
    S = int(in_closed_interval("samples", samples, 64, 2**20))
    K = int(in_closed_interval("harmonics", harmonics, 2, S // 4))
    response = _response(dual, abs(B) + A)
    if response is None:
        return unavailable(f"{dual!r} has no time-domain response")
    plant = as_plant(G)
    g0 = static_gain(G) if dc_gain is None else float(dc_gain)
    Gk, usable = plant_harmonics(plant, w, K)
    theta = 2 * np.pi * np.arange(S) / S
    x1 = B + A * np.sin(theta)
    y1 = np.asarray(response(x1), float)
    Y = 2j * np.fft.rfft(y1)[1:K + 1] / S
    X = -Gk * Y
    X[0] = A
    distortion = float(np.sqrt(np.sum(np.abs(X[1:]) ** 2)) / A)
    spectrum = np.zeros(S // 2 + 1, complex)
    spectrum[2:K + 1] = -0.5j * S * X[1:]
    y2 = np.asarray(response(x1 + np.fft.irfft(spectrum, n=S)), float)
    dm = float(np.mean(y2) - np.mean(y1))
    dN = (2j * np.fft.rfft(y2)[1] / S - Y[0]) / A

    def balance(b, a, ww):
        m = float(dual.mean(b, a)) + load
        f = m if math.isinf(g0) else b + g0 * m - r0
        r = 1 + complex(plant(np.array([ww]))[0]) * complex(dual.N_A(b, a))
        return np.array([f, r.real, r.imag])

    hB, hA, hw = _STEP * (abs(B) + A), _STEP * A, _STEP * w
    J = np.column_stack([(balance(B + hB, A, w) - balance(B - hB, A, w)) / (2 * hB),
                         (balance(B, A + hA, w) - balance(B, A - hA, w)) / (2 * hA),
                         (balance(B, A, w + hw) - balance(B, A, w - hw)) / (2 * hw)])
    gdn = Gk[0] * dN
    rhs = -np.array([dm if math.isinf(g0) else g0 * dm, gdn.real, gdn.imag])
    note = (f"{S} samples per period, {K} harmonics; errors from one harmonic-balance step with the bias"
            + ("" if usable.all() else f"; G known for {int(usable.sum())} of {K} harmonics"))
    try:
        dB, dA, dw = np.linalg.solve(J, rhs)
    except np.linalg.LinAlgError:
        return Confidence(distortion, np.inf, np.inf, X, True, "the biased balance is singular in (B, A, w) here: "
                          "no error estimate", bias_error=np.inf)
    if not np.all(np.isfinite([dB, dA, dw])):
        return Confidence(distortion, np.inf, np.inf, X, True, "the biased balance is singular in (B, A, w) here: "
                          "no error estimate", bias_error=np.inf)
    return Confidence(distortion, float(-dA / (A + dA)), float(-dw / (w + dw)), X, True, note,
                      bias_error=float(-dB))
