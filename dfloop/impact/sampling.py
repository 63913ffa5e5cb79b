"""The exact runs behind a :class:`dfloop.impact.DynamicBacklash` table: what one table sample is.

:class:`ImpactSampler` turns table coordinates into :class:`dfloop.tables.Samples` of the dimensionless
D = N M2 w^2: it runs the impact simulations (:func:`dfloop.impact.extract.impact_describing_function_batch`)
from rest and from the alternative starts, labels each motion's regime (period, impacts per cycle, sticking),
measures how far coexisting periodic motions lie (branch spread), and provides the two block-local hooks of
:meth:`dfloop.tables.Table1D.extend`: window probes (is the motion between two samples still the same one?)
and branch continuation (follow a coexisting motion to the neighbouring samples). The table package knows
nothing of this physics; the element (:mod:`dfloop.impact.dynamic_backlash`) knows nothing of how samples are
run.

Coordinates: the 1-D (similarity-law) table is in u = ln beta, beta = F/(M2 h w^2), and its runs are made at
w = ``OMEGA_REF``; the 2-D table (effects) is in (u, v = ln w).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..tables import Samples
from ._core import FREE
from .extract import PERIODICITY_TOL, impact_describing_function_batch
from .kernel import simulate
from .model import run_periods

__all__ = ["ImpactSampler", "STARTS", "FAILED", "OMEGA_REF", "regime_label", "matched_orbits"]

OMEGA_REF = 1.0                                # frequency of the similarity-table simulations (rad/s)
REGIME_BASE = 1000                             # label = (period * BASE + impacts per cycle) * BASE + sticking
FAILED = -2                                    # regime label of a sample whose simulation failed
BRANCH_REL = 1e-4                              # relative difference of D that makes another start a new branch
# alternative starts probed for coexisting motions, in similarity units (h = 1, w = 1, force beta):
# (gap / h, u / (beta h w)) with x1 = v1 = 0; rest with a centred gap is the default start
STARTS = ((0.1, 1.5), (0.9, -1.5), (0.5, 3.0), (0.3, -0.75))


def regime_label(period, impacts, sticking) -> np.ndarray:
    """Integer regime label of samples: (period * BASE + impacts per cycle) * BASE + sticking (0/1)."""
    return (np.asarray(period, dtype=np.int64) * REGIME_BASE + np.asarray(impacts, dtype=np.int64)) * REGIME_BASE \
        + np.asarray(sticking, dtype=np.int64)


def matched_orbits(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """Orbit ``b``'s rows reordered to match orbit ``a``'s (rows gap / h, u / v_scale, mode: p points, then
    their p mirror points): the cyclic shift with the same modes and the smallest distance. None when the
    orbits cannot be matched (different periods or modes)."""
    if a.shape != b.shape or a.shape[0] == 0:
        return None
    p = a.shape[0] // 2
    best, out = math.inf, None
    for s in range(p):
        idx = np.r_[(np.arange(p) + s) % p, p + (np.arange(p) + s) % p]
        if np.array_equal(a[:, 2], b[idx, 2]):
            d = float(np.max(np.abs(a[:, :2] - b[idx, :2])))
            if d < best:
                best, out = d, b[idx]
    return out


class ImpactSampler:
    """Table samples of the two-mass impact system: D = N M2 w^2 with regime labels, spreads and uncertainties.

    Parameters
    ----------
    m1, m2, h, restitution : float
        Masses (kg), clearance (m), coefficient of restitution (validated by the element).
    effects : tuple
        Effect objects (:mod:`dfloop.impact.effects`).
    transient_periods, max_transient_periods, periods, max_events :
        Run settings, as in :class:`dfloop.impact.DynamicBacklash`.
    starts : int
        Alternative starts (of :data:`STARTS`) probed at every sample of the paper's model.

    Attributes
    ----------
    tick : callable or None
        Called once per simulation (progress); set by the table build.
    orbits, other : dict
        Orbits from rest and of another periodic motion found, by u = ln beta, of the current 1-D build (read by
        the window probes and the branch continuation); :meth:`reset` clears them.
    probe_runs : list of (u, periods) arrays
        Every window probe run so far (ln beta, forcing periods simulated): the probes' share of the
        simulation work (benchmarks/bench_tables.py).
    """

    def __init__(self, m1: float, m2: float, h: float, restitution: float, effects: tuple = (), *,
                 transient_periods: int | None = None, max_transient_periods: int = 4000, periods: int = 20,
                 max_events: int | None = None, starts: int = 2):
        self.m1, self.m2, self.h, self.restitution = m1, m2, h, restitution
        transient = max_transient_periods if transient_periods is None else transient_periods
        run_periods(f"{'max_' if transient_periods is None else ''}transient_periods + periods", transient + periods)
        self.effects = tuple(effects)
        self.transient_periods, self.max_transient_periods = transient_periods, max_transient_periods
        self.periods, self.max_events, self.starts = periods, max_events, starts
        self.tick: Callable[[], None] | None = None
        self.orbits: dict[float, np.ndarray] = {}
        self.other: dict[float, np.ndarray] = {}
        self._last_orbits = np.empty(0, dtype=object)
        self._last_other = np.empty(0, dtype=object)
        self.probe_runs: list[tuple[np.ndarray, np.ndarray]] = []

    def reset(self) -> None:
        """Forget the orbits of the last 1-D build (window probes and continuation are block-local)."""
        self.orbits, self.other = {}, {}

    def extract(self, force: np.ndarray, omega: np.ndarray, initial=None, attractor=None):
        """The runs of a batch of (F, w) (N, rad/s): :func:`dfloop.impact.extract.impact_describing_function_batch`
        with this sampler's settings; ``initial`` and ``attractor`` as there. Failed runs are recorded."""
        return impact_describing_function_batch(self.m1, self.m2, self.h, self.restitution, force, omega,
                                                effects=self.effects, transient_periods=self.transient_periods,
                                                max_transient_periods=self.max_transient_periods,
                                                periods=self.periods, max_events=self.max_events,
                                                initial=initial, attractor=attractor, on_event_limit="record",
                                                callback=self.tick)

    def labels(self, r):
        """(regime label, regular, failed) of a batch of runs ``r``; failed runs get label FAILED, not regular."""
        period = np.asarray(r.period, dtype=np.int64)
        failed = r.failure != ""
        regular = (period > 0) & ~failed
        # regime: the period and, for motions without sticking, the impacts per cycle; the number of
        # chattering impacts before a stuck phase changes continuously-valued motion and is no regime
        stuck = np.nan_to_num(np.asarray(r.stuck_fraction)) > 0
        per_cycle = np.rint(np.nan_to_num(np.asarray(r.impacts_per_period)) * np.maximum(period, 1)).astype(np.int64)
        label = regime_label(period, np.where(regular & ~stuck, per_cycle, 0), np.where(regular & stuck, 1, 0))
        label = np.where(failed, FAILED, label)
        return label, regular, failed

    def samples(self, force: np.ndarray, omega: np.ndarray) -> Samples:
        """Samples of D at (F, w) (N, rad/s): the run from rest, plus the alternative starts where it is periodic
        (paper's model): their distance to the rest value is the sample's spread."""
        r = self.extract(force, omega)
        self._last_orbits = r.orbit
        label, regular, failed = self.labels(r)
        value = np.where(failed, 0.0, np.nan_to_num(np.asarray(r.N, dtype=complex)) * self.m2 * omega ** 2)
        spread = np.where(failed, np.inf, 0.0)
        extra = {"period": np.asarray(r.period, dtype=np.int64), "periodicity": np.asarray(r.periodicity, dtype=float),
                 "n_A": np.asarray(r.max_run_A, dtype=float), "n_B": np.asarray(r.max_run_B, dtype=float),
                 "impacts_per_period": np.asarray(r.impacts_per_period, dtype=float),
                 "stuck_fraction": np.asarray(r.stuck_fraction, dtype=float),
                 "transient_periods": np.asarray(r.transient_periods, dtype=float),
                 "periods_used": np.asarray(r.periods_used, dtype=float),
                 "failed": failed.astype(float)}
        branches = np.ones(force.shape)
        other = np.empty(force.shape, dtype=object)       # orbit of the farthest other branch found
        # other starts only where rest settled on a periodic motion (elsewhere the value is invalid anyway)
        probe = np.flatnonzero(regular) if not self.effects else np.empty(0, dtype=np.int64)
        for k in range(self.starts):
            gap, u_rel = STARTS[k]
            alt_value = np.full(force.shape, np.nan, dtype=complex)
            alt_label = np.full(force.shape, FAILED, dtype=np.int64)
            if probe.size:
                # a start that settles on the rest start's orbit is the same motion: stopped there
                known = r.orbit[probe] if self.transient_periods is None else None
                alt = self.extract(force[probe], omega[probe], lambda f, w, gap=gap, u_rel=u_rel:
                                    (0.0, 0.0, gap * self.h, u_rel * f / (self.m2 * w)), attractor=known)
                lab, alt_regular, _ = self.labels(alt)
                same = np.asarray(alt.settled, dtype=bool)
                alt_value[probe] = np.where(same, value[probe], np.nan_to_num(np.asarray(alt.N, dtype=complex))
                                            * self.m2 * omega[probe] ** 2)
                alt_label[probe] = np.where(same, label[probe], np.where(alt_regular, lab, FAILED))
            differ = (alt_label != FAILED) & ((alt_label != label) | (np.abs(alt_value - value)
                                                                      > BRANCH_REL * np.abs(value)))
            branches += differ
            farther = differ & (np.abs(alt_value - value) > spread)
            for j in np.flatnonzero(farther[probe]):
                other[probe[j]] = alt.orbit[j]
            spread = np.where(differ, np.maximum(spread, np.abs(alt_value - value)), spread)
            extra[f"start{k}.re"], extra[f"start{k}.im"] = alt_value.real, alt_value.imag
            extra[f"start{k}.regime"] = alt_label.astype(float)
        extra["branches"] = branches
        self._last_other = other
        # a converged sample is within the period detection's tolerance of its orbit: its own uncertainty
        uncertainty = np.abs(value) * (np.nan_to_num(np.asarray(r.periodicity, dtype=float)) + PERIODICITY_TOL)
        return Samples(value, label, regular, extra, spread, uncertainty)

    def sample_1d(self, u: np.ndarray) -> Samples:
        """Samples of the similarity table at u = ln beta (runs at w = OMEGA_REF); keeps their orbits."""
        beta = np.exp(u)
        omega = np.full(u.shape, OMEGA_REF)
        s = self.samples(beta * self.m2 * self.h * OMEGA_REF ** 2, omega)
        self.orbits.update(zip(u.tolist(), self._last_orbits.ravel()))
        self.other.update((x, o) for x, o in zip(u.tolist(), self._last_other.ravel()) if o is not None)
        return s

    def follow_1d(self, u_from: np.ndarray, u_to: np.ndarray, value_to: np.ndarray) -> np.ndarray:
        """Branch continuation: the motions found at u_from (the other periodic branch, and the rest motion),
        followed to the neighbouring sample u_to: runs at u_to started on a point of each orbit, stopped if
        they settle on u_to's rest orbit. A run that reaches another periodic motion, or an irregular one
        (a chaotic attractor coexisting with the periodic motion from rest), makes N not unique at u_to.
        Returns, per pair, the largest distance of D (the irregular motion's average) from the rest value
        ``value_to`` among those runs (0: none); a periodic branch found is continued further from u_to."""
        force = np.exp(u_to) * self.m2 * self.h * OMEGA_REF ** 2
        omega = np.full(u_to.shape, OMEGA_REF)
        vscale = np.maximum(self.h * omega, force / (self.m2 * omega))
        out = np.zeros(u_to.size)
        for source in (self.other, self.orbits):
            orbits = [source.get(a) for a in u_from.tolist()]
            idx = np.array([i for i, o in enumerate(orbits) if o is not None and o.shape[0] > 0], dtype=np.int64)
            if idx.size == 0:
                continue
            # a start on the orbit (a free-flight point if it has one; x1 = v1 = 0: only the relative
            # motion matters, a common velocity is a drift that the DF removes)
            by_force = {}
            for i in idx.tolist():
                o = orbits[i]
                free = np.flatnonzero(o[:, 2] == FREE)
                row = o[free[0] if free.size else 0]
                by_force[float(force[i])] = (0.0, 0.0, float(np.clip(row[0], 0.0, 1.0)) * self.h,
                                             float(row[1] * vscale[i]))
            rest = np.empty(idx.size, dtype=object)
            rest[:] = [self.orbits[b] for b in u_to[idx].tolist()]
            r = self.extract(force[idx], omega[idx], lambda f, w: by_force[float(f)], attractor=rest)
            _, regular, failed = self.labels(r)
            d = np.nan_to_num(np.asarray(r.N, dtype=complex)) * self.m2 * OMEGA_REF ** 2
            dist = np.abs(d - value_to[idx])
            moved = ~np.asarray(r.settled, dtype=bool) & ~failed
            other = moved & (~regular | (dist > BRANCH_REL * np.abs(value_to[idx])))
            dist = np.where(regular, dist, np.maximum(dist, BRANCH_REL * np.abs(value_to[idx])))
            for k in np.flatnonzero(other & regular & (dist > out[idx])):
                self.other[float(u_to[idx[k]])] = r.orbit[k]
            out[idx] = np.where(other, np.maximum(out[idx], dist), out[idx])
        return out

    def probe_1d(self, u: np.ndarray, u_a: np.ndarray, u_b: np.ndarray) -> tuple[np.ndarray, Samples]:
        """Window probes: the motion from rest at ln beta = u (u_a < u < u_b), stopped as soon as it settles
        on the orbit from rest interpolated between the samples at u_a and u_b (or on its mirror): the same
        motion. Returns (settled, samples from rest) (no other starts: the table samples a probe fully
        when it is another branch)."""
        # the orbit at u, interpolated linearly between the two samples' matched orbits (within O(dx^2) of
        # the orbit at u on the same branch); orbits that cannot be matched give the nearer one
        matched = {}
        orbits = np.empty(u.size, dtype=object)
        for i, (x, a, b) in enumerate(zip(u.tolist(), u_a.tolist(), u_b.tolist())):
            oa, ob = self.orbits[a], self.orbits[b]
            if (a, b) not in matched:
                matched[a, b] = matched_orbits(oa, ob)
            t = (x - a) / (b - a)
            mb = matched[a, b]
            if mb is None:
                orbits[i] = oa if t <= 0.5 else ob
            else:
                orbits[i] = oa.copy()
                orbits[i][:, :2] = (1.0 - t) * oa[:, :2] + t * mb[:, :2]
        r = self.extract(np.exp(u) * self.m2 * self.h * OMEGA_REF ** 2, np.full(u.shape, OMEGA_REF),
                          attractor=orbits)
        settled = np.asarray(r.settled, dtype=bool)
        self.probe_runs.append((np.array(u, float), np.asarray(r.transient_periods, float)
                                + np.asarray(r.periods_used, float)))
        label, regular, _ = self.labels(r)
        value = np.nan_to_num(np.asarray(r.N, dtype=complex)) * self.m2 * OMEGA_REF ** 2
        return settled, Samples(value, label, regular & ~settled)

    def sample_2d(self, u: np.ndarray, v: float) -> Samples:
        """Samples of the 2-D table's line v = ln w at u = ln beta."""
        w = math.exp(v)
        return self.samples(np.exp(u) * self.m2 * self.h * w * w, np.full(u.shape, w))

    def collides(self, beta) -> np.ndarray:
        """Whether a motion from rest collides within its first two forcing periods, per beta (paper's model)."""
        beta = np.atleast_1d(np.asarray(beta, dtype=float))
        out = np.empty(beta.shape, dtype=bool)
        for i, b in enumerate(beta.ravel()):
            tr = simulate(self.m1, self.m2, self.h, self.restitution, b * self.m2 * self.h * OMEGA_REF ** 2,
                          OMEGA_REF, 4 * math.pi / OMEGA_REF, effects=self.effects)
            out.ravel()[i] = tr.n_impacts > 0
        return out
