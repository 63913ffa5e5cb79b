"""Discrete-time plants: G(e^{jw dt}) on 0 < w < pi/dt as a :class:`~dfloop.solve.plant.Plant`.

A python-control tf/ss with a sampling period ``dt`` > 0 (``control.sample_system(G, dt)`` for a continuous plant
behind a zero-order hold and a sampler; a digital controller C(z) in series: ``C * control.sample_system(G, dt)``)
is adapted to the frequency response G(e^{jw dt}), w in rad/s, defined on (0, pi/dt]: above the Nyquist
frequency the response repeats, so the describing-function equation is solved there only.

Complete grid bound. G(z) is rational in z, and the bilinear map z = (1 + s) / (1 - s) sends the unit circle
z = e^{jw dt} to the imaginary axis s = j nu, nu = tan(w dt / 2) (monotone in w on (0, pi/dt)). So
G(e^{jw dt}) = H(j nu) with H rational: each pole or zero r of G gives one of H at (r - 1) / (r + 1) (a root
at r = -1 goes to infinity) and the difference of degrees gives a root of H at s = 1. The exact bound of
:meth:`Plant.log_variation` on the change of ln H between two frequencies (monotone turns of each factor)
then holds for G(e^{jw dt}) between nu(w0) and nu(w1) (the Plant's ``frequency_map``): no root of 1 + G N can fall between grid samples, as
for a continuous plant.

When is the DF of a sampled element questionable? The element sees the samples x_k = A sin(w k dt + phi) of
the oscillation; with S = 2 pi / (w dt) samples per period the fundamental of its output depends on the phase
phi of the samples (for a cycle of P samples exactly, phi is fixed by the orbit). :func:`sampled_df_spread`
measures that dependence: the largest relative deviation from N(A) of the fundamental computed from P =
round(S) samples, over phases phi. :func:`dfloop.cycle_confidence` reports it for a discrete plant.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["bilinear_frequency", "discrete_parts", "sampled_df_spread", "SPREAD_PHASES", "NYQUIST_MARGIN"]

SPREAD_PHASES = 64       # phases phi of the samples tried by sampled_df_spread
NYQUIST_MARGIN = 1e-9    # default window ends this far (relative) below the Nyquist frequency pi/dt
_DECADES_BELOW = 2.0     # default window starts two decades below the slowest pole/zero (continuous equivalent)


def bilinear_frequency(dt: float):
    """The map w -> nu = tan(w dt / 2) and its log-derivative d ln nu / d ln w = w dt / sin(w dt)."""
    def nu(omega):
        return np.tan(0.5 * dt * np.asarray(omega, float))

    def slope(omega):
        w = np.asarray(omega, float)
        return w * dt / np.sin(w * dt)

    return nu, slope


def _bilinear_roots(zeros: np.ndarray, poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Zeros and poles of H(s) = G((1 + s) / (1 - s)) from those of G(z) (constant gain dropped).

    z - r = ((1 + r) s + (1 - r)) / (1 - s): a root r != -1 of G gives a root (r - 1) / (r + 1) of H and a
    factor 1 / (1 - s); r = -1 gives only 2 / (1 - s). The factors 1 / (1 - s) of the zeros and poles leave
    (1 - s)^(n_poles - n_zeros): that many zeros of H at s = 1 (poles when negative).
    """
    def image(r):
        far = np.abs(r + 1.0) <= 1e-14
        return (r[~far] - 1.0) / (r[~far] + 1.0)

    hz, hp = image(zeros), image(poles)
    extra = poles.size - zeros.size
    if extra > 0:
        hz = np.concatenate([hz, np.ones(extra)])
    elif extra < 0:
        hp = np.concatenate([hp, np.ones(-extra)])
    return hz.astype(complex), hp.astype(complex)


def discrete_parts(sys, num: np.ndarray, den: np.ndarray) -> dict:
    """The pieces of the :class:`~dfloop.solve.plant.Plant` of a discrete-time SISO system with transfer-function
    coefficients ``num``, ``den`` (powers of z, leading zeros removed) and sampling period ``sys.dt`` (s):
    ``response`` G(e^{jw dt}), ``default_window``, ``domain`` (0, pi/dt), ``roots`` (zeros and poles of the
    bilinear image H), ``frequency_map`` and ``map_slope`` (:func:`bilinear_frequency`) and ``dt``.

    Raises
    ------
    ValueError
        ``sys.dt`` is True (unspecified: no frequency scale) or not a positive number.
    """
    dt = sys.dt
    if dt is True or not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"G must have a numeric sampling period dt > 0 (s) to be used as a discrete-time plant; "
                         f"got dt={dt!r} (create it with control.tf(..., dt=0.1) or control.sample_system)")
    dt = float(dt)

    def response(w):
        z = np.exp(1j * dt * np.asarray(w, float))
        return np.polyval(num, z) / np.polyval(den, z)

    zeros, poles = np.roots(num), np.roots(den)
    finite = [r for r in np.concatenate([zeros, poles]) if abs(r) > 1e-300]
    rates = np.abs(np.log(np.asarray(finite, complex))) / dt if finite else np.empty(0)
    rates = rates[rates > 1e-12 / dt]
    w_nyq = math.pi / dt
    lo = float(rates.min()) * 10.0 ** -_DECADES_BELOW if rates.size else w_nyq * 1e-3
    nu, slope = bilinear_frequency(dt)
    return dict(response=response, default_window=(min(lo, w_nyq * 1e-3), w_nyq * (1.0 - NYQUIST_MARGIN)),
                domain=(0.0, w_nyq), roots=_bilinear_roots(zeros, poles), frequency_map=nu, map_slope=slope, dt=dt)


def sampled_df_spread(response, amplitude: float, frequency: float, dt: float, N_value: complex,
                      phases: int = SPREAD_PHASES) -> tuple[float, int]:
    """How much the fundamental of a sampled element depends on the phase of the samples.

    The element is driven by P = max(2, round(2 pi / (w dt))) samples x_k = A sin(2 pi k / P + phi) of one period
    (a cycle of P samples per period), for ``phases`` phases phi in [0, 2 pi / P); its output's fundamental
    Y(phi) = (2 j / P) sum_k y_k e^{-j (2 pi k / P + phi)} gives a sampled describing function Y(phi) / A (at P = 2,
    the Nyquist frequency, the samples are A sin(phi) (-1)^k and the gain is (y_0 - y_1) / (2 A sin phi)). Returns (max_phi |Y(phi) / A - N| / |N|, P).

    Parameters
    ----------
    response : callable
        The element's output over one period of periodic input samples (``time_model(A).response``).
    amplitude, frequency, dt : float
        A (input unit), w (rad/s), sampling period (s).
    N_value : complex
        The continuous describing function N(A) the prediction used.
    """
    P = max(2, int(round(2.0 * math.pi / (frequency * dt))))
    k = np.arange(P)
    worst = 0.0
    for phi in (np.arange(phases) + 0.5) * (2.0 * math.pi / P / phases):
        theta = 2.0 * math.pi * k / P + phi
        y = np.asarray(response(amplitude * np.sin(theta)), float)
        if P == 2:   # at the Nyquist frequency the samples are A sin(phi) (-1)^k: the element sees A |sin phi|
            n_phi = complex(0.5 * (y[0] - y[1]) / (amplitude * math.sin(phi)))
        else:
            n_phi = 2j * np.sum(y * np.exp(-1j * theta)) / P / amplitude
        worst = max(worst, abs(n_phi - N_value) / max(abs(N_value), 1e-300))
    return float(worst), P
