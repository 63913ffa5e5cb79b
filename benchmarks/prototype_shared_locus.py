"""Prototype of a batch design for issue 19's last target (50 us per loop): one -1/N locus shared by the loops.

The design: for an element whose N depends on A / h only (backlash, here), the locus ln N over the normalized
log-amplitude is resolved once (the driver's ``_resolve_element``) and held as a tree of bounding rectangles of its
monotone pieces. Each loop then only resolves its G (the driver's ``_resolve_plant``) and walks the tree with each
interval of G (the disc of G's certified variation around its ends against a rectangle, as ``_no_root_in`` tests
pieces), instead of choosing its amplitude window and resolving N itself. The pieces that may hold a root are
narrowed once (the G intervals they hit quartered, each with its variation bound), grouped into clusters of
adjacent pieces, and each cluster is refined by the driver's ``refine`` from its best point.

Still missing from the prototype, and not timed: a certificate that a cluster holds exactly the roots refined in it
(windings, isolation, tangent seeds), the continuum test and the stability labels (the driver's ``_finish``: ~3 us).

Measured against the compiled driver alone (the batch floor without Python objects) on the same sampled servo
loops (examples/monte_carlo_servo.py), in the same run: CPU microseconds per loop, cumulative over the stages, and
the share of the driver's roots the prototype found (within 1e-6 relative in A and w).

Run: python benchmarks/prototype_shared_locus.py [--loops N] [--write]   (default 2000 loops; --write writes
benchmarks/results/prototype_shared_locus.md)
"""
from __future__ import annotations

import argparse
import math
import pathlib
import sys
import time

import numba
import numpy as np
from numba import njit

sys.path.insert(0, str(pathlib.Path(__file__).parent))
sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "examples"))

import dfloop as df  # noqa: E402
from bench_compiled import best  # noqa: E402
from dfloop.solve.compiled import driver as D  # noqa: E402
from dfloop.solve.compiled import driver_parts, run_batch  # noqa: E402
from dfloop.solve.compiled.kernels import element, plant, refine  # noqa: E402
from monte_carlo_servo import sample  # noqa: E402

PI = math.pi
SPLIT = 4          # pieces a hit interval of G is cut into
MAX_CAND = 4096    # candidate pieces kept per loop
STAGES = ("G resolved (the driver's _resolve_plant)", "+ the shared locus walked by G's intervals",
          "+ the hit intervals of G quartered and walked again", "+ clusters refined (the driver's refine)")


@njit
def _wrap(d):
    for _ in range(3):
        if d >= PI:
            d -= 2 * PI
        elif d < -PI:
            d += 2 * PI
    return d


@njit
def _rect_gap(r0, r1, i0, i1, t):
    """Distance from t to the rectangle [r0, r1] x [i0, i1] (imaginary part modulo 2 pi)."""
    dx = max(max(r0 - t.real, t.real - r1), 0.0)
    dd = max(abs(_wrap(t.imag - 0.5 * (i0 + i1))) - 0.5 * (i1 - i0), 0.0)
    return math.sqrt(dx * dx + dd * dd)


def locus_tree(kind, p, x):
    """The normalized locus: nodes, and the rectangles of its pieces in a complete binary tree (leaves from
    ``size``)."""
    nodes, vals, _, _, status = D._resolve_element(kind, p, x)
    if status:
        raise RuntimeError(f"the locus did not resolve (status {status})")
    ln = np.log(vals)
    m = nodes.size - 1
    size = 1 << max(m - 1, 0).bit_length()
    R0, I0 = np.full(2 * size, np.inf), np.full(2 * size, np.inf)
    R1, I1 = np.full(2 * size, -np.inf), np.full(2 * size, -np.inf)
    for i in range(m):
        l0, l1 = ln[i], ln[i + 1]
        R0[size + i], R1[size + i] = min(l0.real, l1.real), max(l0.real, l1.real)
        I0[size + i], I1[size + i] = min(l0.imag, l1.imag), max(l0.imag, l1.imag)
    for k in range(size - 1, 0, -1):
        R0[k], R1[k] = min(R0[2 * k], R0[2 * k + 1]), max(R1[2 * k], R1[2 * k + 1])
        I0[k], I1[k] = min(I0[2 * k], I0[2 * k + 1]), max(I1[2 * k], I1[2 * k + 1])
    return nodes, size, R0, R1, I0, I1


