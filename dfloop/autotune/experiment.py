"""The relay experiment of relay-feedback auto-tuning (Astrom-Hagglund), predicted two ways and checked.

Put a relay of output level M (hysteresis a, optional) in the loop of plant G, read the oscillation's amplitude
``a`` (the peak of the relay's input) and period Tu, and take Ku = 4 M / (pi a): the describing-function estimate of
the ultimate gain, the gain at which G's loop would oscillate, with period Tu, at the frequency where arg G = -180
deg. :func:`relay_experiment` predicts the experiment by the DF (:func:`dfloop.predict_limit_cycles`) and exactly
(the orbit the relay loop really settles on), gives (Ku, Tu) estimated from each, the true ultimate point of G and
the errors of the estimates. For an ideal relay the DF estimate is the true ultimate point itself (the DF equation
1 + G N = 0 with N real says exactly arg G = -180 deg, |G| = 1 / N); the experiment (the exact orbit) is not, and
its error is what a tuning inherits.

The exact orbit comes from :func:`dfloop.exact_cycle` for any delay-free continuous or discrete plant, and from
:func:`dfloop.autotune.cycle.relay_cycle` (closed-form segments) for the process models with dead time: first
order (FOPDT) and second order (SOPDT), also with a biased relay (levels bias +- M), whose mean output gives the
static gain.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..describing.static import Relay
from ..exact import ExactCycle, exact_cycle
from ..solve.bias import BiasedCycle, predict_biased_cycles
from ..solve.delay import DelayedSystem
from ..solve.predict import predict_limit_cycles
from ..solve.result import LimitCycle
from .cycle import RelayCycle, relay_cycle
from .models import ProcessModel

__all__ = ["RelayExperiment", "relay_experiment", "process_model"]


@dataclass(frozen=True, repr=False)
class RelayExperiment:
    """The relay experiment on G: DF prediction, exact oscillation, ultimate-point estimates and the truth.

    Attributes
    ----------
    prediction : LimitCycle or BiasedCycle
        The DF's stable oscillation (amplitude of the fundamental of the relay input, rad/s): of the symmetric
        relay, or with a bias the dual-input DF's biased cycle (:func:`dfloop.solve.bias.predict_biased_cycles`,
        the offset as a load at the relay's output; its ``bias`` is the mean of the relay input).
    exact : ExactCycle or None
        The true orbit from :func:`dfloop.exact_cycle` (delay-free plants; None otherwise or when ``exact=False``).
    cycle : RelayCycle or None
        The true orbit of a process model (FOPDT / SOPDT, with dead time and/or bias).
    amplitude_exact : float or None
        Half the peak-to-peak relay input over the exact orbit (continuous ``exact``: its 512 samples per period; a
        digital one: its P samples; ``cycle``: refined extremes): what the experimenter reads as ``a``.
    Ku_df, Tu_df : float
        Ultimate gain 4 M / (pi A) and period 2 pi / w from the DF prediction.
    Ku_experiment, Tu_experiment : float or None
        The same read from the exact orbit (4 M / (pi a), its period (s)).
    Ku, Tu : float
        The true ultimate gain (gain margin) and period 2 pi / w_180 of G.
    bias : float
        Offset of the relay's output levels (bias + M, bias - M).
    static_gain : float or None
        With a bias: mean process output / mean relay output over the exact orbit, the experiment's estimate of
        G(0) (exact for any stable plant: the mean of a periodic response is G(0) times the mean input).
    errors : dict
        Relative errors (estimate - true) / true of ``Ku_df``, ``Tu_df``, ``Ku_experiment``, ``Tu_experiment``.
    """

    prediction: LimitCycle | BiasedCycle
    exact: ExactCycle | None
    amplitude_exact: float | None
    Ku_df: float
    Tu_df: float
    Ku_experiment: float | None
    Tu_experiment: float | None
    Ku: float
    Tu: float
    errors: dict
    cycle: RelayCycle | None = None
    bias: float = 0.0
    static_gain: float | None = None

    def __repr__(self) -> str:
        e = self.errors
        exp = ("" if self.Ku_experiment is None else
               f"; experiment Ku={self.Ku_experiment:.6g} ({100 * e['Ku_experiment']:+.3g} %), "
               f"Tu={self.Tu_experiment:.6g} s ({100 * e['Tu_experiment']:+.3g} %)")
        gain = "" if self.static_gain is None else f"; static gain {self.static_gain:.6g} (bias {self.bias:g})"
        return (f"RelayExperiment(true Ku={self.Ku:.6g}, Tu={self.Tu:.6g} s; DF Ku={self.Ku_df:.6g} "
                f"({100 * e['Ku_df']:+.3g} %), Tu={self.Tu_df:.6g} s ({100 * e['Tu_df']:+.3g} %){exp}{gain})")

    def to_dict(self) -> dict:
        return {"Ku": self.Ku, "Tu": self.Tu, "Ku_df": self.Ku_df, "Tu_df": self.Tu_df,
                "Ku_experiment": self.Ku_experiment, "Tu_experiment": self.Tu_experiment,
                "amplitude_exact": self.amplitude_exact, "bias": self.bias, "static_gain": self.static_gain,
                "errors": dict(self.errors), "cycle": None if self.cycle is None else self.cycle.to_dict()}


def _ultimate_point(G) -> tuple[float, float]:
    """(Ku, Tu) of G: the gain margin and the period at the first crossing of the negative real axis (arg G =
    -180 deg). A plant with a pure delay (:func:`dfloop.delayed`) is evaluated exactly, G(jw) e^{-jwT}."""
    import control as ct

    if isinstance(G, DelayedSystem):
        return _delayed_ultimate_point(G)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)   # python-control's "falling back to frd" notice
        gm, _, _, w180, _, _ = ct.stability_margins(G)
    if not (math.isfinite(gm) and math.isfinite(w180) and w180 > 0):
        raise ValueError(f"G has no finite ultimate point (arg G never reaches -180 deg: gain margin {gm}, phase "
                         f"crossover {w180}); a relay experiment needs one")
    return float(gm), 2.0 * math.pi / float(w180)


_CROSSING_SAMPLES = 400     # samples per decade at least (more where the delay turns the phase faster)


def _delayed_ultimate_point(G: DelayedSystem) -> tuple[float, float]:
    """The ultimate point of G(s) e^{-sT}: the lowest w where G(jw) e^{-jwT} crosses the negative real axis,
    bracketed on a log grid whose phase steps stay below 0.1 rad and refined by brentq on Im."""
    from scipy.optimize import brentq

    scales = [1.0 / G.delay] if G.delay > 0 else []
    poles = np.abs(np.concatenate([np.atleast_1d(ct_poles) for ct_poles in (G.system.poles(), G.system.zeros())]))
    scales += [float(p) for p in poles if p > 0]
    if not scales:
        raise ValueError(f"G = {G!r} has no time scale (no delay, poles or zeros): no ultimate point")
    lo, hi = 1e-3 * min(scales), 1e3 * max(scales)
    a = lo
    while a < hi:            # decade by decade, from the lowest frequency up: the first crossing is the one
        b = min(10.0 * a, hi)
        n = max(_CROSSING_SAMPLES, int(math.ceil(math.log(b / a) * b * G.delay / 0.1)))   # delay phase < 0.1 rad
        w = np.append(a, np.exp(np.linspace(math.log(a), math.log(b), n + 1))[1:])
        g = G.frequency_response_at(w)
        k = np.flatnonzero((np.sign(g.imag[:-1]) != np.sign(g.imag[1:])) & (g.real[:-1] + g.real[1:] < 0))
        if k.size:
            break
        a = b
    else:
        raise ValueError(f"G = {G!r} never crosses the negative real axis for w in [{lo:.3g}, {hi:.3g}] rad/s: no "
                         "ultimate point; a relay experiment needs one")
    w180 = brentq(lambda x: float(G.frequency_response_at(np.array([x]))[0].imag), w[k[0]], w[k[0] + 1],
                  xtol=1e-14 * w[k[0]], rtol=1e-15)
    return float(-1.0 / G.frequency_response_at(np.array([w180]))[0].real), 2.0 * math.pi / w180


def _biased_prediction(plant, relay: Relay, bias: float, symmetric: LimitCycle, omega, static_gain: float):
    """The stable biased DF cycle of the relay with output levels bias +/- M (largest amplitude), searched within a
    factor 5 of the symmetric cycle's amplitude."""
    A = symmetric.amplitude
    found = predict_biased_cycles(plant, relay, load=bias, amplitude=(A / 5.0, 5.0 * A), omega=omega,
                                  dc_gain=static_gain)
    stable = [c for c in found if c.stability == "stable"]
    if not stable:
        raise ValueError(f"the dual-input DF predicts no stable biased oscillation with bias = {bias:g} "
                         f"({len(found)} biased cycle(s) within a factor 5 of the symmetric amplitude {A:.6g})")
    return max(stable, key=lambda c: c.amplitude)


