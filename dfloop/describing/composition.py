"""Compositions: a linear block followed by a static element, and the paper's mass + backlash (Figs. 2-3).

A sinusoid of amplitude F into G_lin gives |G_lin(jw)| F sin(wt + arg G_lin) at the static element, whose
output fundamental is N_s(|G_lin| F) times that; so the composite DF (output over input phasor) is

    N(F, w) = G_lin(jw) N_s(|G_lin(jw)| F),

frequency dependent, and zero wherever |G_lin(jw)| F lies in the static element's dead band.
"""
from __future__ import annotations

import sys

import numpy as np

from .._checks import positive
from .base import DescribingFunction
from .static import Backlash

__all__ = ["LinearThenStatic", "MassBacklash"]


class LinearThenStatic(DescribingFunction):
    """A linear block G_lin followed by an amplitude-only element: N(F, w) = G_lin(jw) N_s(|G_lin(jw)| F).

    Parameters
    ----------
    linear : control.LTI or callable
        A SISO python-control system (tf, ss; frd on its own frequency grid) or a vectorised callable
        ``G(jw)`` taking complex ``1j * omega`` (rad/s) and returning complex values.
    static : DescribingFunction
        An amplitude-only DF (``frequency_dependent`` False), e.g. :class:`Backlash`.
    input_name, input_unit : str
        Name and unit of the composite's input amplitude.
    """

    frequency_dependent = True

    def __init__(self, linear, static: DescribingFunction, input_name: str = "A", input_unit: str = ""):
        ct = sys.modules.get("control")  # an LTI exists only once python-control is imported
        if ct is not None and isinstance(linear, ct.LTI):
            if linear.ninputs != 1 or linear.noutputs != 1:
                raise ValueError(f"linear must be SISO, got {linear.noutputs}x{linear.ninputs}")
        elif not callable(linear):
            raise ValueError(f"linear must be a python-control LTI or a callable G(jw), got {type(linear)!r}")
        if not isinstance(static, DescribingFunction) or static.frequency_dependent:
            raise ValueError("static must be an amplitude-only DescribingFunction")
        self.linear = linear
        self.static = static
        self.input_name, self.input_unit = input_name, input_unit

    def gain(self, omega) -> np.ndarray:
        """G_lin(j omega) with the shape of ``omega`` (rad/s)."""
        ct = sys.modules.get("control")  # an LTI exists only once python-control is imported
        w = np.asarray(omega, dtype=float)
        s = 1j * w.ravel()
        if ct is not None and isinstance(self.linear, ct.LTI):
            g = np.asarray(self.linear(s), dtype=complex).reshape(-1) if s.size else np.empty(0, complex)
        else:
            g = np.asarray(self.linear(s), dtype=complex)
        return np.broadcast_to(g, s.shape).reshape(w.shape)

    def _evaluate(self, A, omega):
        g = self.gain(omega)
        return g * self.static(np.abs(g) * A)

    def amplitude_domain(self, omega=None):
        """The static element's domain divided by |G_lin(j omega)| (omega required)."""
        if omega is None:
            raise ValueError("omega is required: the amplitude domain depends on frequency")
        mag = np.abs(self.gain(omega))
        lo, hi = self.static.amplitude_domain()
        with np.errstate(divide="ignore"):
            return lo / mag, hi / mag

    def __repr__(self) -> str:
        return f"LinearThenStatic({self.linear!r}, {self.static!r})"


class MassBacklash(LinearThenStatic):
    """The paper's classical backlash model (Fig. 2): force on a mass m1 + m2, then geometric backlash.

    G_m(s) = 1 / ((m1 + m2) s^2) from force (N) to position (m), followed by :class:`Backlash` (h, k):
    N(F, w) = G_m(jw) N_bl(F / ((m1 + m2) w^2)), output position over input force (m/N). N = 0 for
    w >= w_L = sqrt(2 F / (h (m1 + m2))), eq. (5), where the displacement amplitude falls to h/2.

    Parameters
    ----------
    m1, m2 : float
        Masses (kg), > 0.
    h : float
        Total clearance (m), > 0.
    k : float
        Slope of the backlash, > 0.
    """

    def __init__(self, m1: float, m2: float, h: float, k: float = 1.0):
        self.m1 = positive("m1", m1)
        self.m2 = positive("m2", m2)
        mass = self.m1 + self.m2
        super().__init__(lambda s: 1.0 / (mass * s * s), Backlash(h, k), input_name="F", input_unit="N")

    @property
    def h(self) -> float:
        """Total clearance (m)."""
        return self.static.h

    def limit_frequency(self, F) -> np.ndarray:
        """w_L = sqrt(2 F / (h (m1 + m2))) in rad/s, eq. (5); F in N (> 0), vectorised."""
        F = np.asarray(F, dtype=float)
        if np.any(~(F > 0)) or np.any(np.isinf(F)):
            raise ValueError("F (force amplitude, N) must be finite and > 0")
        return np.sqrt(2.0 * F / (self.h * (self.m1 + self.m2)))

    def __repr__(self) -> str:
        return f"MassBacklash(m1={self.m1!r}, m2={self.m2!r}, h={self.h!r}, k={self.static.k!r})"
