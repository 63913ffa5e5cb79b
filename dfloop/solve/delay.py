"""A pure time delay as a part of the plant: G(s) e^{-sT}.

python-control has no pure-delay object (only its rational Padé approximation ``control.pade``), so dfloop adds
one: :func:`delayed` wraps a continuous SISO python-control system (tf, ss or frd) and a delay T (s) in a
:class:`DelayedSystem`. Conventions follow python-control's LTI objects where they exist:

- ``Gd(s)`` evaluates G(s) e^{-sT} at complex s (``Gd(1j * w)`` is the frequency response), as ``sys(s)`` does;
- ``Gd * H`` and ``H * Gd`` (H an LTI, a scalar or another DelayedSystem) multiply the rational parts and add the
  delays (a series connection);
- ``Gd.pade(n)`` is the rational approximation ``G * pade(T, n)``, for tools that need a rational plant.

The delay is exact everywhere dfloop uses the plant: the predictor evaluates G(jw) e^{-jwT} (and its grid bound
for rational G carries the delay's exact phase turn, :meth:`dfloop.solve.plant.Plant.log_variation`); the exact
engine (:mod:`dfloop.hybrid.delay`) delays the element's switching instants by T.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["DelayedSystem", "delayed"]


class DelayedSystem:
    """A continuous SISO python-control system followed by a pure delay: G(s) e^{-sT}.

    Parameters
    ----------
    system : python-control tf, ss or frd
        The rational (or measured) part G, continuous time, SISO.
    delay : float
        The pure delay T in seconds, finite and >= 0.

    Notes
    -----
    In time: the plant's input u(t) is the element output y(t - T) (the element's output reaches the plant T
    later). Picklable (a class, not a closure), so loops with delays can be sent to process executors.
    """

    def __init__(self, system, delay: float):
        import control as ct

        if isinstance(system, DelayedSystem):
            delay, system = float(delay) + system.delay, system.system
        if not isinstance(system, ct.LTI):
            raise ValueError(f"system must be a python-control tf, ss or frd system, got {type(system).__name__}")
        nin, nout = getattr(system, "ninputs", 1), getattr(system, "noutputs", 1)
        if nin != 1 or nout != 1:
            raise ValueError(f"system must be SISO; got {nout} outputs and {nin} inputs")
        if getattr(system, "dt", 0) not in (0, None):
            raise ValueError(f"system must be continuous-time for a pure delay in seconds; got dt={system.dt}")
        try:
            T = float(delay)
        except (TypeError, ValueError):
            raise ValueError(f"delay must be a number of seconds, got {delay!r}") from None
        if not (math.isfinite(T) and T >= 0.0):
            raise ValueError(f"delay must be finite and >= 0 (seconds), got {delay!r}")
        self.system = system
        self.delay = T

    ninputs = noutputs = 1
    dt = 0

    def __call__(self, s):
        """G(s) e^{-sT} at complex s (scalar or array), like python-control's ``sys(s)``."""
        s = np.asarray(s, dtype=complex)
        return np.asarray(self.system(s), dtype=complex) * np.exp(-s * self.delay)

    def frequency_response_at(self, omega) -> np.ndarray:
        """G(jw) e^{-jwT} for real frequencies ``omega`` (rad/s)."""
        return self(1j * np.asarray(omega, dtype=float))

    def pade(self, order: int) -> object:
        """The rational approximation G(s) * pade(T, order) (python-control's Padé approximant of the delay)."""
        import control as ct

        num, den = ct.pade(self.delay, int(order))
        return self.system * ct.tf(num, den)

    def _combine(self, other, left: bool):
        import control as ct

        if isinstance(other, DelayedSystem):
            sys_o, T_o = other.system, other.delay
        elif isinstance(other, (ct.LTI, numbers.Number)):
            sys_o, T_o = other, 0.0
        else:
            return NotImplemented
        product = sys_o * self.system if left else self.system * sys_o
        return DelayedSystem(product, self.delay + T_o)

    def __mul__(self, other):
        return self._combine(other, left=False)

    def __rmul__(self, other):
        return self._combine(other, left=True)

    def __eq__(self, other) -> bool:
        return (isinstance(other, DelayedSystem) and self.delay == other.delay
                and self.system is other.system)

    __hash__ = object.__hash__

    def __repr__(self) -> str:
        return f"DelayedSystem({self.system!r}, delay={self.delay:g})"


def delayed(G, T: float) -> DelayedSystem:
    """The plant G followed by a pure delay of T seconds: G(s) e^{-sT}.

    Parameters
    ----------
    G : python-control tf, ss, frd, or DelayedSystem
        Continuous SISO system (the delays of a DelayedSystem add up).
    T : float
        Delay in seconds, finite and >= 0.

    Returns
    -------
    DelayedSystem

    Examples
    --------
    >>> import control as ct
    >>> Gd = delayed(ct.tf([1], [1, 1]), 0.5)     # e^{-0.5 s} / (s + 1)
    >>> abs(Gd(1j * 2.0) - 1 / (2j + 1) * complex(np.exp(-1j))) < 1e-15
    True
    """
    return DelayedSystem(G, T)


def delay_of(G) -> float:
    """The pure delay (s) of a plant: T for a :class:`DelayedSystem`, 0 for anything else."""
    return G.delay if isinstance(G, DelayedSystem) else 0.0
