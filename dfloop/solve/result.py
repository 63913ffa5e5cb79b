"""Result objects of :func:`dfloop.predict_limit_cycles`."""
from __future__ import annotations

from dataclasses import dataclass, field

from .verdict import classify

__all__ = ["LimitCycle", "LimitCycles", "JumpCrossing", "GridReport"]


def exact_kind(cycle) -> tuple[str, str]:
    """(``"confirmed"`` | ``"artefact"`` | ``"not checked"``, detail) of a predicted cycle: its
    :attr:`LimitCycle.verdict` (:func:`dfloop.solve.verdict.classify`, the one place that decides)."""
    v = cycle.verdict
    return v.kind, v.detail


def exact_words(cycle, long: bool = False) -> str:
    """What the exact-orbit search established for a predicted cycle, in the three words every printout shares:

    ``confirmed: exact amplitude=..., frequency=... rad/s, stable`` for an orbit found; ``artefact (...)`` only
    when the search gathered evidence that no orbit exists near the prediction (where the motions started on and
    around it went); otherwise ``not checked (reason)``, since a failed search alone does not prove that no orbit
    exists. ``long`` keeps the whole reason (``str(cycle)``); the table shortens it.
    """
    ex = cycle.exact
    kind, detail = exact_kind(cycle)
    if ex is not None and ex.success:
        return (f"{kind}: exact amplitude={ex.amplitude:.6g}, frequency={ex.frequency:.6g} rad/s, "
                f"{'stable' if ex.stable else 'unstable'}")
    if not long and len(detail) > 60:
        detail = detail[:57].rstrip() + "..."
    return f"{kind} ({detail})" if detail else kind


