"""Two-parameter design charts: traced boundaries against closed forms and a brute-force grid of solves.

References (derived here, not from dfloop's code):

- Saturation (limit 1) around G = K e^{-sT} / (s (s + 1)): the cycle is born from the linear loop where it is
  marginal: at the phase crossover atan(w) + w T = pi/2, with K_c(T) = w sqrt(1 + w^2). A stable cycle exists
  for K > K_c(T) and none below (one crossing of the negative real axis in the chart's range).
- Backlash (h) around K / (s (s + 1) (s + 2)): N depends on X / h only, so the fold gain does not depend on h:
  the fold boundary is the vertical line K = K*, K* the tangency gain (minimum over X of the gain at which
  K G(jw) meets -1/N(X)).
"""
import math
from concurrent.futures import ThreadPoolExecutor

import matplotlib

matplotlib.use("Agg")
import control as ct  # noqa: E402
import numpy as np  # noqa: E402
from scipy.optimize import brentq, minimize_scalar  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.chart import ChartAxis, design_chart  # noqa: E402
from dfloop.solve.delay import delayed  # noqa: E402

G1 = ct.tf([1], [1, 1, 0])
OMEGA = (0.05, 20.0)


def delayed_saturation(K, T):
    return delayed(K * G1, T), df.Saturation(1.0)


class Servo:
    """K / (jw (jw + 1) (jw + 2)) as a callable (cheaper to rebuild than a python-control tf)."""

    def __init__(self, K):
        self.K = K

    def __call__(self, w):
        s = 1j * np.asarray(w)
        return self.K / (s * (s + 1) * (s + 2))


def backlash_servo(K, h):
    return Servo(K), df.Backlash(h)


def critical_gain(T):
    w = brentq(lambda w: math.atan(w) + w * T - math.pi / 2, 1e-9, 1e3, xtol=1e-15, rtol=1e-15)
    return w * math.sqrt(1 + w * w)


def test_delay_chart_birth_curve_is_the_closed_form_and_splits_a_brute_force_grid():
    xa, ya = ChartAxis(0.5, 5.0, "gain K"), ChartAxis(0.1, 1.0, "delay T", "s")
    with ThreadPoolExecutor(2) as pool:
        res = design_chart(delayed_saturation, xa, ya, nominal=(1.0, 0.5), omega=OMEGA, samples=5,
                           resolution=40, executor=pool, progress=False)
    (b,) = res.boundaries
    assert b.kind == "linear range" and b.ends == ("chart edge", "chart edge")
    for K, T in zip(b.x, b.y):  # every traced point on the closed-form curve
        assert abs(K / critical_gain(T) - 1) < 1e-10
    assert np.allclose(b.amplitude, 1.0, rtol=1e-9)
    assert b.x.size >= 20 and not res.notes
    # the curve ends on the chart's edges: K = 5 (T where K_c = 5) and T = 1 (K = K_c(1))
    ends = sorted([(b.x[0], b.y[0]), (b.x[-1], b.y[-1])])
    assert abs(ends[0][0] - critical_gain(1.0)) < 1e-9 and abs(ends[0][1] - 1.0) < 1e-12
    assert abs(ends[1][0] - 5.0) < 1e-12 and abs(critical_gain(ends[1][1]) / 5 - 1) < 1e-9
    # brute force: predict_limit_cycles on an independent grid, each point on the traced curve's correct side
    order = np.argsort(b.y)
    for T in (0.23, 0.41, 0.67, 0.93):
        Kb = float(np.interp(T, b.y[order], b.x[order]))
        for K in (0.7, 1.6, 2.9, 4.6):
            found = df.predict_limit_cycles(*delayed_saturation(K, T), omega=OMEGA)
            stable = [c for c in found if c.stability == "stable"]
            assert (len(found), len(stable)) == ((1, 1) if K > Kb else (0, 0)), (K, T, Kb)
    # margin of the design point K = 1, T = 0.5: the gain may grow to K_c(0.5); T never reaches the curve
    m = res.margin
    assert abs(m.x_above - (critical_gain(0.5) - 1.0)) < 1e-6
    assert m.x_below is None and m.y_below is None and m.y_above is None
    # filled picture: labels agree with the closed form away from the curve
    KK, TT = np.meshgrid(res.grid_x, res.grid_y)
    Kc = np.vectorize(critical_gain)(TT)
    far = np.abs(KK / Kc - 1) > 0.05
    assert np.all((res.labels == "stable cycle")[far] == (KK > Kc)[far])


