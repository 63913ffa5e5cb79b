"""Regime maps of the paper's two-mass impact system beyond its Fig. 9: what the motion is over (w, eps) and over
(w, M1/M2).

Every point is a direct simulation from rest with the exact kernel (:func:`dfloop.impact.extract.
impact_describing_function`), classified from the extraction's own regime information: the detected period
(period-k motion, or irregular when no period up to 12 is found), the impacts per period and the runs of
consecutive impacts on one side, and the stuck fraction (the masses moving as one body). The transient adapts:
a point found irregular after ``TRANSIENT`` periods is simulated again with ``LONG_TRANSIENT`` periods (slowly
converging periodic motions near w_J otherwise pass for irregular) and keeps the second answer.

Coexisting attractors (different motions from different initial states at the same (F, w)) are *not* mapped:
the kernel on this base simulates from rest only (``dfloop.impact.kernel.simulate`` has no initial-state
argument), so every point is the motion reached from rest.

Maps (PNG in the output directory, default docs/figures/):
- ``regime_map_eps.png``: F = 50 N, M1 = M2 = 1 kg, h = 0.1 m, w in [3, 46] rad/s, eps = 0.05..0.95;
- ``regime_map_mass_ratio.png``: eps = 0.5, M1/M2 = 0.1..10, on the similarity axis w / sqrt(F/(M2 h)) (so it
  holds for every F, M2 and h: beta = F/(M2 h w^2) = 1/(that axis)^2).
Each map has a second panel with the stuck fraction. Also writes ``regime_maps.md`` (the counts per class).

Run:  python examples/regime_maps.py [out_dir]      (about a minute on two cores)
"""
from __future__ import annotations

import math
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from dfloop.impact.extract import impact_describing_function  # noqa: E402
from dfloop.impact.limits import lower_limit_frequency  # noqa: E402
from dfloop.progress import progress_bar  # noqa: E402

F, M1, M2, H = 50.0, 1.0, 1.0, 0.1
TRANSIENT, LONG_TRANSIENT, PERIODS = 200, 1000, 40
W = np.linspace(3.0, 46.0, 240)
EPS = np.round(np.arange(0.05, 0.951, 0.05), 2)
RATIOS = np.geomspace(0.1, 10.0, 13)
EPS_RATIO_MAP = 0.5

# classes (codes, names, colours): the legend of both maps
CLASSES = [("no impact", "#ffffff"), ("period 1, one impact per side", "#1b9e77"),
           ("period 1, more impacts", "#66c2a5"), ("period 2", "#7570b3"), ("period 3", "#e7298a"),
           ("period 4-12", "#e6ab02"), ("irregular (no period <= 12)", "#d95f02")]
NO_IMPACT, P1_ALTERNATE, P1_MORE, P2, P3, P4_PLUS, IRREGULAR = range(len(CLASSES))


def classify(df) -> int:
    """Class code of one :class:`dfloop.impact.extract.ImpactDF`."""
    if df.n_impacts == 0:
        return NO_IMPACT
    if df.period == 0:
        return IRREGULAR
    if df.period == 1:
        return P1_ALTERNATE if df.max_run_A == 1 and df.max_run_B == 1 and df.impacts_per_period == 2 else P1_MORE
    return {2: P2, 3: P3}.get(df.period, P4_PLUS)


def simulate_point(m1: float, eps: float, beta: float):
    """The motion from rest at similarity parameter beta (m2 = h = w = 1, force = beta), adaptive transient.

    Returns (class code, stuck fraction, period, transient periods used, |X1| / h).
    """
    df = impact_describing_function(m1, 1.0, 1.0, eps, beta, 1.0, transient_periods=TRANSIENT, periods=PERIODS)
    used = TRANSIENT
    if df.n_impacts > 0 and df.period == 0:
        df = impact_describing_function(m1, 1.0, 1.0, eps, beta, 1.0, transient_periods=LONG_TRANSIENT,
                                        periods=PERIODS)
        used = LONG_TRANSIENT
    return classify(df), df.stuck_fraction, df.period, used, abs(df.X1)


def scan(points: list[tuple[float, float, float]], label: str, workers: int = 2) -> np.ndarray:
    """:func:`simulate_point` over (m1/m2, eps, beta) triples, in threads (the kernel releases the GIL).

    Returns an array (n, 5): class, stuck fraction, period, transient used, |X1| / h.
    """
    out = np.empty((len(points), 5))
    with progress_bar(label, len(points)) as bar, ThreadPoolExecutor(max_workers=workers) as pool:
        for i, row in enumerate(pool.map(lambda p: simulate_point(*p), points)):
            out[i] = row
            bar.update()
    return out


def _draw(ax_c, ax_s, x, y, classes, second, xlabel, ylabel, title, amplitude=False):
    """Classes on ax_c; on ax_s the stuck fraction, or (amplitude=True) |X1|/h on a log scale."""
    cmap = ListedColormap([c for _, c in CLASSES])
    norm = BoundaryNorm(np.arange(len(CLASSES) + 1) - 0.5, len(CLASSES))
    ax_c.pcolormesh(x, y, classes, cmap=cmap, norm=norm, shading="nearest")
    ax_c.set_title(title, fontsize=9)
    if amplitude:
        mesh = ax_s.pcolormesh(x, y, second, cmap="magma", norm=LogNorm(), shading="nearest")
        ax_s.set_title("amplitude of x1's fundamental, |X1| / h", fontsize=9)
        plt.colorbar(mesh, ax=ax_s, label="|X1| / h")
    else:
        mesh = ax_s.pcolormesh(x, y, second, cmap="Greys", vmin=0, vmax=1, shading="nearest")
        ax_s.set_title("fraction of the time stuck (masses moving as one body)", fontsize=9)
        plt.colorbar(mesh, ax=ax_s, label="stuck fraction")
    for ax in (ax_c, ax_s):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
    ax_c.legend(handles=[Patch(facecolor=c, edgecolor="0.5", label=n) for n, c in CLASSES], fontsize=7,
                loc="upper left", bbox_to_anchor=(0.0, -0.14), ncol=3, frameon=False)