@njit
def _walk(t0, t1, e, size, R0, R1, I0, I1, margin, j, cj, cl, nc, stack):
    """Leaves of the tree within ``margin`` of both discs of radius e around t0 and t1, appended to (cj, cl)."""
    top = 1
    stack[0] = 1
    while top:
        top -= 1
        k = stack[top]
        if R0[k] == np.inf:
            continue
        if max(_rect_gap(R0[k], R1[k], I0[k], I1[k], t0), _rect_gap(R0[k], R1[k], I0[k], I1[k], t1)) - e >= margin:
            continue
        if k >= size:
            if nc < cj.size:
                cj[nc], cl[nc] = j, k - size
            nc += 1
        else:
            stack[top], stack[top + 1] = 2 * k, 2 * k + 1
            top += 2
    return nc


@njit
def _target(num, den, delay, w):
    g = plant(num, den, delay, w)
    return complex(-math.log(abs(g)), PI - math.atan2(g.imag, g.real))


@njit
def one_loop(num, den, zeros, poles, delay, kind, p, ln_h, nw, nodes, size, R0, R1, I0, I1, margin, stage):
    """(nodes or pieces, candidates or clusters, roots a, roots v, ok) of one loop up to ``stage`` (1-4)."""
    none = np.empty(0)
    lo, hi = np.inf, 0.0
    for r in (zeros, poles):
        for x in r:
            if abs(x) > 0:
                lo, hi = min(lo, abs(x)), max(hi, abs(x))
    v = D._linspace(math.log(lo * 0.01), math.log(hi * 100), nw)
    v, wn, eps_v, _ = D._resolve_plant(zeros, poles, delay, v)
    nv = v.size
    t = np.empty(nv, np.complex128)
    for j in range(nv):
        t[j] = _target(num, den, delay, wn[j])
    if stage == 1:
        return nv, 0, none, none, np.zeros(0, np.bool_)
    cj, cl = np.empty(MAX_CAND, np.int64), np.empty(MAX_CAND, np.int64)
    stack = np.empty(128, np.int64)
    nc = 0
    for j in range(nv - 1):
        nc = _walk(t[j], t[j + 1], eps_v[j], size, R0, R1, I0, I1, margin, j, cj, cl, nc, stack)
    if stage == 2:
        return nv, nc, none, none, np.zeros(0, np.bool_)
    nc = min(nc, MAX_CAND)
    hit = np.zeros(nv, np.bool_)
    for c in range(nc):
        hit[cj[c]] = True
    nsub = 0
    for j in range(nv - 1):
        nsub += SPLIT if hit[j] else 0
    sv0, sv1 = np.empty(nsub), np.empty(nsub)
    q = nc = 0
    for j in range(nv - 1):
        if not hit[j]:
            continue
        prev = t[j]
        for s in range(SPLIT):
            x0 = v[j] + (v[j + 1] - v[j]) * s / SPLIT
            x1 = v[j + 1] if s == SPLIT - 1 else v[j] + (v[j + 1] - v[j]) * (s + 1) / SPLIT
            nxt = t[j + 1] if s == SPLIT - 1 else _target(num, den, delay, math.exp(x1))
            e = D._variation_bound(zeros, poles, delay, math.exp(x0), math.exp(x1))
            sv0[q], sv1[q] = x0, x1
            nc = _walk(prev, nxt, e, size, R0, R1, I0, I1, margin, q, cj, cl, nc, stack)
            prev = nxt
            q += 1
    nc = min(nc, MAX_CAND)
    if stage == 3:
        return nsub, nc, none, none, np.zeros(0, np.bool_)
    comp = np.arange(nc)  # clusters: pieces adjacent along the locus and along G (touching pieces of G)
    for c in range(nc):
        for d in range(c):
            jc, jd = cj[c], cj[d]
            near_g = jc == jd or (abs(jc - jd) == 1 and sv0[max(jc, jd)] == sv1[min(jc, jd)])
            if near_g and abs(cl[c] - cl[d]) <= 1:
                x, y = c, d
                while comp[x] != x:
                    x = comp[x]
                while comp[y] != y:
                    y = comp[y]
                if x != y:
                    comp[max(x, y)] = min(x, y)
    for c in range(nc):
        x = c
        while comp[x] != x:
            x = comp[x]
        comp[c] = x
    heads = np.unique(comp)
    nr = heads.size
    sa, sv, lowest = np.empty(nr), np.empty(nr), np.full(nr, np.inf)
    la, lv = np.full(nr, np.inf), np.full(nr, np.inf)
    ha, hv = np.full(nr, -np.inf), np.full(nr, -np.inf)
    for c in range(nc):
        r = np.searchsorted(heads, comp[c])
        i, j = cl[c], cj[c]
        a0, a1 = nodes[i] + ln_h, nodes[i + 1] + ln_h
        la[r], ha[r] = min(la[r], a0), max(ha[r], a1)
        lv[r], hv[r] = min(lv[r], sv0[j]), max(hv[r], sv1[j])
        am, vm = 0.5 * (a0 + a1), 0.5 * (sv0[j] + sv1[j])
        P = element(kind, p, math.exp(am)) * plant(num, den, delay, math.exp(vm))
        m = abs(1 + P) / (1 + abs(P))
        if m < lowest[r]:
            lowest[r], sa[r], sv[r] = m, am, vm
    ra, rv, ok, _, _ = refine(num, den, zeros, poles, delay, kind, p, -np.inf, np.inf, sa, sv, la, ha, lv, hv,
                              1e-10, False)
    return nsub, nr, ra, rv, ok