@dataclass(frozen=True)
class LimitCycle:
    """One predicted limit cycle, a root of 1 + G(jw) N(A, w) = 0.

    Attributes
    ----------
    amplitude : float
        Amplitude A of the fundamental at the element's input (the DF's input unit).
    frequency : float
        Angular frequency w in rad/s.
    stability : str
        ``"stable"``, ``"unstable"`` or ``"marginal"`` (tangent / double root: sign not decidable), or
        ``"loeb-stable only"``: the Loeb criterion says stable but the plant has unstable real poles, a
        non-oscillatory mode the criterion cannot see (such loops can diverge); ``exact=True`` decides by
        the exact orbit's Floquet multipliers instead.
    residual : float
        |1 + G N| at the answer; ``relative_residual`` divides it by 1 + |G N|.
    loeb_determinant : float
        U_A V_w - U_w V_A with R = U + jV (per unit amplitude, per rad/s); > 0 means stable.
    loeb_conditioning : float
        The signed sine of the angle between dR/d(ln A) and dR/d(ln w), in [-1, 1] (0 for a double
        root); scale-free, used for the marginal decision.
    G : complex
        G(jw) at the answer (the point on the Nyquist plane, equal to -1/N there).
    N : complex
        N(A, w) at the answer.
    on_edge : bool
        True when the root lies on the boundary of the search window (a warning was issued).
    valid : bool
        N's own ``validity`` at the answer. False e.g. in the chaotic regions of a tabulated DF, where N
        is an average over irregular motion: the cycle solves the equation for that average only.
    n_error : float
        N's ``error_estimate`` at the answer (0 for closed forms; inf where N gives no estimate).
    confidence : dfloop.Confidence or None
        How far the prediction can be trusted: the harmonic distortion at the element's input that the
        DF neglects and the estimated errors of amplitude and frequency it implies (always available on
        cycles from :func:`dfloop.predict_limit_cycles`, computed on first access; "unavailable" with a
        reason for elements without a static time-domain response).
    exact : dfloop.ExactCycle or None
        The true periodic orbit near this prediction, when ``predict_limit_cycles(..., exact=True)``.
    """

    amplitude: float
    frequency: float
    stability: str
    residual: float
    relative_residual: float
    loeb_determinant: float
    loeb_conditioning: float
    G: complex
    N: complex
    on_edge: bool = False
    valid: bool = True
    n_error: float = 0.0
    exact: object = None
    _confidence: object = field(default=None, repr=False, compare=False)

    @property
    def confidence(self):
        """The cycle's :class:`dfloop.Confidence`, computed on first access (a few ms) and kept."""
        conf = self._confidence
        if callable(conf):
            conf = conf()
            object.__setattr__(self, "_confidence", conf)
        return conf

    @property
    def verdict(self):
        """Confirmed (an exact orbit near it), artefact (none; where the motions go) or not checked (why):
        :func:`dfloop.solve.verdict.classify`."""
        return classify(self)

    @property
    def stable(self) -> bool:
        """True only for a stable cycle (marginal cycles are not stable)."""
        return self.stability == "stable"

    @property
    def marginal(self) -> bool:
        return self.stability == "marginal"

    @property
    def period(self) -> float:
        """Period 2 pi / w in seconds."""
        import math

        return 2 * math.pi / self.frequency

    def to_dict(self) -> dict:
        """The cycle as one flat row of plain data (``pandas.DataFrame([c.to_dict() for c in cycles])``).

        Keys: the attribute names (``amplitude``, ``frequency``, ``stability``, ``residual``, ...; complex ``G``
        and ``N`` as ``G_real``/``G_imag``, ``N_real``/``N_imag``), the confidence as ``confidence_distortion``,
        ``confidence_amplitude_error``, ``confidence_frequency_error``, ``confidence_available``,
        ``confidence_reliable``, and with ``exact`` attached ``exact_verdict`` (confirmed, artefact or not
        checked), ``exact_success``, ``exact_amplitude``,
        ``exact_frequency``, ``exact_stable``, ``exact_message`` (see :mod:`dfloop.export`).
        """
        from ..export import flat

        fields = {name: getattr(self, name) for name in (
            "amplitude", "frequency", "stability", "residual", "relative_residual", "loeb_determinant",
            "loeb_conditioning", "G", "N", "on_edge", "valid", "n_error")}
        conf = self.confidence
        if conf is not None:
            fields["confidence"] = {"available": conf.available, "reliable": conf.reliable,
                                    "distortion": conf.distortion, "amplitude_error": conf.amplitude_error,
                                    "frequency_error": conf.frequency_error}
        if self.exact is not None:
            ex = self.exact
            fields["exact"] = {"verdict": exact_kind(self)[0], "success": ex.success, "amplitude": ex.amplitude,
                               "frequency": ex.frequency, "stable": ex.stable, "message": ex.message}
        return flat(fields)

    def to_csv(self, path) -> None:
        """Write :meth:`to_dict` as a one-row CSV file (header = its keys)."""
        from ..export import write_csv

        write_csv(path, [self.to_dict()])

    def __str__(self) -> str:
        flags = ("" if self.valid else " [N not valid here: an average over irregular motion]")
        flags += " [on window edge]" if self.on_edge else ""
        conf = self.confidence
        if conf is not None and getattr(conf, "available", False):
            flags += (f" [distortion {100 * conf.distortion:.2g} %, est. DF error: amplitude "
                      f"{100 * conf.amplitude_error:+.2g} %, frequency {100 * conf.frequency_error:+.2g} %]")
        if self.exact is not None:
            flags += f" [{exact_words(self, long=True)}]"
        return (f"LimitCycle(amplitude={self.amplitude:.6g}, frequency={self.frequency:.6g} rad/s, {self.stability}, "
                f"|1+GN|={self.residual:.1e}{flags})")


@dataclass(frozen=True)
class JumpCrossing:
    """A place where G(jw) passes through the gap of a jump of -1/N: 1 + G N winds around a box that
    contains a discontinuity of N but no root. Not a limit cycle of the DF equation; the loop may
    oscillate near it in a way the describing function cannot describe (the "jumping phenomenon").

    Attributes
    ----------
    amplitude, frequency : float
        Centre of the box (amplitude in N's input unit, frequency in rad/s).
    resolution : float
        Relative size of the box (its side in ln A and ln w).
    winding : int
        Winding number of 1 + G N around the box (counter-clockwise in (ln A, ln w)).
    G : complex
        G(jw) there.
    N_sides : (complex, complex)
        The values of N on the two sides of the jump (at the box corners with the smallest and largest
        arg(1 + G N)).
    """

    amplitude: float
    frequency: float
    resolution: float
    winding: int
    G: complex
    N_sides: tuple

    def __str__(self) -> str:
        lo, hi = self.N_sides
        return (f"JumpCrossing(amplitude={self.amplitude:.6g}, frequency={self.frequency:.6g} rad/s, N jumps "
                f"{lo:.4g} -> {hi:.4g}, winding {self.winding:+d})")


@dataclass(frozen=True)
class GridReport:
    """How the solver's grid was chosen (see docs/solver.md).

    Attributes
    ----------
    shape : (int, int)
        Final (amplitudes, frequencies) grid size.
    frequency_rule, amplitude_rule : str
        How each axis was resolved: ``"exact"`` (a certified bound from G's poles and zeros, no sampling),
        ``"sampled"`` (dense scan with midpoint and golden-section aliasing check), or for a frequency-dependent N
        the sampled rules applied to G N along omega and to N along A.
    max_step_frequency, max_step_amplitude : float
        The largest bound left on |d ln G| (|d ln G N| for a frequency-dependent N) resp. |d ln N| within
        one interval of the axis (jumps of N, which no refinement shrinks, excepted: ``n_jumps`` counts
        those intervals).
    n_jumps : int
        Intervals left with an unbounded step (a discontinuity of N or a zero of G or N at a node).
    candidate_cells : int or None
        Cells that the variation bounds could not exclude (amplitude-only N); every other cell provably
        holds no root. None when every cell's winding was computed.
    n_evaluations : int
        Points at which G or N was sampled to choose the grid.
    uncertified : tuple of (float, float)
        Frequency intervals (rad/s) where the sampled bound on |d ln G| (|d ln G N|) could not be certified:
        the samples and the slopes at them still disagree at the smallest interval width (a discontinuity
        of a callable or frd G, or a feature narrower than the sampling can follow), and those of places
        where 1 + G N winds around 0 but no root could be refined (a warning names their amplitudes too).
        Roots inside them may be missed.
    rejected : int
        Refined points dropped because they did not satisfy the residual bound (``roots.residual_bound``);
        every returned cycle satisfies it.
    """

    shape: tuple
    frequency_rule: str
    amplitude_rule: str
    max_step_frequency: float
    max_step_amplitude: float
    n_jumps: int
    candidate_cells: int | None
    n_evaluations: int
    uncertified: tuple = ()
    rejected: int = 0

    def __str__(self) -> str:
        cand = "" if self.candidate_cells is None else f", {self.candidate_cells} candidate cells"
        if self.uncertified:
            cand += (f"; {len(self.uncertified)} frequency interval(s) not certified (roots may be missed there): "
                     + ", ".join(f"[{lo:.6g}, {hi:.6g}]" for lo, hi in self.uncertified[:3])
                     + (" ..." if len(self.uncertified) > 3 else ""))
        if self.rejected:
            cand += f"; {self.rejected} point(s) rejected by the residual bound"
        return (f"grid {self.shape[0]} x {self.shape[1]} (omega: {self.frequency_rule}, max step "
                f"{self.max_step_frequency:.3g}; A: {self.amplitude_rule}, max step "
                f"{self.max_step_amplitude:.3g}; {self.n_jumps} jump interval(s){cand})")


