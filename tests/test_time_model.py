"""The time-model protocol: what each element says about its behaviour in time, checked against the element's
own output and operator; the dispatcher's errors."""
import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.describing.base import DescribingFunction
from dfloop.describing.time_model import Impact, PiecewiseAffine, Sampled, Smooth, impact_model
from dfloop.exact import exact_cycle
from dfloop.hybrid import loop_model

G = ct.tf([8.0], [1.0, 2.0, 2.0, 1.0])


def _run_modes(model: PiecewiseAffine, x: np.ndarray, e0: float = 0.0) -> np.ndarray:
    """Drive a piecewise-affine model through samples x by its guards alone (x' from differences): the outputs."""
    mode, e = model.initial(x[:1], x[1] - x[0])
    out = np.empty(x.size)
    for i, v in enumerate(x):
        xd = v - x[i - 1] if i else x[1] - x[0]
        for _ in range(len(model.modes)):
            m = model.modes[mode]
            hit = [g for g in m.guards if g.cx * v + g.cxd * xd + g.ce * e + g.c1 < 0]
            if not hit:
                break
            g = hit[0]
            if g.reset is not None:
                e = g.reset[0] * v + g.reset[1]
            mode = g.target
        m = model.modes[mode]
        if m.de:
            e = e + m.de * xd
        out[i] = m.gx * v + m.ge * e + m.g1
    return out


@pytest.mark.parametrize("N", [df.Relay(1.0), df.Relay(1.5, hysteresis=0.1), df.Relay(2.0, dead_zone=0.3),
                               df.Relay(1.0, hysteresis=0.1, dead_zone=0.2)], ids=repr)
def test_relay_guards_switch_like_the_relay_operator(N):
    """The modes and guards, driven sample by sample, give the RelayOperator's output on a random smooth input."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 20.0, 4001)
    x = sum(rng.uniform(0.2, 1.0) * np.sin(rng.uniform(0.3, 3.0) * t + rng.uniform(0, 6)) for _ in range(4))
    model = N.time_model(1.0)
    assert isinstance(model, PiecewiseAffine) and len(model.modes) == 3
    op = N.operator()
    expected = np.array([op(v) for v in x])
    ours = _run_modes(model, x)
    assert np.count_nonzero(ours != expected) <= 2      # the first samples, before the start rule has history
    assert np.array_equal(ours[10:], expected[10:])


@pytest.mark.parametrize("N", [df.Saturation(1.0), df.DeadZone(0.5), df.Quantizer(0.25), df.PreloadedSpring(0.3, 2.0),
                               df.CoulombViscousFriction(0.4, 1.5)], ids=repr)
def test_static_pieces_are_the_element_output(N):
    model = N.time_model(2.0)
    assert isinstance(model, PiecewiseAffine)
    x = np.linspace(-3.0, 3.0, 2001)
    x = x[np.all(np.abs(np.abs(x)[:, None] - N.breakpoints(128.0)[None, :]) > 1e-9, axis=1)]   # off the jumps
    np.testing.assert_allclose(_run_modes(model, x), N.output(x), atol=1e-12)
    np.testing.assert_allclose(model.response(x), N.output(x), atol=0)


def test_smooth_model_and_its_slope():
    N = df.CubicStiffness(10.0, -1.0)
    model = N.time_model(1.0)
    assert isinstance(model, Smooth)
    x = np.linspace(-2.0, 2.0, 41)
    h = 1e-6
    np.testing.assert_allclose(model.slope(x), (N.output(x + h) - N.output(x - h)) / (2 * h), rtol=1e-8, atol=1e-8)
    assert isinstance(df.NumericDF(np.tanh).time_model(1.0), Smooth)


def test_impact_and_sampled_models_and_the_dispatcher_errors():
    db = df.DynamicBacklash(1.0, 2.0, 0.1, 0.5, cache=False)
    model = impact_model(db)
    assert isinstance(model, Impact) and (model.m1, model.m2, model.h, model.restitution) == (1.0, 2.0, 0.1, 0.5)
    assert impact_model(df.Relay()) is None

    class Hysteron:        # a user's operator without a time model: sampled, fixed step
        def __init__(self):
            self.state = -1.0

        def __call__(self, x):
            self.state = 1.0 if x > 0.2 else (-1.0 if x < -0.2 else self.state)
            return self.state

    N = df.NumericDF(Hysteron(), hysteretic=True)
    assert isinstance(N.time_model(1.0), Sampled)
    with pytest.raises(ValueError, match="^N: NumericDF is known only through a sampled operator"):
        exact_cycle(G, N, (1.0, 1.0))

    class Bare(DescribingFunction):      # neither a time model nor an operator
        def _evaluate(self, A, omega):
            return np.ones_like(A, dtype=complex)

    with pytest.raises(ValueError, match="^N: Bare has no time-domain model"):
        loop_model(G, Bare(), 1.0, 1.0)
