"""Nyquist-plane loci of -1/N for describing functions (the paper's Fig. 3 for frequency-dependent N)."""
from __future__ import annotations

import numpy as np

from ..describing.base import DescribingFunction, negative_inverse
from ..describing.interop import as_element
from ._curves import add_direction_arrow, curve_with_gaps
from ._labels import axes_or_new, legend, plane_labels
from .controlplot import control_plot

__all__ = ["plot_loci", "default_amplitudes"]


def default_amplitudes(N: DescribingFunction, n: int = 300) -> np.ndarray:
    """Log-spaced amplitudes spanning an amplitude-only element's domain (lo, hi).

    (lo (1 + 1e-6), 1e3 lo) when lo > 0 and hi = inf; up to hi (1 - 1e-6) when hi is finite;
    (1e-3 hi, hi) when lo = 0; (1e-3, 1e3) when the domain is (0, inf) (pass amplitudes then).
    """
    lo, hi = (float(v) for v in N.amplitude_domain())
    if lo > 0:
        top = hi * (1 - 1e-6) if np.isfinite(hi) else 1e3 * lo
        return np.geomspace(lo * (1 + 1e-6), top, n)
    if np.isfinite(hi):
        return np.geomspace(1e-3 * hi, hi * (1 - 1e-6), n)
    return np.geomspace(1e-3, 1e3, n)


def plot_loci(N: DescribingFunction, amplitudes=None, omega=None, ax=None, **kw):
    """Draw -1/N in the complex plane (python-control's Nyquist conventions) and return what was drawn.

    Amplitude-only elements: one curve over ``amplitudes`` (default :func:`default_amplitudes`).
    Frequency-dependent elements: one curve per amplitude over ``omega`` (rad/s), both required, as in
    the paper's Fig. 3. Points where N = 0 (outside the domain, -1/N infinite) are left out, and every
    curve breaks at jumps of N (located by bisection) instead of bridging them. An arrow on each curve
    points the way of increasing amplitude (increasing frequency for the family), and the point -1
    (N = 1) is marked with a red "+".

    Parameters
    ----------
    N : DescribingFunction
    amplitudes : array_like, optional
        Input amplitudes, in ``N.input_unit``.
    omega : array_like, optional
        Frequencies (rad/s); required for frequency-dependent N.
    ax : matplotlib.axes.Axes, optional
        Axes to draw into (default: a new figure).
    **kw
        Passed to ``ax.plot`` for every curve.

    Returns
    -------
    control.ControlPlot
        ``lines``: [the -1/N curves (Line2D)], [the -1 marker]; ``axes[0, 0]``, ``figure``.
    """
    import matplotlib.pyplot as plt

    N = as_element(N)
    ax = axes_or_new(ax)
    curves = []
    if N.frequency_dependent:
        if amplitudes is None or omega is None:
            raise ValueError("amplitudes and omega are required for a frequency-dependent N")
        w = np.sort(np.asarray(omega, dtype=float).ravel())
        amps = np.atleast_1d(np.asarray(amplitudes, dtype=float))
        colors = plt.cm.viridis(np.linspace(0.0, 0.85, amps.size)) if amps.size > 1 else ["C0"]
        for A, color in zip(amps, colors):
            _, z = curve_with_gaps(lambda x, A=A: negative_inverse(N, A, x), w)
            label = f"{N.input_name} = {A:g} {N.input_unit}".rstrip()
            curves += ax.plot(z.real, z.imag, label=label, **{"color": color, **kw})
    else:
        A = default_amplitudes(N) if amplitudes is None else np.sort(np.asarray(amplitudes, dtype=float).ravel())
        _, z = curve_with_gaps(lambda a: negative_inverse(N, a), A)
        curves += ax.plot(z.real, z.imag, label=f"-1/N({N.input_name})", **kw)
    critical = ax.plot([-1.0], [0.0], "r+", ms=10, mew=1.5, label="-1 (critical point)")
    plane_labels(ax, N)
    ax.axhline(0.0, color="0.8", lw=0.5)
    ax.axvline(0.0, color="0.8", lw=0.5)
    for line in curves:
        add_direction_arrow(ax, line.get_xdata() + 1j * line.get_ydata(), line.get_color())
    return control_plot([curves, critical], ax, legend(ax))
