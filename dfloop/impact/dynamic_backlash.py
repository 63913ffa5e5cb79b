"""The paper's dynamic backlash (two masses, clearance, impacts) as a tabulated describing function N(F, w).

N(F, w) = X1/F is the ratio of the phasor of x1's fundamental to the force F cos(w t) on M2 (m/N).
The table stores the dimensionless, well-conditioned D = N M2 w^2 (D -> -M2/(M1+M2) for slow forcing).

Paper's model (no effects): with x = h xi and tau = w t the motion depends only on
beta = F / (M2 h w^2), M1/M2 and eps, so D is a function of beta alone: one adaptive table in ln beta
serves every (F, w). For beta <= 1/4 (w >= w_L of eq. 11) the masses never touch: N = 0 exactly.
Effects that add a time or length scale (:mod:`dfloop.impact.effects`) break the law: the table is then
two-dimensional in (ln beta, ln w).

The element is thin: it maps (F, w) to table coordinates and back, and decides which window a request needs.
What a sample is (the exact runs, regime labels, coexisting motions) is :class:`dfloop.impact.sampling.
ImpactSampler`; the tables themselves, their lazy builds with progress and their disk cache are
:mod:`dfloop.tables` (:class:`dfloop.tables.TableStore`). A call can therefore simulate (a table build over a
window not yet covered, minutes for a wide window from an empty cache); :meth:`DynamicBacklash.prepare` does
that build up front, and a second evaluation of the same window, in this process or the next, simulates
nothing.
"""
from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np

from .. import _checks
from ..errors import DfloopError
from ..describing.base import DescribingFunction
from ..describing.time_model import Impact
from ..progress import compile_pending
from ..tables import Table1D, Table2D, TableSettings, TableStore, TableValues, settings_dict
from .limits import BETA_NO_IMPACT
from .model import DEFAULT_CHATTER_TOL, effects_tuple
from .sampling import STARTS, ImpactSampler

__all__ = ["DynamicBacklash", "prepare_many"]

U_START = math.log(BETA_NO_IMPACT) + 1e-9      # first table point (ln beta), just above the no-impact limit
_MIN_Y_WINDOW = 0.25                           # 2-D tables: narrowest ln w range built (two lines at least)
_BLOCK_BASE_INTERVALS = 8                      # a canonical block holds 8 base intervals
_PRIOR_SIMULATIONS_PER_BLOCK = 60              # progress estimate (per start) before the first block is done
_COMPILE_SECONDS = 16                          # first-use compilation of the table driver (docs/impact.md, JIT row)
_EFFECTS_COMPILE_SECONDS = 15                  # first-use compilation of the effects engine (fresh numba cache)
_MOTIONS = {"simulated": 0, "samples": 0}      # work done for tables by every DynamicBacklash in this process
_MOTIONS_LOCK = threading.Lock()


def motions_simulated() -> int:
    """Motions simulated for tables by every :class:`DynamicBacklash` in this process so far (a scene run
    reports the difference over the run: what the run actually simulated, whichever elements did it)."""
    return _MOTIONS["simulated"]


def table_samples() -> int:
    """Table samples computed by every :class:`DynamicBacklash` in this process so far (each sample simulates
    one or more motions: from rest, and from alternative starts where coexisting motions are looked for)."""
    return _MOTIONS["samples"]


