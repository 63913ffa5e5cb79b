"""python-control interoperability: any nonlinearity python-control accepts, as a dfloop element.

:func:`as_element` turns python-control's nonlinearity objects and plain static functions f(x) into
:class:`~dfloop.DescribingFunction` objects (the other direction, dfloop elements inside python-control's
``describing_function_response`` / ``describing_function_plot``, is :meth:`DescribingFunction.describing_function`).

Mapping (exact in every case, python-control's parameter names in the errors):

=========================================================  ================================================
python-control object                                      dfloop element
=========================================================  ================================================
``saturation_nonlinearity(ub)`` (symmetric, lb = -ub)      :class:`~dfloop.Saturation` ``(limit=ub)``
``saturation_nonlinearity(ub, lb)`` (asymmetric)           :class:`~dfloop.NumericDF` with breakpoints ub, lb
``friction_backlash_nonlinearity(b)``                      :class:`~dfloop.Backlash` ``(h=b)``
``relay_hysteresis_nonlinearity(b, c)``                    :class:`~dfloop.Relay` ``(M=b, hysteresis=c)``
any other object with a ``describing_function(A)`` method  :class:`ControlDescribingFunction` (its values)
a static SISO ``control.nlsys`` (no states)                 :class:`~dfloop.NumericDF` of its output map
a callable f(x) without one                                :class:`~dfloop.NumericDF` (switching points
                                                           located), static or hysteretic (see below)
=========================================================  ================================================

A plain callable is treated as a static map y = f(x) unless it has memory: ``hysteretic=True``, an object
whose ``_isstatic()`` (python-control's convention) is False and whose outputs differ between rising and
falling input sweeps (probed over amplitudes 1e-6 ... 1e6), is wrapped as a rate-independent hysteretic operator.

The other direction, in one call, is :func:`to_control` (dfloop element -> python-control object), and
:func:`control_loop` builds the closed loop of the paper's Fig. 1 as a python-control ``nlsys`` for
``control.input_output_response``. The two calling conventions differ, which is why a conversion is needed:
python-control calls a nonlinearity as its time-domain map y = F(x) (``describing_function(..., try_method=False)``,
its simulations), a dfloop element's call is its describing function N(A, w).

=====================================================  =========================================================
dfloop element                                         :func:`to_control` gives
=====================================================  =========================================================
static (Saturation, DeadZone, Relay without             ``ControlNonlinearity``: ``F(x)`` the static map,
hysteresis, CubicStiffness, NumericDF of a function,   ``_isstatic()`` True, ``describing_function(A)`` dfloop's
...)                                                   N(A); ``to_nlsys()`` a static ``nlsys``
hysteretic (Backlash, Relay with hysteresis,           ``ControlNonlinearity``: ``F(x)`` the stateful operator from
hysteretic NumericDF)                                  rest (python-control's own convention for its
                                                       friction_backlash_nonlinearity), ``_isstatic()`` False;
                                                       ``to_nlsys(dt)`` a discrete-time ``nlsys`` whose state is
                                                       the play (Backlash, Relay, and a hysteretic NumericDF of
                                                       dfloop's PlayOperator or RelayOperator)
dynamic (LinearThenStatic, MassBacklash)               a continuous-time ``nlsys``: the linear block's states and
                                                       the static part's play (a proper block with D != 0 before
                                                       a play: in :func:`control_loop` only, which knows the
                                                       input's rate)
DynamicBacklash                                        with ``dt``: a discrete-time ``nlsys`` (force on M2 in,
                                                       x1 out, state [x1, v1, gap, v2 - v1]) whose step is the
                                                       exact motion over a sample with the force held; without:
                                                       ``ValueError`` (impacts are velocity jumps, no
                                                       continuous-time ``nlsys``); its closed loop runs exactly
                                                       in :func:`dfloop.verify.simulate_loop`
=====================================================  =========================================================

Backlash and relays share one state model: the play operator c = clip(c, x - a, x + a) of half-width a (a = h/2
for backlash, output k c; a = the hysteresis for a relay, output M [c > d] - M [c < -d] with d its dead zone,
which switches on at x = d + a and off at d - a exactly as :class:`~dfloop.Relay`). In continuous time the play
moves with the input's rate when engaged, dc/dt = dx/dt if |x - c| >= a and x moves outward, else 0; inside
:func:`control_loop` that rate is known from the plant's state (x = r - C z, dx/dt = -C (A z + B y) for a
constant r), so the loop is an ordinary ``nlsys``. The output uses clip(c, x - a, x + a), so the integration
error of c never shows as a violation of the play.
"""
from __future__ import annotations

