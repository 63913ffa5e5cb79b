"""The describing-function protocol shared by every nonlinear element in dfloop.

Convention (docs/design.md section 1): the input is x(t) = A sin(w t); the output's fundamental is
Y1 sin(w t + phi1); N(A, w) = (Y1 / A) exp(j phi1). Amplitudes are amplitudes of the fundamental.
"""
from __future__ import annotations

import difflib
import functools
import inspect
from abc import ABC, abstractmethod

import numpy as np

from .._checks import amplitude_array, frequency_array
from ..errors import DfloopError

__all__ = ["DescribingFunction", "negative_inverse"]

#: Names a newcomer tries for an element's parameter, and the parameter dfloop uses (docs/design.md, vocabulary):
#: the slope or gain of every linear part is ``k``, a clearance ``h``, a dead band's half-width ``delta``
#: (``dead_zone`` for a relay), a relay's output level ``M``, a saturation's input breakpoint ``limit``.
PARAMETER_SYNONYMS = {"slope": "k", "gain": "k", "stiffness": "k", "clearance": "h", "gap": "h", "play": "h",
                      "backlash": "h", "width": "delta", "deadband": "delta", "dead_band": "delta",
                      "deadzone": "dead_zone", "level": "M", "hyst": "hysteresis",
                      "saturation": "limit", "lim": "limit", "ub": "limit"}


class UnknownParameterError(DfloopError, TypeError):
    """An element built with a keyword it does not have: a ``TypeError`` like Python's own for an unexpected
    keyword, and a :class:`~dfloop.DfloopError` (``ValueError``) like every other bad input to dfloop."""


def _parameter_hint(cls: type, init, kwargs: dict) -> str | None:
    """Why ``cls(**kwargs)`` cannot bind: each unknown keyword with the parameter it probably means."""
    signature = inspect.signature(init)
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in signature.parameters.values()):
        return None   # takes any keyword: the TypeError is the constructor's own
    params = [p for p in signature.parameters if p != "self"]
    unknown = [k for k in kwargs if k not in params]
    if not unknown:
        return None
    hints = []
    for name in unknown:
        guess = PARAMETER_SYNONYMS.get(name.lower())
        if guess not in params:
            close = difflib.get_close_matches(name, params, n=1, cutoff=0.6)
            guess = close[0] if close else None
        hints.append(f"{name!r} (did you mean {guess!r}?)" if guess else repr(name))
    return (f"{cls.__name__} has no parameter {', '.join(hints)}; its parameters are "
            f"{', '.join(params)} (docs/elements.md)")


