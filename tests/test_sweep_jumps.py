"""Sweeps across the thresholds of a quantizer: every given value is reached, branch ends are events.

A quantizer's N = (4 q / (pi A)) sum_{c_i < A} sqrt(1 - (c_i / A)^2) (thresholds c_i = (i - 1/2) q) is continuous
at each threshold but has a square-root edge there (dN/dA -> inf from above): the sweep calls it a jump of N, and
a branch of cycles reaches it tangentially in the parameter (A - c ~ (p - p*)^2). A given value between the last
continuation step and that end was then out of the plain corrector's reach (the interpolated start lies too far
from the curve, and a full Newton step from it lands below the threshold, where N is another function): sweeping
the delay of the shipped scene ``digital_quantizer_delay`` stopped with "could not land on the given value
p=0.3". The references:

- at every given value, :func:`dfloop.predict_limit_cycles` run on the loop at that value, on its own (same
  number of cycles; A and w to 1e-8);
- for K e^{-sT} / (s + 1)^3 (continuous time, ``dfloop.delayed``), where a branch ends on the threshold c the
  loop is marginal with N(c) (N is continuous there): K N(c) / (1 + w^2)^{3/2} = 1 and 3 atan w + w T = pi,
  so w = sqrt((K N(c))^{2/3} - 1), T = (pi - 3 atan w) / w, with N(c) summed here from the formula above. The
  sweep puts the end just inside the edge (1e-15 in ln A), where N differs from N(c) by ~sqrt(1e-15): the ends
  agree to 1e-6.
"""
import math
from pathlib import Path

import control as ct
import numpy as np

import dfloop as df
from dfloop import load_scene, predict_limit_cycles
from dfloop.continuation import sweep
from dfloop.scene.load import SceneLoop

ROOT = Path(__file__).resolve().parents[1]
STEP = 0.05


def _points_at_values(res, k):
    """The distinct (A, w) of the sweep's branches at given value k (a shared end point counts once)."""
    pts = []
    for b in res.branches:
        for j in np.flatnonzero(b.value_index == k):
            p = (float(b.amplitude[j]), float(b.frequency[j]))
            if not any(abs(p[0] - x[0]) <= 1e-12 and abs(p[1] - x[1]) <= 1e-12 for x in pts):
                pts.append(p)
    return sorted(pts)


def _assert_cycles_are_the_solvers(res, loop_at, values, omega, amplitude):
    assert not res.notes
    assert not [e for e in res.events if e.kind == "lost"]
    for k, value in enumerate(values):
        G, N = loop_at(value)
        ref = sorted((c.amplitude, c.frequency) for c in predict_limit_cycles(G, N, omega=omega, amplitude=amplitude))
        got = _points_at_values(res, k)
        assert len(got) == len(ref), (value, got, ref)
        for (a, w), (ar, wr) in zip(got, ref):
            assert abs(a - ar) <= 1e-8 and abs(w - wr) <= 1e-8, (value, got, ref)


def test_digital_quantizer_delay_sweep_lands_on_every_value():
    # the reported failure: 0.3 lies between the last step and the end of a branch at the threshold 0.075
    scene = load_scene(ROOT / "models" / "digital_quantizer_delay.toml")
    loop_at = SceneLoop(scene.data, "plant.delay")
    values = np.array([0.2, 0.25, 0.3, 0.35, 0.4])
    res = sweep(loop_at, values, omega=scene.omega, amplitude=scene.amplitude, parameter="delay T", unit="s",
                progress=False)
    _assert_cycles_are_the_solvers(res, loop_at, values, scene.omega, scene.amplitude)
    # the branches through 0.3 end on the threshold 0.075 (between 0.3 and 0.35), a stable one from below and an
    # unstable one from above: one fold on the edge (before: two deaths 8e-8 apart)
    ends = [e for e in res.events if abs(e.amplitude - 0.075) < 1e-12]
    assert len(ends) == 1 and 0.3 < ends[0].parameter < 0.35
    (e,) = ends
    assert e.kind == "fold" and e.cause == "element edge" and "die together" in e.detail
    pair = [res.branches[i] for i in e.branches]
    assert {b.kind for b in pair} == {"stable", "unstable"} and all(b.end == "fold" for b in pair)
    assert all(abs(b.parameter[-1] - e.parameter) < 1e-6 for b in pair)
    assert not [x for x in res.events if x.kind in ("birth", "death")]  # every end here is such a fold


def _N_at_threshold(c):
    """N of the quantizer at its threshold c (the term of c itself is zero there)."""
    inner = [(i - 0.5) * STEP for i in range(1, 10_000) if (i - 0.5) * STEP < c * (1 - 1e-12)]
    return 4 * STEP / (math.pi * c) * sum(math.sqrt(1 - (ci / c) ** 2) for ci in inner)


def test_delayed_quantizer_sweep_ends_at_the_closed_form_thresholds():
    K = 4.0
    G0 = ct.tf([K], [1, 3, 3, 1])

    def loop_at(T):
        return df.delayed(G0, T), df.Quantizer(STEP)

    values = np.linspace(0.35, 0.55, 9)  # 0.475 lies between the last step and the end at the threshold 0.125
    amplitude = (0.026, 1.0)
    res = sweep(loop_at, values, amplitude=amplitude, parameter="delay T", unit="s", progress=False)
    _assert_cycles_are_the_solvers(res, loop_at, values, res.omega_window, amplitude)
    ends = [e for e in res.events if e.cause in ("jump", "element edge")]
    assert len(ends) >= 10
    # a stable and an unstable branch reach a threshold from either side at the same point: one fold there
    assert not [e for e in res.events if e.kind in ("birth", "death") and any(
        f.kind == e.kind and f is not e and abs(f.amplitude - e.amplitude) < 1e-12
        and abs(f.parameter - e.parameter) < 1e-6 for f in res.events)]
    for e in ends:
        i = round(e.amplitude / STEP + 0.5)
        c = (i - 0.5) * STEP
        assert abs(e.amplitude - c) <= 1e-12 * c
        w = math.sqrt((K * _N_at_threshold(c)) ** (2 / 3) - 1)
        T = (math.pi - 3 * math.atan(w)) / w
        assert abs(e.parameter - T) <= 1e-6 and abs(e.frequency - w) <= 1e-6, (e, T, w)