def process_model(G, delay: float = 0.0) -> ProcessModel:
    """The :class:`ProcessModel` K e^{-Ls} / prod (T_i s + 1) of a continuous first- or second-order tf/ss G
    without zeros and with real stable poles (ValueError otherwise); a ``delayed(G, T)`` adds its T to ``delay``."""
    import control as ct

    if isinstance(G, DelayedSystem):
        G, delay = G.system, G.delay + delay
    if not isinstance(G, (ct.TransferFunction, ct.StateSpace)) or not G.isctime():
        raise ValueError(f"G must be a continuous first- or second-order tf K/((T1 s + 1)(T2 s + 1)) here; got "
                         f"{type(G).__name__}")
    tf = ct.tf(G)
    num, den = np.trim_zeros(np.asarray(tf.num[0][0], float), "f"), np.trim_zeros(np.asarray(tf.den[0][0], float), "f")
    poles = np.roots(den) if den.size > 1 else np.array([])
    if num.size != 1 or den.size not in (2, 3) or np.any(np.abs(poles.imag) > 1e-12 * np.abs(poles).max()) or \
            np.any(poles.real >= 0) or num[0] / den[-1] <= 0:
        raise ValueError(f"G must be K/(T s + 1) or K/((T1 s + 1)(T2 s + 1)) with K, T > 0 (first or second order plus "
                         f"dead time: no zeros, real stable poles); got num={num.tolist()}, den={den.tolist()}")
    return ProcessModel(float(num[0] / den[-1]), tuple(float(-1.0 / p.real) for p in poles), float(delay))


