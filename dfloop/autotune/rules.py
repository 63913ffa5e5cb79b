"""PID tuning rules from the relay experiment's ultimate point or a fitted process model, and their check.

Ziegler-Nichols from (Ku, Tu); Skogestad's SIMC and Astrom-Hagglund's AMIGO from a first-order-plus-dead-time
model (K, T, L) (a second-order model is reduced by Skogestad's half rule, except for SIMC PID which uses T2 as
the derivative time). Each rule returns a python-control controller C(s) from the error to the process input.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..solve.delay import DelayedSystem
from .models import ProcessModel

__all__ = ["Tuning", "tune", "closed_loop_check", "RULES"]

RULES = ("zn-p", "zn-pi", "zn-pid", "simc-pi", "simc-pid", "amigo-pi", "amigo-pid")
_PADE_ORDER = 12


@dataclass(frozen=True)
class Tuning:
    """A tuned controller: ``controller`` (python-control tf, from the error to the plant input), the rule, and
    Kp, Ti (s, inf without integral action), Td (s, 0 without derivative action)."""

    rule: str
    Kp: float
    Ti: float
    Td: float
    controller: object

    def to_dict(self) -> dict:
        return {"rule": self.rule, "Kp": self.Kp, "Ti": self.Ti, "Td": self.Td}


def _model(model, rule):
    from .._checks import positive

    if isinstance(model, ProcessModel):
        return model
    try:
        p = [float(v) for v in model]
    except TypeError:
        raise ValueError(f"model must be a ProcessModel or (K, T, L) / (K, T1, T2, L) for rule {rule!r}; got "
                         f"{model!r}") from None
    if len(p) not in (3, 4):
        raise ValueError(f"model must be (K, T, L) or (K, T1, T2, L) for rule {rule!r}; got {model!r}")
    names = ProcessModel.names(len(p) - 2)
    for name, v in zip(names, p):
        positive(f"model {name}", v)
    return ProcessModel.from_params(p)


def tune(rule: str = "zn-pid", *, Ku: float | None = None, Tu: float | None = None, model=None,
         tau_c: float | None = None, derivative_filter: float = 10.0) -> Tuning:
    """PID parameters from the ultimate point (Ziegler-Nichols) or from a process model (SIMC, AMIGO).

    Parameters
    ----------
    rule : {"zn-p", "zn-pi", "zn-pid", "simc-pi", "simc-pid", "amigo-pi", "amigo-pid"}
        Ziegler-Nichols from (Ku, Tu): P Kp = 0.5 Ku; PI Kp = 0.45 Ku, Ti = Tu / 1.2; PID Kp = 0.6 Ku, Ti = Tu / 2,
        Td = Tu / 8.
        Skogestad's SIMC from the FOPDT (K, T, L): PI Kp = T / (K (tau_c + L)), Ti = min(T, 4 (tau_c + L)),
        tau_c = L by default; PID from a SOPDT (K, T1, T2, L): the same with T = T1, and Td = T2 (series form,
        converted to the parallel form used here: Kp (1 + Td/Ti), Ti + Td, Ti Td / (Ti + Td)).
        AMIGO (Astrom and Hagglund 2006, FOPDT): PI Kp = 0.15/K + (0.35 - L T/(L + T)^2) T/(K L),
        Ti = 0.35 L + 13 L T^2 / (T^2 + 12 L T + 7 L^2); PID Kp = (0.2 + 0.45 T/L)/K, Ti = (0.4 L + 0.8 T)/(L + 0.1 T) L,
        Td = 0.5 L T / (0.3 L + T).
    Ku, Tu : float
        Ultimate gain and period (s), e.g. from :func:`relay_experiment` or a record's fit.
    model : ProcessModel or (K, T, L) or (K, T1, T2, L)
        Process model (gain, time constants (s), dead time (s)); a SOPDT is reduced by the half rule
        (:meth:`ProcessModel.fopdt`) for SIMC PI and AMIGO.
    tau_c : float, optional
        SIMC closed-loop time constant (s), > 0.
    derivative_filter : float
        N of the derivative's filter Td s / (Td / N s + 1), > 0.

    Returns
    -------
    Tuning
    """
    import control as ct

    from .._checks import positive

    if rule not in RULES:
        raise ValueError(f"rule must be one of {RULES}; got {rule!r}")
    n_f = positive("derivative_filter", derivative_filter)
    if rule.startswith("zn"):
        Ku, Tu = positive("Ku", Ku), positive("Tu", Tu)
        Kp, Ti, Td = {"zn-p": (0.5 * Ku, math.inf, 0.0), "zn-pi": (0.45 * Ku, Tu / 1.2, 0.0),
                      "zn-pid": (0.6 * Ku, Tu / 2.0, Tu / 8.0)}[rule]
    else:
        m = _model(model, rule)
        if rule == "simc-pid" and m.order == 2:
            K, (T1, T2), L = m.K, m.T, m.L
        else:
            f = m.fopdt()
            K, (T1,), L, T2 = f.K, f.T, f.L, 0.0
        if L <= 0:
            raise ValueError(f"rule {rule!r} needs a dead time L > 0; got model {m!r}")
        if rule.startswith("simc"):
            tc = L if tau_c is None else positive("tau_c", tau_c)
            kc, ti = T1 / (K * (tc + L)), min(T1, 4.0 * (tc + L))
            Kp, Ti, Td = kc * (1 + T2 / ti), ti + T2, ti * T2 / (ti + T2)   # series -> parallel (T2 = 0: PI)
        elif rule == "amigo-pi":
            T = T1
            Kp = 0.15 / K + (0.35 - L * T / (L + T) ** 2) * T / (K * L)
            Ti, Td = 0.35 * L + 13.0 * L * T ** 2 / (T ** 2 + 12.0 * L * T + 7.0 * L ** 2), 0.0
        else:
            T = T1
            Kp = (0.2 + 0.45 * T / L) / K
            Ti, Td = (0.4 * L + 0.8 * T) / (L + 0.1 * T) * L, 0.5 * L * T / (0.3 * L + T)
    s = ct.tf("s")
    C = Kp * (1 + (0 if math.isinf(Ti) else 1 / (Ti * s)) + (0 if Td == 0 else Td * s / (Td / n_f * s + 1)))
    return Tuning(rule, float(Kp), float(Ti), float(Td), ct.tf(C))


def closed_loop_check(controller, G, *, delay: float = 0.0, t_end: float | None = None) -> dict:
    """Margins, peak sensitivity and step response of the loop controller * G (unit negative feedback).

    A delay is replaced by a 12th-order Pade approximation. Returns ``gain_margin``, ``phase_margin`` (deg),
    ``Ms`` (max |1 / (1 + loop)| over 1e-4..1e3 rad/s divided by the loop's crossover scale: a 4000-point log grid),
    ``stable`` (all closed-loop poles in the left half plane), ``overshoot`` (fraction) and ``final_value`` of the
    step response over [0, ``t_end``] s (default 100 s). G may be a :class:`ProcessModel` (its delay is used) or a
    ``delayed(G, T)`` (T is added to ``delay``).
    """
    import control as ct

    from .._checks import nonnegative

    if isinstance(G, ProcessModel):
        G, delay = G.tf(), G.L
    if isinstance(G, DelayedSystem):   # delayed(G, T): its delay joins ``delay``
        G, delay = G.system, G.delay + delay
    delay = nonnegative("delay", delay)
    loop = controller * G
    if delay > 0:
        num, den = ct.pade(delay, _PADE_ORDER)
        loop = loop * ct.tf(num, den)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        gm, pm, _, _, wc, _ = ct.stability_margins(loop)
    w = np.geomspace(1e-4, 1e3, 4000) * (wc if math.isfinite(wc) and wc > 0 else 1.0)
    Ms = float(np.max(np.abs(1.0 / (1.0 + loop(1j * w)))))
    cl = ct.feedback(loop, 1)
    stable = bool(np.all(np.real(ct.poles(cl)) < 0))
    t_end = 100.0 if t_end is None else float(t_end)
    resp = ct.step_response(cl, T=np.linspace(0.0, t_end, 4001))
    y = np.asarray(resp.outputs, float).ravel()
    final = float(y[-1])
    return {"gain_margin": float(gm), "phase_margin": float(pm), "Ms": Ms, "stable": stable,
            "overshoot": float(max(0.0, (y.max() - final) / abs(final))) if final else math.inf,
            "final_value": final}
