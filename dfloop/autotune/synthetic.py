"""Synthetic relay recordings from the exact relay orbit of a known process, with measurement noise.

The orbit is :func:`dfloop.autotune.cycle.relay_cycle`'s (closed-form segments, exact): the recording starts on the
settled oscillation (no start-up transient). The noise is white Gaussian measurement noise added to the logged y
only, not fed back to the relay: the switching instants are those of the noise-free loop, seen through the
sampling (the logged u changes level at the first sample after the switch).
"""
from __future__ import annotations

import math

import numpy as np

from .cycle import relay_cycle
from .models import ProcessModel
from .record import RelayRecord

__all__ = ["synthetic_record"]


def synthetic_record(model: ProcessModel, *, high: float = 1.0, low: float | None = None, hysteresis: float = 0.0,
                     dt: float | None = None, cycles: float = 10.0, noise: float = 0.0, seed: int = 0,
                     phase: float = 0.3, meta: dict | None = None) -> RelayRecord:
    """A relay recording of ``model``: the exact orbit sampled every ``dt`` plus N(0, noise^2) on y.

    Parameters
    ----------
    model : ProcessModel
    high, low, hysteresis : float
        The relay (``low`` defaults to -high).
    dt : float, optional
        Sampling interval (s); default period / 200.
    cycles : float
        Length of the recording in periods (>= 3).
    noise : float
        Standard deviation of the measurement noise on y (y unit), >= 0.
    seed : int
        Seed of the noise.
    phase : float
        Where in the cycle the recording starts (fraction of a period after a relay switch to high), in [0, 1).
    meta : dict, optional
        ``# key = value`` lines for the file (a description is added).
    """
    from .._checks import in_closed_interval, nonnegative, positive

    cycles = in_closed_interval("cycles", cycles, 3.0, 10_000.0)
    noise = nonnegative("noise", noise)
    phase = in_closed_interval("phase", phase, 0.0, 1.0)
    cyc = relay_cycle(model, high, low, hysteresis)
    dt = cyc.period / 200.0 if dt is None else positive("dt", dt)
    n = int(math.ceil(cycles * cyc.period / dt))
    if n > 10_000_000:
        raise ValueError(f"the recording would hold {n} samples (> 1e7); raise dt or record fewer cycles")
    t = np.arange(n) * dt
    shifted = t + phase * cyc.period
    y = cyc.output(shifted) + np.random.default_rng(seed).normal(0.0, noise, n) * (noise > 0)
    info = {"description": (f"SYNTHETIC relay experiment: exact relay orbit of {model!r} (dfloop.autotune.cycle."
                            f"relay_cycle), sampled every {dt:g} s, white Gaussian measurement noise sd {noise:g} on y "
                            f"(seed {seed}), not fed back to the relay"),
            "units": "t [s], u [process input], y [process output, deviation from the setpoint]"}
    info.update(meta or {})
    return RelayRecord(t, cyc.relay_output(shifted), y, cyc.high, cyc.low, cyc.hysteresis, info)
