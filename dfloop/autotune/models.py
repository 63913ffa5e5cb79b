"""Process models of relay auto-tuning: first and second order plus dead time, with their exact step segments.

``ProcessModel(K, (T,), L)`` is K e^{-Ls} / (T s + 1) (FOPDT); ``ProcessModel(K, (T1, T2), L)`` is
K e^{-Ls} / ((T1 s + 1)(T2 s + 1)) (SOPDT, T1 >= T2 > 0, equal time constants allowed). The state is the cascade
z1' = (K u - z1) / T1, z2' = (z1 - z2) / T2 (output c = last state), whose response to a constant input has a
closed form (:meth:`ProcessModel.propagate`), so the relay cycle (:mod:`dfloop.autotune.cycle`) is exact without a
matrix exponential or an integrator.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ProcessModel", "fopdt_ultimate_point"]


def _lag_gap(t, d):
    """(1 - e^{-t d}) / d, and t at d = 0 (continuous in d): the cascade term of two lags."""
    t = np.asarray(t, float)
    if d == 0.0:
        return t
    return -np.expm1(-t * d) / d


@dataclass(frozen=True)
class ProcessModel:
    """A first- or second-order lag with dead time: K e^{-Ls} / prod (T_i s + 1).

    Attributes
    ----------
    K : float
        Static gain (output unit per input unit), > 0.
    T : tuple of float
        Time constants (s): (T,) or (T1, T2) with T1 >= T2 > 0.
    L : float
        Dead time (s), >= 0.
    """

    K: float
    T: tuple
    L: float

    def __post_init__(self):
        T = tuple(float(x) for x in self.T)
        if not (math.isfinite(self.K) and self.K > 0):
            raise ValueError(f"K (static gain) must be finite and > 0; got {self.K!r}")
        if len(T) not in (1, 2) or not all(math.isfinite(x) and x > 0 for x in T):
            raise ValueError(f"T must be one or two finite time constants > 0 (s); got {self.T!r}")
        if not (math.isfinite(self.L) and self.L >= 0):
            raise ValueError(f"L (dead time) must be finite and >= 0 s; got {self.L!r}")
        object.__setattr__(self, "T", tuple(sorted(T, reverse=True)))
        object.__setattr__(self, "K", float(self.K))
        object.__setattr__(self, "L", float(self.L))

    @property
    def kind(self) -> str:
        """"FOPDT" or "SOPDT"."""
        return "FOPDT" if len(self.T) == 1 else "SOPDT"

    @property
    def order(self) -> int:
        return len(self.T)

    @property
    def params(self) -> tuple:
        """(K, T, L) or (K, T1, T2, L)."""
        return (self.K, *self.T, self.L)

    @staticmethod
    def names(order: int) -> tuple:
        """Parameter names of :attr:`params`."""
        return ("K", "T", "L") if order == 1 else ("K", "T1", "T2", "L")

    @classmethod
    def from_params(cls, params) -> "ProcessModel":
        p = [float(x) for x in params]
        if len(p) not in (3, 4):
            raise ValueError(f"params must be (K, T, L) or (K, T1, T2, L); got {params!r}")
        return cls(p[0], tuple(p[1:-1]), p[-1])

    def __repr__(self) -> str:
        lags = "".join(f"({t:.6g} s + 1)" for t in self.T)
        return f"ProcessModel({self.kind}: {self.K:.6g} e^(-{self.L:.6g} s) / {lags})"

    def to_dict(self) -> dict:
        return {"kind": self.kind, **dict(zip(self.names(self.order), self.params))}

    def tf(self):
        """The delay-free part K / prod (T_i s + 1) as a python-control tf (the delay is :attr:`L`)."""
        import control as ct

        den = np.array([1.0])
        for t in self.T:
            den = np.polymul(den, [t, 1.0])
        return ct.tf([self.K], den)

    def frequency_response(self, w) -> np.ndarray:
        """G(jw) including the delay."""
        s = 1j * np.asarray(w, float)
        g = self.K * np.exp(-s * self.L)
        for t in self.T:
            g = g / (t * s + 1.0)
        return g

    def ultimate_point(self) -> tuple[float, float]:
        """(Ku, Tu): the gain margin 1/|G(jw180)| and 2 pi / w180 where the phase -L w - sum atan(T_i w) = -pi."""
        from scipy.optimize import brentq

        def phase(w):
            return w * self.L + sum(math.atan(w * t) for t in self.T) - math.pi

        if self.order == 1 and self.L == 0:
            raise ValueError("a first-order lag without dead time has no ultimate point (phase > -180 deg)")
        hi = 1.0
        for _ in range(200):
            if phase(hi) > 0:
                break
            hi *= 2.0
        else:  # pragma: no cover - the phase grows without bound for every valid model
            raise ValueError("no phase crossover below 2^200 rad/s")
        w = brentq(phase, 0.0, hi, xtol=1e-15, rtol=1e-15, maxiter=400)
        return 1.0 / abs(self.frequency_response(w)), 2.0 * math.pi / w

    def fopdt(self) -> "ProcessModel":
        """Skogestad's half rule: T1 + T2 / 2, L + T2 / 2 (the model itself when first order)."""
        if self.order == 1:
            return self
        return ProcessModel(self.K, (self.T[0] + self.T[1] / 2.0,), self.L + self.T[1] / 2.0)

    # --- exact segments -------------------------------------------------------------------------------------
    def propagate(self, z0, u: float, t) -> np.ndarray:
        """State at times t >= 0 after z0 under the constant input u: shape t.shape + (order,) (z0 may hold
        arrays broadcasting with t)."""
        if isinstance(t, (float, int)) and not isinstance(z0[0], np.ndarray):
            return np.array(self._step(float(z0[0]), float(z0[-1]), float(u), float(t)))
        t = np.asarray(t, float)
        Ku = self.K * u
        T1 = self.T[0]
        e1 = np.exp(-t / T1)
        z1 = Ku + (z0[0] - Ku) * e1
        if self.order == 1:
            return z1[..., None]
        T2 = self.T[1]
        d = 1.0 / T2 - 1.0 / T1
        z2 = Ku + (z0[1] - Ku) * np.exp(-t / T2) + (z0[0] - Ku) * e1 * _lag_gap(t, d) / T2
        return np.stack([z1, z2], axis=-1)

    def _step(self, z1: float, z2: float, u: float, t: float) -> tuple:
        """Scalar :meth:`propagate` (the orbit solver's inner loop)."""
        Ku = self.K * u
        T1 = self.T[0]
        e1 = math.exp(-t / T1)
        w = (z1 - Ku) * e1
        if self.order == 1:
            return (Ku + w,)
        T2 = self.T[1]
        d = 1.0 / T2 - 1.0 / T1
        gap = t if d == 0.0 else -math.expm1(-t * d) / d
        return (Ku + w, Ku + (z2 - Ku) * math.exp(-t / T2) + w * gap / T2)

    def transition(self, u: float, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, gamma) with z(t) = Phi z0 + gamma for the constant input u over time t."""
        gamma = self.propagate(np.zeros(self.order), u, t)
        Phi = np.column_stack([self.propagate(e, 0.0, t) for e in np.eye(self.order)])
        return Phi, gamma

    def output_derivative(self, z, u: float) -> float:
        """dc/dt at state z under input u."""
        if self.order == 1:
            return (self.K * u - z[0]) / self.T[0]
        return (z[0] - z[1]) / self.T[1]


def fopdt_ultimate_point(K: float, T: float, L: float) -> tuple[float, float]:
    """(Ku, Tu) of K e^{-Ls} / (T s + 1): atan(w T) + w L = pi, Ku = sqrt(1 + (w T)^2) / K, Tu = 2 pi / w."""
    from scipy.optimize import brentq

    if not (K > 0 and T > 0 and L > 0):
        raise ValueError(f"fopdt_ultimate_point needs K, T, L > 0; got K={K}, T={T}, L={L}")
    hi = math.pi / L
    w = brentq(lambda w: math.atan(w * T) + w * L - math.pi, 1e-12 * hi, hi, xtol=1e-15, rtol=1e-15)
    return math.sqrt(1.0 + (w * T) ** 2) / K, 2.0 * math.pi / w
