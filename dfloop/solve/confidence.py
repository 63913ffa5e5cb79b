"""A cheap confidence on every prediction: the harmonic distortion the describing function neglects.

For a predicted cycle (A, w): drive the element with x = A sin(w t), pass its output's harmonics through G
(X_k = -G(jkw) Y_k, k >= 2) and measure the distortion d = sqrt(sum_k |X_k|^2) / A at the element's input (the
filter hypothesis in one number). Then drive the element once more with the distorted input
x = A sin(w t) + sum_k Im(X_k e^{jkwt}); the change of its fundamental, dN, is the first correction the
harmonics make to the balance 1 + G(jw) N = 0. Solving the balance linearised in (A, w),

    R_A dA + R_w dw = -G(jw) dN,      R(A, w) = 1 + G(jw) N(A, w),

gives estimates of the prediction's errors, (predicted - exact) / exact ~ -dA / (A + dA) and -dw / (w + dw):
one step of a two-term harmonic balance. Cost: two passes of the element over one sampled period (a few ms).
How well the estimates bracket the true errors from :func:`dfloop.exact_cycle` is measured by
``benchmarks/bench_exact.py`` (docs/exact.md).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .._checks import scale, show
from ..describing.interop import as_element

__all__ = ["Confidence", "cycle_confidence", "plant_harmonics"]

_SAMPLES = 2048       # samples of one period
_HARMONICS = 15       # harmonics carried through G
BRACKET = 2.0         # |true error| <= BRACKET |estimate| held on every reliable loop of benchmarks/bench_exact.py
DISTORTION_LIMIT = 0.05   # above this distortion the filter hypothesis fails: estimates are indicators only


@dataclass(frozen=True, repr=False)
class Confidence:
    """Distortion and estimated errors of one predicted cycle (:func:`cycle_confidence`).

    Attributes
    ----------
    distortion : float or None
        RMS of the harmonics k >= 2 of the element's input relative to its fundamental amplitude A.
    amplitude_error, frequency_error : float or None
        Estimated relative errors of the prediction, (predicted - exact) / exact (signed).
    harmonics : ndarray or None
        Estimated complex amplitudes X_k of the input, k = 1..K (X_1 = A; x ~ sum Im(X_k e^{jkwt})).
    available : bool
        False when the element has no time-domain model here (frequency-dependent elements such as the
        dynamic backlash, elements without an operator); ``note`` says why and the numbers are None.
    note : str
        How the numbers were obtained, or why they are missing.
    sampled_spread, samples_per_period : float or int or None
        Discrete-time plants only (:mod:`dfloop.solve.sampled`): the cycle has about ``samples_per_period``
        samples per period, and the describing function computed from that many samples of A sin(w t + phi)
        deviates from N(A) by up to ``sampled_spread`` (relative) over the phases phi of the samples. Above 5 %
        the DF of the sampled element is questionable (not :attr:`reliable`): compare with
        :func:`dfloop.hybrid.discrete.discrete_orbits`.
    bias_error : float or None
        Biased cycles only (:func:`dfloop.solve.bias.biased_confidence`): estimated error of the predicted bias,
        predicted - exact (absolute, input units).
    table : dict or None
        Tabulated elements only (the dynamic backlash): the certificate of the table value at the cycle
        (:func:`dfloop.impact.certificate.table_certificate`: ``status`` "confirmed" or "replaced", the table
        value, its error estimate and the re-simulated value). The estimated errors then come from the
        re-simulated value (the table's own error at the cycle); the harmonic-balance correction is not
        computed for an impact element (its response to a distorted force would need a second simulation).
    """

    distortion: float | None
    amplitude_error: float | None
    frequency_error: float | None
    harmonics: np.ndarray | None
    available: bool
    note: str
    sampled_spread: float | None = None
    samples_per_period: int | None = None
    bias_error: float | None = None
    table: dict | None = None

    @property
    def reliable(self) -> bool:
        """True when the distortion is at most ``DISTORTION_LIMIT`` (5 %): the estimates and the bracket are
        then trustworthy. Above it the DF's premise fails and the errors may be several times the estimates
        (they still say the prediction is poor); ``benchmarks/bench_exact.py`` shows both cases."""
        return (self.available and self.distortion <= DISTORTION_LIMIT
                and (self.sampled_spread is None or self.sampled_spread <= DISTORTION_LIMIT))

    @property
    def bracket(self) -> tuple[float, float] | None:
        """(amplitude, frequency) relative error bounds, ``BRACKET`` (2) times the estimates' sizes: the bound
        held on every reliable loop of ``benchmarks/bench_exact.py`` (an empirical factor, not a theorem).
        None when unavailable or not :attr:`reliable`."""
        if not self.reliable:
            return None
        return BRACKET * abs(self.amplitude_error), BRACKET * abs(self.frequency_error)

    def to_dict(self) -> dict:
        """Plain data: ``distortion``, ``amplitude_error``, ``frequency_error``, ``available``, ``reliable``,
        ``note`` and ``harmonics`` (a list of complex, or None)."""
        from ..export import plain

        return {"distortion": plain(self.distortion), "amplitude_error": plain(self.amplitude_error),
                "frequency_error": plain(self.frequency_error), "available": self.available,
                "reliable": self.reliable, "note": self.note, "harmonics": plain(self.harmonics),
                "sampled_spread": plain(self.sampled_spread), "samples_per_period": self.samples_per_period,
                "bias_error": plain(self.bias_error),
                "table": None if self.table is None else {k: plain(v) for k, v in self.table.items()}}

    def to_csv(self, path) -> None:
        """Write the scalars of :meth:`to_dict` as a one-row CSV file (the harmonics are in ``to_dict``)."""
        from ..export import flat, write_csv

        write_csv(path, [flat(self.to_dict())])

    def __repr__(self) -> str:
        table = "" if self.table is None else f"; table value {self.table['status']} at the cycle"
        if not self.available:
            return f"Confidence(unavailable: {self.note}{table})"
        warn = "" if self.reliable else "; distortion above 5 %: the DF is unreliable here, errors may be larger"
        if self.sampled_spread is not None and self.sampled_spread > DISTORTION_LIMIT:
            warn = (f"; {self.samples_per_period} samples per period: the sampled element's DF varies by "
                    f"{100 * self.sampled_spread:.3g} % with the phase of the samples, the DF is questionable here")
        return (f"Confidence(distortion {100 * self.distortion:.3g} %, estimated DF error: amplitude "
                f"{100 * self.amplitude_error:+.3g} %, frequency {100 * self.frequency_error:+.3g} %{table}{warn})")


def _fundamentals(y: np.ndarray, K: int) -> np.ndarray:
    """Complex amplitudes Y_k, k = 1..K, of uniform samples of one period (y ~ sum Im(Y_k e^{jk theta}))."""
    return 2j * np.fft.rfft(y)[1:K + 1] / y.size


def plant_harmonics(plant, w: float, K: int) -> tuple[np.ndarray, np.ndarray]:
    """(G(j k w) for k = 1..K, mask of the k w inside the plant's frequency domain) for a resolved plant
    (:func:`dfloop.solve.plant.as_plant`); harmonics outside the domain (an frd's measured band) are 0, left out
    of the harmonic balance."""
    k = np.arange(1, K + 1)
    lo, hi = plant.domain
    usable = (k * w >= lo) & (k * w <= hi)
    Gk = np.zeros(K, complex)
    Gk[usable] = plant(k[usable] * w)
    return Gk, usable


def unavailable(note: str) -> Confidence:
    """A Confidence without numbers, saying why."""
    return Confidence(None, None, None, None, False, note)


def cycle_confidence(G, N, amplitude: float, frequency: float | None = None, *, samples: int = _SAMPLES,
                     harmonics: int = _HARMONICS) -> Confidence:
    """Harmonic distortion at the element's input and estimated errors of a predicted cycle.

    Parameters
    ----------
    G : python-control LTI or callable G(jw)
        The plant (any form :func:`dfloop.predict_limit_cycles` accepts).
    N : DescribingFunction
        The element (amplitude-only elements with an ``output`` or ``operator``; others give an unavailable
        Confidence that says why).
    amplitude, frequency : float
        The predicted cycle: amplitude of x's fundamental and angular frequency (rad/s), > 0. Both are
        required (a missing frequency is a ``ValueError``; for a LimitCycle ``c`` pass ``c.amplitude,
        c.frequency``).
    samples : int
        Samples of one period (>= 64).
    harmonics : int
        Harmonics carried through G (>= 2).

    Returns
    -------
    Confidence
    """
    from .._checks import in_closed_interval
    from .plant import as_plant

    N = as_element(N)
    if frequency is None:
        raise ValueError(f"frequency is required (rad/s): cycle_confidence(G, N, amplitude, frequency); got "
                         f"amplitude={show(amplitude)} and no frequency (for a LimitCycle c pass c.amplitude, c.frequency)")
    A = scale("amplitude", amplitude)
    w = scale("frequency", frequency)
    S = int(in_closed_interval("samples", samples, 64, 2**20))
    K = int(in_closed_interval("harmonics", harmonics, 2, S // 4))
    if N.frequency_dependent:
        return _tabulated_confidence(G, N, A, w, S, K)
    try:
        response = N.time_model(A).response
    except NotImplementedError:
        response = None
    if response is None:
        return unavailable(f"{type(N).__name__} has no time-domain operator")
    plant = as_plant(G)
    Gk, usable = plant_harmonics(plant, w, K)
    theta = 2 * np.pi * np.arange(S) / S
    x1 = A * np.sin(theta)
    Y = _fundamentals(response(x1), K)
    X = -Gk * Y
    X[0] = A
    distortion = float(np.sqrt(np.sum(np.abs(X[1:]) ** 2)) / A)
    spectrum = np.zeros(S // 2 + 1, complex)
    spectrum[2:K + 1] = -0.5j * S * X[1:]          # irfft: sum_k Re(-j X_k e^{jk theta}) = sum_k Im(X_k e^{jk theta})
    x2 = x1 + np.fft.irfft(spectrum, n=S)
    dN = (_fundamentals(response(x2), 1)[0] - Y[0]) / A

    shift = _balance_shift(plant, N, A, w, -Gk[0] * dN)
    if shift is None:
        return Confidence(distortion, np.inf, np.inf, X, True, _SINGULAR)
    dA, dw = shift
    note = (f"{S} samples per period, {K} harmonics; errors from one two-term harmonic-balance step"
            + ("" if usable.all() else f"; G known for {int(usable.sum())} of {K} harmonics"))
    spread, n_samples = None, None
    dt = getattr(plant, "dt", None)
    if dt is not None:   # a discrete-time plant: how much the phase of the samples moves the element's DF
        from dfloop.solve.sampled import sampled_df_spread

        spread, n_samples = sampled_df_spread(response, A, w, dt, complex(N(A)))
        note += (f"; discrete time (dt={dt:g} s): {n_samples} samples per period, the sampled DF varies by "
                 f"{100 * spread:.3g} % with the phase of the samples")
    return Confidence(distortion, float(-dA / (A + dA)), float(-dw / (w + dw)), X, True, note, spread, n_samples)


def _tabulated_confidence(G, N, A: float, w: float, S: int, K: int) -> Confidence:
    """The confidence of a cycle of a frequency-dependent element: for a tabulated impact element (the dynamic
    backlash), the table certified at the cycle, the distortion from the re-simulated steady motion's harmonics
    and the errors the table's deviation from that motion makes; unavailable (saying why) otherwise."""
    from ..impact.certificate import table_certificate
    from .plant import as_plant

    why = f"{type(N).__name__} depends on frequency (its harmonic response is not a static map)"
    plant = as_plant(G)
    cert = table_certificate(lambda om: complex(plant(np.array([om]))[0]), N, A, w)
    if cert is None or cert["direct"] is None:
        return dataclasses.replace(unavailable(why), table=cert)
    if not cert["regular"]:
        return dataclasses.replace(unavailable(f"the re-simulated motion at the cycle is not periodic "
                                               f"(N there is an average): no harmonics"), table=cert)
    Y = _impact_harmonics(N.time_model(A), A, w, S, K)
    if Y is None or abs(Y[0] / A - cert["direct"]) > 1e-6 * abs(cert["direct"]):
        return dataclasses.replace(unavailable("the steady motion at the cycle could not be reproduced for its "
                                               "harmonics"), table=cert)
    Gk, usable = plant_harmonics(plant, w, K)
    X = -Gk * Y
    X[0] = A
    distortion = float(np.sqrt(np.sum(np.abs(X[1:]) ** 2)) / A)
    dN = cert["direct"] - cert["table"]
    shift = _balance_shift(plant, N, A, w, -Gk[0] * dN)
    if shift is None:
        return Confidence(distortion, np.inf, np.inf, X, True, _SINGULAR, table=cert)
    dA, dw = shift
    note = (f"{S} samples per period, {K} harmonics of the re-simulated steady motion; errors from the table's "
            f"deviation from it (table value {cert['status']}), no harmonic-balance correction for an impact "
            "element" + ("" if usable.all() else f"; G known for {int(usable.sum())} of {K} harmonics"))
    return Confidence(distortion, float(-dA / (A + dA)), float(-dw / (w + dw)), X, True, note, table=cert)


_SINGULAR = "the balance is singular in (A, w) here (a marginal cycle): no error estimate"


def _balance_shift(plant, N, A: float, w: float, rhs: complex) -> tuple[float, float] | None:
    """(dA, dw) solving the balance R = 1 + G(jw) N(A, w) linearised at (A, w): R_A dA + R_w dw = rhs, with the
    solver's Jacobian in (ln A, ln w) (R_A = dR/d(ln A) / A, R_w likewise); None where it is singular."""
    from .roots import Residual

    R_a, R_v = Residual(plant, N).jacobian(np.array([np.log(A)]), np.array([np.log(w)]))
    R_A, R_w = complex(R_a[0]) / A, complex(R_v[0]) / w
    J = np.array([[R_A.real, R_w.real], [R_A.imag, R_w.imag]])
    try:
        dA, dw = np.linalg.solve(J, [rhs.real, rhs.imag])
    except np.linalg.LinAlgError:
        return None
    return float(dA), float(dw)


def _impact_harmonics(tm, F: float, w: float, S: int, K: int) -> np.ndarray | None:
    """Complex amplitudes Y_k (k = 1..K, y ~ sum Im(Y_k e^{jk w t'})) of the steady output x1 of the impact element
    driven by F sin(w t') (the DF's phase convention), or None when its motion is not periodic.

    The steady motion's period and transient come from :func:`dfloop.impact.extract.impact_describing_function`;
    a plain run from rest over that transient and two more periods is sampled (``S`` points per forcing period)
    over its last period, with x1's constant drift (a free mass) removed."""
    from ..impact.extract import impact_describing_function
    from ..impact.kernel import simulate

    r = impact_describing_function(tm.m1, tm.m2, tm.h, tm.restitution, F, w, effects=tm.effects,
                                   chatter_tol=tm.chatter_tol)
    if not r.regular:
        return None
    P, Tp = int(r.period), 2.0 * np.pi / w
    t_b = (r.transient_periods + 2 * P) * Tp
    traj = simulate(tm.m1, tm.m2, tm.h, tm.restitution, F, w, t_b, effects=tm.effects, chatter_tol=tm.chatter_tol)
    t_a = t_b - P * Tp
    t = t_a + P * Tp * np.arange(S * P) / (S * P)
    ends = traj.evaluate(np.array([t_a, t_b]))["x1"]
    y = traj.evaluate(t)["x1"] - (ends[1] - ends[0]) / (P * Tp) * (t - t_a)
    Y = 2j * np.fft.rfft(y)[P * np.arange(1, K + 1)] / y.size     # x1 against cos(w t), t from a whole period
    return Y * (-1j) ** np.arange(1, K + 1)                        # F cos(w t) = F sin(w t'), t' = t + pi / (2 w)
