"""The relay experiment of relay-feedback auto-tuning (Astrom-Hagglund), predicted two ways and checked.

Put a relay of output level M (hysteresis a, optional) in the loop of plant G, read the oscillation's amplitude
``a`` (the peak of the relay's input) and period Tu, and take Ku = 4 M / (pi a): the describing-function estimate of
the ultimate gain, the gain at which G's loop would oscillate, with period Tu, at the frequency where arg G = -180
deg. :func:`relay_experiment` predicts the experiment by the DF (:func:`dfloop.predict_limit_cycles`) and exactly
(:func:`dfloop.exact_cycle`: the orbit the relay loop really settles on), gives (Ku, Tu) estimated from each, the
true ultimate point of G (python-control's ``stability_margins``: gain margin and phase-crossover frequency) and
the errors of the estimates. For an ideal relay the DF estimate is the true ultimate point itself (the DF equation
1 + G N = 0 with N real says exactly arg G = -180 deg, |G| = 1 / N); the experiment (the exact orbit) is not, and
its error is what a tuning inherits.

Works for any plant ``exact_cycle`` takes: continuous tf/ss, and digital loops (discrete tf/ss: the experiment run
by a sampled controller); and for the first-order-plus-dead-time model K e^{-Ls} / (T s + 1) (``delay=L`` with a
first-order G), whose exact relay cycle has a closed form (:func:`fopdt_relay_cycle`).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .describing.static import Relay
from .exact import ExactCycle, exact_cycle
from .solve.predict import predict_limit_cycles
from .solve.result import LimitCycle

__all__ = ["RelayExperiment", "relay_experiment", "fopdt_relay_cycle", "fopdt_ultimate_point", "Tuning", "tune",
           "closed_loop_check"]

RULES = ("zn-p", "zn-pi", "zn-pid", "simc-pi")
_PADE_ORDER = 12


@dataclass(frozen=True, repr=False)
class RelayExperiment:
    """The relay experiment on G: DF prediction, exact oscillation, ultimate-point estimates and the truth.

    Attributes
    ----------
    prediction : LimitCycle
        The DF's stable oscillation (amplitude of the fundamental of the relay input, rad/s).
    exact : ExactCycle or None
        The true orbit (None when ``exact=False``).
    amplitude_exact : float or None
        Peak |x - mean x| of the relay input over the exact orbit (its samples: 512 per period for a continuous
        loop, the P samples of a digital one): what the experimenter reads as ``a``.
    Ku_df, Tu_df : float
        Ultimate gain 4 M / (pi A) and period 2 pi / w from the DF prediction.
    Ku_experiment, Tu_experiment : float or None
        The same read from the exact orbit (4 M / (pi a), its period (s)).
    Ku, Tu : float
        The true ultimate gain (gain margin) and period 2 pi / w_180 of G.
    errors : dict
        Relative errors (estimate - true) / true of ``Ku_df``, ``Tu_df``, ``Ku_experiment``, ``Tu_experiment``.
    """

    prediction: LimitCycle
    exact: ExactCycle | None
    amplitude_exact: float | None
    Ku_df: float
    Tu_df: float
    Ku_experiment: float | None
    Tu_experiment: float | None
    Ku: float
    Tu: float
    errors: dict

    def __repr__(self) -> str:
        e = self.errors
        exp = ("" if self.Ku_experiment is None else
               f"; experiment Ku={self.Ku_experiment:.6g} ({100 * e['Ku_experiment']:+.3g} %), "
               f"Tu={self.Tu_experiment:.6g} s ({100 * e['Tu_experiment']:+.3g} %)")
        return (f"RelayExperiment(true Ku={self.Ku:.6g}, Tu={self.Tu:.6g} s; DF Ku={self.Ku_df:.6g} "
                f"({100 * e['Ku_df']:+.3g} %), Tu={self.Tu_df:.6g} s ({100 * e['Tu_df']:+.3g} %){exp})")


def _ultimate_point(G) -> tuple[float, float]:
    import control as ct

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)   # python-control's "falling back to frd" notice
        gm, _, _, w180, _, _ = ct.stability_margins(G)
    if not (math.isfinite(gm) and math.isfinite(w180) and w180 > 0):
        raise ValueError(f"G has no finite ultimate point (arg G never reaches -180 deg: gain margin {gm}, phase "
                         f"crossover {w180}); a relay experiment needs one")
    return float(gm), 2.0 * math.pi / float(w180)


def fopdt_relay_cycle(K: float, T: float, L: float, M: float, a: float = 0.0) -> tuple[float, float]:
    """Exact relay oscillation of K e^{-Ls} / (T s + 1) with a relay of level M and hysteresis a (switches at
    x = +-a, x = -c): (peak |x|, period).

    Let the relay switch to +M at t = 0 (c falls through -a); the plant input follows at t = L, when c is at its
    extreme -c1; then c = K M - (K M + c1) e^{-(t - L)/T}. Symmetry gives c(L + h) = c1 (h the half period) and
    the next switch c(h) = a. With q = e^{-h/T}: c1 = K M (1 - q) / (1 + q) and
    q = (1 - a / (K M)) / (2 e^{L/T} - 1 + a / (K M)), so h = -T ln q, peak c1 = K M tanh(h / 2T), period 2h.
    Valid when h > L (always for a = 0) and a < K M.
    """
    if not (K > 0 and T > 0 and L >= 0 and M > 0 and 0 <= a < K * M):
        raise ValueError(f"fopdt_relay_cycle needs K, T, M > 0, L >= 0 and 0 <= a < K M; got K={K}, T={T}, L={L}, "
                         f"M={M}, a={a}")
    r = a / (K * M)
    q = (1.0 - r) / (2.0 * math.exp(L / T) - 1.0 + r)
    h = -T * math.log(q)
    if h <= L:
        raise ValueError(f"no symmetric relay oscillation of this form: half period {h:g} s <= delay {L:g} s")
    return K * M * math.tanh(h / (2.0 * T)), 2.0 * h


def fopdt_ultimate_point(K: float, T: float, L: float) -> tuple[float, float]:
    """(Ku, Tu) of K e^{-Ls} / (T s + 1): atan(w T) + w L = pi, Ku = sqrt(1 + (w T)^2) / K, Tu = 2 pi / w."""
    from scipy.optimize import brentq

    if not (K > 0 and T > 0 and L > 0):
        raise ValueError(f"fopdt_ultimate_point needs K, T, L > 0; got K={K}, T={T}, L={L}")
    hi = math.pi / L
    w = brentq(lambda w: math.atan(w * T) + w * L - math.pi, 1e-12 * hi, hi, xtol=1e-15, rtol=1e-15)
    return math.sqrt(1.0 + (w * T) ** 2) / K, 2.0 * math.pi / w


def _first_order(G) -> tuple[float, float]:
    """(K, T) of K / (T s + 1) (ValueError otherwise)."""
    import control as ct

    if not isinstance(G, (ct.TransferFunction, ct.StateSpace)) or not G.isctime():
        raise ValueError(f"with a delay, G must be a continuous first-order tf K/(T s + 1); got {type(G).__name__}")
    tf = ct.tf(G)
    num, den = np.trim_zeros(np.asarray(tf.num[0][0], float), "f"), np.trim_zeros(np.asarray(tf.den[0][0], float), "f")
    if num.size != 1 or den.size != 2 or not (den[1] != 0 and den[0] / den[1] > 0 and num[0] / den[1] > 0):
        raise ValueError(f"with a delay, G must be K/(T s + 1) with K, T > 0 (first order plus dead time); got "
                         f"num={num.tolist()}, den={den.tolist()}")
    return float(num[0] / den[1]), float(den[0] / den[1])


def relay_experiment(G, relay: Relay | None = None, *, exact: bool = True, omega=None,
                     delay: float = 0.0) -> RelayExperiment:
    """Predict the relay experiment on G (DF and exact), and the errors of its ultimate-point estimates.

    Parameters
    ----------
    G : python-control tf or ss (SISO; continuous, or discrete with dt > 0)
        The process, with the loop convention of dfloop (the relay sees x = -c).
    relay : Relay, optional
        The relay (default ``Relay(1.0)``, ideal); hysteresis and dead zone allowed.
    exact : bool
        Also compute the exact orbit (:func:`dfloop.exact_cycle`) and the experiment's estimates.
    omega : (float, float), optional
        Frequency window of the prediction (rad/s); default from G (with a delay: 1e-3/L .. 100/L).
    delay : float
        Dead time L (s) >= 0. With L > 0, G must be K/(T s + 1) (FOPDT): the exact cycle is the closed form
        :func:`fopdt_relay_cycle` (relays without dead zone; ``exact`` is then the closed form's (peak, period)
        and the ``exact`` attribute is None), the DF runs on G(jw) e^{-jwL}.

    Returns
    -------
    RelayExperiment

    Raises
    ------
    ValueError
        ``relay`` is not a :class:`Relay`; G has no ultimate point; the DF predicts no stable oscillation.
    """
    from ._checks import nonnegative

    relay = Relay(1.0) if relay is None else relay
    if not isinstance(relay, Relay):
        raise ValueError(f"relay must be a dfloop Relay, got {type(relay).__name__}")
    if not isinstance(exact, (bool, np.bool_)):
        raise ValueError(f"exact must be True or False; got {exact!r}")
    delay = nonnegative("delay", delay)
    if delay > 0:
        K, T = _first_order(G)
        Ku, Tu = fopdt_ultimate_point(K, T, delay)
        plant = lambda w: K * np.exp(-1j * w * delay) / (1j * w * T + 1.0)   # noqa: E731
        omega = omega if omega is not None else (1e-3 / delay, 100.0 / delay)
    else:
        Ku, Tu = _ultimate_point(G)
        plant = G
    cycles = predict_limit_cycles(plant, relay, omega=omega)
    stable = [c for c in cycles if c.stability == "stable"]
    if not stable:
        raise ValueError(f"the DF predicts no stable oscillation of G with {relay!r} ({len(cycles)} cycle(s) in the "
                         "window): no relay experiment")
    c = max(stable, key=lambda c: c.amplitude)
    Ku_df, Tu_df = 4.0 * relay.M / (math.pi * c.amplitude), 2.0 * math.pi / c.frequency
    errors = {"Ku_df": (Ku_df - Ku) / Ku, "Tu_df": (Tu_df - Tu) / Tu}
    ex, a_ex, Ku_ex, Tu_ex = None, None, None, None
    if exact and delay > 0:
        if relay.dead_zone != 0:
            raise ValueError("the closed-form FOPDT relay cycle is for relays without dead zone; got dead_zone="
                             f"{relay.dead_zone!r}")
        a_ex, Tu_ex = fopdt_relay_cycle(K, T, delay, relay.M, relay.hysteresis)
    elif exact:
        ex = exact_cycle(G, relay, c)
        if not ex.success:
            raise ValueError(f"no exact orbit near the DF's oscillation: {ex.message}")
        a_ex = float(np.max(np.abs(ex.x - np.mean(ex.x))))
        Tu_ex = 2.0 * math.pi / ex.frequency
    if a_ex is not None:
        Ku_ex = 4.0 * relay.M / (math.pi * a_ex)
        errors.update({"Ku_experiment": (Ku_ex - Ku) / Ku, "Tu_experiment": (Tu_ex - Tu) / Tu})
    return RelayExperiment(c, ex, a_ex, Ku_df, Tu_df, Ku_ex, Tu_ex, Ku, Tu, errors)


@dataclass(frozen=True)
class Tuning:
    """A tuned controller: ``controller`` (python-control tf, from the error to the plant input), the rule, and
    Kp, Ti (s, inf without integral action), Td (s, 0 without derivative action)."""

    rule: str
    Kp: float
    Ti: float
    Td: float
    controller: object


def tune(rule: str = "zn-pid", *, Ku: float | None = None, Tu: float | None = None, model=None,
         tau_c: float | None = None, derivative_filter: float = 10.0) -> Tuning:
    """PID parameters from the ultimate point (Ziegler-Nichols) or from a FOPDT model (SIMC).

    Parameters
    ----------
    rule : {"zn-p", "zn-pi", "zn-pid", "simc-pi"}
        Ziegler-Nichols from (Ku, Tu): P Kp = 0.5 Ku; PI Kp = 0.45 Ku, Ti = Tu / 1.2; PID Kp = 0.6 Ku, Ti = Tu / 2,
        Td = Tu / 8. Skogestad's SIMC PI from ``model`` = (K, T, L) of K e^{-Ls}/(T s + 1): Kp = T / (K (tau_c + L)),
        Ti = min(T, 4 (tau_c + L)), tau_c = L by default.
    Ku, Tu : float
        Ultimate gain and period (s), e.g. from :func:`relay_experiment` (``Ku_experiment``, ``Tu_experiment``).
    model : (K, T, L)
        FOPDT gain, time constant (s), delay (s) for SIMC.
    tau_c : float, optional
        SIMC closed-loop time constant (s), > 0.
    derivative_filter : float
        N of the derivative's filter Td s / (Td / N s + 1), > 0.

    Returns
    -------
    Tuning
    """
    import control as ct

    from ._checks import positive

    if rule not in RULES:
        raise ValueError(f"rule must be one of {RULES}; got {rule!r}")
    n_f = positive("derivative_filter", derivative_filter)
    if rule.startswith("zn"):
        Ku, Tu = positive("Ku", Ku), positive("Tu", Tu)
        Kp, Ti, Td = {"zn-p": (0.5 * Ku, math.inf, 0.0), "zn-pi": (0.45 * Ku, Tu / 1.2, 0.0),
                      "zn-pid": (0.6 * Ku, Tu / 2.0, Tu / 8.0)}[rule]
    else:
        try:
            K, T, L = (positive(name, v) for name, v in zip(("model K", "model T", "model L"), model))
        except TypeError:
            raise ValueError(f"model must be (K, T, L) for rule {rule!r}; got {model!r}") from None
        tc = L if tau_c is None else positive("tau_c", tau_c)
        Kp, Ti, Td = T / (K * (tc + L)), min(T, 4.0 * (tc + L)), 0.0
    s = ct.tf("s")
    C = Kp * (1 + (0 if math.isinf(Ti) else 1 / (Ti * s)) + (0 if Td == 0 else Td * s / (Td / n_f * s + 1)))
    return Tuning(rule, float(Kp), float(Ti), float(Td), ct.tf(C))


def closed_loop_check(controller, G, *, delay: float = 0.0, t_end: float | None = None) -> dict:
    """Margins and step response of the loop controller * G (unit negative feedback), a check of a tuning.

    A delay is replaced by a 12th-order Pade approximation. Returns ``gain_margin``, ``phase_margin`` (deg),
    ``stable`` (all closed-loop poles in the left half plane), ``overshoot`` (fraction) and ``final_value`` of
    the step response over [0, ``t_end``] s (default 100 s).
    """
    import control as ct

    from ._checks import nonnegative

    delay = nonnegative("delay", delay)
    loop = controller * G
    if delay > 0:
        num, den = ct.pade(delay, _PADE_ORDER)
        loop = loop * ct.tf(num, den)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        gm, pm, _, _, _, _ = ct.stability_margins(loop)
    cl = ct.feedback(loop, 1)
    stable = bool(np.all(np.real(ct.poles(cl)) < 0))
    t_end = 100.0 if t_end is None else float(t_end)
    resp = ct.step_response(cl, T=np.linspace(0.0, t_end, 4001))
    y = np.asarray(resp.outputs, float).ravel()
    final = float(y[-1])
    return {"gain_margin": float(gm), "phase_margin": float(pm), "stable": stable,
            "overshoot": float(max(0.0, (y.max() - final) / abs(final))) if final else math.inf,
            "final_value": final}
