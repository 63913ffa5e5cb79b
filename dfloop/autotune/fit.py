"""Process-model parameters from a recorded relay experiment, by matching the exact relay orbit (not the DF).

The model (FOPDT K e^{-Ls}/(T s + 1) or SOPDT K e^{-Ls}/((T1 s + 1)(T2 s + 1))) and the recorded relay (levels,
hysteresis) have one exact periodic orbit (:func:`dfloop.autotune.cycle.relay_cycle`). The fit finds the
parameters (and the time of one relay switch to high, t0) that minimise sum_i (y_i - c(t_i - t0))^2 over the
samples of the whole cycles used: nonlinear least squares (``scipy.optimize.least_squares``, trust region, in
log K, log T_i, log L and t0), started from the best of a grid of model shapes each scaled to the recording's
period and amplitude (:func:`grid_start`). Since c(t - t0) holds the model's own period and
phase, the drift over n cycles pins the period down as the switching instants would, and the waveform fixes the
rest.

Confidence intervals: with i.i.d. measurement noise of unknown variance, the covariance of the estimate is
s^2 (J^T J)^{-1} (J the Jacobian of the residuals at the optimum, s^2 = RSS / (N - p)); intervals are
exp(log p +- t_{N-p} se) (Student's t), and the ultimate point (Ku, Tu) of the fitted model gets its interval by
the delta method. These hold to first order in the noise (checked by a coverage test over noise seeds,
``tests/test_autotune_fit.py``); colored noise or a model structure that does not contain the process makes them
too narrow.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .cycle import RelayCycle, relay_cycle
from .models import ProcessModel
from .record import RecordFeatures, RelayRecord

__all__ = ["ModelFit", "fit_relay_record", "grid_start"]

_LOG_BOUND = 30.0       # |log parameter| bound of the search


@dataclass(frozen=True, repr=False)
class ModelFit:
    """A process model fitted to a relay recording through its exact relay orbit.

    Attributes
    ----------
    model : ProcessModel
        The fitted model.
    names : tuple of str
        Parameter names (K, T, L) or (K, T1, T2, L).
    stderr : dict
        Standard error of each parameter (delta method from the log parameters).
    intervals : dict
        name -> (lo, hi) at ``confidence`` (also "Ku", "Tu" of the fitted model's ultimate point).
    confidence : float
    covariance : ndarray
        Covariance of (log K, log T_i, log L, t0).
    t0 : float
        Time (s) of a relay switch to high in the fitted orbit.
    cycle : RelayCycle
        The fitted model's exact orbit under the recorded relay.
    residual_sd : float
        s, the estimated noise standard deviation (y unit).
    n_samples, dof : int
    Ku, Tu : float
        Ultimate point of the fitted model (gain margin, period of the phase crossover).
    features : RecordFeatures
        The model-free reading of the record, with the DF's estimate ``features.Ku``, ``features.Tu``.
    evaluations : int
        Residual evaluations of the least-squares search (each solves the model's orbit).
    record : RelayRecord
        The fitted recording.
    """

    model: ProcessModel
    names: tuple
    stderr: dict
    intervals: dict
    confidence: float
    covariance: np.ndarray
    t0: float
    cycle: RelayCycle
    residual_sd: float
    n_samples: int
    dof: int
    Ku: float
    Tu: float
    features: RecordFeatures
    evaluations: int
    record: RelayRecord

    def __repr__(self) -> str:
        pct = f"{100 * self.confidence:g} %"
        rows = [f"  {n:<3s} = {v:<10.6g} [{self.intervals[n][0]:.6g}, {self.intervals[n][1]:.6g}]"
                for n, v in zip(self.names + ("Ku", "Tu"), self.model.params + (self.Ku, self.Tu))]
        return "\n".join([f"ModelFit({self.model!r}; {self.n_samples} samples, residual sd {self.residual_sd:.3g}, "
                          f"{pct} intervals:"] + rows + [f"  DF reading of the record: Ku = {self.features.Ku:.6g}, "
                                                         f"Tu = {self.features.Tu:.6g} s)"])

    def to_dict(self) -> dict:
        return {"model": self.model.to_dict(), "stderr": dict(self.stderr),
                "intervals": {k: list(v) for k, v in self.intervals.items()}, "confidence": self.confidence,
                "t0": self.t0, "residual_sd": self.residual_sd, "n_samples": self.n_samples, "Ku": self.Ku,
                "Tu": self.Tu, "features": self.features.to_dict(), "evaluations": self.evaluations}

    def fitted_output(self, t) -> np.ndarray:
        """The fitted orbit's process output at times t (s) of the record."""
        return self.cycle.output(np.asarray(t, float) - self.t0)

    def plot(self, ax=None):
        """:func:`dfloop.plot.autotune.plot_relay_fit`."""
        from ..plot.autotune import plot_relay_fit

        return plot_relay_fit(self, ax=ax)


_SHAPES = {1: [(r,) for r in np.geomspace(0.05, 50.0, 16)],
           2: [(r, q) for r in np.geomspace(0.1, 50.0, 10) for q in (0.05, 0.15, 0.35, 0.7, 1.0)]}


def grid_start(record: RelayRecord, features: RecordFeatures, order: int) -> ProcessModel:
    """The start of the fit: over a grid of shapes (T/L for FOPDT: 16 values in 0.05..50; T1/L in 0.1..50 times
    T2/T1 in 0.05..1 for SOPDT: 50 shapes), the model whose exact orbit has the record's period (time scaled
    exactly) and amplitude (K from K a(1, hysteresis/K) = A, two fixed-point steps), the one of least squared
    mismatch to the record with the record's phase."""
    use = (record.t >= features.t_start) & (record.t < features.t_end)
    t, y = record.t[use], record.y[use]
    best, best_cost = None, math.inf
    for shape in _SHAPES[order]:
        taus = (shape[0],) if order == 1 else (shape[0], shape[0] * shape[1])
        try:
            K = 1.0
            h = None
            for _ in range(3):
                cyc = relay_cycle(ProcessModel(K, taus, 1.0), record.high, record.low, record.hysteresis, guess=h)
                h = (cyc.h1, cyc.h2)
                K = K * features.amplitude / cyc.amplitude
            scale = features.period / cyc.period
            m = ProcessModel(K, tuple(x * scale for x in taus), scale)
            cyc = relay_cycle(m, record.high, record.low, record.hysteresis, guess=(h[0] * scale, h[1] * scale))
        except ValueError:
            continue
        r = cyc.output(t - features.t0) - y
        cost = float(r @ r)
        if cost < best_cost:
            best, best_cost = m, cost
    if best is None:
        raise ValueError(f"no {('FOPDT', 'SOPDT')[order - 1]} shape in the start grid has a relay orbit with this "
                         "relay: check the relay levels and hysteresis of the record")
    return best


def fit_relay_record(record: RelayRecord, model: str = "FOPDT", *, skip_cycles: int = 1, confidence: float = 0.95,
                     initial: ProcessModel | None = None, max_evaluations: int = 2000) -> ModelFit:
    """Fit a FOPDT or SOPDT model to a relay recording by matching its exact relay orbit.

    Parameters
    ----------
    record : RelayRecord
        E.g. from :func:`dfloop.autotune.record.load_relay_record`.
    model : {"FOPDT", "SOPDT"}
        Model structure.
    skip_cycles : int
        Whole cycles dropped at the start of the record (settling).
    confidence : float
        Level of the intervals, in (0, 1).
    initial : ProcessModel, optional
        Start of the search (default: :func:`grid_start`).
    max_evaluations : int
        Bound on the residual evaluations of each least-squares run; hitting it raises ValueError.

    Returns
    -------
    ModelFit

    Raises
    ------
    ValueError
        Bad arguments; a record without two whole cycles; a search that does not converge within its bound.
    """
    from scipy.optimize import least_squares
    from scipy.stats import t as student

    from .._checks import in_closed_interval, integer_at_least

    if not isinstance(record, RelayRecord):
        raise ValueError(f"record must be a RelayRecord, got {type(record).__name__}")
    if model not in ("FOPDT", "SOPDT"):
        raise ValueError(f"model must be 'FOPDT' or 'SOPDT'; got {model!r}")
    confidence = in_closed_interval("confidence", confidence, 1e-6, 1 - 1e-9)
    max_evaluations = integer_at_least("max_evaluations", max_evaluations, 10)
    feats = record.features(skip_cycles)
    use = (record.t >= feats.t_start) & (record.t < feats.t_end)
    t, y = record.t[use], record.y[use]
    order = 1 if model == "FOPDT" else 2
    if initial is None:
        initial = grid_start(record, feats, order)
    elif not isinstance(initial, ProcessModel):
        raise ValueError(f"initial must be a ProcessModel, got {type(initial).__name__}")
    if initial.order != order:
        p = initial.params
        initial = (initial.fopdt() if order == 1 else
                   ProcessModel(p[0], (p[1] * 0.9, p[1] * 0.1), p[-1]))
    names = ProcessModel.names(order)
    state = {"h": None, "evals": 0, "cycle": None}
    scale = float(np.std(y)) or 1.0

    def orbit(x):
        m = ProcessModel.from_params(np.exp(x[:-1]))
        cyc = relay_cycle(m, record.high, record.low, record.hysteresis, guess=state["h"])
        if state["h"] is not None and abs(cyc.period / sum(state["h"]) - 1.0) > 0.2:
            # a far step: the warm start may have found a faster orbit (h < L) than the one the relay settles on
            cyc = relay_cycle(m, record.high, record.low, record.hysteresis)
        return cyc

    def residuals(x):
        state["evals"] += 1
        if state["evals"] > max_evaluations:
            raise _Budget()
        try:
            cyc = orbit(x)
        except ValueError:
            return np.full(t.size, 10.0 * scale)       # no orbit with one switch per level: far from the data
        state["h"] = (cyc.h1, cyc.h2)
        return cyc.output(t - x[-1]) - y

    x0 = np.array([math.log(v) for v in initial.params] + [feats.t0])
    lo = np.array([-_LOG_BOUND] * (order + 2) + [feats.t0 - feats.period])
    hi = np.array([_LOG_BOUND] * (order + 2) + [feats.t0 + feats.period])
    try:
        sol = least_squares(residuals, x0, bounds=(lo, hi), method="trf", x_scale="jac", xtol=1e-12, ftol=1e-14,
                            gtol=1e-14, max_nfev=max_evaluations)
    except _Budget:
        raise ValueError(f"the fit did not converge within max_evaluations={max_evaluations} residual evaluations; "
                         "raise max_evaluations or give a closer initial model") from None
    if sol.status <= 0:
        raise ValueError(f"the fit did not converge: {sol.message}")
    x = sol.x
    cyc = orbit(x)
    r = cyc.output(t - x[-1]) - y
    N, p = t.size, x.size
    dof = N - p
    s2 = float(r @ r) / dof
    J = sol.jac
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        raise ValueError("the fitted parameters are not identifiable from this record (singular J^T J); record "
                         "more cycles, use a biased relay, or fit the FOPDT") from None
    q = float(student.ppf(0.5 + confidence / 2.0, dof))
    fitted = cyc.model
    stderr, intervals = {}, {}
    for i, name in enumerate(names):
        se = math.sqrt(max(cov[i, i], 0.0))
        v = math.exp(x[i])
        stderr[name] = v * se
        intervals[name] = (math.exp(max(x[i] - q * se, -700.0)), math.exp(min(x[i] + q * se, 700.0)))
    Ku, Tu = fitted.ultimate_point()
    grads = []
    for i in range(order + 2):
        step = 1e-6
        xp = x[:-1].copy()
        xp[i] += step
        Kp, Tp = ProcessModel.from_params(np.exp(xp)).ultimate_point()
        grads.append(((math.log(Kp) - math.log(Ku)) / step, (math.log(Tp) - math.log(Tu)) / step))
    G = np.array(grads)          # d log (Ku, Tu) / d log params
    C = cov[:-1, :-1]
    for j, (name, v) in enumerate((("Ku", Ku), ("Tu", Tu))):
        se = math.sqrt(max(float(G[:, j] @ C @ G[:, j]), 0.0))
        stderr[name] = v * se
        intervals[name] = (v * math.exp(-min(q * se, 700.0)), v * math.exp(min(q * se, 700.0)))
    return ModelFit(fitted, names, stderr, intervals, confidence, cov, float(x[-1]), cyc, math.sqrt(s2), N, dof, Ku, Tu,
                    feats, state["evals"], record)


class _Budget(Exception):
    """The residual-evaluation bound was hit."""
