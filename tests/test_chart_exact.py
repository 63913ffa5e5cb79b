"""Design charts sampled with exact orbits: a dead-zone relay's fold boundary in (K, d) against its closed form,
and the exact stable orbits found at the samples against an independent frequency-domain solution (Tsypkin's
switching conditions with the Fourier series of the three-level relay output)."""
import math

import control as ct
import numpy as np

import dfloop as df
from dfloop.chart import ChartAxis, design_chart

G3 = ct.tf([1], [1, 3, 2, 0])


def relay_dead_zone(K, d):
    return K * G3, df.Relay(1.0, dead_zone=d)


def _tsypkin(K, d, w0, tau0, M=1.0):
    """The exact symmetric orbit of a relay (output M for a dwell tau each half period) with dead zone d around
    K/(s(s+1)(s+2)), from the switching conditions x(0) = x(tau) = d written with the Fourier series of the
    three-level output (terms ~ k^-4): returns (w, amplitude of x's fundamental)."""
    from scipy.optimize import fsolve

    k = np.arange(1, 8001, 2)

    def x(t, w, tau):
        s = 1j * k * w
        Yk = 2 * M * (1 - np.exp(-s * tau)) / (s * 2 * np.pi / w)
        return -2 * np.real(np.sum(K / (s * (s + 1) * (s + 2)) * Yk * np.exp(s * t)))

    (w, tau), info, ier, _ = fsolve(lambda p: [x(0, *p) - d, x(p[1], *p) - d], [w0, tau0], full_output=True,
                                    xtol=1e-13)
    assert np.max(np.abs(info["fvec"])) < 1e-12 * d
    s = 1j * w
    Y1 = 2 * M * (1 - np.exp(-s * tau)) / (s * 2 * np.pi / w)
    return w, 2 * abs(K / (s * (s + 1) * (s + 2)) * Y1)


def test_relay_dead_zone_chart_fold_closed_form_and_exact_orbits():
    """Fold K = 3 pi d / M (the maximum 2M/(pi d) of N at A = d sqrt 2 meets 6/K): R_a vanishes there, the
    fold condition must still have a simple zero. The exact stable orbits found at the samples agree with an
    independent frequency-domain (Tsypkin) solution of the switching conditions."""
    res = design_chart(relay_dead_zone, ChartAxis(0.5, 3.0, "gain K"), ChartAxis(0.05, 0.25, "dead zone d"),
                       samples=4, resolution=20, exact=True, progress=False)
    (b,) = res.boundaries
    assert b.kind == "fold" and np.all(np.abs(b.x / (3 * math.pi * b.y) - 1) < 1e-9)
    checked = 0
    for j, y in enumerate(res.sample_y):
        for i, x in enumerate(res.sample_x):
            for A, w, stable in res.exact_orbits[j][i]:
                if stable:
                    tau0 = (math.pi - 2 * math.asin(min(1.0, y / A))) / w
                    w_ref, A_ref = _tsypkin(x, y, w, tau0)
                    assert abs(w / w_ref - 1) < 1e-6 and abs(A / A_ref - 1) < 1e-6
                    checked += 1
            if x > 3 * math.pi * y * 1.2:  # well inside the DF's two-cycle region: the stable orbit is there
                assert res.exact_counts[j, i, 0] == 1
    assert checked >= 3
    assert "exact orbits (exact_cycle)" in repr(res)


def _true_fold_gain(d, M=1.0):
    """The smallest gain with an exact symmetric orbit (Tsypkin): with K = 1, x1(t; w, tau) from the Fourier
    series; an orbit needs x1(0) = x1(tau) (then K = d / x1(0)); minimise K over the duty r = w tau / pi."""
    from scipy.optimize import brentq, minimize_scalar

    k = np.arange(1, 4001, 2)

    def x1(t, w, tau):
        s = 1j * k * w
        Yk = 2 * M * (1 - np.exp(-s * tau)) / (s * 2 * np.pi / w)
        return -2 * np.real(np.sum(1 / (s * (s + 1) * (s + 2)) * Yk * np.exp(s * t)))

    def gain(r):
        f = lambda w: x1(0, w, r * math.pi / w) - x1(r * math.pi / w, w, r * math.pi / w)  # noqa: E731
        ws = np.linspace(0.5, 2.0, 31)
        vals = [f(w) for w in ws]
        roots = [brentq(f, ws[i], ws[i + 1], xtol=1e-14) for i in range(30) if vals[i] * vals[i + 1] < 0]
        return min(d / x1(0, w, r * math.pi / w) for w in roots)

    return minimize_scalar(gain, bounds=(0.2, 0.7), method="bounded", options={"xatol": 1e-8}).fun


def test_exact_orbits_between_the_true_and_the_df_fold():
    """The DF puts the dead-zone relay's fold at K = 3 pi d / M = 9.42 d/M; the exact orbits appear earlier, at
    K_true = 8.98 d/M (Tsypkin, computed here). Between the two the chart's DF regions say "no cycle" and the
    exact check, seeded from the neighbouring samples' predictions, finds orbits; below K_true it finds none."""
    c_true = _true_fold_gain(1.0)  # K_true = c_true d / M (x scales with K M, the switching level with d)
    assert 0.9 * 3 * math.pi < c_true < 3 * math.pi
    res = design_chart(relay_dead_zone, ChartAxis(0.8, 1.1, "gain K"), ChartAxis(0.09, 0.11, "dead zone d"),
                       samples=5, resolution=20, exact=True, progress=False)
    between = 0
    for j, d in enumerate(res.sample_y):
        for i, K in enumerate(res.sample_x):
            ratio = K / d
            df_count, ex_count = res.sample_counts[j, i, :2].sum(), res.exact_counts[j, i, :2].sum()
            if ratio < c_true * 0.995:
                assert ex_count == 0
            elif c_true * 1.005 < ratio < 3 * math.pi * 0.995:
                assert df_count == 0 and ex_count >= 1  # cycles the DF does not predict
                between += 1
            elif ratio > 3 * math.pi * 1.005:
                assert df_count == 2 and res.exact_counts[j, i, 0] == 1
    assert between >= 2
    bad = res.exact_disagreements()
    assert all(df_region == "no cycle" for _, _, df_region, _ in bad) and len(bad) >= between
