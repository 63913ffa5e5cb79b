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
