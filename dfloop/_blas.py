"""Run the exact engines' small linear algebra on one BLAS thread.

The exact flows (``dfloop.hybrid``, the impact engine's closed loop) make many thousands of tiny BLAS calls
(matrix exponentials and products of a few states). A multi-threaded BLAS only adds thread hand-off to each of
them: on a busy 2-core machine one ``exact_cycle`` took anywhere from 43 ms to 3.8 s with the default threads
and 29 ms with one. :func:`single_threaded_blas` limits BLAS to one thread for the duration of a call
(threadpoolctl, ~14 us per call) and restores the caller's setting afterwards.
"""
from __future__ import annotations

import functools
from typing import Callable, TypeVar

__all__ = ["single_threaded_blas"]

F = TypeVar("F", bound=Callable)
_controller = None


def single_threaded_blas(fn: F) -> F:
    """Decorator: ``fn`` runs with BLAS limited to one thread (nested calls keep the outer limit)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        global _controller
        if _controller is None:
            from threadpoolctl import ThreadpoolController

            _controller = ThreadpoolController()
        with _controller.limit(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper
