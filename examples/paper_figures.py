"""The paper's Figs. 5-9 computed from the model (exact impact kernel -> adaptive, cached DF tables), and the
gallery of every paper figure as a scene (``models/paper_fig*.toml``: Figs. 3, 5-14).

M1 = M2 = 1 kg, h = 0.1 m, F = 10..50 N, eps = 0.1..0.9, w = 1..100 rad/s. Writes fig5.png ... fig9.png
and limits.md (measured limit frequencies next to eqs. 10-12) into the output directory (default ``out/``). Points where the motion is irregular (chaotic: the DF is an
average) are drawn as faint dots, regular (periodic) ones as lines; the static backlash of Fig. 2
(``MassBacklash``) is drawn for comparison in Figs. 7-8. Log-log panels plot |Re{-1/N}| and |Im{-1/N}|
with slopes (dB/dec) fitted on the regular part of the low-frequency band.

The gallery runs each ``paper_fig*`` scene (``dfloop run paper_figN``) and copies its figure to
``<out_dir>/paper_figN.png``. ``--no-gallery`` skips it (the table timing alone).

Run:  python examples/paper_figures.py [out_dir] [--no-gallery]
"""
from __future__ import annotations

import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dfloop.describing.composition import MassBacklash  # noqa: E402
from dfloop.impact.dynamic_backlash import DynamicBacklash, prepare_many  # noqa: E402
from dfloop.impact.limits import (jump_frequency, lower_limit_frequency, measured_limits,  # noqa: E402
                                  no_impact_frequency)
from dfloop.plot import case_labels, curve_with_gaps  # noqa: E402

M1, M2, H = 1.0, 1.0, 0.1
FORCES = (10.0, 20.0, 30.0, 40.0, 50.0)
EPS_ALL = tuple(round(0.1 * k, 1) for k in range(1, 10))
W = np.exp(np.linspace(0.0, math.log(100.0), 3000))


def curve(nl, F):
    """w, -1/N and validity along W for force F (w < w_L only: N = 0 above), NaN-separated at the jumps
    of N (located by bisection: the jump at w_J is a gap, not a line).

    Invalid points far outside the range of the valid ones (the grazing band just below w_L, where
    N -> 0 and the motion has not settled) are set to NaN (a gap: no line joins their neighbours) so that
    they do not set the axes.
    """
    w, z = curve_with_gaps(lambda x: nl.negative_inverse(F, x), W[W < no_impact_frequency(F, M2, H) * (1 - 1e-9)])
    ok = np.zeros(w.size, bool)
    ok[np.isfinite(w)] = nl.validity(F, w[np.isfinite(w)])
    far = ~ok & (np.abs(z) > 2 * np.abs(z[ok]).max())
    return w, np.where(far, complex(np.nan, np.nan), z), ok


def draw_nyquist(ax, w, z, ok, color, label):
    zr = np.where(ok, z, np.nan)
    ax.plot(zr.real, zr.imag, color=color, lw=1.0, label=label)
    ax.plot(z.real[~ok], z.imag[~ok], ".", color=color, ms=1.0, alpha=0.3)


def fig_nyquist(tables, cases, title, path):
    fig, ax = plt.subplots(figsize=(7, 6))
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(cases)))
    labels, common = case_labels([{"eps": f"{eps:g}", "F": f"{F:g} N"} for eps, F in cases])
    for (eps, F), color, label in zip(cases, colors, labels):
        w, z, ok = curve(tables[eps], F)
        draw_nyquist(ax, w, z, ok, color, label)
    ax.set_xlabel("Re{-1/N} [N/m]")
    ax.set_ylabel("Im{-1/N} [N/m]")
    ax.set_title(title)
    ax.legend(fontsize=7, title=common or None, title_fontsize=7)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def fitted_slope(w, y, ok, w_hi):
    """Slope of log10|y| vs log10 w (x 20: dB/dec) on the regular points with w < w_hi."""
    m = ok & (w < w_hi) & (np.abs(y) > 0)
    if np.count_nonzero(m) < 5:
        return math.nan
    return 20 * np.polyfit(np.log10(w[m]), np.log10(np.abs(y[m])), 1)[0]