import copy
import functools
import sys
from typing import Any

import numpy as np

from .._checks import finite, nonnegative, positive
from ..errors import DfloopError
from .base import DescribingFunction
from .composition import LinearThenStatic
from .numeric import NumericDF
from .static import Backlash, PlayOperator, Relay, RelayOperator, Saturation, StaticElement
from .time_model import impact_model

__all__ = ["as_element", "ControlDescribingFunction", "to_control", "control_loop", "control_initial_state"]

_PROBE_SCALES = 10.0 ** np.arange(-6, 7)  # input scales at which a callable is probed for memory
_SWEEP = np.arange(-8, 9) / 8.0  # exact binary fractions: rising and falling sweeps visit identical inputs


class ControlDescribingFunction(DescribingFunction):
    """An amplitude-only element whose N(A) is an object's own ``describing_function(A)`` method.

    Wraps objects that follow python-control's ``DescribingFunctionNonlinearity`` protocol (any object
    with a ``describing_function(A)`` returning the complex N at a scalar amplitude). Values are the
    object's, unchanged; a NaN it returns for a finite amplitude raises ``ValueError`` (a silent NaN
    would look like "no cycle here").

    Parameters
    ----------
    nonlinearity : object
        Object with a ``describing_function(A: float) -> complex`` method.
    input_name, input_unit : str
        Name and unit of the input amplitude.
    """

    def __init__(self, nonlinearity: Any, input_name: str = "A", input_unit: str = ""):
        if not callable(getattr(nonlinearity, "describing_function", None)):
            raise ValueError(
                f"nonlinearity must have a describing_function(A) method, got {type(nonlinearity).__name__}")
        self.nonlinearity = nonlinearity
        self.input_name, self.input_unit = input_name, input_unit

    def _evaluate(self, A, omega):
        flat = A.ravel()
        out = np.full(flat.shape, complex(np.nan, np.nan))
        for i, a in enumerate(flat):
            if np.isnan(a):
                continue
            n = complex(self.nonlinearity.describing_function(float(a)))
            if np.isnan(n.real) or np.isnan(n.imag):
                raise ValueError(
                    f"{type(self.nonlinearity).__name__}.describing_function({self.input_name}={a!r}) returned NaN")
            out[i] = n
        return out.reshape(A.shape)

    def __repr__(self) -> str:
        return f"ControlDescribingFunction({self.nonlinearity!r})"


def _control_class(name: str):
    """python-control's class ``name`` if control is already imported (its objects cannot exist otherwise)."""
    module = sys.modules.get("control.descfcn")
    return getattr(module, name, None) if module is not None else None


def _is(obj, name: str) -> bool:
    cls = _control_class(name)
    return cls is not None and type(obj) is cls  # exact type: a subclass may override the map or its DF


def _scalar(f, x: float) -> float:
    """f(x) as a float; python-control allows a one-element array as the output."""
    try:
        y = np.asarray(f(x), dtype=float)
    except Exception as err:  # noqa: BLE001 - report any failure of user code as bad input, with the input
        raise ValueError(f"the nonlinearity failed at x = {x!r}: {type(err).__name__}: {err}") from err
    if y.size != 1:
        raise ValueError(f"the nonlinearity must return one number per input; f({x!r}) has shape {y.shape}")
    return float(y.reshape(()))


def _has_memory(f) -> bool:
    """True when a copy of ``f`` answers differently for the same input on falling and rising sweeps."""
    try:
        op = copy.deepcopy(f)
    except Exception:  # noqa: BLE001 - an object that cannot be copied is probed in place
        op = f
    for scale in _PROBE_SCALES:
        _scalar(op, 0.0)
        for x in scale * _SWEEP[8:]:  # 0 -> +s
            _scalar(op, x)
        falling = [_scalar(op, x) for x in scale * _SWEEP[::-1]]  # +s -> -s
        rising = [_scalar(op, x) for x in scale * _SWEEP]  # -s -> +s
        if not np.array_equal(np.array(falling[::-1]), np.array(rising), equal_nan=True):
            return True
    return False


def _vectorised(f):
    """``f`` itself when it maps arrays elementwise (checked against scalar calls), else a vectorised wrapper."""
    probe = np.outer(_PROBE_SCALES, _SWEEP)
    expected = np.array([[_scalar(f, x) for x in row] for row in probe])
    try:
        with np.errstate(all="ignore"):
            got = np.asarray(f(probe), dtype=float)
        if got.shape == probe.shape and np.array_equal(got, expected, equal_nan=True):
            return f
    except Exception:  # noqa: BLE001 - scalar-only code (math functions, if/else on x) fails on arrays
        pass
    return _Elementwise(f)


