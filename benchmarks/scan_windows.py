"""Regime windows the default dynamic-backlash table misses, found by a fine scan from rest.

For each eps the motion from rest is simulated (the table's own adaptive run) at a spacing of ``--dx``
(default 1e-4) in ln beta over ``--span`` ln-beta units above the no-impact limit beta = 1/4. The default
table (and, for comparison, the same table without window probes) is evaluated at every scan point; a
*miss* is a scan point where the table says valid but the scan's motion is irregular or its value is
farther from the table's than the error_estimate. Misses are grouped into contiguous runs of scan points. A regime window
of the scan is a run of equal regime labels narrower than 0.05 in ln beta with another regime on both sides.

Run:  python benchmarks/scan_windows.py [--dx 1e-4] [--span 3] [--eps 0.5 0.7 0.8 0.9] [--write]
(--write: benchmarks/results/scan_windows.md)
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from dfloop.impact.dynamic_backlash import U_START, DynamicBacklash

M1, M2, H = 1.0, 1.0, 0.1


def scan(eps: float, u: np.ndarray):
    """(D, regime label, regular) of the motion from rest at ln beta = u (similarity units, w = 1 rad/s)."""
    db = DynamicBacklash(M1, M2, H, eps, cache=False, progress=False, starts=0)
    r = db.sampler.extract(np.exp(u) * M2 * H, np.ones(u.size))        # the table's own run from rest
    label, regular, _ = db.sampler.labels(r)
    return np.nan_to_num(np.asarray(r.N, dtype=complex)) * M2, label, regular


def runs(mask: np.ndarray, u: np.ndarray, join: float) -> list[tuple[float, float]]:
    """[lo, hi] ranges of u where mask holds, points closer than ``join`` joined."""
    x = u[mask]
    if x.size == 0:
        return []
    cut = np.flatnonzero(np.diff(x) > join)
    return [(float(a), float(b)) for a, b in zip(np.r_[x[0], x[cut + 1]], np.r_[x[cut], x[-1]])]


def regime_windows(u, label, regular, width=0.05):
    key = np.where(regular, label, -1)
    cut = np.flatnonzero(np.diff(key) != 0) + 1
    starts, ends = np.r_[0, cut], np.r_[cut, key.size]
    out = []
    for j in range(1, len(starts) - 1):
        a, b = starts[j], ends[j] - 1
        if key[a] >= 0 and u[b] - u[a] < width and key[starts[j - 1]] != key[a] and key[starts[j + 1]] != key[a]:
            out.append((float(u[a]), float(u[b])))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--dx", type=float, default=1e-4)
    ap.add_argument("--span", type=float, default=3.0)
    ap.add_argument("--eps", type=float, nargs="+", default=[0.5, 0.7, 0.8, 0.9])
    ap.add_argument("--write", action="store_true")
    a = ap.parse_args()
    u = U_START + 1e-6 + np.arange(0.0, a.span, a.dx)
    lines = ["# scan_windows: regime windows the default table misses", "",
             f"Motion from rest at {u.size} points {a.dx:g} apart in ln beta, ln beta in "
             f"[{u[0]:.4f}, {u[-1]:.4f}] (M1 = M2, w = 1 rad/s similarity units). 'windows' = runs of one "
             "regime narrower than 0.05 with another regime on both sides; 'missed' = groups of scan points "
             "(contiguous runs) where the table is valid but the scan's motion is irregular or farther from the table's "
             "value than its error_estimate.", "",
             "| eps | scan (s) | windows | narrowest | table | samples | build CPU (s) | missed runs | "
             "widest missed run | missed points | first missed runs |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for eps in a.eps:
        t0 = time.perf_counter()
        D, label, regular = scan(eps, u)
        t_scan = time.perf_counter() - t0
        wins = regime_windows(u, label, regular)
        narrow = min((b - a_ + a.dx for a_, b in wins), default=math.nan)
        for name, kw in (("default", {}), ("no window probes", dict(window_dx=100.0))):
            db = DynamicBacklash(M1, M2, H, eps, cache=False, progress=False, **kw)
            c0 = time.process_time()
            t = db.similarity_table(math.exp(u[-1]))
            cpu = time.process_time() - c0
            tv = t.evaluate(u)
            miss = tv.valid & (~regular | (np.abs(tv.value - D) > tv.error))
            groups = runs(miss, u, 1.5 * a.dx)
            widest = max((hi - lo + a.dx for lo, hi in groups), default=0.0)
            rng = ", ".join(f"[{lo:.4f}, {hi:.4f}]" for lo, hi in groups[:6]) + (" ..." if len(groups) > 6 else "")
            row = (f"| {eps} | {t_scan:.0f} | {len(wins)} | {narrow:.4f} | {name} | {t.x.size} | {cpu:.2f} | "
                   f"{len(groups)} | {widest:.4f} | {int(miss.sum())} ({miss.mean():.2%}) | {rng} |")
            print(row, flush=True)
            lines.append(row)
    text = "\n".join(lines) + "\n"
    print(text)
    if a.write:
        out = Path(__file__).parent / "results" / "scan_windows.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)


if __name__ == "__main__":
    main()