@njit
def _run(nums, dens, zs, ps, dls, kind, pp, lnh, nw, nodes, size, R0, R1, I0, I1, margin, stage):
    a = b = 0
    for k in range(len(nums)):
        x, y, _, _, _ = one_loop(nums[k], dens[k], zs[k], ps[k], dls[k], kind, pp[k], lnh[k], nw, nodes, size, R0,
                                 R1, I0, I1, margin, stage)
        a, b = a + x, b + y
    return a, b


def main() -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loops", type=int, default=2000)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    n, nw = args.loops, 32
    loops = [(G, df.as_element(N)) for G, N in sample(n, 1)]
    parts = [driver_parts(G, N) for G, N in loops]
    kind = parts[0][1][0]
    if any(e[0] != kind for _, e in parts):
        raise RuntimeError("the sampled loops do not share one element kind")
    L = numba.typed.List
    nums, dens, zs, ps = (L([g[q] for g, _ in parts]) for q in range(4))
    dls = np.array([g[4] for g, _ in parts])
    pp = L([e[1] for _, e in parts])
    hs, ks = np.array([e[1][0] for _, e in parts]), np.unique([e[1][1] for _, e in parts])
    if ks.size != 1:
        raise RuntimeError("the sampled loops do not share one backlash slope")
    t0 = time.process_time()
    x = np.linspace(math.log(0.5 * (1 + 1e-9)), math.log(1e6), 64)
    tree = locus_tree(kind, np.array([1.0, ks[0], 0.5]), x)
    t_tree = time.process_time() - t0
    lnh = np.log(hs)
    margin = D.CONSTANTS["SEED_MARGIN"]
    windows = [(np.nan,) * 4] * n
    drive = lambda: run_batch(parts, windows, 8, nw, 1e-10, 1e-4)  # noqa: E731
    drive()
    t_driver = best(drive, 5)[0]
    rows = [f"| the compiled driver alone, grid (8, {nw}) | {t_driver / n * 1e6:.1f} | 1.00 | |"]
    for stage in (1, 2, 3, 4):
        run = lambda: _run(nums, dens, zs, ps, dls, kind, pp, lnh, nw, *tree, margin, stage)  # noqa: E731
        counts = run()
        t = best(run, 5)[0]
        what = (f"{counts[0] / n:.0f} nodes of G" if stage < 3 else f"{counts[0] / n:.0f} pieces of G") + \
               (f", {counts[1] / n:.1f} candidate pieces" if stage in (2, 3) else "") + \
               (f", {counts[1] / n:.1f} clusters" if stage == 4 else "")
        rows.append(f"| {STAGES[stage - 1]} | {t / n * 1e6:.1f} | {t / t_driver:.2f} | {what} |")
    found = total = 0
    for k, (G, N) in enumerate(loops[:300]):
        cycles = df.predict_limit_cycles(G, N, grid=(8, nw))
        _, _, ra, rv, ok = one_loop(nums[k], dens[k], zs[k], ps[k], dls[k], kind, pp[k], lnh[k], nw, *tree, margin, 4)
        got = [(math.exp(a), math.exp(b)) for a, b, o in zip(ra, rv, ok) if o]
        for c in cycles:
            total += 1
            found += any(abs(A - c.amplitude) <= 1e-6 * c.amplitude and abs(w - c.frequency) <= 1e-6 * c.frequency
                         for A, w in got)
    text = "\n".join([
        f"{n} sampled servo loops (examples/monte_carlo_servo.py, backlash), CPU us per loop, cumulative; "
        f"the shared locus built once in {t_tree * 1e3:.1f} ms.", "",
        "| stage | us per loop | / driver | work per loop |", "|---|---|---|---|", *rows, "",
        f"Roots: the prototype found {found} of the driver's {total} roots on the first 300 loops "
        "(no certificate that it found all of them: that stage is not built)."])
    print(text)
    if args.write:
        out = pathlib.Path(__file__).parent / "results" / "prototype_shared_locus.md"
        out.write_text("# Prototype: one shared -1/N locus for a batch (issue 19)\n\nCommand: "
                       f"`python benchmarks/prototype_shared_locus.py --loops {n} --write` (CPU times, best of 5, "
                       "one process on a machine shared with other jobs)\n\n" + text + "\n")
    return text


if __name__ == "__main__":
    main()