class _Elementwise:
    """A scalar-only f(x) applied elementwise to arrays (repr: the wrapped function's)."""

    def __init__(self, f):
        self.f = f

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        return np.array([_scalar(self.f, v) for v in x.ravel()]).reshape(x.shape)

    def __repr__(self) -> str:
        return repr(self.f)


def _from_control(obj) -> DescribingFunction | None:
    """dfloop's analytic element for python-control's built-in nonlinearities (None for anything else)."""
    if _is(obj, "saturation_nonlinearity"):
        ub, lb = finite("ub", obj.ub), finite("lb", obj.lb)
        if lb == -ub:
            return Saturation(limit=positive("ub", ub))
        if not lb < 0 < ub:
            raise ValueError(f"saturation_nonlinearity needs lb < 0 < ub, got lb={lb}, ub={ub}")
        return NumericDF(obj, breakpoints=[ub, -lb])  # bias ignored, as python-control does
    if _is(obj, "friction_backlash_nonlinearity"):
        return Backlash(h=positive("b", obj.b))
    if _is(obj, "relay_hysteresis_nonlinearity"):
        return Relay(M=positive("b", obj.b), hysteresis=nonnegative("c", obj.c))
    return None


def _check_not_a_system(obj) -> None:
    """python-control systems are callable too: only a static SISO nonlinear system is an element."""
    iosys = sys.modules.get("control.iosys")
    if iosys is None or not isinstance(obj, iosys.InputOutputSystem):
        return
    lti = sys.modules.get("control.lti")
    if lti is not None and isinstance(obj, lti.LTI):
        raise ValueError(f"N is a linear system ({type(obj).__name__}): it belongs in the plant G; the element N "
                         "must be a nonlinearity")
    if obj.nstates != 0 or obj.ninputs != 1 or obj.noutputs != 1:
        raise ValueError(f"N must be a static SISO input/output system to act as a nonlinearity; got one with "
                         f"{obj.nstates} states, {obj.ninputs} inputs, {obj.noutputs} outputs (move its dynamics "
                         "into the plant G, or wrap a rate-independent operator as NumericDF(op, hysteretic=True))")


def as_element(obj, *, hysteretic: bool | None = None) -> DescribingFunction:
    """Any nonlinearity python-control accepts, as a dfloop :class:`~dfloop.DescribingFunction`.

    Parameters
    ----------
    obj : DescribingFunction, python-control nonlinearity, object with ``describing_function``, or callable
        A dfloop element is returned unchanged. python-control's ``saturation_nonlinearity``,
        ``friction_backlash_nonlinearity`` and ``relay_hysteresis_nonlinearity`` become dfloop's analytic
        elements with the same parameters; any other object with a ``describing_function(A)`` method is
        wrapped as :class:`ControlDescribingFunction` (falling back to the numeric DF of its map when the
        method raises ``NotImplementedError``); a callable f(x) becomes a :class:`~dfloop.NumericDF` (exact
        quadrature, switching points located). Scalar-only callables are vectorised.
    hysteretic : bool, optional
        For callables: treat ``obj`` as a stateful rate-independent operator (True) or a static map y = f(x)
        (False). Default: static when ``obj._isstatic()`` says so, otherwise decided by probing a copy of
        ``obj`` for memory (outputs that differ between falling and rising sweeps of the same inputs at
        scales 1e-6 ... 1e6). Pass it explicitly for memory that only shows outside that range.

    Returns
    -------
    DescribingFunction

    Raises
    ------
    ValueError
        For anything else (naming what is accepted), and for invalid parameters of python-control's
        objects (named as python-control names them: ``ub``, ``lb``, ``b``, ``c``).

    Examples
    --------
    >>> import control as ct
    >>> as_element(ct.saturation_nonlinearity(2.0))
    Saturation(limit=2.0, k=1.0)
    """
    if isinstance(obj, DescribingFunction):
        return obj
    if not callable(obj) and not hasattr(obj, "describing_function"):
        raise ValueError(
            f"N must be a dfloop DescribingFunction (e.g. Saturation, Backlash, Relay), a python-control "
            f"nonlinearity (an object with a describing_function(A) method) or a callable static map f(x) "
            f"(wrapped as NumericDF); got {type(obj).__name__}: {obj!r}")
    _check_not_a_system(obj)
    known = _from_control(obj)
    if known is not None:
        return known
    if callable(getattr(obj, "describing_function", None)):
        try:
            obj.describing_function(1.0)
        except NotImplementedError:
            pass  # python-control's convention: compute the DF numerically from the map
        else:
            return ControlDescribingFunction(obj)
    if not callable(obj):
        raise ValueError(f"{type(obj).__name__} has no usable describing_function and is not callable")
    if hysteretic is None:
        static_flag = getattr(obj, "_isstatic", None)
        hysteretic = not (callable(static_flag) and static_flag()) and _has_memory(obj)
    if hysteretic:
        return NumericDF(obj, hysteretic=True)
    return NumericDF(_vectorised(obj), hysteretic=False)


