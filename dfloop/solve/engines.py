"""The exact engine the solver hands predictions to, registered from above.

``predict_limit_cycles(..., exact=True)`` attaches an exact orbit to every cycle, but the exact layer
(:mod:`dfloop.exact`) sits above the solver and itself uses the solver (to find a misplaced cycle's counterpart
among the loop's predictions). So the solver does not import it: the exact layer registers its entry point here
when it is imported, and the first request loads the provider by name (``PROVIDER``, as the lazy top-level
namespace loads its modules) if nothing is registered yet.
"""
from __future__ import annotations

import importlib
from typing import Callable

__all__ = ["register_exact_engine", "exact_engine"]

PROVIDER = "dfloop.exact"   # the module that registers the exact engine when it is imported
_ENGINE: dict = {}


def register_exact_engine(exact_cycle: Callable, not_checked: Callable) -> None:
    """Register ``exact_cycle(G, N, cycle)`` and ``not_checked(message, predicted)`` (an ExactCycle that says why a
    loop could not be checked)."""
    _ENGINE["exact_cycle"], _ENGINE["not_checked"] = exact_cycle, not_checked


def exact_engine() -> tuple[Callable, Callable]:
    """(exact_cycle, not_checked) as registered by :mod:`dfloop.exact` (loaded by name on first use)."""
    if not _ENGINE:
        importlib.import_module(PROVIDER)
    return _ENGINE["exact_cycle"], _ENGINE["not_checked"]
