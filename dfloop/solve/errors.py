"""Errors of the solver that carry data a caller may act on."""
from __future__ import annotations

from ..errors import DfloopError

__all__ = ["ContinuumError"]


class ContinuumError(DfloopError):
    """1 + G(jw) N(A, w) = 0 along a whole curve (G lies on the -1/N locus): no isolated limit cycle.

    Attributes
    ----------
    amplitude_range : (float, float)
        Amplitudes (N's input unit) spanned by the points of the curve that were followed.
    omega_range : (float, float)
        Frequencies (rad/s) spanned by them.
    """

    def __init__(self, amplitude_range: tuple[float, float], omega_range: tuple[float, float]):
        self.amplitude_range = amplitude_range
        self.omega_range = omega_range
        (a0, a1), (w0, w1) = amplitude_range, omega_range
        super().__init__(
            "continuum of solutions: 1 + G(jw) N(A, w) = 0 along a whole curve through "
            f"A in [{a0:.6g}, {a1:.6g}] and omega in [{w0:.6g}, {w1:.6g}] rad/s (G(jw) lies on the -1/N "
            "locus there, so the describing-function equation has no isolated limit cycle; the curve may "
            "continue beyond the points followed). Exclude it with the amplitude= or omega= window, or "
            "perturb the loop.")