# ------------------------------------------------------------------------- dfloop -> python-control
class _StaticModel:
    """y = f(x), no state."""

    nstates = 0
    needs_rate = False

    def __init__(self, f):
        self.f = f

    def output(self, s, u: float) -> float:
        return float(np.asarray(self.f(np.array([u], dtype=float)), dtype=float).reshape(-1)[0])

    def rate(self, s, u: float, udot: float) -> np.ndarray:
        return np.empty(0)

    def step(self, s, u: float) -> np.ndarray:
        return np.empty(0)

    def initial(self, X: complex, w: float) -> np.ndarray:
        return np.empty(0)


class _PlayModel:
    """A play of half-width ``a`` (state c, the driven side) followed by ``out(c)``."""

    nstates = 1
    needs_rate = True

    def __init__(self, a: float, out):
        self.a, self.out = a, out

    def _engaged(self, c: float, u: float) -> float:
        return min(max(c, u - self.a), u + self.a)

    def output(self, s, u: float) -> float:
        return float(self.out(self._engaged(float(s[0]), u)))

    def rate(self, s, u: float, udot: float) -> np.ndarray:
        gap = u - float(s[0])
        moving = (gap >= self.a and udot > 0.0) or (gap <= -self.a and udot < 0.0)
        return np.array([udot if moving else 0.0])

    def step(self, s, u: float) -> np.ndarray:
        return np.array([self._engaged(float(s[0]), u)])

    def initial(self, X: complex, w: float) -> np.ndarray:
        # the play at t = 0 in the periodic regime of x = Im(X e^{jwt}): since the last extremum -/+|X| it was
        # held at -|X| + a (+|X| - a) until dragged along at x -/+ a; at rest (c = 0) if |X| <= a
        amp, x0 = abs(X), X.imag
        if amp <= self.a:
            return np.array([0.0])
        rising = X.real >= 0.0          # dx/dt(0) = w Re(X)
        return np.array([max(self.a - amp, x0 - self.a) if rising else min(amp - self.a, x0 + self.a)])


class _LinearModel:
    """A proper linear block (A, B, C, D) followed by an element model (input C z + D u).

    With D != 0 and an inner play, the play's rate needs the input's rate du/dt (``needs_rate``): known inside
    :func:`control_loop` (from the plant's state), not in a standalone ``nlsys``."""

    def __init__(self, A, B, C, inner, D: float = 0.0):
        self.A, self.B, self.C, self.D, self.inner = A, B, C, float(D), inner
        self.n = A.shape[0]
        self.nstates = self.n + inner.nstates
        self.needs_rate = self.D != 0.0 and inner.needs_rate

    def output(self, s, u: float) -> float:
        return self.inner.output(s[self.n:], float(self.C @ s[:self.n]) + self.D * u)

    def rate(self, s, u: float, udot: float) -> np.ndarray:
        z = s[:self.n]
        zdot = self.A @ z + self.B * u
        return np.concatenate([zdot, self.inner.rate(s[self.n:], float(self.C @ z) + self.D * u,
                                                     float(self.C @ zdot) + self.D * udot)])

    def step(self, s, u: float) -> np.ndarray:
        raise ValueError("a linear block has no discrete-time model here: use the continuous-time system")

    def initial(self, X: complex, w: float) -> np.ndarray:
        Z = np.linalg.solve(1j * w * np.eye(self.n) - self.A, self.B) * X   # the block's periodic state phasor
        return np.concatenate([Z.imag, self.inner.initial(complex(self.C @ Z) + self.D * X, w)])


def _relay_output(M: float, d: float):
    return lambda c: M * (float(c > d) - float(c < -d))