class DynamicBacklash(DescribingFunction):
    """Describing function of the two-mass impact system, force amplitude F (N) -> x1 (m).

    Parameters
    ----------
    m1, m2 : float
        Masses (kg); the force F cos(w t) acts on ``m2``, the output is x1.
    h : float
        Clearance (m).
    restitution : float
        Coefficient of restitution eps in [0, 1]. ``eps=`` is accepted as an alias (give one of the two).
    effects : sequence, optional
        Extra physics from :mod:`dfloop.impact.effects` (effect objects; anything else is a ValueError at
        construction); any effect with ``keeps_similarity`` False makes the table two-dimensional.
    tol : float
        Relative tolerance of the midpoint check of the refinement, on D (hence on -1/N) inside smooth
        periodic regions. The default 1e-5 keeps the actual error of -1/N below 1e-4 with margin
        (``benchmarks/bench_tables.py``: a tolerance of 1e-4 lets a few points reach 1.5e-4).
    method : {'cubic', 'pchip', 'linear'}
        Interpolation inside smooth segments.
    transient_periods : int or None
        Forcing periods discarded per sample; None (default): adaptive, until the period detection has
        converged (:func:`dfloop.impact.extract.impact_describing_function`), at most
        ``max_transient_periods``.
    periods : int
        Forcing periods of each sample's detection window: with the adaptive transient a motion is periodic
        once it repeats over the last ``periods`` periods (over 3 for an exact repeat), and its fundamental is
        averaged over the whole cycles of the periods it was checked on (the window when it is irregular);
        with a fixed ``transient_periods``, the periods integrated after the transient.
    base_dx, min_dx : float
        Initial spacing and smallest refined interval of the table in ln beta (and ln w for 2-D tables).
    edge_dx : float
        Width in ln beta to which edges of irregular regions and bifurcations without a jump are located.
    probe_dx : float
        Widest accepted interval in ln beta between two samples of the same regime: wider intervals are
        probed inside even when the interpolation check passed (regime windows narrower than this can
        still hide between two samples; see docs/tables.md).
    window_dx : float
        Spacing in ln beta of the window probes (paper's model, adaptive transient): between two samples of
        one periodic regime the motion from rest is simulated at points at most window_dx apart until it
        settles on the orbit interpolated between the two samples' orbits (a few periods); a probe that
        reaches another motion is sampled and bracketed like any regime change. Windows narrower than
        window_dx can still be missed (docs/tables.md gives the measured rate).
    starts : int
        Start states probed besides rest at every sample (paper's model) to find coexisting periodic motions.
        Where another start settles on a different periodic motion, the value from rest is kept, every
        branch is stored with the sample, ``validity`` is False and ``error_estimate`` includes the
        distance to the farthest branch; such a branch is followed to the neighbouring samples until it ends
        (branch continuation), so the whole region where it coexists is flagged.
    max_events : int, optional
        Event bound per simulated sample (default sized from the run length); a sample that reaches it is
        recorded as failed (not valid, infinite error estimate) and the build goes on.
    beta_max : float
        Largest beta the table may reach. Beyond it (deep in the low-frequency region, where the masses
        move almost as one body) the paper's model returns the rigid-body value -1/((M1 + M2) w^2), whose
        distance to the true N is bounded exactly by (M2/(M1 + M2)) (2h/pi)/F (a relative 2/(pi beta)):
        that bound is its ``error_estimate`` and ``validity`` is False there. With effects, requests beyond
        ``beta_max`` raise ValueError.
    cache : bool
        Load and save tables in :func:`dfloop.tables.cache_dir`.
    progress : bool, None or callable
        None (default): a progress bar with the time left (:func:`dfloop.progress.progress_bar`) for builds
        longer than a second; True: from the start; False: none; a callable gets ``(n_samples, stage)``.

    Attributes
    ----------
    sampler : dfloop.impact.sampling.ImpactSampler
        What one table sample runs (the exact simulations, regime labels, coexisting motions).
    store : dfloop.tables.TableStore
        The table, its lazy build with progress and its cache file (``store.table``, ``store.path``).

    Notes
    -----
    ``validity`` is False where the sampled motion was not periodic (irregular / chaotic, below the
    lower limit w_c), where other periodic motions coexist, where a sample failed, and inside the tiny
    brackets around regime changes; ``error_estimate`` is the interpolation error measured during
    refinement plus the spread of coexisting branches (absolute, m/N). Subharmonic but periodic motion is
    valid. The table is built block by block on a fixed lattice in ln beta and saved after every block, so
    its content does not depend on the order of requests and an interrupted build resumes (docs/tables.md).
    """

    frequency_dependent = True
    input_name = "F"
    input_unit = "N"

    def __init__(self, m1: float, m2: float, h: float, restitution: float | None = None, effects=(), *,
                 eps: float | None = None, tol: float = 1e-5, method: str = "cubic",
                 transient_periods: int | None = None, max_transient_periods: int = 4000, periods: int = 20,
                 base_dx: float = 0.1, min_dx: float = 2e-4, edge_dx: float = 1e-2, probe_dx: float = 0.05,
                 window_dx: float = 2e-3,
                 starts: int = 2, beta_max: float = 1e4, max_events: int | None = None, cache: bool = True,
                 progress: bool | None | Callable[[int, str], None] = None):
        self.m1 = _checks.positive("m1", m1)
        self.m2 = _checks.positive("m2", m2)
        self.h = _checks.positive("h", h)
        if eps is not None and restitution is not None:
            raise ValueError(f"restitution: give the coefficient of restitution once, as restitution= or its "
                             f"alias eps=, got restitution={restitution!r} and eps={eps!r}")
        if eps is None and restitution is None:
            raise ValueError("restitution: the coefficient of restitution is required (restitution= or eps=)")
        self.restitution = _checks.in_closed_interval("restitution", restitution if eps is None else eps, 0.0, 1.0)
        self.effects = effects_tuple(effects)
        self.transient_periods = (None if transient_periods is None
                                  else _checks.integer_at_least("transient_periods", transient_periods, 0))
        self.max_transient_periods = _checks.integer_at_least("max_transient_periods", max_transient_periods, 1)
        self.periods = _checks.integer_at_least("periods", periods, 1)
        self.starts = _checks.integer_at_least("starts", starts, 0)
        if self.starts > len(STARTS):
            raise ValueError(f"starts must be <= {len(STARTS)}, got {starts!r}")
        self.max_events = None if max_events is None else _checks.integer_at_least("max_events", max_events, 1)
        self.beta_max = _checks.positive("beta_max", beta_max)
        if self.beta_max <= BETA_NO_IMPACT:
            raise ValueError(f"beta_max must exceed 1/4, got {self.beta_max}")
        base_dx = _checks.positive("base_dx", base_dx)
        if _checks.positive("min_dx", min_dx) > base_dx:  # the table's finest step cannot exceed its coarsest
            raise DfloopError(f"min_dx must be <= base_dx = {base_dx!r}, got min_dx = {min_dx!r}")
        self._settings = TableSettings(tol=_checks.positive("tol", tol), method=method, base_dx=base_dx,
                                       min_dx=_checks.positive("min_dx", min_dx),
                                       edge_dx=_checks.positive("edge_dx", edge_dx),
                                       probe_dx=_checks.positive("probe_dx", probe_dx),
                                       window_dx=_checks.positive("window_dx", window_dx),
                                       block_dx=_BLOCK_BASE_INTERVALS * base_dx, origin=U_START)
        self._y_settings = TableSettings(tol=tol, method=method, base_dx=1.0, min_dx=max(min_dx, 1e-3))
        self.sampler = ImpactSampler(self.m1, self.m2, self.h, self.restitution, self.effects,
                                     transient_periods=self.transient_periods,
                                     max_transient_periods=self.max_transient_periods, periods=self.periods,
                                     max_events=self.max_events, starts=self.starts)
        self.store = TableStore("dynamic_backlash", self.parameters, self._restore, cache=cache, progress=progress,
                                label=f"DynamicBacklash(restitution={self.restitution:g}) table",
                                provenance=dict(m1=self.m1, m2=self.m2, h=self.h),
                                settings={"settings": settings_dict(self._settings),
                                          "y_settings": settings_dict(self._y_settings)})

    # ------------------------------------------------------------------ identity
    @property
    def similarity(self) -> bool:
        """True when the motion obeys the similarity law (1-D table in beta)."""
        return all(getattr(e, "keeps_similarity", False) for e in self.effects)

    def parameters(self) -> dict:
        """Everything the table's content depends on (the cache key is built from this)."""
        p = {"kind": "DynamicBacklash/1" if self.similarity else "DynamicBacklash/2",
             "restitution": self.restitution, "effects": [repr(e) for e in self.effects],
             "transient_periods": self.transient_periods, "periods": self.periods,
             "max_transient_periods": self.max_transient_periods, "starts": self.starts,
             "max_events": self.max_events,
             "settings": settings_dict(self._settings)}
        if self.similarity:
            p["mass_ratio"] = self.m1 / self.m2        # D(beta) depends on m1/m2 and eps only
        else:
            p.update(m1=self.m1, m2=self.m2, h=self.h, y_settings=settings_dict(self._y_settings),
                     line_settings=settings_dict(self._line_settings), y_rate=self._y_rate,
                     u_min=self._u_min)
        return p

    @property
    def cache_path(self) -> Path:
        """The table's file in the cache directory (its name holds the cache key)."""
        return self.store.path

    @property
    def n_simulations(self) -> int:
        """Table samples computed by this object so far (0 when everything came from the cache); each sample
        simulates one or more motions (:func:`motions_simulated` counts those)."""
        return self.store.n_sampled

    @property
    def table(self) -> Table1D | Table2D | None:
        """The current table (None before the first evaluation)."""
        return self.store.table

    def _restore(self, arrays: dict) -> Table1D | Table2D:
        """The table saved as ``arrays`` (1-D or 2-D, with this element's settings)."""
        if self.similarity:
            return Table1D.from_arrays(arrays, self._settings)
        return Table2D.from_arrays(arrays, self._line_settings, self._y_settings)

    @property
    def _line_settings(self) -> TableSettings:
        """Settings of the 2-D table's lines: value jumps bracketed only to ``edge_dx`` like every other regime
        change (between lines the band flagged invalid around a jump is set by the lines' spacing in y, far
        wider than any bracket on one line)."""
        st = self._settings
        edge = max(st.edge_dx, st.probe_dx)
        return replace(st, edge_dx=edge, jump_dx=max(st.jump_dx, edge), min_dx=max(st.min_dx, 0.04 * edge))

    @property
    def _u_min(self) -> float:
        """ln beta from which the 2-D table starts (the first point of the 1-D one, just above beta = 1/4,
        where below N = 0 exactly), -inf where that limit is not known for these effects.

        From rest only M2 moves until the first impact, x2 - x1 = beta h (1 - cos w t) <= 2 beta h: below
        beta = 1/4 it never reaches a wall of the centred gap. Effects on M1 (damping, spring, friction of M1)
        do not touch that motion, so there x1 = 0 forever and N = 0.
        """
        on_m1 = all(getattr(e, "acts_on", None) == "m1" for e in self.effects)
        return U_START if on_m1 else -math.inf

    @property
    def _y_rate(self) -> float:
        """Rate r of the 2-D table's interpolation coordinate exp(-r ln w) = w^-r between lines.

        At fixed beta every effect enters through one dimensionless group proportional to a power of 1/w
        (its ``frequency_power``: c/(M2 w), k/(M2 w^2), f/(M2 h w^2)), and D = N M2 w^2 is a smooth function
        of those groups: interpolated in w^-p with p the smallest such power, D is smooth down to the
        effect-free limit w -> infinity (in ln w it flattens exponentially there and bends fast at low w).
        """
        return float(min((getattr(e, "frequency_power", 1) for e in self.effects), default=1))

    # ------------------------------------------------------------------ table windows
    def _build(self, extend, n_units: int) -> None:
        """Run ``extend(progress, checkpoint)`` through the store (progress bar, save after every unit), with
        the sampler ticking the bar once per simulation."""
        def run(progress, checkpoint, tick):
            def counted():
                tick()
                with _MOTIONS_LOCK:
                    _MOTIONS["simulated"] += 1

            self.sampler.tick = counted
            samples_before = self.store.n_sampled
            try:
                extend(progress, checkpoint)
            finally:
                self.sampler.tick = None
                with _MOTIONS_LOCK:
                    _MOTIONS["samples"] += self.store.n_sampled - samples_before

        self.store.build(run, n_units, _PRIOR_SIMULATIONS_PER_BLOCK * (1 + self.starts),
                         first_use=self._first_use())

    def _first_use(self) -> str | None:
        """What to announce before the first sample: numba compiling the table driver (once per installation)."""
        if self.effects:
            from . import _effects_core

            pending, seconds = compile_pending(_effects_core.run_engine), _EFFECTS_COMPILE_SECONDS
        else:
            from . import _core

            pending, seconds = compile_pending(_core.adaptive_batch), _COMPILE_SECONDS
        if not pending:
            return None
        return f"compiling once for this installation, about {seconds} s (later runs load the compiled code)"

    def _check_beta(self, beta_hi: float) -> None:
        if beta_hi > self.beta_max:
            raise ValueError(f"F is too large for omega: beta = F/(M2 h w^2) = {beta_hi:.6g} exceeds beta_max = "
                             f"{self.beta_max:g} (deep in the irregular low-frequency region); raise beta_max "
                             f"to tabulate further")

    def similarity_table(self, beta_max: float) -> Table1D:
        """The 1-D table D(ln beta), extended to cover 1/4 < beta <= ``beta_max``."""
        if not self.similarity:
            raise ValueError("effects break the similarity law: this DynamicBacklash has a 2-D table")
        self._ensure_1d(float(beta_max))
        return self.store.table

    def _ensure_1d(self, beta_hi: float) -> None:
        self._check_beta(beta_hi)
        self.store.load_cached()
        u_hi = max(math.log(beta_hi), U_START + self._settings.base_dx)
        if self.store.table is None:
            self.store.table = Table1D(self._settings)
        missing = self.store.table.missing_blocks(U_START, u_hi)
        if missing.size:
            # window probes need the adaptive run's orbits (a fixed transient has none): otherwise probe_dx only
            s = self.sampler
            prober = s.probe_1d if self.transient_periods is None else None
            follow = s.follow_1d if self.transient_periods is None and self.starts else None
            s.reset()
            try:
                self._build(lambda progress, checkpoint: self.store.table.extend(
                    s.sample_1d, U_START, u_hi, progress, checkpoint, prober, follow), int(missing.size))
            finally:
                s.reset()

    def _ensure_2d(self, u_hi: float, s_lo: float, s_hi: float, v_lo: float, v_hi: float) -> None:
        """Cover ln F - ln(M2 h) = u + 2 v in [s_lo, s_hi] for v = ln w in [v_lo, v_hi] (u = ln beta <= u_hi).

        The window is a rectangle in (ln F, ln w), sheared in (ln beta, ln w): every line of the 2-D table
        spans only the ln beta range its own frequencies need.
        """
        self._check_beta(math.exp(u_hi))
        self.store.load_cached()
        pad = 1e-12
        sw = (s_lo - pad, max(s_hi, s_lo + self._settings.base_dx) + pad)
        yw = (v_lo - pad, max(v_hi, v_lo + _MIN_Y_WINDOW) + pad)
        if self.store.table is not None and self.store.table.covers(sw, yw, shear=2.0):
            return
        if self.store.table is None:
            self.store.table = Table2D(self._line_settings, self._y_settings, self._y_rate, self._u_min)
        # progress in lines (saved after each): the lines on the base grid in y and a prior of twice as many
        # added by the refinement in y (the damped scene: 6 + 11); the time left is corrected as lines finish
        n_lines = 3 * (int(math.ceil((yw[1] - yw[0]) / self._y_settings.base_dx)) + 1)
        self._build(lambda progress, checkpoint: self.store.table.extend(self.sampler.sample_2d, sw, yw, progress, shear=2.0,
                                                                    checkpoint=checkpoint), n_lines)

    def prepare(self, F, omega) -> "DynamicBacklash":
        """Build (or load) the table over the window spanned by force amplitudes F and frequencies omega."""
        F = _checks.amplitude_array(F, "F")
        w = _checks.frequency_array(omega)
        self._lookup(*np.broadcast_arrays(np.array([np.nanmin(F), np.nanmax(F)]),
                                          np.array([np.nanmax(w), np.nanmin(w)])))
        return self

    # ------------------------------------------------------------------ evaluation
    def _lookup(self, F: np.ndarray, w: np.ndarray) -> TableValues:
        """N, absolute error and validity at validated, broadcast (F, w)."""
        shape = F.shape
        F, w = F.ravel(), w.ravel()
        n = np.zeros(F.size, dtype=complex)
        err = np.zeros(F.size)
        valid = np.ones(F.size, dtype=bool)
        regime = np.zeros(F.size, dtype=np.int64)
        nan = np.isnan(F) | np.isnan(w)
        n[nan], err[nan], valid[nan] = complex(np.nan, np.nan), np.nan, False
        scale = self.m2 * w ** 2
        with np.errstate(divide="ignore"):
            beta = F / (self.m2 * self.h * w ** 2)
        if self.similarity:
            need = ~nan & (beta > BETA_NO_IMPACT)
            far = need & (beta > self.beta_max)
            need &= ~far
            if np.any(far):
                # beyond the table: the rigid-body value -1/((M1 + M2) w^2), within the exact centre-of-mass
                # bound |N - N_rigid| <= (M2/(M1 + M2)) (2h/pi) / F (x1 differs from the centre of mass by at
                # most M2 h/(M1 + M2)); reported through error_estimate and flagged not valid (not simulated)
                mass = self.m1 + self.m2
                n[far] = -1.0 / (mass * w[far] ** 2)
                err[far] = (self.m2 / mass) * (2.0 * self.h / np.pi) / F[far]
                valid[far] = False
            if np.any(need):
                u = np.maximum(np.log(beta[need]), U_START)
                self._ensure_1d(float(np.exp(u.max())))
                tv = self.store.table.evaluate(u)
        else:
            u_min = self._u_min
            need = ~nan & (beta > (BETA_NO_IMPACT if u_min > -math.inf else 0.0))     # N = 0 below u_min
            if np.any(need):
                u, v = np.maximum(np.log(beta[need]), u_min), np.log(w[need])
                s_ = u + 2.0 * v
                self._ensure_2d(float(u.max()), float(s_.min()), float(s_.max()), float(v.min()), float(v.max()))
                tv = self.store.table.evaluate(u, v)
        if np.any(need):
            n[need] = tv.value / scale[need]
            err[need] = tv.error / scale[need]
            valid[need] = tv.valid
            regime[need] = tv.regime
        return TableValues(n.reshape(shape), err.reshape(shape), valid.reshape(shape), regime.reshape(shape))

    def _evaluate(self, A: np.ndarray, omega: np.ndarray) -> np.ndarray:
        return self._lookup(A, omega).value

    def _validated(self, F, omega):
        a = _checks.amplitude_array(F, "F")
        if omega is None:
            raise ValueError("omega is required: DynamicBacklash depends on frequency")
        return np.broadcast_arrays(a, _checks.frequency_array(omega))

    def validity(self, A, omega=None) -> np.ndarray:
        """True where N is a trustworthy DF value: periodic motion (or no impacts), not at a jump."""
        return self._lookup(*self._validated(A, omega)).valid

    def error_estimate(self, A, omega=None) -> np.ndarray:
        """Estimated absolute interpolation error of N (m/N); 0 where N = 0 exactly (no impacts)."""
        return self._lookup(*self._validated(A, omega)).error

    def amplitude_domain(self, omega=None) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) force amplitudes (N): N = 0 below lo (no impacts, eq. 11).

        hi is infinite for the paper's model (beyond ``beta_max`` the rigid-body value with its exact bound
        is returned, flagged not valid) and ``beta_max`` M2 h w^2 with effects (beyond it: ValueError).
        """
        if omega is None:
            raise _checks.DfloopError("omega is required: the amplitude domain of DynamicBacklash depends on "
                                      "frequency (rad/s), got omega=None")
        w = _checks.frequency_array(omega)
        base = self.m2 * self.h * w ** 2
        hi = np.full(np.shape(base), np.inf) if self.similarity else self.beta_max * base
        return BETA_NO_IMPACT * base, hi

    def time_model(self, amplitude: float):
        """The masses, clearance, restitution and effects for the exact impact engine (:mod:`dfloop.hybrid`)."""
        return Impact(type(self).__name__, self.m1, self.m2, self.h, self.restitution, tuple(self.effects),
                      DEFAULT_CHATTER_TOL)

    def sampled_model(self, dt: float):
        """The masses as a sampled system (force held over each sample of ``dt`` s, exact motion between
        samples): how :func:`dfloop.to_control` hands this element to python-control
        (:class:`dfloop.impact.sampled_model.SampledImpactModel`)."""
        from .sampled_model import SampledImpactModel
        return SampledImpactModel(self.m1, self.m2, self.h, self.restitution, tuple(self.effects),
                                  DEFAULT_CHATTER_TOL, dt)

    def negative_inverse(self, F, omega) -> np.ndarray:
        """-1/N(F, w) (N/m) computed from the table as -M2 w^2 / D; complex infinity where N = 0."""
        n = self(F, omega)
        out = np.full(n.shape, complex(np.inf, 0.0))
        nz = n != 0
        out[nz] = -1.0 / n[nz]
        return out

    # ------------------------------------------------------------------ persistence
    def save(self, path) -> Path | None:
        """Write the current table with its provenance (parameters, code version, date, build settings)."""
        return self.store.save(path)

    def load(self, path) -> bool:
        """Adopt a table saved by :meth:`save` if it was built for exactly these parameters and this code.

        Returns False (and keeps the current table) when the file is missing, corrupted or stale.
        """
        return self.store.load(path)

    def __repr__(self) -> str:
        eff = f", effects={list(self.effects)!r}" if self.effects else ""
        return (f"DynamicBacklash(m1={self.m1:g}, m2={self.m2:g}, h={self.h:g}, restitution={self.restitution:g}"
                f"{eff}, table={self.store.table!r})")


def prepare_many(elements, F, omega, *, workers: int = 2) -> list:
    """Build (or load) the tables of several :class:`DynamicBacklash` objects over one (F, w) window.

    The objects are prepared concurrently in ``workers`` threads (each also samples in parallel), which
    keeps both cores busy while a single table refines only a few intervals. Returns the elements.
    """
    elements = list(elements)
    workers = int(workers)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    with ThreadPoolExecutor(max_workers=workers) as pool:
        list(pool.map(lambda e: e.prepare(F, omega), elements))
    return elements
