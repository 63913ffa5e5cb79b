"""Quickstart: predict, read and check the limit cycles of a loop with backlash.

Run: python examples/quickstart.py   (a few seconds; writes dfloop_quickstart_nyquist.png and
dfloop_quickstart_residual.png to the system's temporary directory)
"""
import pathlib
import tempfile

import control as ct
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.plot import plot_residual_map

# plant G(s) = 1.5 / (s (s + 1)^2) and a backlash of total clearance h = 0.2 in the loop of Fig. 1
G = ct.tf([1.5], [1, 2, 1, 0])
N = df.Backlash(h=0.2)

cycles = df.predict_limit_cycles(G, N)  # windows chosen from the plant and the element
print(cycles)

for c in cycles:  # closed-loop time simulation from inside and outside each predicted cycle
    print(df.verify_cycle(G, N, c, perturbation=0.5, steps_per_period=200))

out = pathlib.Path(tempfile.gettempdir())
cplt = cycles.plot()  # a control.ControlPlot: .lines, .axes, .figure (same as df.plot_nyquist(cycles))
cplt.figure.savefig(out / "dfloop_quickstart_nyquist.png", dpi=120)
cplt = plot_residual_map(cycles)
cplt.figure.savefig(out / "dfloop_quickstart_residual.png", dpi=120)
plt.close("all")
print("figures written to", out)