def eps_map(out: Path) -> dict:
    beta = F / (M2 * H * W ** 2)
    points = [(M1 / M2, float(e), float(b)) for e in EPS for b in beta]
    res = scan(points, f"regime map over (w, eps): {len(points)} motions").reshape(EPS.size, W.size, 5)
    fig, (ax_c, ax_s) = plt.subplots(1, 2, figsize=(13, 5.6))
    _draw(ax_c, ax_s, W, EPS, res[..., 0], res[..., 1], "omega (rad/s)", "restitution eps",
          f"motion from rest, F = {F:g} N, M1 = M2 = {M1:g} kg, h = {H:g} m")
    e = np.linspace(0.0, 0.95, 100)
    for ax in (ax_c, ax_s):
        ax.plot([float(lower_limit_frequency(F, M2, H, v)) for v in e], e, "k--", lw=1.0)
        ax.axvline(math.sqrt(F / (M2 * H)), color="k", ls=":", lw=1.0)
        ax.axvline(2 * math.sqrt(F / (M2 * H)), color="k", ls="-.", lw=1.0)
        ax.set_xlim(W[0], W[-1])
        ax.set_ylim(EPS[0] - 0.025, EPS[-1] + 0.025)
    ax_c.text(0.99, 0.02, "--  w_c, eq. (10)\n:   w_J, eq. (12)\n-.  w_L, eq. (11)", transform=ax_c.transAxes,
              ha="right", va="bottom", fontsize=7, bbox=dict(facecolor="white", alpha=0.8, edgecolor="0.7"))
    fig.tight_layout()
    fig.savefig(out / "regime_map_eps.png", dpi=130)
    plt.close(fig)
    return {"eps": res}


def ratio_map(out: Path) -> dict:
    x = W / math.sqrt(F / (M2 * H))  # w / sqrt(F/(M2 h)), the eps map's grid for F = 50 N
    beta = 1.0 / x ** 2
    points = [(float(r), EPS_RATIO_MAP, float(b)) for r in RATIOS for b in beta]
    res = scan(points, f"regime map over (w, M1/M2): {len(points)} motions").reshape(RATIOS.size, x.size, 5)
    fig, (ax_c, ax_s) = plt.subplots(1, 2, figsize=(13, 5.6))
    _draw(ax_c, ax_s, x, RATIOS, res[..., 0], res[..., 4], "w / sqrt(F / (M2 h))  (= 1 / sqrt(beta))",
          "mass ratio M1 / M2", f"motion from rest, eps = {EPS_RATIO_MAP:g}, any F, M2, h (similarity law)",
          amplitude=True)
    for ax in (ax_c, ax_s):
        ax.set_yscale("log")
        ax.axvline(1.0, color="k", ls=":", lw=1.0)
        ax.axvline(2.0, color="k", ls="-.", lw=1.0)
    ax_c.text(0.99, 0.02, ":   w_J, eq. (12)\n-.  w_L, eq. (11)", transform=ax_c.transAxes, ha="right",
              va="bottom", fontsize=7, bbox=dict(facecolor="white", alpha=0.8, edgecolor="0.7"))
    fig.tight_layout()
    fig.savefig(out / "regime_map_mass_ratio.png", dpi=130)
    plt.close(fig)
    return {"ratio": res}


def summary(maps: dict, path: Path) -> str:
    lines = ["Regime maps (`python examples/regime_maps.py`): number of grid points per class, motion from rest.",
             "", "| map | points | " + " | ".join(n for n, _ in CLASSES) + " | stuck > 0 | long transient |",
             "|---|---|" + "---|" * (len(CLASSES) + 2)]
    for name, res in maps.items():
        cls = res[..., 0].ravel()
        counts = " | ".join(str(int(np.count_nonzero(cls == k))) for k in range(len(CLASSES)))
        lines.append(f"| {name} | {cls.size} | {counts} | {int(np.count_nonzero(res[..., 1] > 0))} | "
                     f"{int(np.count_nonzero(res[..., 3] == LONG_TRANSIENT))} |")
    ratio = maps["(w, M1/M2), eps = 0.5"]
    same = int(np.count_nonzero(np.all(ratio[..., 0] == ratio[:1, :, 0], axis=0)))
    lines += ["", f"Mass ratio: the class is the same for all {RATIOS.size} ratios at {same} of {ratio.shape[1]} "
              "frequencies. Expected at all of them: between impacts the gap obeys g'' = F cos(w t)/M2 (M1 is "
              "free), an impact sets g' -> -eps g' (eq. 6), and a stuck pair separates when cos(w t) changes "
              "sign, whatever M1; only x1 (hence N) depends on M1/M2."]
    text = "\n".join(lines) + "\n"
    path.write_text(text)
    return text


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    maps = {"(w, eps), F = 50 N": eps_map(out)["eps"], "(w, M1/M2), eps = 0.5": ratio_map(out)["ratio"]}
    print(summary(maps, out / "regime_maps.md"))
    print(f"wrote regime_map_eps.png, regime_map_mass_ratio.png, regime_maps.md to {out} in "
          f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/figures"))
