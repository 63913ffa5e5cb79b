"""A digital loop with a quantizer: the describing-function prediction next to the exact orbits of the map.

The loop: a continuous plant 1/(s+1)^3 behind a zero-order hold, sampled every dt = 0.2 s, a digital proportional
controller of gain 5.6 and a quantizer of step 0.05 on the controller's output (a DAC). The linear loop is stable
(|C G| = 0.90 at the phase crossover), but the quantizer's gain rises to 1.27 near one step: the DF predicts a
pair of cycles. The exact orbits of the map x[k+1] = A x[k] + B Q(-C x[k]) are found by
:func:`dfloop.exact_cycle` (which knows the loop is discrete), and for a second-order digital loop every orbit
of period <= 10 samples is enumerated by :func:`dfloop.hybrid.discrete.discrete_orbits`.

Run: python examples/digital_quantizer.py [--figure PATH]   (a few seconds; writes the figure to PATH, default
docs/figures/digital_quantizer.png)
"""
import math
import pathlib
import sys

import control as ct
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.hybrid.discrete import discrete_orbits  # noqa: E402

dt = 0.2
G = 5.6 * ct.sample_system(ct.tf([1.0], [1.0, 3.0, 3.0, 1.0]), dt, "zoh")   # C(z) G_zoh(z)
N = df.Quantizer(0.05)

cycles = df.predict_limit_cycles(G, N, amplitude=(0.026, 1.0), exact=True)
print(cycles)
for c in cycles:
    print(f"  predicted A={c.amplitude:.5g}, w={c.frequency:.5g} rad/s ({c.stability}); {c.confidence}")
    print(f"  exact: {c.exact}")

# a second-order digital loop where the enumeration is exhaustive: every orbit of period <= 10 within |x| <= 4
G2 = ct.tf([0.9, 0.3], [1.0, -0.2, 0.45], 1.0)
N2 = df.Quantizer(1.0)
orbits = discrete_orbits(G2, N2, max_period=10, bound=4.0)
print(orbits)
print(df.predict_limit_cycles(G2, N2, amplitude=(0.51, 4.0)))

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
cycles.plot(ax=ax1, inset=False)
ax1.set_title("DF prediction: G(e^{jωΔt}) and -1/N")
stable = [c for c in cycles if c.stability == "stable"][0]
ex = stable.exact
k = np.arange(3 * ex.extra["samples_per_period"])
x = np.tile(ex.x, 3)
ax2.stem(k * dt, x, linefmt="C4-", markerfmt="C4o", basefmt=" ", label=f"exact orbit ({ex.extra['samples_per_period']} "
         f"samples, A={ex.amplitude:.4g}, ω={ex.frequency:.4g} rad/s)")
t = np.linspace(0, k[-1] * dt, 2000)
phase = float(np.angle(np.fft.fft(ex.x)[ex.extra["harmonic"]])) + math.pi / 2
ax2.plot(t, stable.amplitude * np.sin(stable.frequency * t + phase), "C0--",
         label=f"DF sinusoid (A={stable.amplitude:.4g}, ω={stable.frequency:.4g} rad/s)")
for q in np.arange(-2, 3) * 0.05 + 0.025:
    ax2.axhline(q, color="0.85", lw=0.8, zorder=0)
ax2.set_xlabel("time t = k Δt [s]")
ax2.set_ylabel("quantizer input x")
ax2.set_title("stable cycle: exact samples vs the DF sinusoid")
ax2.legend(fontsize=8, loc="lower right")
fig.tight_layout()
path = pathlib.Path(sys.argv[sys.argv.index("--figure") + 1]) if "--figure" in sys.argv else \
    pathlib.Path(__file__).resolve().parents[1] / "docs" / "figures" / "digital_quantizer.png"
fig.savefig(path, dpi=110)
plt.close("all")
print("figure written to", path)
