"""dfloop's own exception and warning classes.

Every rejection of bad input by dfloop is a ``ValueError`` naming the parameter and the value; the ones raised
by :mod:`dfloop._checks` are :class:`DfloopError`, a ``ValueError`` subclass, so ``except ValueError`` and
``except DfloopError`` both catch them. The reference table of what each entry point rejects is
``docs/errors.md``.
"""
from __future__ import annotations

__all__ = ["DfloopError", "EventLimitError", "CacheWarning"]


class DfloopError(ValueError):
    """Bad input to a dfloop function or constructor; the message names the parameter and the value."""


class EventLimitError(RuntimeError):
    """A simulation reached its bound on the number of events (impacts, separations, switchings).

    The message says where the run stopped and how to raise the bound (``max_events=``).
    """


class CacheWarning(UserWarning):
    """The disk cache could not be read or written (or held a corrupted file); dfloop computed in memory.

    The result is unaffected: the cache only saves recomputation. The message says what failed and where.
    """