class DescribingFunction(ABC):
    """A describing function N(A, omega), called with numpy broadcasting and returning complex values.

    Subclasses implement :meth:`_evaluate` on validated float arrays (already broadcast-compatible)
    and set the class attributes below.

    Input rules, the same for every element (checked here, in :meth:`__call__`; docs/errors.md lists them):

    - ``A`` is real and >= 0; ``omega`` is real, finite and > 0 (rad/s). Complex, negative, non-numeric,
      None or ragged input raises :class:`dfloop.errors.DfloopError` (a ``ValueError``) naming the
      parameter and the value; so do ``A`` and ``omega`` that do not broadcast together.
    - ``A = 0`` and ``A = inf`` give the limit of N as A -> 0+ and A -> inf (which may be 0 or an infinite
      value, never NaN); each element's docstring states its limits. The one exception is
      :class:`dfloop.NumericDF`, which cannot take a limit numerically: it raises ``DfloopError`` naming
      ``A`` outside [1e-250, 1e250].
    - NaN entries of ``A`` or ``omega`` give NaN in those entries only; dfloop's elements never return NaN
      for other input (tests/test_bad_input_hypothesis.py checks it).

    Attributes
    ----------
    frequency_dependent : bool
        Whether N depends on omega. Amplitude-only elements accept and ignore ``omega``.
    continuous : bool
        Whether N is known to be continuous in (A, omega) for A, omega > 0, the edges of its amplitude domain
        included (N rises from 0 there). The solver then never reports a winding of 1 + G N as a jump crossing:
        it yields a root or says where it could not (``GridReport.uncertified``). False (unknown) by default.
    input_name, input_unit : str
        Name and unit of the input amplitude (e.g. ``"X"``, ``"m"``; ``"F"``, ``"N"``).
    """

    frequency_dependent: bool = False
    continuous: bool = False
    input_name: str = "A"
    input_unit: str = ""

    def __init_subclass__(cls, **kwargs):
        # an unknown keyword (Saturation(limit=1, slope=2)) names the parameter meant (k), not only Python's
        # "unexpected keyword argument"; the wrapped __init__ keeps its signature (inspect follows __wrapped__)
        super().__init_subclass__(**kwargs)
        init = cls.__dict__.get("__init__")
        if init is None or getattr(init, "_names_parameters", False):
            return

        @functools.wraps(init)
        def __init__(self, *args, **kw):
            try:
                init(self, *args, **kw)
            except TypeError as err:
                hint = _parameter_hint(type(self), init, kw)
                if hint is None:
                    raise
                raise UnknownParameterError(hint) from err

        __init__._names_parameters = True
        cls.__init__ = __init__

    def __call__(self, A, omega=None) -> np.ndarray:
        """Evaluate N(A, omega).

        Parameters
        ----------
        A : array_like
            Input amplitude(s), real, >= 0 (``inf`` gives the limit), in ``input_unit``. NaN entries give NaN
            in those entries only.
        omega : array_like, optional
            Frequency in rad/s (real, finite, > 0), broadcast against ``A``. Required when
            ``frequency_dependent``; validated (and ignored) for amplitude-only elements.

        Returns
        -------
        numpy.ndarray of complex
            N with the broadcast shape of ``A`` and ``omega`` (a 0-d array for scalar input).

        Raises
        ------
        dfloop.errors.DfloopError
            Bad ``A`` or ``omega`` (see the class docstring), naming the parameter and the value.
        """
        a = amplitude_array(A, self.input_name)
        if omega is None:
            if self.frequency_dependent:
                raise DfloopError(f"omega is required: {type(self).__name__} depends on frequency, got omega=None")
            w = None
        else:
            w = frequency_array(omega)
            try:
                a, w = np.broadcast_arrays(a, w)
            except ValueError:
                raise DfloopError(f"{self.input_name} and omega must broadcast together, got shapes "
                                  f"{np.shape(a)} and {np.shape(w)}") from None
        return np.asarray(self._evaluate(a, w), dtype=complex)

    @abstractmethod
    def _evaluate(self, A: np.ndarray, omega: np.ndarray | None) -> np.ndarray:
        """N on validated, broadcast arrays (``omega`` is None only for amplitude-only elements)."""

    def amplitude_domain(self, omega=None) -> tuple[np.ndarray, np.ndarray]:
        """Open interval (lo, hi) of amplitudes where N is defined and non-zero.

        For frequency-dependent elements the bounds may depend on ``omega`` (broadcast).
        Default: (0, inf).
        """
        shape = np.shape(frequency_array(omega)) if omega is not None else ()
        return np.zeros(shape), np.full(shape, np.inf)

    def tail_bound(self, A) -> np.ndarray | None:
        """Upper bound on |N(A, w) - N(inf, w)| for every w, at amplitudes ``A`` (non-increasing in A).

        The solver's default amplitude window rests on it: where N(inf, w) is finite and non-zero, a root
        needs |G| |N - N(inf)| >= |1 + G N(inf)|, so no root lies beyond the amplitude where
        ``max |G| tail_bound(A)`` falls below ``min |1 + G N(inf)|`` (docs/solver.md, "Default windows").
        None (the default) when the element states no bound; then only |N| itself limits the window.
        """
        return None

    def head_bound(self, A) -> np.ndarray | None:
        """Upper bound on |N(A, w) - N(0, w)| for every w, at amplitudes ``A`` (non-decreasing in A), for
        elements whose N(0) is finite and non-zero with no dead band (the small-amplitude side of
        :meth:`tail_bound`). None (the default) when the element states none."""
        return None

    def validity(self, A, omega=None) -> np.ndarray:
        """Boolean mask: True where N(A, omega) is a trustworthy DF value (broadcast shape).

        Analytic elements are valid wherever N is finite. Tabulated elements (e.g. dynamic backlash)
        return False where the motion was not periodic or the value lies outside the model's range;
        the solver reports cycles found there with reduced confidence instead of dropping them.
        """
        return np.isfinite(self(A, omega))

    def error_estimate(self, A, omega=None) -> np.ndarray:
        """Estimated absolute error of N(A, omega) (0 for closed forms; interpolation error for tables)."""
        return np.zeros(np.shape(self(A, omega)))

    def operator(self):
        """A fresh time-domain operator of this element, for closed-loop simulation.

        Returns a stateful callable ``op`` with ``op(x: float) -> float`` giving the output for the next
        input sample (rate-independent elements: static functions, backlash, relays with hysteresis),
        starting from rest (zero output, centred state). Elements without one raise NotImplementedError.
        """
        raise NotImplementedError(f"{type(self).__name__} has no time-domain operator")

    def time_model(self, amplitude: float):
        """How this element behaves in time, for the exact engines (:mod:`dfloop.hybrid`).

        Parameters
        ----------
        amplitude : float
            Amplitude scale of the motion (element input units), > 0: sizes numerical checks and ranges.

        Returns
        -------
        PiecewiseAffine, Smooth, Impact or Sampled
            One of the models of :mod:`dfloop.describing.time_model`. The default is :class:`Sampled` built
            on :meth:`operator` (a fixed-step simulation, not exact); elements override it with an exact model,
            and a user-defined element may too.

        Raises
        ------
        NotImplementedError
            The element has neither a time model nor an operator.
        """
        from .time_model import Sampled

        self.operator()   # raises NotImplementedError when there is none
        return Sampled(type(self).__name__, self.operator)

    def describing_function(self, A):
        """N(A) through python-control's describing-function protocol (amplitude-only elements).

        ``control.describing_function``, ``describing_function_response`` and ``describing_function_plot``
        call this method (they look it up by name) instead of treating the element as a static map f(x).

        Parameters
        ----------
        A : float or array_like
            Input amplitude(s), >= 0, in ``input_unit``.

        Returns
        -------
        complex or numpy.ndarray of complex
            The same values as ``self(A)`` (a Python complex for scalar ``A``).

        Raises
        ------
        ValueError
            For a frequency-dependent element: python-control's analysis assumes N(A) only; use
            :func:`dfloop.predict_limit_cycles`, which solves 1 + G(jw) N(A, w) = 0.
        """
        if self.frequency_dependent:
            raise ValueError(
                f"{type(self).__name__} depends on frequency (N(A, omega)); python-control's describing-function "
                "analysis assumes N(A) only: use dfloop.predict_limit_cycles(G, element) instead")
        n = self(A)
        return complex(n) if n.ndim == 0 else n

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in vars(self).items() if not k.startswith("_"))
        return f"{type(self).__name__}({params})"


def negative_inverse(N: DescribingFunction, A, omega=None) -> np.ndarray:
    """-1/N(A, omega) for plots; entries where N = 0 give complex infinity (not NaN)."""
    if not isinstance(N, DescribingFunction):
        raise DfloopError(f"N must be a dfloop DescribingFunction (see dfloop.as_element), got {type(N).__name__}")
    n = N(A, omega)
    out = np.full(n.shape, complex(np.inf, 0.0))
    nan = np.isnan(n)                 # a gap (A = NaN, or outside the element's domain) stays a gap
    nz = (n != 0) & ~nan
    out[nz] = -1.0 / n[nz]
    out[nan] = complex(np.nan, np.nan)
    return out