def _ss_matrices(G, name: str, *, proper_only: bool = True):
    """(A, B, C) of a SISO python-control tf/ss (``ValueError`` naming ``name`` otherwise); with
    ``proper_only=False`` (A, B, C, D), D a float."""
    import control as ct

    if not isinstance(G, (ct.TransferFunction, ct.StateSpace)) or G.ninputs != 1 or G.noutputs != 1:
        raise ValueError(f"{name} must be a SISO python-control tf or ss system, got {type(G).__name__}: {G!r}")
    if not G.isctime():
        raise ValueError(f"{name} must be a continuous-time system, got dt = {G.dt!r}")
    s = ct.ss(G)
    if proper_only and np.any(np.asarray(s.D) != 0):
        raise ValueError(f"{name} must be strictly proper (D = 0: a direct feedthrough closes an algebraic loop "
                         f"through the element), got D = {float(np.asarray(s.D).ravel()[0])!r}")
    mats = np.asarray(s.A, float), np.asarray(s.B, float)[:, 0], np.asarray(s.C, float)[0]
    return mats if proper_only else (*mats, float(np.asarray(s.D).ravel()[0]))


def _model(N):
    """The state model of an element for python-control systems, or None (no model: say why at the caller)."""
    if isinstance(N, StaticElement):
        return _StaticModel(N.output)
    if type(N) is Backlash:
        k = N.k
        return _PlayModel(0.5 * N.h, lambda c: k * c)
    if type(N) is Relay:
        out = _relay_output(N.M, N.dead_zone)
        return _StaticModel(np.vectorize(out, otypes=[float])) if N.hysteresis == 0.0 else _PlayModel(N.hysteresis, out)
    if isinstance(N, NumericDF) and not N.hysteretic:
        return _StaticModel(N.element)
    if isinstance(N, NumericDF) and type(N.element) is PlayOperator:   # its state is the play: a state vector
        k = N.element.k
        return _PlayModel(0.5 * N.element.h, lambda c: k * c)
    if isinstance(N, NumericDF) and type(N.element) is RelayOperator:
        op = N.element                       # on = d + a, off = d - a
        return _PlayModel(0.5 * (op.on - op.off), _relay_output(op.M, 0.5 * (op.on + op.off)))
    if isinstance(N, ControlDescribingFunction):
        f = N.nonlinearity
        static = getattr(f, "_isstatic", None)
        return _StaticModel(_vectorised(f)) if callable(f) and callable(static) and static() else None
    if isinstance(N, LinearThenStatic):
        ct = sys.modules.get("control")
        inner = _model(N.static)
        if inner is None:
            return None
        if callable(getattr(N.linear, "state_space", None)):   # dfloop's own blocks (MassBacklash's rigid mass)
            return _LinearModel(*N.linear.state_space(), inner)
        if ct is None or not isinstance(N.linear, ct.LTI):
            return None
        A, B, C, D = _ss_matrices(N.linear, "the element's linear block", proper_only=False)
        return _LinearModel(A, B, C, inner, D)
    return None


def _no_model(N) -> ValueError:
    why = ("its impacts (velocity jumps) are no continuous-time python-control nlsys: dfloop.to_control(N, dt=...) "
           "gives the element sampled (exact for a force held over each sample), and "
           "dfloop.verify.simulate_loop(G, N, amplitude, frequency) runs its closed loop on the exact impact engine"
           if impact_model(N) is not None else
           "it has no state model here (a hysteretic NumericDF of an operator other than dfloop's play or relay "
           "keeps its state inside that operator; a LinearThenStatic needs a python-control tf/ss linear block)")
    return ValueError(f"N = {N!r} cannot be converted to a python-control system: {why}")


def _fresh_operator(N):
    """The element's time-domain operator at rest (None for a static map)."""
    if isinstance(N, NumericDF):
        return copy.deepcopy(N.element) if N.hysteretic else None
    if isinstance(N, StaticElement) or (type(N) is Relay and N.hysteresis == 0.0):
        return None
    if isinstance(N, ControlDescribingFunction):
        static = getattr(N.nonlinearity, "_isstatic", None)
        return None if callable(static) and static() else copy.deepcopy(N.nonlinearity)
    return N.operator()


