"""predict_limit_cycles: bad input raises ValueError naming the problem; no NaN in results."""
import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.describing.base import DescribingFunction

H = ct.tf([8], [1, 2, 2, 1])


@pytest.mark.parametrize("omega, match", [
    ((-1, 10), "omega window must be positive"),
    ((0, 10), "omega window must be positive"),
    ((10, 1), "omega window must satisfy lo < hi"),
    ((1, 1), "omega window must satisfy lo < hi"),
    ((np.nan, 10), "omega window must be finite"),
    ((1, np.inf), "omega window must be finite"),
    ((1,), "omega window must be a pair"),
])
def test_bad_omega_window(omega, match):
    with pytest.raises(ValueError, match=match):
        df.predict_limit_cycles(H, df.Saturation(1.0), omega=omega)


@pytest.mark.parametrize("amplitude, match", [
    ((-1, 10), "amplitude window must be positive"),
    ((5, 2), "amplitude window must satisfy lo < hi"),
    ((0.1, 0.4), "outside N's amplitude domain"),  # dead zone delta = 0.5: N = 0 there
])
def test_bad_amplitude_window(amplitude, match):
    with pytest.raises(ValueError, match=match):
        df.predict_limit_cycles(H, df.DeadZone(0.5), amplitude=amplitude)


def test_mimo_plant_rejected():
    G = ct.rss(2, 2, 2)
    with pytest.raises(ValueError, match="SISO"):
        df.predict_limit_cycles(G, df.Saturation(1.0))


def test_discrete_plant_without_sampling_period_rejected():
    with pytest.raises(ValueError, match="numeric sampling period dt > 0"):
        df.predict_limit_cycles(ct.tf([1], [1, 0.5], dt=True), df.Saturation(1.0))


def test_nan_in_G_rejected():
    G = lambda w: np.where(w > 2, np.nan, -3.0 / (1 + 1j * w))  # noqa: E731
    with pytest.raises(ValueError, match="G\\(jw\\) is not finite"):
        df.predict_limit_cycles(G, df.Saturation(1.0), omega=(0.1, 10))


def test_callable_plant_needs_omega_window():
    with pytest.raises(ValueError, match="omega window is required"):
        df.predict_limit_cycles(lambda w: 1 / (1j * w), df.Saturation(1.0))


class _NanAbove(DescribingFunction):
    def _evaluate(self, A, omega):
        return np.where(A > 2, np.nan, 1.0 / (1 + A)).astype(complex)


class _Zero(DescribingFunction):
    def _evaluate(self, A, omega):
        return np.zeros(A.shape, complex)


def test_nan_in_N_rejected():
    with pytest.raises(ValueError, match="N returned NaN"):
        df.predict_limit_cycles(H, _NanAbove(), amplitude=(0.1, 10))


def test_zero_N_rejected():
    with pytest.raises(ValueError, match="N is zero everywhere"):
        df.predict_limit_cycles(H, _Zero(), amplitude=(0.1, 10))
    with pytest.raises(ValueError, match="N is zero everywhere"):
        df.predict_limit_cycles(H, _Zero())


def test_not_a_describing_function_rejected():
    with pytest.raises(ValueError, match="N must be a dfloop DescribingFunction"):
        df.predict_limit_cycles(H, 3.0)


@pytest.mark.parametrize("kw, match", [({"grid": (1, 10)}, r"grid\[0\] \(amplitudes\) must be an integer >= 2"), ({"tol": 0.0}, "tol"),
                                       ({"grid": (10, 2_000_000)}, "grid sizes must lie in"),
                                       ({"grid": "x"}, "grid must be a pair")])
def test_bad_options(kw, match):
    with pytest.raises(ValueError, match=match):
        df.predict_limit_cycles(H, df.Saturation(1.0), **kw)


def test_frd_window_outside_grid_rejected():
    frd = ct.frd(H, np.logspace(-1, 1, 50))
    with pytest.raises(ValueError, match="leaves the plant's frequency range"):
        df.predict_limit_cycles(frd, df.Saturation(1.0), omega=(0.01, 5))
