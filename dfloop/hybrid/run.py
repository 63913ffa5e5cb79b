"""The one closed-loop driver: any loop model of :mod:`dfloop.hybrid`, run period by period and sampled."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .loop import HybridError

__all__ = ["LoopSimulation", "simulate"]

MAX_EVENTS_PER_PERIOD = 100_000   # bound on switches / impacts in one period (sliding or chatter hits it)


@dataclass
class LoopSimulation:
    """Samples of a closed-loop run: times t (s), element input x and output y; ``diverged`` when |x| passed the
    divergence bound (the samples stop there); ``method`` says how the loop was run."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    diverged: bool
    method: str = ""


def simulate(loop, z, mode, period: float, periods: float, steps_per_period: int, *, limit: float,
             max_events: int = MAX_EVENTS_PER_PERIOD) -> LoopSimulation:
    """Run ``loop`` from (z, mode) for ``periods`` periods of length ``period`` (s), one flow per period.

    Parameters
    ----------
    loop : loop model
        From :func:`dfloop.hybrid.loop_model`.
    z, mode
        Start state and mode (e.g. from :func:`dfloop.hybrid.start_on_prediction`).
    period, periods : float
        The period (s) and the length of the run in periods.
    steps_per_period : int
        Uniform samples per period of the returned signals.
    limit : float
        |x| beyond this stops the run as divergent.
    max_events : int
        Bound on the events of one period's flow.

    Raises
    ------
    RuntimeError
        The flow cannot continue (sliding motion, more than ``max_events`` events in one period, ...), with
        the time reached.
    """
    ts, xs, ys = [], [], []
    diverged = False
    for p in range(int(math.ceil(periods))):
        span = min(period, periods * period - p * period)
        try:
            fl = loop.flow(z, mode, span, max_events=max_events, **({"limit": limit} if getattr(loop, "bounded", False) else {}))
        except HybridError as exc:
            raise RuntimeError(f"the loop cannot be simulated past t = {p * period:.6g} s: {exc}") from None
        tk = np.arange(int(round(span / period * steps_per_period))) * (period / steps_per_period)
        if getattr(fl, "stopped", None) is not None:   # the state passed the divergence bound within the period
            tk = tk[tk <= fl.stopped]
            diverged = True
        x, y = loop.signals(fl, tk)
        ts.append(p * period + tk)
        xs.append(x)
        ys.append(y)
        z, mode = fl.z, fl.mode
        if diverged or not np.all(np.isfinite(z)) or not np.all(np.isfinite(x)) or np.max(np.abs(x), initial=0.0) > limit:
            diverged = True
            break
    x = np.concatenate(xs)
    keep = np.isfinite(x) & (np.abs(x) <= limit) if diverged else slice(None)
    if diverged:   # samples up to the first one beyond the bound
        bad = np.flatnonzero(~keep)
        keep = slice(0, int(bad[0]) if bad.size else x.size)
    return LoopSimulation(np.concatenate(ts)[keep], x[keep], np.concatenate(ys)[keep], diverged, loop.method)
