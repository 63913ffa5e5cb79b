"""The compiled form of a loop: :class:`CompiledResidual`, a :class:`~dfloop.solve.roots.Residual` whose
evaluations and refinement run in the numba kernels of :mod:`.kernels`.

Where it applies: a rational G (tf or ss, continuous, optionally with the pure delay of a
:class:`~dfloop.solve.delay.DelayedSystem`) and an element whose ``compiled_form()`` returns a kind and its
parameters (the built-in static elements with closed-form DFs). Everything else (callables, frd, sampled
plants, frequency-dependent, numeric and user-defined elements) keeps the Python residual. The environment
variable ``DFLOOP_COMPILED=0`` forces the Python path everywhere (the reference the tests compare with).

Two layers: the compiled driver (:mod:`.driver`, reached through :func:`driver_parts` and :func:`run_driver`, or
:func:`run_batch` for many loops) runs a whole prediction in one numba call and hands every branch it does not
carry back to the Python driver (:func:`dfloop.predict_limit_cycles`), which then uses this residual: the same
grid rule, winding tests, tangent and continuum searches, with the evaluation of G, N and their slopes and the
Levenberg-Marquardt refinement compiled. Each part announces its first compile (:func:`_announce_compile`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..._checks import environ
from ...progress import announce_compile
from ..plant import Plant
from ..roots import Residual
from .kinds import KINDS
from .parts import element_part, plant_part


class _Kernels:
    """The numba kernels (:mod:`.kernels`), imported on first use: a loop that cannot be compiled (a callable G,
    a user's element) loads no numba."""

    def __getattr__(self, name):
        from . import kernels

        return getattr(kernels, name)


K = _Kernels()

__all__ = ["CompiledResidual", "compiled_loop", "driver_parts", "element_form", "residual_for", "enabled", "prepare",
           "run_batch", "run_driver", "warmup", "driver_wanted", "COMPILE_SECONDS"]

COMPILE_SECONDS = 50
"""About how long compiling the driver takes once per installation (s; benchmarks/bench_startup.py)."""
RESIDUAL_SECONDS = 6
"""About how long compiling the compiled residual's kernels takes (s; benchmarks/bench_startup.py)."""
BATCH_COMPILE_SECONDS = 6
"""About how long the batch driver (the rows of a batch, run by threads) adds to it (s; benchmarks/bench_startup.py)."""
_CHECK_W = np.array([0.37, 1.0, 2.9])  # frequencies (rad/s) where the extracted coefficients are checked
_MEMO_BATCH, _MEMO_SIZE = 64, 8192  # refined batches remembered (as Residual.slopes does)


def _kernels(part: str | None = None) -> tuple:
    """The numba dispatchers of one part of the compiled path: ``"driver"`` (a whole call), ``"residual"`` (the
    kernels of the Python driver's compiled residual, where the driver hands over), ``"batch"`` (the driver's
    form over the rows of a batch), or all (None)."""
    from . import driver

    parts = {"driver": (driver.solve_one_dispatcher(), driver.kept_seeds_dispatcher(),
                        driver.apart_cells_dispatcher()),
             "residual": (K.refine, K.evaluate_slopes, K.products, K.plant_values, K.element_values),
             "batch": (driver.solve_many_dispatcher(),)}
    return parts[part] if part is not None else sum(parts.values(), ())


def mode() -> str:
    """The value of ``DFLOOP_COMPILED`` (``"1"`` when unset): read once per call of the solver and handed down
    (the environment may change between calls, e.g. in tests)."""
    value = environ("DFLOOP_COMPILED")
    return "1" if value is None else value


def enabled(mode_: str | None = None) -> bool:
    """Whether the compiled path is used where it applies: always, unless ``DFLOOP_COMPILED=0`` in the
    environment selects the Python reference path (``mode_``: that variable's value when already read, see
    :func:`mode`). The first use on a fresh install compiles the residual's kernels (a few seconds), announced on
    the progress channel. Whether a single call also runs the compiled driver is :func:`driver_wanted`.
    """
    return (mode() if mode_ is None else mode_) != "0"


_DRIVER_READY: list = []   # [True] once the driver is known to be compiled or cached in this process


def driver_wanted(mode_: str | None = None) -> bool:
    """Whether a single :func:`dfloop.predict_limit_cycles` call runs the compiled driver (:mod:`.driver`).

    ``DFLOOP_COMPILED=0``: never. ``DFLOOP_COMPILED=driver``: always (compiling it first if needed, announced).
    Otherwise (the default): when the driver is ready, compiled in this process or in numba's on-disk cache (after
    ``dfloop warmup``, or any earlier process that compiled it). A fresh installation does not make a
    single call wait about ``COMPILE_SECONDS`` for it: the call runs the Python driver on the compiled residual
    (the same algorithm; results agree to 1e-12, tests/test_compiled.py), and says once that ``dfloop warmup``
    compiles the driver. Batches (:func:`dfloop.predict_many`) compile it, announced: their loops amortise it.
    ``mode_``: the value of ``DFLOOP_COMPILED`` when already read (:func:`mode`).
    """
    mode_ = mode() if mode_ is None else mode_
    if mode_ == "0":
        return False
    if mode_ == "driver" or _DRIVER_READY:
        return True
    from ...progress import announce, compile_pending

    if compile_pending(*_kernels("driver")) is False:
        _DRIVER_READY.append(True)
        return True
    if not _DRIVER_HINTED:
        _DRIVER_HINTED.append(True)
        announce(f"dfloop: the compiled solver driver is not compiled on this installation: this run uses the "
                 f"standard path (same results, 10-60x slower per call); `dfloop warmup` compiles the driver once "
                 f"(about {COMPILE_SECONDS} s)")
    return False


_DRIVER_HINTED: list = []


def prepare() -> None:
    """Make the kernels ready for the calls to come (a batch, before its progress starts): compile them, or load
    them from numba's cache, announcing a compile first (:func:`dfloop.progress.announce_compile`). Nothing when
    ``DFLOOP_COMPILED=0``."""
    if enabled() and not all(d.signatures for d in _kernels()):
        warmup()


def _coefficients(plant: Plant):
    """(num, den, delay) of a rational continuous plant, read from its response, or None.

    The coefficients are the ones :class:`Plant` evaluates (its closure); they are checked against the plant
    itself at a few frequencies, so a plant built any other way is never evaluated wrongly, only not compiled.
    """
    if plant.roots is None or plant.frequency_map is not None or plant.dt is not None:
        return None
    fn, delay = plant.response, float(plant.delay)
    cells = dict(zip(fn.__code__.co_freevars, (c.cell_contents for c in (fn.__closure__ or ()))))
    if delay != 0.0:
        inner = cells.get("inner")
        if inner is None or cells.get("T") != delay:
            return None
        cells = dict(zip(inner.__code__.co_freevars, (c.cell_contents for c in (inner.__closure__ or ()))))
    num, den = cells.get("num"), cells.get("den")
    if not (isinstance(num, np.ndarray) and isinstance(den, np.ndarray)):
        return None
    num, den = np.ascontiguousarray(num, float), np.ascontiguousarray(den, float)
    try:
        ref = plant(_CHECK_W)
    except ValueError:
        return None
    _announce_compile()  # the first kernel call below may compile them all
    got = K.plant_values(num, den, delay, _CHECK_W)
    if not np.allclose(got, ref, rtol=1e-13, atol=0.0):
        return None
    return num, den, delay


def _own_form(cls) -> bool:
    """Whether ``cls`` evaluates N where its ``compiled_form`` is defined: a subclass of a built-in element that
    overrides ``_evaluate`` or ``__call__`` (a user's variant) inherits a compiled form that is not its own.
    A fact of the class, remembered."""
    hit = _OWN_FORM.get(cls)
    if hit is None:
        owner = next((c for c in cls.__mro__ if "compiled_form" in c.__dict__), None)
        hit = _OWN_FORM[cls] = owner is not None and all(getattr(cls, name) is getattr(owner, name)
                                                         for name in ("_evaluate", "__call__"))
    return hit


_OWN_FORM: dict = {}


def compiled_loop(plant: Plant, N):
    """The arrays the kernels take for the loop (G, N), or None when either has no compiled form or the
    compiled path is not to be used now (:func:`enabled`)."""
    if not enabled() or _form(plant, N) is None:
        return None
    return _loop_arrays(plant, N)


def _form(plant: Plant, N):
    """The element's compiled form (kind, parameters) when G and N both have one (checked without numba)."""
    if plant.roots is None or plant.frequency_map is not None or plant.dt is not None:
        return None
    return element_form(N)


def element_form(N):
    """The compiled form (kind name, parameters) of an amplitude-only element, or None: no compiled form, a
    frequency-dependent element, or a user's subclass that evaluates N its own way."""
    if getattr(N, "frequency_dependent", True):
        return None
    form = getattr(N, "compiled_form", None)
    if form is None or not _own_form(type(N)):
        return None
    form = form()
    return form if form is not None and form[0] in KINDS else None


def _loop_arrays(plant: Plant, N):
    form = _form(plant, N)
    if form is None:
        return None
    coef = _coefficients(plant)
    if coef is None:
        return None
    zeros, poles = (np.ascontiguousarray(r, complex) for r in plant.roots)
    lo, hi = (float(np.asarray(x, float)) for x in N.amplitude_domain())  # static N: fixed edges
    with np.errstate(divide="ignore"):
        ln_lo, ln_hi = float(np.log(lo)), float(np.log(hi))
    return (*coef[:2], zeros, poles, coef[2], KINDS[form[0]], np.ascontiguousarray(form[1], float), ln_lo, ln_hi)


_SETTLED: set = set()  # parts (see _kernels) whose compile was announced or found unneeded in this process


def _announce_compile(part: str = "residual") -> None:
    """Say once, before the first compile of this installation, that ``part`` (see :func:`_kernels`) compiles and
    about how long it takes. Once said, or once the part is found compiled or cached, later calls cost a set
    lookup (a part compiled or cached stays so for the process)."""
    if part in _SETTLED:
        return
    what, seconds = {"driver": ("the solver", COMPILE_SECONDS), "batch": ("the batch solver", BATCH_COMPILE_SECONDS),
                     "residual": ("the solver's residual kernels", RESIDUAL_SECONDS)}[part]
    announce_compile(what, seconds, *_kernels(part))
    _SETTLED.add(part)


class CompiledResidual(Residual):
    """A :class:`~dfloop.solve.roots.Residual` evaluated by the numba kernels (same values, same interface),
    with a compiled :meth:`refine`."""

    def __init__(self, plant: Plant, N, loop):
        num, den, delay = loop[0], loop[1], loop[4]

        def response(w):  # G by the kernel wherever the driver evaluates the plant (checks stay Plant's)
            w = np.asarray(w, float)
            return K.plant_values(num, den, delay, np.ascontiguousarray(w.ravel())).reshape(w.shape)

        super().__init__(dataclasses.replace(plant, response=response), N)
        self._loop = loop
        self._gpart = (loop[0], loop[1], loop[4])
        self._npart = (loop[5], loop[6])
        _announce_compile()

    def _n(self, A, w):
        A = np.asarray(A, float)
        if A.ndim != 1 or not np.all(np.isfinite(A) & (A > 0)):
            return super()._n(A, w)
        n = K.element_values(*self._npart, np.ascontiguousarray(A))
        return super()._n(A, w) if np.isnan(n).any() else n  # the Python residual names the amplitude

    def _g(self, w: np.ndarray) -> np.ndarray:
        return K.plant_values(*self._gpart, np.ascontiguousarray(w, float))

    def terms(self, a, v) -> np.ndarray:
        a, v = np.broadcast_arrays(np.asarray(a, float), np.asarray(v, float))
        if a.ndim != 1:
            return super().terms(a, v)
        self.n_points += a.size
        return K.products(*self._gpart, *self._npart, np.exp(a), np.exp(v))

    def grid(self, a: np.ndarray, v: np.ndarray) -> np.ndarray:
        self.n_points += a.size * v.size
        return self._n(np.exp(a), None)[:, None] * self._g(np.exp(v))[None, :]

    def _evaluate_slopes(self, a: np.ndarray, v: np.ndarray):
        A, w = np.exp(a), np.exp(v)
        if not np.all(np.isfinite(A) & (A > 0)):
            return super()._evaluate_slopes(a, v)
        self.n_points += 3 * a.size
        out = K.evaluate_slopes(*self._loop, np.ascontiguousarray(a, float), np.ascontiguousarray(A),
                                np.ascontiguousarray(w))
        if np.isnan(out[4]).any():
            return super()._evaluate_slopes(a, v)
        return out[0], out[1], out[2], out[3], out[4]

    def kept_seeds(self, a, v, P, si, sj, bounds) -> np.ndarray | None:
        """The tangent seeds worth refining (:func:`dfloop.solve.roots._refined_seeds`), decided in the compiled
        driver's kernel (the same sound exclusion: the roots found do not change, only the work), or None (the
        Python decision) while the compiled driver is not ready: its kernels compile with the driver's
        (:func:`driver_wanted`), not on a single call of a fresh installation."""
        if not driver_wanted():
            return None
        from .driver import kept_seeds

        _announce_compile("driver")
        return kept_seeds(self._loop, a, v, P.n, P.g, bounds[0], bounds[1], si, sj)

    def apart_cells(self, a, v, P, ci, cj, bounds) -> np.ndarray | None:
        """The cells whose windings the Python driver passes over (:func:`dfloop.solve.roots._winding_cells`),
        decided in the compiled driver's kernel as the compiled driver decides, or None (the Python decision)
        while the compiled driver is not ready (as :meth:`kept_seeds`)."""
        if not driver_wanted():
            return None
        from .driver import apart_cells

        _announce_compile("driver")
        return apart_cells(self._loop, a, v, P.n, P.g, bounds[0], bounds[1], ci, cj)

    def refine(self, a, v, box, tol: float, certified: bool = False):
        """:func:`dfloop.solve.roots.refine` in the kernels (point by point; the same iteration)."""
        a, v = np.array(a, float).ravel(), np.array(v, float).ravel()
        lo_a, hi_a, lo_v, hi_v = (np.ascontiguousarray(np.broadcast_to(x, a.shape), float)
                                  for x in (box.a_lo, box.a_hi, box.v_lo, box.v_hi))
        ra, rv, ok, vals, evaluated = K.refine(*self._loop, a, v, lo_a, hi_a, lo_v, hi_v, float(tol),
                                                   bool(certified))
        self.n_points += int(evaluated)
        if a.size <= _MEMO_BATCH:  # remembered as the Python refinement's last evaluations are
            if len(self._memo) + a.size > _MEMO_SIZE:
                self._memo.clear()
            self._memo.update(zip(zip(ra.tolist(), rv.tolist()), zip(*(x.tolist() for x in vals))))
        return ra, rv, ok


def driver_parts(G, N, mode_: str | None = None):
    """(plant part, element part) of the loop for the compiled driver (:mod:`.driver`), or None where it does not
    apply: the compiled path switched off, an element without a compiled form (or one the driver does not mirror),
    a plant that is not a rational continuous tf/ss (with or without a pure delay). Loads no numba. ``mode_``: the
    value of ``DFLOOP_COMPILED`` when already read (:func:`mode`)."""
    if not enabled(mode_):
        return None
    npart = element_part(N, element_form)
    if npart is None:
        return None
    gpart = plant_part(G)
    if gpart is None:  # a state-space form: its polynomials as the Python path reads them (checked there)
        from .. import plant as plant_module

        try:
            plant = plant_module.as_plant(G)
        except (ValueError, TypeError):
            return None
        coef = _coefficients(plant) if _form(plant, N) is not None else None
        if coef is None:
            return None
        gpart = (coef[0], coef[1], *(np.ascontiguousarray(r, complex) for r in plant.roots), coef[2])
    return gpart, npart


def run_driver(gpart, npart, w_lo, w_hi, A_lo, A_hi, na, nw, tol, marginal_tol, mem_limit=None):
    """The compiled driver on one loop (windows NaN: the defaults; ``mem_limit``: the memory bound in bytes when
    already read), announcing a first compile: (status, floats, ints, roots) (:func:`.driver.solve_one`)."""
    _announce_compile("driver")
    solve_one = _SOLVE_ONE[0] if _SOLVE_ONE else _load_solve_one()
    return solve_one(gpart, npart, w_lo, w_hi, A_lo, A_hi, na, nw, tol, marginal_tol, mem_limit)


_SOLVE_ONE: list = []  # the driver's entry, imported on first use (importing it loads numba)


def _load_solve_one():
    from .driver import solve_one

    _SOLVE_ONE.append(solve_one)
    return solve_one


def run_batch(parts, windows, na, nw, tol, marginal_tol):
    """The compiled driver over many loops, shared among threads (:func:`.driver.solve_many`), announcing a first
    compile: arrays (status, floats, ints, roots, root counts), one row per loop."""
    from .driver import solve_many

    _announce_compile("batch")
    return solve_many(parts, windows, na, nw, tol, marginal_tol)


def residual_for(plant: Plant, N) -> Residual:
    """The residual of the loop: compiled where :func:`compiled_loop` applies, the Python one otherwise."""
    loop = compiled_loop(plant, N)
    return Residual(plant, N) if loop is None else CompiledResidual(plant, N, loop)


def warmup() -> float:
    """Compile (or load from numba's cache) every kernel of the compiled path; returns the seconds spent."""
    import time

    import control as ct

    from ...describing.static import Backlash
    from ..plant import as_plant

    t0 = time.perf_counter()
    plant, N = as_plant(ct.tf([5.0], [1.0, 1.0, 0.0])), Backlash(1.0)
    loop = _loop_arrays(plant, N)
    if loop is not None:
        res = CompiledResidual(plant, N, loop)
        a, v = np.array([0.0]), np.array([0.5])
        res.terms(a, v)
        res.grid(a, v)
        res._evaluate_slopes(a, v)
        from ..roots import Box, OuterProduct

        res.refine(a, v, Box(-1.0, 1.0, 0.0, 1.0), 1e-10, True)
        ga, gv = np.linspace(0.0, 1.0, 6), np.linspace(-1.0, 1.0, 6)  # the tangent seeds' exclusion
        P = OuterProduct(res._n(np.exp(ga), None), res._g(np.exp(gv)))
    parts = driver_parts(ct.tf([5.0], [1.0, 1.0, 0.0]), N)
    if parts is not None:  # the driver, for one loop and for a batch, and its kernels for the Python driver
        nan = float("nan")
        run_driver(*parts, nan, nan, nan, nan, 8, 16, 1e-10, 1e-4)
        run_batch([parts], [(nan, nan, nan, nan)], 8, 16, 1e-10, 1e-4)
        if loop is not None:  # called directly: the residual's methods use them only once the driver is ready
            from .driver import apart_cells, kept_seeds

            args = (loop, ga, gv, P.n, P.g, np.full(5, 0.1), np.full(5, 0.1), np.array([2]), np.array([3]))
            kept_seeds(*args)
            apart_cells(*args)
    return time.perf_counter() - t0
