"""The exact engine the solver hands predictions to, registered from above.

``predict_limit_cycles(..., exact=True)`` attaches an exact orbit to every cycle, but the exact layer
(:mod:`dfloop.exact`) sits above the solver and itself uses it (to find a misplaced cycle's counterpart): the
exact layer registers its entry point here when it is imported (``import dfloop`` always imports it), so the
solver never imports upward.
"""
from __future__ import annotations

from typing import Callable

__all__ = ["register_exact_engine", "exact_engine"]

_ENGINE: dict = {}


def register_exact_engine(exact_cycle: Callable, not_checked: Callable) -> None:
    """Register ``exact_cycle(G, N, cycle)`` and ``not_checked(message, predicted)`` (an ExactCycle that says why a
    loop could not be checked)."""
    _ENGINE["exact_cycle"], _ENGINE["not_checked"] = exact_cycle, not_checked


def exact_engine() -> tuple[Callable, Callable]:
    """(exact_cycle, not_checked) as registered by :mod:`dfloop.exact`."""
    if not _ENGINE:
        raise RuntimeError("no exact engine registered: import dfloop (dfloop.exact registers it)")
    return _ENGINE["exact_cycle"], _ENGINE["not_checked"]
