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
