"""Result objects of :func:`dfloop.predict_limit_cycles`."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["LimitCycle", "LimitCycles"]


@dataclass(frozen=True)
class LimitCycle:
    """One predicted limit cycle, a root of 1 + G(jw) N(A, w) = 0.

    Attributes
    ----------
    amplitude : float
        Amplitude A of the fundamental at the element's input (the DF's input unit).
    frequency : float
        Angular frequency w in rad/s.
    stability : str
        ``"stable"``, ``"unstable"`` or ``"marginal"`` (tangent / double root: sign not decidable).
    residual : float
        |1 + G N| at the answer; ``relative_residual`` divides it by 1 + |G N|.
    loeb_determinant : float
        U_A V_w - U_w V_A with R = U + jV (per unit amplitude, per rad/s); > 0 means stable.
    loeb_conditioning : float
        The determinant's conditioning in log coordinates, 2 det J / |J|_F^2 in [-1, 1] (0 for a
        double root), used for the marginal decision.
    G : complex
        G(jw) at the answer (the point on the Nyquist plane, equal to -1/N there).
    N : complex
        N(A, w) at the answer.
    on_edge : bool
        True when the root lies on the boundary of the search window (a warning was issued).
    valid : bool
        N's own ``validity`` at the answer (False e.g. in chaotic regions of a tabulated DF).
    n_error : float
        N's ``error_estimate`` at the answer (0 for closed forms; inf where N gives no estimate).
    """

    amplitude: float
    frequency: float
    stability: str
    residual: float
    relative_residual: float
    loeb_determinant: float
    loeb_conditioning: float
    G: complex
    N: complex
    on_edge: bool = False
    valid: bool = True
    n_error: float = 0.0

    @property
    def stable(self) -> bool:
        """True only for a stable cycle (marginal cycles are not stable)."""
        return self.stability == "stable"

    @property
    def marginal(self) -> bool:
        return self.stability == "marginal"

    @property
    def period(self) -> float:
        """Period 2 pi / w in seconds."""
        import math

        return 2 * math.pi / self.frequency

    def __str__(self) -> str:
        flags = ("" if self.valid else " [N not valid here]") + (" [on window edge]" if self.on_edge else "")
        return (f"LimitCycle(A={self.amplitude:.6g}, omega={self.frequency:.6g} rad/s, {self.stability}, "
                f"|1+GN|={self.residual:.1e}{flags})")


class LimitCycles(list):
    """The predicted cycles (a list of :class:`LimitCycle`, sorted by frequency) and how they were found.

    Attributes
    ----------
    amplitude_window, omega_window : (float, float)
        The windows searched (amplitude in N's input unit, frequency in rad/s).
    window_source : dict
        ``{"amplitude": ..., "omega": ...}``: ``"given"`` or how the default was chosen.
    grid_shape : (int, int)
        Final (amplitudes, frequencies) grid size after adaptive refinement.
    n_evaluations : int
        Number of (A, w) points at which 1 + G N was evaluated.
    """

    def __init__(self, cycles, amplitude_window, omega_window, window_source, grid_shape, n_evaluations):
        super().__init__(cycles)
        self.amplitude_window = amplitude_window
        self.omega_window = omega_window
        self.window_source = window_source
        self.grid_shape = grid_shape
        self.n_evaluations = n_evaluations

    def __repr__(self) -> str:
        head = (f"{len(self)} limit cycle(s); amplitude window [{self.amplitude_window[0]:.4g}, "
                f"{self.amplitude_window[1]:.4g}] ({self.window_source['amplitude']}), omega window "
                f"[{self.omega_window[0]:.4g}, {self.omega_window[1]:.4g}] rad/s ({self.window_source['omega']})")
        if not self:
            return head
        rows = [f"{'#':>3} {'amplitude':>12} {'omega [rad/s]':>14} {'stability':>10} {'|1+GN|':>9} "
                f"{'Loeb det':>10} {'Re G':>11} {'Im G':>11}  notes"]
        for i, c in enumerate(self):
            notes = ", ".join(n for n, on in (("on edge", c.on_edge), ("N not valid", not c.valid)) if on)
            rows.append(f"{i:>3} {c.amplitude:>12.6g} {c.frequency:>14.6g} {c.stability:>10} {c.residual:>9.1e} "
                        f"{c.loeb_determinant:>10.3g} {c.G.real:>11.4g} {c.G.imag:>11.4g}  {notes}")
        return head + "\n" + "\n".join(rows)

    __str__ = __repr__