class LimitCycles(list):
    """The predicted cycles (a list of :class:`LimitCycle`, sorted by frequency) and how they were found.

    Attributes
    ----------
    amplitude_window, omega_window : (float, float)
        The windows searched (amplitude in N's input unit, frequency in rad/s).
    window_source : dict
        ``{"amplitude": ..., "omega": ...}``: ``"given"`` or how the default was chosen.
    grid_shape : (int, int)
        Final (amplitudes, frequencies) grid size after adaptive refinement.
    n_evaluations : int
        Number of (A, w) points at which 1 + G N was evaluated.
    jump_crossings : list of JumpCrossing
        Where the winding of 1 + G N comes from a discontinuity of N, not a root (sorted by frequency).
    grid_report : GridReport or None
        How the grid was chosen (sizes, rules, largest step left).
    """

    def __init__(self, cycles, amplitude_window, omega_window, window_source, grid_shape, n_evaluations,
                 jump_crossings=(), grid_report=None):
        super().__init__(cycles)
        self._grid_report = grid_report
        self.jump_crossings = list(jump_crossings)
        self.amplitude_window = amplitude_window
        self.omega_window = omega_window
        self.window_source = window_source
        self.grid_shape = grid_shape
        self.n_evaluations = n_evaluations

    @property
    def grid_report(self) -> GridReport | None:
        """How the grid was chosen (:class:`GridReport`), or None. The compiled driver hands over the report's values
        with the result and the report is built from them on first reading (most batch results are never asked
        for theirs: ~1 us of a call that takes ~20)."""
        report = self._grid_report
        if isinstance(report, DeferredReport):
            report = self._grid_report = report.build()
        return report

    @grid_report.setter
    def grid_report(self, value: GridReport | None) -> None:
        self._grid_report = value

    def __repr__(self) -> str:
        head = (f"{len(self)} limit cycle(s); amplitude window [{self.amplitude_window[0]:.4g}, "
                f"{self.amplitude_window[1]:.4g}] ({self.window_source['amplitude']}), omega window "
                f"[{self.omega_window[0]:.4g}, {self.omega_window[1]:.4g}] rad/s ({self.window_source['omega']})")
        if self.jump_crossings:
            head += f"; {len(self.jump_crossings)} jump crossing(s) of N (no cycle there)"
        if self.grid_report is not None:
            head += f"\n{self.grid_report}"
        jumps = (["jump crossings (G passes through the gap of a jump of -1/N; not limit cycles):"]
                 + [f"  {j}" for j in self.jump_crossings]) if self.jump_crossings else []
        if not self:
            return "\n".join([head] + jumps)
        rows = [f"{'#':>3} {'amplitude':>12} {'frequency [rad/s]':>18} {'stability':>10} {'|1+GN|':>9} "
                f"{'Loeb det':>10} {'Re G':>11} {'Im G':>11} {'distortion':>10}  notes"]
        for i, c in enumerate(self):
            conf = c.confidence
            available = conf is not None and getattr(conf, "available", False)
            distortion = f"{100 * conf.distortion:.2g} %" if available else "-"
            notes = ", ".join(n for n, on in (("on edge", c.on_edge),
                                               ("N not valid: average over irregular motion", not c.valid),
                                               ("DF unreliable (distortion > 5 %)", available and not conf.reliable
                                                and conf.distortion > 0.05),
                                               (f"sampled DF questionable ({getattr(conf, 'samples_per_period', 0)} "
                                                "samples/period)", available and not conf.reliable
                                                and conf.distortion <= 0.05))
                              if on)
            if c.exact is not None:
                notes += ("; " if notes else "") + exact_words(c)
            rows.append(f"{i:>3} {c.amplitude:>12.6g} {c.frequency:>18.6g} {c.stability:>10} {c.residual:>9.1e} "
                        f"{c.loeb_determinant:>10.3g} {c.G.real:>11.4g} {c.G.imag:>11.4g} {distortion:>10}  {notes}")
        return "\n".join([head] + rows + jumps)

    __str__ = __repr__

    def to_dict(self) -> dict:
        """Plain data: ``cycles`` (a list of :meth:`LimitCycle.to_dict` rows, DataFrame-ready), the windows,
        ``window_source``, ``grid_shape``, ``n_evaluations``, ``jump_crossings`` (rows of their fields) and
        ``grid_report`` (its fields, or None)."""
        from dataclasses import asdict

        from ..export import flat, plain

        return {"cycles": [c.to_dict() for c in self],
                "amplitude_window": plain(self.amplitude_window), "omega_window": plain(self.omega_window),
                "window_source": plain(self.window_source), "grid_shape": plain(self.grid_shape),
                "n_evaluations": plain(self.n_evaluations),
                "jump_crossings": [flat({"amplitude": j.amplitude, "frequency": j.frequency,
                                         "resolution": j.resolution, "winding": j.winding, "G": j.G,
                                         "N_low": j.N_sides[0], "N_high": j.N_sides[1]})
                                   for j in self.jump_crossings],
                "grid_report": None if self.grid_report is None else plain(asdict(self.grid_report))}

    def to_csv(self, path) -> None:
        """Write one row per cycle (the keys of :meth:`LimitCycle.to_dict`) to ``path``."""
        from ..export import write_csv

        write_csv(path, [c.to_dict() for c in self])

    def to_control(self, dt: float | None = None):
        """The closed loop these cycles come from as a python-control ``nlsys`` (:func:`dfloop.control_loop`).

        Simulate it with ``control.input_output_response(loop, T, 0.0, loop.initial_state(cycles[i]))``: the
        start lies on the harmonic-balance orbit of cycle i. The plant must be a python-control tf/ss. ``dt``
        (s): the sampled loop of a dynamic backlash (see :func:`dfloop.control_loop`).
        """
        from ..describing.interop import control_loop

        G, N = getattr(self, "plant", None), getattr(self, "element", None)
        if G is None or N is None:
            raise ValueError("these cycles do not record the plant and element they came from: use "
                             "dfloop.control_loop(G, N)")
        return control_loop(G, N, dt=dt)

    @property
    def plant_response(self):
        """G(jw) of the plant these cycles were predicted for: a :class:`~dfloop.solve.plant.Plant` (callable
        on frequencies in rad/s, with ``feature_frequencies``), or None when the result records no plant."""
        from .plant import as_plant

        G = getattr(self, "plant", None)
        return None if G is None else as_plant(G)

    def plot(self, ax=None, **kwargs):
        """Nyquist picture of these cycles: :func:`dfloop.plot.nyquist.plot_nyquist` (python-control
        conventions).

        Parameters
        ----------
        ax : matplotlib Axes, optional
        **kwargs
            Passed to ``plot_nyquist`` (``n_loci``, ``omega`` and ``amplitude`` windows, ``inset``).

        Returns
        -------
        control.ControlPlot
        """
        from ..plot.nyquist import plot_nyquist

        return plot_nyquist(self, ax, **kwargs)


