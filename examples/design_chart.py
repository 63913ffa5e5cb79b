"""Design chart: for which gains and delays does a saturating servo oscillate, and how far is the design point?

Loop: K e^{-sT} / (s (s + 1)) closed by a saturation of limit 1. The chart traces the curve where a stable limit
cycle is born from the linear loop (here K_c(T) = w sqrt(1 + w^2) with atan(w) + w T = pi/2), fills the regions,
and measures the design point (K = 1, T = 0.5 s) against it. The same chart is the shipped scene
``dfloop run saturation_delay_chart``.

Run: python examples/design_chart.py [--figure]   (a few seconds; --figure writes docs/figures/design_chart_delay.png,
otherwise the picture goes to the system's temporary directory)
"""
import argparse
import pathlib
import tempfile

import control as ct
import matplotlib

matplotlib.use("Agg")

import dfloop as df  # noqa: E402
from dfloop.chart import ChartAxis, design_chart  # noqa: E402
from dfloop.scene.plant import DelayedPlant  # noqa: E402

G1 = ct.tf([1], [1, 1, 0])


def loop(K: float, T: float):
    """The loop at gain K and delay T (s); module level, so process executors can run it."""
    return DelayedPlant(K * G1, T), df.Saturation(1.0)


def main(figure: bool) -> None:
    res = design_chart(loop, ChartAxis(0.5, 5.0, "gain K"), ChartAxis(0.1, 1.0, "delay T", "s"),
                       nominal=(1.0, 0.5), omega=(0.05, 20.0))
    print(res)
    cp = res.plot()
    cp.axes[0, 0].set_title("Saturation around K e^(-sT)/(s(s+1)): where a limit cycle exists", fontsize="medium")
    out = (pathlib.Path(__file__).parents[1] / "docs" / "figures" if figure else pathlib.Path(tempfile.gettempdir()))
    cp.figure.savefig(out / "design_chart_delay.png", dpi=110)
    print(f"figure: {out / 'design_chart_delay.png'}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--figure", action="store_true", help="write docs/figures/design_chart_delay.png")
    main(ap.parse_args().figure)