@functools.lru_cache(maxsize=1)
def _nonlinearity_class():
    import control as ct

    class ControlNonlinearity(ct.DescribingFunctionNonlinearity):
        """A dfloop element as a python-control nonlinearity (made by :func:`dfloop.to_control`).

        ``F(x)`` is the element's time-domain map (scalar or array input, applied in order for a hysteretic
        element, whose state starts at rest; :meth:`reset` puts it back), ``describing_function(A)`` is dfloop's
        N(A) (python-control's convention: ``ValueError`` "cannot evaluate describing function for A < 0"),
        ``_isstatic()`` says whether F has memory, and ``element`` is the dfloop element.
        """

        def __init__(self, element):
            super().__init__()
            self.element = element
            self._static_map = None
            self.reset()
            if self._op is None:
                model = _model(element)
                self._static_map = model.f if model is not None else element.output

        def reset(self) -> None:
            """Put a hysteretic element's state back at rest (no effect for a static map)."""
            self._op = _fresh_operator(self.element)

        def __call__(self, x):
            if self._op is None:
                y = np.asarray(self._static_map(np.asarray(x, dtype=float)), dtype=float)
                return float(y) if y.ndim == 0 else y
            arr = np.asarray(x, dtype=float)
            if arr.ndim == 0:
                return float(self._op(float(arr)))
            return np.array([float(self._op(float(v))) for v in arr.ravel()]).reshape(arr.shape)

        def describing_function(self, A):
            a = float(A)
            if not a >= 0.0:
                raise ValueError(f"cannot evaluate describing function for A < 0 (got A = {A!r})")
            try:
                return complex(self.element(a))
            except DfloopError:
                if a == 0.0:  # no limit at A = 0 (a numeric DF): python-control then computes it from F
                    raise NotImplementedError("no describing-function value at A = 0 for this element") from None
                raise

        def _isstatic(self) -> bool:
            return self._op is None

        def to_nlsys(self, dt: float | None = None, name: str | None = None):
            """The element as a python-control ``nlsys`` (input ``x``, output ``y``).

            A static element gives a static ``nlsys`` (no state). Backlash and relays with hysteresis give a
            discrete-time ``nlsys`` with sampling period ``dt`` (s, > 0) whose state is the play (the exact
            operator at the samples; also a hysteretic NumericDF of dfloop's PlayOperator or RelayOperator); in
            continuous time the play needs its input's rate, which only a closed loop provides:
            :func:`dfloop.control_loop`.
            """
            model = _model(self.element)
            if model is None:
                raise _no_model(self.element)
            if model.nstates == 0:
                return ct.nlsys(None, lambda t, s, u, p: np.array([model.output(s, float(np.ravel(u)[0]))]), inputs=["x"],
                                outputs=["y"], name=name)
            if dt is None:
                raise ValueError(f"dt is required for {self.element!r}: its play needs the input's rate in continuous "
                                 "time; give a sampling period dt > 0 (discrete-time nlsys), or build the closed "
                                 "loop with dfloop.control_loop(G, element)")
            dt = positive("dt", dt)
            return ct.nlsys(lambda t, s, u, p: model.step(s, float(np.ravel(u)[0])),
                            lambda t, s, u, p: np.array([model.output(s, float(np.ravel(u)[0]))]),
                            inputs=["x"], outputs=["y"], states=model.nstates, dt=dt, name=name)

        def __repr__(self) -> str:
            return f"to_control({self.element!r})"

    return ControlNonlinearity


