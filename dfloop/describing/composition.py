"""Compositions: a linear block followed by a static element, and the paper's mass + backlash (Figs. 2-3).

A sinusoid of amplitude F into G_lin gives |G_lin(jw)| F sin(wt + arg G_lin) at the static element, whose
output fundamental is N_s(|G_lin| F) times that; so the composite DF (output over input phasor) is

    N(F, w) = G_lin(jw) N_s(|G_lin(jw)| F),

frequency dependent, and zero wherever |G_lin(jw)| F lies in the static element's dead band.
"""
from __future__ import annotations

import math
import sys

import numpy as np

from .._checks import frequency_array, positive, real_array
from ..errors import DfloopError
from .base import DescribingFunction
from .static import Backlash

__all__ = ["LinearThenStatic", "MassBacklash"]


def _product(g: np.ndarray, n: np.ndarray) -> np.ndarray:
    """g * n with 0 * inf = 0 per component: an exactly zero part of G stays zero when N_s is infinite
    (the limit A -> 0 of an ideal relay or a preloaded spring), instead of numpy's NaN."""
    with np.errstate(invalid="ignore"):
        out = np.asarray(g * n, dtype=complex)  # an array also for 0-d input (item assignment below)
    inf = np.isinf(n)
    if np.any(inf):  # rare: only there the careful product

        def mul(x, y):
            with np.errstate(invalid="ignore"):
                return np.where((x == 0) | (y == 0), 0.0, x * y)

        gi, ni = g[inf], n[inf]
        re = mul(gi.real, ni.real) - mul(gi.imag, ni.imag)
        out[inf] = re + 1j * (mul(gi.real, ni.imag) + mul(gi.imag, ni.real))
    return out


class LinearThenStatic(DescribingFunction):
    """A linear block G_lin followed by an amplitude-only element: N(F, w) = G_lin(jw) N_s(|G_lin(jw)| F).

    Limits: N(0, w) = G_lin(jw) N_s(0) and N(inf, w) = G_lin(jw) N_s(inf) (the static element's limits; a
    part of G_lin(jw) that is exactly zero stays zero when N_s is infinite). ``omega`` must be finite and > 0.

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
                raise DfloopError(f"linear must be SISO, got a system with {linear.ninputs} inputs and "
                                  f"{linear.noutputs} outputs")
        elif not callable(linear):
            raise DfloopError(f"linear must be a python-control LTI or a callable G(jw), got {linear!r} "
                              f"({type(linear).__name__})")
        if not isinstance(static, DescribingFunction) or static.frequency_dependent:
            raise DfloopError(f"static must be an amplitude-only DescribingFunction, got {static!r}")
        self.linear = linear
        self.static = static
        self.input_name, self.input_unit = input_name, input_unit

    def gain(self, omega) -> np.ndarray:
        """G_lin(j omega) with the shape of ``omega`` (rad/s, finite and > 0).

        Raises ``DfloopError`` naming omega where G_lin is not finite there (a pole on the imaginary axis,
        or a value beyond the float range, e.g. 1/s^2 at omega = 1e-200). NaN entries of omega give NaN.
        """
        ct = sys.modules.get("control")
        w = frequency_array(omega)
        s = 1j * w.ravel()
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            if ct is not None and isinstance(self.linear, ct.LTI):
                g = (np.asarray(self.linear(s, warn_infinite=False), dtype=complex).reshape(-1) if s.size
                     else np.empty(0, complex))
            else:
                g = np.asarray(self.linear(s), dtype=complex)
        g = np.broadcast_to(g, s.shape).reshape(w.shape)
        bad = ~np.isfinite(g) & ~np.isnan(w)
        if np.any(bad):
            raise DfloopError(f"the linear block G_lin(j omega) is not finite at omega = {float(w[bad].ravel()[0])!r} "
                              "rad/s (a pole on the imaginary axis, or beyond the float range)")
        return g

    def _evaluate(self, A, omega):
        g = self.gain(omega)
        mag = np.abs(g)
        with np.errstate(over="ignore", invalid="ignore"):
            x = np.where(mag == 0.0, 0.0, mag * A)  # G_lin = 0 exactly: the element sees no input at any A
        return _product(g, self.static(x))

    @property
    def continuous(self) -> bool:
        """Whether N is continuous: when the static element's N is (G_lin is finite and continuous)."""
        return bool(self.static.continuous)

    def amplitude_domain(self, omega=None):
        """The static element's domain divided by |G_lin(j omega)| (omega required)."""
        if omega is None:
            raise DfloopError("omega is required: the amplitude domain depends on frequency, got omega=None")
        mag = np.abs(self.gain(omega))
        lo, hi = self.static.amplitude_domain()
        with np.errstate(divide="ignore"):
            return lo / mag, hi / mag

    def tail_bound(self, A):
        """The static element's bound, unchanged in the composite's unit when it is of the form C / X:
        |N - N(inf, w)| = |G_lin| |N_s(X) - N_s(inf)| <= |G_lin| C / (|G_lin| F) = C / F for every w."""
        b = self.static.tail_bound(np.array([1.0, 2.0]))
        if b is None or not b[0] == 2 * b[1]:  # only a bound of the form C / X carries over to F
            return None
        return float(b[0]) / np.asarray(A, float)

    def __repr__(self) -> str:
        return f"LinearThenStatic({self.linear!r}, {self.static!r})"


class _RigidMass:
    """G_m(s) = 1 / (m s^2): force (N) to position (m) of a free mass m (kg); a class, so elements pickle."""

    def __init__(self, mass: float):
        self.mass = mass

    def __call__(self, s):
        return 1.0 / (self.mass * s * s)

    def state_space(self):
        """(A, B, C) of 1 / (m s^2): state (position, velocity), input force, output position."""
        return np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([0.0, 1.0 / self.mass]), np.array([1.0, 0.0])

    def __repr__(self) -> str:
        return f"1/({self.mass:g} s^2)"


class MassBacklash(LinearThenStatic):
    """The paper's classical backlash model (Fig. 2): force on a mass m1 + m2, then geometric backlash.

    G_m(s) = 1 / ((m1 + m2) s^2) from force (N) to position (m), followed by :class:`Backlash` (h, k):
    N(F, w) = G_m(jw) N_bl(F / ((m1 + m2) w^2)), output position over input force (m/N). N = 0 for
    w >= w_L = sqrt(2 F / (h (m1 + m2))), eq. (5), where the displacement amplitude falls to h/2.

    Limits: N(0, w) = 0, N(inf, w) = -k / ((m1 + m2) w^2) (the rigid mass).

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
        super().__init__(_RigidMass(self.m1 + self.m2), Backlash(h, k), input_name="F", input_unit="N")

    @property
    def h(self) -> float:
        """Total clearance (m)."""
        return self.static.h

    def limit_frequency(self, F) -> np.ndarray:
        """w_L = sqrt(2 F / (h (m1 + m2))) in rad/s, eq. (5); F in N (> 0), vectorised."""
        F = real_array(F, "F")
        bad = ~(F > 0) | np.isinf(F)
        if np.any(bad):
            raise DfloopError(f"F (force amplitude, N) must be finite and > 0, got {float(F[bad].ravel()[0])!r}")
        return np.sqrt(F) * math.sqrt(2.0 / (self.h * (self.m1 + self.m2)))  # no overflow of 2 F near 1e308

    def __repr__(self) -> str:
        return f"MassBacklash(m1={self.m1!r}, m2={self.m2!r}, h={self.h!r}, k={self.static.k!r})"
