"""Forced response by the describing function: r = R sin(w t) at the summing junction, e = r - G u, u = element(e).

The DF balance at the element's input amplitude A (docs/bias_forced.md) is

    h(A, w) = A^2 |1 + G(jw) N(A, w)|^2 - R^2 = 0,

so every solution A at a frequency w is a root of a real function of A. Completeness: at each frequency, h is
evaluated on a log grid of amplitudes and every sign change is bisected to rounding; two roots closer than one
grid cell (only next to a fold) would be missed there, but the folds themselves are located directly. A
multi-valued band narrower than one step of the frequency grid (both folds between two grid frequencies, near the
cusp where the band is born) is not seen: refine ``omega`` there.

Jumps are folds of A(w): where the number of roots changes between two grid frequencies, the two roots that merge
bracket a local extremum of h in A; the extremum's value phi(w) changes sign across the fold, and the fold
frequency is the root of phi (Brent's method, to rounding in w), its amplitude the extremum's position.

Stability of a branch point: the classical incremental criterion of jump resonance (a perturbation of the
amplitude at fixed forcing grows where the forcing needed to hold a larger amplitude decreases): a point is stable
where dh/dA > 0 (R needed grows with A) and unstable where dh/dA < 0 (the middle branch of a triple-valued
region). It does not see instabilities of the unforced loop (a limit cycle or an unstable linear part at small
amplitude) nor subharmonic responses: check those by simulation (docs/bias_forced.md, "Limits").
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from .._checks import integer_at_least, positive, window as checked_window
from ..describing.interop import as_element
from ..errors import DfloopError
from .plant import as_plant

__all__ = ["ForcedPoint", "Jump", "ForcedResponse", "JumpRegion", "forced_response", "jump_region"]

_BISECTIONS = 200


@dataclass(frozen=True)
class ForcedPoint:
    """One DF solution of the forced loop at one frequency.

    Attributes
    ----------
    omega : float
        Forcing frequency (rad/s).
    amplitude : float
        A, amplitude of the fundamental of the element's input e (input units).
    output_amplitude : float
        |G N| A, amplitude of the fundamental of the plant's output y.
    stable : bool
        dh/dA > 0 (see the module notes).
    """

    omega: float
    amplitude: float
    output_amplitude: float
    stable: bool

    def __repr__(self) -> str:
        return (f"ForcedPoint(omega={self.omega:.6g} rad/s, amplitude={self.amplitude:.6g}, output_amplitude={self.output_amplitude:.6g}"
                f", {'stable' if self.stable else 'unstable'})")


@dataclass(frozen=True)
class Jump:
    """A fold of A(w): two solutions meet and the response jumps to another stable branch.

    Attributes
    ----------
    omega : float
        Fold frequency (rad/s), located to rounding.
    amplitude : float
        Amplitude A at the fold.
    target : float or None
        Amplitude of the stable solution the response jumps to (None when none is in the window).
    sweep : str
        ``"up"`` when the fold is reached sweeping w upward (the solutions exist below it), ``"down"`` otherwise.
    output_amplitude : float
        |G N| A at the fold (the plant output's amplitude).
    """

    omega: float
    amplitude: float
    target: float | None
    sweep: str
    output_amplitude: float = math.nan

    def __repr__(self) -> str:
        to = "out of the window" if self.target is None else f"{self.target:.6g}"
        return f"Jump(omega={self.omega:.10g} rad/s, sweeping {self.sweep}: A {self.amplitude:.6g} -> {to})"


@dataclass
class ForcedResponse:
    """The DF forced response at each frequency of a grid: every solution, its stability, and the jumps.

    Attributes
    ----------
    R : float
        Forcing amplitude (element input units: r is added at the summing junction).
    omega : ndarray
        The frequencies (rad/s).
    solutions : list of list of ForcedPoint
        ``solutions[k]``: every solution at ``omega[k]``, by increasing amplitude.
    jumps : list of Jump
        Folds, by frequency.
    amplitude_window : (float, float)
        Amplitudes searched; a solution outside it is not reported.
    amplitude_name, amplitude_unit : str
        The element's input name and unit (for plots).
    """

    R: float
    omega: np.ndarray
    solutions: list
    jumps: list = field(default_factory=list)
    amplitude_window: tuple = (0.0, math.inf)
    amplitude_name: str = "A"
    amplitude_unit: str = ""

    @property
    def multiple(self) -> np.ndarray:
        """Frequencies (rad/s) where the response has more than one solution (the jump-resonance region)."""
        return np.array([w for w, s in zip(self.omega, self.solutions) if len(s) > 1])

    def branches(self):
        """Curves for plotting: lists of ForcedPoint along each continuous solution, in increasing frequency.

        Where two solutions are born or die at a jump between grid frequencies, the two curves end (or start) at
        the fold point; the other solutions continue their curves. Where the number of solutions changes without
        a located fold (a solution leaving the amplitude window), every curve restarts.
        """
        done, live = [], []
        for k, sols in enumerate(self.solutions):
            if k == 0 or len(sols) == len(live):
                if k == 0:
                    live = [[p] for p in sols]
                else:
                    for curve, p in zip(live, sols):
                        curve.append(p)
                continue
            w0, w1 = self.omega[k - 1], self.omega[k]
            jump = next((j for j in self.jumps if w0 <= j.omega <= w1), None)
            if jump is None or abs(len(sols) - len(live)) != 2:
                done += live
                live = [[p] for p in sols]
                continue
            more = sols if len(sols) > len(live) else [c[-1] for c in live]
            pair = min(range(len(more) - 1), key=lambda i: abs(math.log(math.sqrt(more[i].amplitude
                                                                               * more[i + 1].amplitude) / jump.amplitude)))
            fold = [ForcedPoint(jump.omega, jump.amplitude, jump.output_amplitude, p.stable) for p in more[pair:pair + 2]]
            if len(sols) > len(live):  # born at the fold: two new curves from it, the others continue in order
                rest = sols[:pair] + sols[pair + 2:]
                for curve, p in zip(live, rest):
                    curve.append(p)
                new = [[fold[0], sols[pair]], [fold[1], sols[pair + 1]]]
                live = live[:pair] + new + live[pair:]
            else:  # dying at the fold: two curves end there
                live[pair].append(fold[0])
                live[pair + 1].append(fold[1])
                done += live[pair:pair + 2]
                live = live[:pair] + live[pair + 2:]
                for curve, p in zip(live, sols):
                    curve.append(p)
        return done + live

    def plot(self, ax=None, **kwargs):
        """Magnitude against frequency (:func:`dfloop.plot.forced.plot_forced_response`)."""
        from ..plot.forced import plot_forced_response

        return plot_forced_response(self, ax=ax, **kwargs)

    def __repr__(self) -> str:
        counts = [len(s) for s in self.solutions]
        head = (f"ForcedResponse(R={self.R:g}, {len(self.omega)} frequencies in [{self.omega[0]:.4g}, "
                f"{self.omega[-1]:.4g}] rad/s, up to {max(counts, default=0)} solution(s) per frequency, "
                f"{len(self.jumps)} jump(s))")
        return "\n".join([head] + [f"  {j!r}" for j in self.jumps])


def forced_response(G, N, R: float, omega, *, amplitude, n_amplitudes: int = 400) -> ForcedResponse:
    """Every DF solution A of A |1 + G(jw) N(A, w)| = R at each frequency, their stability, and the jumps.

    Parameters
    ----------
    G : python-control tf, ss or frd, or callable
        The linear part.
    N : DescribingFunction or static function
        The element (amplitude-only or frequency-dependent; complex N allowed).
    R : float
        Forcing amplitude at the summing junction, > 0.
    omega : array_like
        Increasing frequencies (rad/s), at least 2; folds are located between them to rounding.
    amplitude : (float, float)
        Amplitude window of the element's input.
    n_amplitudes : int
        Log-spaced amplitudes per frequency on which roots are bracketed (>= 16).

    Returns
    -------
    ForcedResponse

    Raises
    ------
    ValueError
        Bad R, frequencies, window or grid size, naming the parameter.
    """
    plant = as_plant(G)
    N = as_element(N)
    R = positive("R", R)
    w = np.asarray(omega, dtype=float).ravel()
    if w.size < 2 or not np.all(np.isfinite(w)) or np.any(w <= 0) or np.any(np.diff(w) <= 0):
        raise DfloopError(f"omega must hold at least 2 increasing, positive, finite frequencies (rad/s), got {omega!r}")
    a_lo, a_hi = checked_window("amplitude", amplitude)
    n_a = integer_at_least("n_amplitudes", n_amplitudes, 16)
    lnA = np.linspace(math.log(a_lo), math.log(a_hi), n_a)

    def h(a, ww):
        """(A^2 |1 + G N|^2 - R^2) / R^2 at ln-amplitudes ``a`` and frequencies ``ww`` (broadcast)."""
        a, ww = np.broadcast_arrays(np.asarray(a, float), np.asarray(ww, float))
        A = np.exp(a)
        n = N(A, ww) if N.frequency_dependent else N(A)
        val = (A / R) ** 2 * np.abs(1 + plant(ww) * n) ** 2 - 1
        if not np.all(np.isfinite(val)):
            raise DfloopError("1 + G N is not finite on the amplitude window (narrow amplitude=)")
        return val

    H = h(lnA[None, :], w[:, None])
    solutions = []
    for k, ww in enumerate(w):
        cells = np.flatnonzero(np.sign(H[k, :-1]) * np.sign(H[k, 1:]) < 0)
        pts = []
        for c in cells:
            lo, hi = lnA[c], lnA[c + 1]
            f_lo = H[k, c]
            for _ in range(_BISECTIONS):
                mid = 0.5 * (lo + hi)
                if mid in (lo, hi):
                    break
                f_mid = float(h(mid, ww))
                if np.sign(f_mid) == np.sign(f_lo):
                    lo, f_lo = mid, f_mid
                else:
                    hi = mid
            a = 0.5 * (lo + hi)
            pts.append(_point(plant, N, ww, a, h))
        solutions.append(pts)
    jumps = []
    for k in range(w.size - 1):
        n0, n1 = len(solutions[k]), len(solutions[k + 1])
        if n0 == n1:
            continue
        more, fewer = (k, k + 1) if n0 > n1 else (k + 1, k)
        jump = _fold(h, w, lnA, solutions, more, fewer)
        if jump is not None:
            jumps.append(jump)
    jumps = [dataclasses.replace(j, output_amplitude=float(abs(plant(np.array([j.omega]))[0] * complex(
        N(j.amplitude, j.omega) if N.frequency_dependent else N(j.amplitude))) * j.amplitude)) for j in jumps]
    return ForcedResponse(R, w, solutions, sorted(jumps, key=lambda j: j.omega), (a_lo, a_hi),
                          getattr(N, "input_name", "A"), getattr(N, "input_unit", ""))


def _point(plant, N, ww: float, a: float, h) -> ForcedPoint:
    A = math.exp(a)
    n = complex(N(A, ww) if N.frequency_dependent else N(A))
    step = 1e-6
    slope = float(h(a + step, ww) - h(a - step, ww))
    return ForcedPoint(float(ww), A, float(abs(plant(np.array([ww]))[0] * n) * A), slope > 0)


def _fold(h, w, lnA, solutions, more: int, fewer: int):
    """The fold between grid frequencies w[more] (two more roots) and w[fewer]: the adjacent pair of roots at
    w[more] whose bracketed extremum of h changes sign, then Brent's method on the extremum's value in w."""
    roots = [math.log(p.amplitude) for p in solutions[more]]
    da = lnA[1] - lnA[0]
    for i in range(len(roots) - 1):
        lo, hi = roots[i] - da, roots[i + 1] + da
        sigma = -1.0 if float(h(0.5 * (roots[i] + roots[i + 1]), w[more])) < 0 else 1.0  # h's sign between them

        def phi(ww, lo=lo, hi=hi, c=-sigma):
            """h at its extremum between the two roots (a minimum of c h), and where it lies (ln A)."""
            best = minimize_scalar(lambda a: c * float(h(a, ww)), bounds=(lo, hi), method="bounded",
                                   options={"xatol": 1e-13})
            return c * best.fun, best.x

        if not (phi(w[more])[0] * sigma > 0 > phi(w[fewer])[0] * sigma):
            continue
        w_star = brentq(lambda ww: phi(ww)[0], min(w[more], w[fewer]), max(w[more], w[fewer]), xtol=1e-14,
                        rtol=4 * np.finfo(float).eps, maxiter=200)
        a_star = math.exp(phi(w_star)[1])
        others = [p.amplitude for p in solutions[fewer] if p.stable]
        target = min(others, key=lambda x: abs(math.log(x / a_star))) if others else None
        return Jump(float(w_star), a_star, target, "up" if more < fewer else "down")
    return None


@dataclass
class JumpRegion:
    """Where the forced response jumps, in the (w, R) plane: the fold frequencies at each forcing amplitude.

    Attributes
    ----------
    R : ndarray
        The forcing amplitudes.
    folds : list of list of Jump
        ``folds[i]``: the jumps at ``R[i]`` (empty: single-valued response on the frequency grid).
    """

    R: np.ndarray
    folds: list

    def plot(self, ax=None):
        """The region in the (frequency, forcing amplitude) plane (:func:`dfloop.plot.forced.plot_jump_region`)."""
        from ..plot.forced import plot_jump_region

        return plot_jump_region(self, ax=ax)

    def to_dict(self) -> dict:
        """``R`` and, per forcing amplitude, its jumps (``omega``, ``amplitude``, ``target``, ``sweep``)."""
        return {"R": [float(r) for r in self.R],
                "folds": [[{"omega": j.omega, "amplitude": j.amplitude, "target": j.target, "sweep": j.sweep}
                           for j in folds] for folds in self.folds]}

    def band(self, i: int) -> tuple[float, float] | None:
        """(lowest, highest) fold frequency at ``R[i]`` (rad/s): the multi-valued band; None without jumps."""
        w = [j.omega for j in self.folds[i]]
        return (min(w), max(w)) if w else None

    def __repr__(self) -> str:
        rows = [f"JumpRegion({len(self.R)} forcing amplitudes)"]
        for i, r in enumerate(self.R):
            band = self.band(i)
            rows.append(f"  R={r:.6g}: " + ("no jump" if band is None else
                                            f"jumps at {band[0]:.8g} .. {band[1]:.8g} rad/s ({len(self.folds[i])})"))
        return "\n".join(rows)


def jump_region(G, N, R, omega, *, amplitude, n_amplitudes: int = 400) -> JumpRegion:
    """The jump-resonance region: :func:`forced_response` at each forcing amplitude ``R`` (array, each > 0), its
    folds kept. Parameters as for :func:`forced_response`; a fold outside the frequency grid is not seen."""
    Rs = np.atleast_1d(np.asarray(R, dtype=float))
    if Rs.ndim != 1 or Rs.size == 0:
        raise DfloopError(f"R must be one or more forcing amplitudes, got {R!r}")
    folds = [forced_response(G, N, float(r), omega, amplitude=amplitude, n_amplitudes=n_amplitudes).jumps for r in Rs]
    return JumpRegion(Rs, folds)