def to_control(element: Any, *, dt: float | None = None) -> Any:
    """A dfloop element as a python-control object, in one call.

    Amplitude-only elements give a ``control.DescribingFunctionNonlinearity`` whose call ``F(x)`` is the
    element's time-domain map (the static function, or the hysteretic operator starting at rest) and whose
    ``describing_function(A)`` is dfloop's N(A): it goes into ``control.describing_function`` (with or without
    ``try_method``), ``describing_function_response`` and ``describing_function_plot``. Its ``to_nlsys()`` is
    the element as a ``control.nlsys``. Frequency-dependent elements with a state model (a linear block followed
    by a static element, e.g. :class:`~dfloop.MassBacklash`) give a continuous-time ``control.nlsys`` (input
    ``x``, output ``y``; its ``element`` attribute is the dfloop element). The table at the top of
    :mod:`dfloop.describing.interop` lists every case.

    The dynamic backlash (impacts: velocity jumps) has no continuous-time form; with ``dt`` it gives a
    discrete-time ``control.nlsys`` (input the force on M2 in N, output x1 in m, state [x1, v1, gap, v2 - v1]
    starting at rest with the gap centred) whose step is the exact motion over one sample with the force held.

    Parameters
    ----------
    element : DescribingFunction or anything :func:`as_element` accepts
    dt : float, optional
        Sampling period (s) of the discrete-time ``nlsys`` of an element that has one (the dynamic backlash).

    Returns
    -------
    control.DescribingFunctionNonlinearity or control.NonlinearIOSystem

    Raises
    ------
    ValueError
        For an element without a python-control form, or the dynamic backlash without ``dt``, saying what to
        use.

    Examples
    --------
    >>> import control as ct, dfloop as df
    >>> F = df.to_control(df.Backlash(h=2.0))
    >>> [F(x) for x in (0.5, 2.0, 1.5)]          # the play: dragged at 2.0, held on the way back
    [0.0, 1.0, 1.0]
    """
    import control as ct

    N = as_element(element)
    if callable(getattr(N, "sampled_model", None)):
        if dt is None:
            raise _no_model(N)
        model = N.sampled_model(positive("dt", dt))
        out = ct.nlsys(lambda t, s, u, p: model.step(s, float(np.ravel(u)[0])),
                       lambda t, s, u, p: np.array([model.output(s)]), inputs=["x"], outputs=["y"],
                       states=model.nstates, dt=dt, name=f"{type(N).__name__}")
        out.element, out.model = N, model
        return out
    if dt is not None:
        raise ValueError(f"dt: only an element with a sampled model (the dynamic backlash) takes dt here, got "
                         f"dt = {dt!r} for {N!r} (a play's discrete nlsys: to_control(N).to_nlsys(dt))")
    if not N.frequency_dependent:
        try:
            return _nonlinearity_class()(N)
        except NotImplementedError as err:   # a user's element with a DF but no time-domain operator
            raise ValueError(f"N = {N!r} cannot be converted to a python-control nonlinearity: it has no "
                             f"time-domain map ({err})") from None
    model = _model(N)
    if model is None:
        raise _no_model(N)
    if model.needs_rate:
        raise ValueError(f"N = {N!r} cannot be a standalone python-control nlsys: its linear block passes the input "
                         "straight through (D != 0) to a play, whose motion needs the input's rate; build the closed "
                         "loop with dfloop.control_loop(G, N), which knows that rate from the plant's state")

    def rhs(t, s, u, p):
        return model.rate(s, float(np.ravel(u)[0]), 0.0)

    out = ct.nlsys(rhs, lambda t, s, u, p: np.array([model.output(s, float(np.ravel(u)[0]))]), inputs=["x"], outputs=["y"],
                   states=model.nstates, name=f"{type(N).__name__}")
    out.element = N
    return out


def _sampled_loop(G, N, dt: float, name: str):
    """The loop of a plant and an element with a sampled model as a discrete-time nlsys (see control_loop)."""
    import control as ct

    model = N.sampled_model(dt)
    Gd = ct.c2d(ct.ss(G), dt, "zoh")
    Ad, Bd, Cd = np.asarray(Gd.A, float), np.asarray(Gd.B, float)[:, 0], np.asarray(Gd.C, float)[0]
    n = Ad.shape[0]

    def update(t, z, u, p):
        zp, s = z[:n], z[n:]
        x = float(np.ravel(u)[0]) - float(Cd @ zp)
        return np.concatenate([Ad @ zp + Bd * model.output(s), model.step(s, x)])

    def output(t, z, u, p):
        return np.array([float(np.ravel(u)[0]) - float(Cd @ z[:n]), model.output(z[n:])])

    loop = ct.nlsys(update, output, inputs=["r"], outputs=["x", "y"], states=n + model.nstates, dt=dt, name=name)
    A, B, _ = _ss_matrices(G, "G")

    def initial_state(cycle):
        """Plant on the harmonic-balance orbit of the cycle (c2d keeps the realisation), masses at rest."""
        A0, w = _cycle_pair(cycle)
        X = np.linalg.solve(1j * w * np.eye(n) - A, B) * complex(N(A0, w)) * A0
        return np.concatenate([X.imag, model.initial()])

    loop.initial_state = initial_state
    loop.element, loop.model = N, model
    return loop


def _cycle_pair(cycle) -> tuple[float, float]:
    if hasattr(cycle, "amplitude") and hasattr(cycle, "frequency"):
        return positive("cycle amplitude", cycle.amplitude), positive("cycle frequency", cycle.frequency)
    try:
        A0, w = cycle
    except (TypeError, ValueError):
        raise ValueError(f"cycle must be a LimitCycle or an (amplitude, frequency) pair, got {cycle!r}") from None
    return positive("cycle amplitude", A0), positive("cycle frequency", w)


