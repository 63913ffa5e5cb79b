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
"""
from __future__ import annotations

import copy
import sys
from typing import Any

import numpy as np

from .._checks import finite, nonnegative, positive
from .base import DescribingFunction
from .numeric import NumericDF
from .static import Backlash, Relay, Saturation

__all__ = ["as_element", "ControlDescribingFunction"]

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