def relay_experiment(G, relay: Relay | None = None, *, exact: bool = True, omega=None, delay: float = 0.0,
                     bias: float = 0.0) -> RelayExperiment:
    """Predict the relay experiment on G (DF and exact), and the errors of its ultimate-point estimates.

    Parameters
    ----------
    G : python-control tf or ss (SISO; continuous, or discrete with dt > 0), or ProcessModel
        The process, with the loop convention of dfloop (the relay sees x = -c).
    relay : Relay, optional
        The relay (default ``Relay(1.0)``, ideal); hysteresis and dead zone allowed (dead zone: delay-free G only).
    exact : bool
        Also compute the exact orbit and the experiment's estimates.
    omega : (float, float), optional
        Frequency window of the prediction (rad/s); default from G (with a delay: 1e-3/L .. 100/L).
    delay : float
        Dead time L (s) >= 0. With L > 0, G must be a first- or second-order lag K/((T1 s + 1)(T2 s + 1)) (or give a
        :class:`ProcessModel`): the exact orbit is :func:`~dfloop.autotune.cycle.relay_cycle`'s, the DF runs on
        G(jw) e^{-jwL}.
    bias : float
        Relay output offset b (levels b + M and b - M, |b| < M): the asymmetric experiment that estimates the static
        gain (process models only). The DF prediction is then the dual-input DF's biased cycle.

    Returns
    -------
    RelayExperiment

    Raises
    ------
    ValueError
        ``relay`` is not a :class:`Relay`; G has no ultimate point; the DF predicts no stable oscillation; a delay
        or bias with a plant that is not a first- or second-order lag.
    """
    from .._checks import finite, nonnegative

    relay = Relay(1.0) if relay is None else relay
    if not isinstance(relay, Relay):
        raise ValueError(f"relay must be a dfloop Relay, got {type(relay).__name__}")
    if not isinstance(exact, (bool, np.bool_)):
        raise ValueError(f"exact must be True or False; got {exact!r}")
    delay = nonnegative("delay", delay)
    bias = finite("bias", bias)
    if abs(bias) >= relay.M:
        raise ValueError(f"bias must satisfy |bias| < M = {relay.M:g} (both relay levels on either side of 0); got "
                         f"{bias!r}")
    model = G if isinstance(G, ProcessModel) else (process_model(G, delay) if delay > 0 or bias != 0 else None)
    if model is not None:
        if relay.dead_zone != 0:
            raise ValueError(f"the process-model relay orbit is for relays without dead zone; got dead_zone="
                             f"{relay.dead_zone!r}")
        Ku, Tu = model.ultimate_point()
        plant = model.frequency_response
        scale = model.L if model.L > 0 else min(model.T)
        omega = omega if omega is not None else (1e-3 / scale, 100.0 / scale)
    else:
        Ku, Tu = _ultimate_point(G)
        plant = G
    cycles = predict_limit_cycles(plant, relay, omega=omega)
    stable = [c for c in cycles if c.stability == "stable"]
    if not stable:
        raise ValueError(f"the DF predicts no stable oscillation of G with {relay!r} ({len(cycles)} cycle(s) in the "
                         "window): no relay experiment")
    c = max(stable, key=lambda c: c.amplitude)
    if bias != 0:     # the experiment the DF predicts is the biased one: the offset is a load on the relay output
        c = _biased_prediction(plant, relay, bias, c, omega, model.K)
    Ku_df, Tu_df = 4.0 * relay.M / (math.pi * c.amplitude), 2.0 * math.pi / c.frequency
    errors = {"Ku_df": (Ku_df - Ku) / Ku, "Tu_df": (Tu_df - Tu) / Tu}
    ex, cyc, a_ex, Ku_ex, Tu_ex, gain = None, None, None, None, None, None
    if exact and model is not None:
        cyc = relay_cycle(model, bias + relay.M, bias - relay.M, relay.hysteresis)
        a_ex, Tu_ex = cyc.amplitude, cyc.period
        if bias != 0:
            gain = cyc.mean_output / cyc.mean_input
    elif exact:
        ex = exact_cycle(G, relay, c)
        if not ex.success:
            raise ValueError(f"no exact orbit near the DF's oscillation: {ex.message}")
        a_ex = float(0.5 * (np.max(ex.x) - np.min(ex.x)))
        Tu_ex = 2.0 * math.pi / ex.frequency
    if a_ex is not None:
        Ku_ex = 4.0 * relay.M / (math.pi * a_ex)
        errors.update({"Ku_experiment": (Ku_ex - Ku) / Ku, "Tu_experiment": (Tu_ex - Tu) / Tu})
    return RelayExperiment(c, ex, a_ex, Ku_df, Tu_df, Ku_ex, Tu_ex, Ku, Tu, errors, cyc, bias, gain)
