"""The exact delay flow tends to the undelayed exact flow as the delay T goes to 0: an asymmetric relay with a
constant input around K/(s+1)^3 (a biased orbit), T from 1e-9 to 1e-2 of the period. The orbit moves linearly in
T (dw/dT and d mean/dT constant over seven decades), so no tiny delay is out of reach of the delay flow."""
from __future__ import annotations

import control as ct
import numpy as np

from dfloop import exact_cycle
from dfloop.describing.dual_input import DualInputDF
from dfloop.solve.bias import predict_biased_cycles
from dfloop.solve.delay import delayed

M1, M2, K, R0 = 1.5, 0.6, 4.0, 0.4


def test_tiny_delays_tend_linearly_to_the_undelayed_orbit():
    G = ct.tf([K], [1, 3, 3, 1])
    relay = DualInputDF.piecewise_affine([0.0], [-M2, M1], [0.0, 0.0])
    (c,) = predict_biased_cycles(G, relay, r0=R0, amplitude=(0.01, 50))
    ref = exact_cycle(G, relay.describing_function, c, r0=R0)
    assert ref.success
    P = ref.period
    fractions = 10.0 ** np.arange(-9, -1)
    slopes = []
    for f in fractions:   # T = 1e-7 P used to stop Newton: the clock's rounding put a pending instant above T
        ex = exact_cycle(delayed(G, f * P), relay.describing_function, c, r0=R0, globalise=False)
        assert ex.success, (f, ex.message)
        assert ex.method.startswith("exact delay flow")
        slopes.append(((ex.frequency - ref.frequency) / (f * P), (ex.mean - ref.mean) / (f * P),
                       (ex.amplitude - ref.amplitude) / (f * P)))
    slopes = np.array(slopes)
    # from 1e-9 to 1e-6 of the period the slopes agree to 3e-4 (measured 1.1e-4: the solver's tolerance 1e-11
    # over T = 4e-9 s limits the smallest); beyond, the second order shows: the slope moves by 10x per decade of T
    # (measured ratios 10.1 and 9.0 in w from 1e-4 to 1e-2)
    first = slopes[:4].mean(axis=0)
    assert np.all(np.abs(slopes[:4] / first - 1.0) < 3e-4), slopes
    drift = np.abs(slopes[[5, 6, 7]] - first)
    ratios = drift[1:] / drift[:-1]
    assert np.all((ratios > 8.0) & (ratios < 12.0)), ratios