def control_initial_state(G: Any, N: Any, cycle: Any) -> np.ndarray:
    """State of :func:`control_loop` (G, N) on the harmonic-balance orbit of a cycle, at t = 0 (x = 0, rising).

    The plant state is Im((jw I - A)^-1 B N(A0, w) A0) (the steady state of G driven by the element output's
    fundamental); the element's state is the one a full period of x = A0 sin(w t) leaves (the play; a linear
    block's steady state). Use it as ``X0`` of ``control.input_output_response``.

    Parameters
    ----------
    cycle : LimitCycle or (amplitude, frequency)
        Amplitude in N's input unit, frequency in rad/s.
    """
    N = as_element(N)
    A, B, _ = _ss_matrices(G, "G")
    A0, w = _cycle_pair(cycle)
    model = _model(N)
    if model is None:
        raise _no_model(N)
    n_val = complex(N(A0, w) if N.frequency_dependent else N(A0))
    X = np.linalg.solve(1j * w * np.eye(A.shape[0]) - A, B) * n_val * A0
    return np.concatenate([X.imag, model.initial(complex(A0), w)])


def control_loop(G: Any, N: Any, *, dt: float | None = None, name: str = "dfloop_loop") -> Any:
    """The closed loop of the paper's Fig. 1 as a python-control ``nlsys`` for ``control.input_output_response``.

    Reference r (the input, 0 for the autonomous loop), element input x = r - c, element output y, plant output
    c = G y. States: the plant's (``control.ss(G)``) then the element's (the play of backlash and hysteretic
    relays; a linear block's states). Outputs ``x`` and ``y``. The element's time-domain map is dfloop's own
    (see the module notes for the play in continuous time).

    Parameters
    ----------
    G : control.TransferFunction or control.StateSpace
        SISO, continuous-time, strictly proper (D = 0).
    N : DescribingFunction or anything :func:`as_element` accepts
        Any element with a state model: all but a hysteretic ``NumericDF`` of an operator other than dfloop's
        ``PlayOperator`` / ``RelayOperator`` (its state is opaque). The dynamic backlash (impacts are velocity
        jumps) needs ``dt``.
    dt : float, optional
        Only for an element with a sampled model (the dynamic backlash): the loop as a discrete-time ``nlsys`` of
        sampling period dt (s), the element's exact motion over each sample with its input force held, the plant
        discretised with a zero-order hold on the element's output x1 (``control.c2d``). A sampled-data
        approximation of the continuous loop, whose error falls with dt (first order: the holds), unlike the
        other elements' loops; :func:`dfloop.verify.simulate_loop` runs the continuous loop exactly.

    Returns
    -------
    control.NonlinearIOSystem
        With inputs ``["r"]``, outputs ``["x", "y"]``; its ``initial_state(cycle)`` gives
        :func:`control_initial_state` for this loop.

    Examples
    --------
    >>> import control as ct, numpy as np, dfloop as df
    >>> G, N = ct.tf([8], [1, 2, 2, 1]), df.Saturation(1.0)
    >>> loop = df.control_loop(G, N)
    >>> c = df.predict_limit_cycles(G, N)[0]
    >>> T = np.linspace(0, 40 * c.period, 4001)
    >>> resp = ct.input_output_response(loop, T, 0.0, loop.initial_state(c))
    """
    import control as ct

    N = as_element(N)
    A, B, C = _ss_matrices(G, "G")
    if callable(getattr(N, "sampled_model", None)) and dt is not None:
        return _sampled_loop(G, N, positive("dt", dt), name)
    if dt is not None:
        raise ValueError(f"dt: only an element with a sampled model (the dynamic backlash) makes a sampled loop; "
                         f"got dt = {dt!r} for {N!r}, whose loop is continuous-time")
    model = _model(N)
    if model is None:
        raise _no_model(N)
    n = A.shape[0]

    def update(t, z, u, p):
        zp, s = z[:n], z[n:]
        x = float(np.ravel(u)[0]) - float(C @ zp)
        y = model.output(s, x)
        zdot = A @ zp + B * y
        return np.concatenate([zdot, model.rate(s, x, -float(C @ zdot))])

    def output(t, z, u, p):
        x = float(np.ravel(u)[0]) - float(C @ z[:n])
        return np.array([x, model.output(z[n:], x)])

    loop = ct.nlsys(update, output, inputs=["r"], outputs=["x", "y"], states=n + model.nstates, name=name)
    loop.initial_state = lambda cycle: control_initial_state(G, N, cycle)
    loop.element = N
    return loop