def test_backlash_fold_boundary_is_independent_of_the_clearance(tmp_path):
    def gain(X):  # tangency computed independently (h = 1: N depends on X/h only)
        N = 0.5 * (1 + (2 / math.pi) * (math.asin(1 - 1 / X) + (1 - 1 / X) * math.sqrt(1 - (1 - 1 / X) ** 2))) \
            - 1j * (2 / (math.pi * X * X)) * (X - 0.5)
        target = np.angle(-1 / N)
        g = lambda w: 1 / (1j * w * (1j * w + 1) * (1j * w + 2))  # noqa: E731
        w = brentq(lambda w: np.angle(g(w)) - target, 1e-3, math.sqrt(2) - 1e-12, xtol=1e-15, rtol=1e-15)
        return 1 / (abs(N) * abs(g(w)))

    Kstar = minimize_scalar(gain, bounds=(0.55, 2.5), method="bounded", options={"xatol": 1e-10}).fun
    res = design_chart(backlash_servo, ChartAxis(2.5, 5.5, "gain K"), ChartAxis(0.1, 0.5, "clearance h", "m"),
                       nominal=(3.0, 0.3), samples=3, resolution=12, omega=(0.01, 100.0), progress=False)
    (b,) = res.boundaries
    assert b.kind == "fold"
    assert np.all(np.abs(b.x / Kstar - 1) < 1e-9)
    assert abs(b.y.min() - 0.1) < 1e-12 and abs(b.y.max() - 0.5) < 1e-12
    fr = res.region_fractions()
    share = (Kstar - 2.5) / 3.0  # left of the fold: no cycle; right: a stable and an unstable one
    assert abs(fr["no cycle"] - share) < 0.06 and abs(fr["several cycles"] - (1 - share)) < 0.06
    assert abs(res.margin.x_above - (Kstar - 3.0)) < 1e-8 and abs(res.margin.distance - (Kstar - 3) / 3) < 1e-8
    res.to_csv(tmp_path / "b.csv")
    res.regions_to_csv(tmp_path / "r.csv")
    head = (tmp_path / "b.csv").read_text().splitlines()
    assert head[0] == "curve,kind,gain K,clearance h [m],amplitude,frequency [rad/s]" and len(head) == b.x.size + 1
    assert (tmp_path / "r.csv").read_text().splitlines()[0].startswith("gain K,clearance h [m],region")
    cp = res.plot()
    ax = cp.axes[0, 0]
    assert ax.get_xlabel() == "gain K [-]" and ax.get_ylabel() == "clearance h [m]"
    labels = [t.get_text() for t in cp.legend.get_texts()]
    assert "fold / stability change" in labels and "design point" in labels
    import matplotlib.pyplot as plt
    import pytest

    from dfloop.plot.chart import plot_chart

    fig, given = plt.subplots()
    assert plot_chart(res, ax=given).axes[0, 0] is given
    with pytest.raises(ValueError, match="ax must be"):
        plot_chart(res, ax=fig)
    plt.close("all")


def test_bad_axes_and_options():
    import pytest

    with pytest.raises(ValueError, match="start and stop"):
        ChartAxis(1.0, 1.0, "gain K")
    with pytest.raises(ValueError, match="log scale"):
        ChartAxis(-1.0, 1.0, "gain K", scale="log")
    with pytest.raises(ValueError, match="samples"):
        design_chart(backlash_servo, ChartAxis(2.5, 5.5), ChartAxis(0.1, 0.5), samples=2)


def test_process_pool_gives_the_serial_chart():
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    xa, ya = ChartAxis(0.5, 5.0, "gain K"), ChartAxis(0.1, 1.0, "delay T", "s")
    serial = design_chart(delayed_saturation, xa, ya, omega=OMEGA, samples=3, resolution=10, progress=False)
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
        par = design_chart(delayed_saturation, xa, ya, omega=OMEGA, samples=3, resolution=10, progress=False,
                           executor=pool)
    assert np.array_equal(serial.sample_counts, par.sample_counts)
    assert len(par.boundaries) == len(serial.boundaries) == 1
    np.testing.assert_array_equal(par.boundaries[0].x, serial.boundaries[0].x)