class DeferredReport(tuple):
    """The values of a :class:`GridReport` not built yet (shape, max_step_frequency, max_step_amplitude, n_jumps,
    candidate_cells, n_evaluations, rejected; the rules "exact" along omega and "sampled" along A, the compiled
    driver's): :attr:`LimitCycles.grid_report` builds it when first read."""

    __slots__ = ()

    def build(self) -> GridReport:
        shape, step_v, step_a, n_jumps, n_cand, n_eval, rejected = self
        return assembled(GridReport, shape=shape, frequency_rule="exact", amplitude_rule="sampled",
                         max_step_frequency=step_v, max_step_amplitude=step_a, n_jumps=n_jumps, candidate_cells=n_cand,
                         n_evaluations=n_eval, rejected=rejected)


def assembled(cls, **values):
    """``cls(**values)`` for :class:`LimitCycle` and :class:`GridReport`, built without the per-field
    ``object.__setattr__`` of a frozen dataclass's ``__init__`` (about 2 us of a compiled solver call that takes
    tens): the same instance, every field set (defaults filled); neither class has a ``__post_init__``. A name
    that is not a field raises TypeError, as the constructor does."""
    defaults, names = _FIELDS[cls]
    if not names.issuperset(values):
        raise TypeError(f"{cls.__name__} has no field(s) {sorted(set(values) - names)}")
    obj = object.__new__(cls)
    d = obj.__dict__
    d.update(defaults)
    d.update(values)
    if len(d) != len(names):
        raise TypeError(f"{cls.__name__} missing field(s) {sorted(names - set(d))}")
    return obj


def _field_table(cls):
    from dataclasses import MISSING, fields

    fs = fields(cls)
    return {f.name: f.default for f in fs if f.default is not MISSING}, frozenset(f.name for f in fs)


_FIELDS = {cls: _field_table(cls) for cls in (LimitCycle, GridReport)}
