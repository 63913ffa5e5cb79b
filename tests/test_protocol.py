import numpy as np
import pytest

from dfloop.describing.base import DescribingFunction, negative_inverse


class Gain(DescribingFunction):
    def __init__(self, k):
        self.k = k

    def _evaluate(self, A, omega):
        return np.full(np.shape(A), self.k, dtype=complex)


def test_broadcast_grid_and_scalar():
    N = Gain(2.0)
    assert N(3.0).shape == ()
    assert N(np.ones(4)[:, None], np.ones(5)[None, :]).shape == (4, 5)


def test_negative_amplitude_raises_with_name():
    with pytest.raises(ValueError, match="A"):
        Gain(1.0)(-1.0)


def test_nonpositive_frequency_raises():
    with pytest.raises(ValueError, match="omega"):
        Gain(1.0)(1.0, 0.0)


def test_negative_inverse_zero_gives_inf_not_nan():
    z = negative_inverse(Gain(0.0), [1.0, 2.0])
    assert np.all(np.isinf(z)) and not np.any(np.isnan(z))


def test_library_elements_pickle_with_the_same_values():
    """Process executors (batch, sweeps) ship elements to workers by pickle: every library element must
    survive it and give bit-identical N (checked against the element it came from)."""
    import pickle

    import control as ct

    import dfloop as df

    elements = [df.Backlash(0.2, 3.0), df.Saturation(1.5, 2.0), df.DeadZone(0.5), df.Relay(1.0, 0.1, 0.2),
                df.CubicStiffness(1.0, 0.5), df.Quantizer(0.5), df.PreloadedSpring(1.0, 0.3),
                df.CoulombViscousFriction(1.0, 0.3), df.MassBacklash(1.0, 3.0, 0.1),
                df.LinearThenStatic(ct.tf([1.0], [1.0, 1.0]), df.Relay(1.0)),
                df.NumericDF(np.tanh), df.NumericDF(df.Relay(1.0, 0.1))]
    A, w = np.array([0.3, 1.0, 4.0]), np.array([0.5, 2.0, 7.0])
    for N in elements:
        clone = pickle.loads(pickle.dumps(N))
        args = (A, w) if N.frequency_dependent else (A,)
        assert np.array_equal(clone(*args), N(*args)), N