def fig_loglog(tables, cases, title, path, static_forces):
    fig, (ax_re, ax_im) = plt.subplots(1, 2, figsize=(12, 5))
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(cases)))
    labels, common = case_labels([{"eps": f"{eps:g}", "F": f"{F:g} N"} for eps, F in cases])
    for (eps, F), color, label in zip(cases, colors, labels):
        w, z, ok = curve(tables[eps], F)
        w_lo = 2.0 * lower_limit_frequency(F, M2, H, eps)      # low-frequency band: below 2 w_c
        for ax, y in ((ax_re, z.real), (ax_im, z.imag)):
            s = fitted_slope(w, y, ok, max(w_lo, w[0] * 3))
            ax.loglog(w, np.where(ok, np.abs(y), np.nan), color=color, lw=1.0, label=f"{label}: {s:.0f} dB/dec")
            print(f"{path.name}: eps={eps:g} F={F:g} {'Re' if ax is ax_re else 'Im'}{{-1/N}} low-frequency "
                  f"slope {s:.1f} dB/dec")
            ax.loglog(w[~ok], np.abs(y[~ok]), ".", color=color, ms=1.0, alpha=0.3)
    static = MassBacklash(M1, M2, H)
    for F in static_forces:
        w = W[W < static.limit_frequency(F) * (1 - 1e-9)]
        z = -1.0 / static(F, w)
        for ax, y in ((ax_re, z.real), (ax_im, z.imag)):
            s = fitted_slope(w, y, np.ones(w.size, bool), w[0] * 5)
            ax.loglog(w, np.abs(y), "k--", lw=0.8, label=f"static (Fig. 2), F={F:g} N: {s:.0f} dB/dec")
            print(f"{path.name}: static F={F:g} {'Re' if ax is ax_re else 'Im'}{{-1/N}} low-frequency "
                  f"slope {s:.1f} dB/dec")
    for ax, name in ((ax_re, "|Re{-1/N}|"), (ax_im, "|Im{-1/N}|")):
        ax.set_xlabel("Frequency [rad/s]")
        ax.set_ylabel(name + " [N/m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, title=common or None, title_fontsize=6)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def fig_collisions(tables, F, path):
    """n_A (longest run of consecutive impacts on side A) vs w and eps, from the table samples."""
    fig, ax = plt.subplots(figsize=(8, 5))
    w_span = [np.inf, -np.inf]
    for eps, nl in tables.items():
        t = nl.similarity_table(F / (M2 * H * W[0] ** 2))
        w = np.sqrt(F / (M2 * H * np.exp(t.x)))
        order = np.argsort(w)
        sc = ax.scatter(w[order], np.full(w.size, eps), c=t.extra["n_A"][order], s=6, cmap="plasma",
                        vmin=0, vmax=10, marker="s")
        w_span = [min(w_span[0], w.min()), max(w_span[1], w.max())]
    fig.colorbar(sc, ax=ax, label="n_A (clipped at 10)")
    ax.set_xscale("log")
    ax.set_xlim(w_span[0] / 1.05, w_span[1] * 1.05)  # the data's range: no impacts (no data) above w_L
    ax.set_xlabel("Frequency [rad/s]")
    ax.set_ylabel("restitution eps")
    ax.set_title(f"Fig. 9: consecutive collisions on side A, F = {F:g} N")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def limits_table(tables, F, path):
    """Measured limit frequencies (from the model) next to the paper's eqs. (10)-(12), as markdown."""
    lines = [f"| eps | w_L measured | eq. (11) | w_J measured | eq. (12) | w_c measured | eq. (10) |",
             "|---|---|---|---|---|---|---|"]
    for eps, nl in tables.items():
        m = measured_limits(nl, beta_max=F / (M2 * H * W[0] ** 2)).omegas(F, M2, H)
        lines.append(f"| {eps:g} | {m['omega_L']:.2f} | {float(no_impact_frequency(F, M2, H)):.2f} | "
                     f"{m['omega_J']:.2f} | {float(jump_frequency(F, M2, H)):.2f} | {m['omega_c']:.2f} | "
                     f"{float(lower_limit_frequency(F, M2, H, eps)):.2f} |")
    text = f"Limit frequencies (rad/s), F = {F:g} N, M1 = M2 = {M1:g} kg, h = {H:g} m\n\n" + "\n".join(lines) + "\n"
    path.write_text(text)
    print(text)


def scene_gallery(out: Path) -> list[Path]:
    """Run every shipped ``paper_fig*`` scene and copy its figure to ``out/<scene>.png``."""
    from dfloop.progress import progress_bar
    from dfloop.scene import load_scene, run_scene, shipped_scenes

    names = sorted((n for n in shipped_scenes() if n.startswith("paper_fig")),
                   key=lambda n: int(n.removeprefix("paper_fig")))
    written = []
    with tempfile.TemporaryDirectory() as tmp, progress_bar("paper scenes", len(names)) as bar:
        for name in names:
            report = run_scene(load_scene(name), tmp, log=lambda line: None, progress=False)
            figure = next(p for p in report.files if p.name == f"{name}_figure.png")
            written.append(Path(shutil.copy(figure, out / f"{name}.png")))
            bar.update(stage=name)
    return written


def main(out: Path, gallery: bool = True) -> None:
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    tables = {eps: DynamicBacklash(M1, M2, H, eps, progress=True) for eps in EPS_ALL}
    print(f"building / loading {len(tables)} tables (eps = {EPS_ALL}) ...", file=sys.stderr)
    prepare_many(tables.values(), (min(FORCES), max(FORCES)), (W[0], W[-1]))
    sims = sum(nl.n_simulations for nl in tables.values())
    print(f"tables ready in {time.perf_counter() - t0:.1f} s ({sims} simulations)", file=sys.stderr)
    fig_nyquist(tables, [(e, 50.0) for e in EPS_ALL], "Fig. 5: -1/N, F = 50 N, eps = 0.1..0.9", out / "fig5.png")
    fig_nyquist(tables, [(e, F) for e in (0.2, 0.5, 0.8) for F in FORCES],
                "Fig. 6: -1/N, F = 10..50 N, eps = 0.2, 0.5, 0.8", out / "fig6.png")
    fig_loglog(tables, [(0.5, F) for F in FORCES], "Fig. 7: eps = 0.5, F = 10..50 N", out / "fig7.png", (10.0, 50.0))
    fig_loglog(tables, [(e, 50.0) for e in (0.1, 0.3, 0.5, 0.7, 0.9)], "Fig. 8: F = 50 N, eps = 0.1..0.9",
               out / "fig8.png", (50.0,))
    fig_collisions(tables, 50.0, out / "fig9.png")
    limits_table(tables, 50.0, out / "limits.md")
    print(f"wrote fig5.png .. fig9.png to {out} in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    if gallery:
        files = scene_gallery(out)
        print(f"wrote {', '.join(p.name for p in files)} to {out} in {time.perf_counter() - t0:.1f} s",
              file=sys.stderr)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--no-gallery"]
    main(Path(args[0]) if args else Path("out"), gallery="--no-gallery" not in sys.argv[1:])
