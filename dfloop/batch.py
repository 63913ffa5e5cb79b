"""Batches of independent loop studies on any ``concurrent.futures.Executor`` (threads, processes, Dask).

A batch is a list of work items run by one picklable function. Items are grouped in chunks (one task per
chunk, so a cheap item does not pay a task's overhead) and submitted to the executor; results come back in
the order of the items, whatever order the chunks finish in. ``executor=None`` runs everything in this
process, in the same order and with the same code, so a serial run and a parallel run give identical numbers.

Any object with ``submit(fn, *args) -> concurrent.futures.Future`` works: a
:class:`~concurrent.futures.ProcessPoolExecutor`, a :class:`~concurrent.futures.ThreadPoolExecutor`, or a Dask
cluster's executor (``distributed.Client(...).get_executor()``), so the same code runs on a laptop or a
cluster. Process-based executors pickle the function and the items: plants, elements and module-level
functions pickle; lambdas need an executor that uses cloudpickle (Dask does).
"""
from __future__ import annotations

import collections
import concurrent.futures as cf
import inspect
import itertools
import math
import time
from functools import partial
from typing import Any, Callable, Iterable, Sequence

from . import _checks
from .progress import progress_bar
from .solve import predict_limit_cycles
from .solve.compiled import prepare as prepare_compiled

__all__ = ["predict_many", "run_batch", "solver_options"]

_CHUNKS_PER_BATCH = 64  # default chunk size: about this many tasks per batch


def _run_chunk(fn: Callable, start: int, chunk: Sequence, label: str = "batch") -> list:
    """``[fn(x) for x in chunk]``; a failure names the item's index in the whole batch."""
    out = []
    for i, item in enumerate(chunk):
        try:
            out.append(fn(item))
        except ValueError as exc:
            raise ValueError(f"{label}, item {start + i}: {exc}") from exc
        except Exception as exc:  # noqa: BLE001 - re-raised with the index; the type is named in the text
            raise RuntimeError(f"{label}, item {start + i}: {type(exc).__name__}: {exc}") from exc
    return out


def _chunk_size(chunksize, n: int) -> int:
    if chunksize is None:
        return max(1, math.ceil(n / _CHUNKS_PER_BATCH))
    return _checks.integer_at_least("chunksize", chunksize, 1)


def run_batch(fn: Callable[[Any], Any], items: Iterable, *, executor: cf.Executor | None = None,
              chunksize: int | None = None, progress: bool | None = None, label: str = "batch",
              timeout: float | None = None) -> list:
    """``[fn(item) for item in items]``, in chunks on ``executor`` (or in this process), in item order.

    Parameters
    ----------
    fn : callable
        Applied to each item; must be picklable for a process-based executor (a module-level function
        or a :func:`functools.partial` of one).
    items : iterable
        The work items.
    executor : concurrent.futures.Executor, optional
        Anything with ``submit``; e.g. ``distributed.Client(...).get_executor()``. None: run here, serially.
    chunksize : int, optional
        Items per task (default: the batch in about 64 tasks). Ignored without an executor.
    progress : bool or None
        Progress bar (see :func:`dfloop.progress.progress_bar`): None shows it only for long batches.
    label : str
        Name of the work in the progress bar.
    timeout : float, optional
        Seconds to wait for the whole batch on the executor; exceeding it raises ``TimeoutError``
        (pass a larger ``timeout`` or None to wait indefinitely).

    Returns
    -------
    list
        ``fn(item)`` for each item, in the order of ``items``.
    """
    try:
        items = list(items)
    except TypeError:
        raise ValueError(f"items must be an iterable of work items; got {_checks.show(items)}") from None
    n = len(items)
    if chunksize is not None:
        chunksize = _checks.integer_at_least("chunksize", chunksize, 1)
    progress = _checks.flag("progress", progress, none=True)
    if timeout is not None and not (isinstance(timeout, (int, float)) and not isinstance(timeout, bool)
                                    and timeout > 0):
        raise ValueError(f"timeout must be a positive number of seconds or None; got {timeout!r}")
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise ValueError(f"executor must be a concurrent.futures.Executor (with submit); got "
                         f"{type(executor).__name__}")
    with progress_bar(label, n, enabled=progress) as bar:
        if executor is None:
            out = []
            for i, item in enumerate(items):
                out.extend(_run_chunk(fn, i, [item], label))
                bar.update(1)
            return out
        c = _chunk_size(chunksize, n)
        starts = range(0, n, c)
        futures = {executor.submit(_run_chunk, fn, s, items[s:s + c], label): s for s in starts}
        results: dict[int, list] = {}
        try:
            for fut in cf.as_completed(futures, timeout=timeout):
                s = futures[fut]
                results[s] = fut.result()
                bar.update(len(results[s]))
        except cf.TimeoutError:
            for fut in futures:
                fut.cancel()
            raise TimeoutError(f"{label}: {n - sum(map(len, results.values()))} of {n} items unfinished after "
                               f"timeout={timeout} s; pass a larger timeout (or None to wait)") from None
        except BaseException:  # a failed item (or an interrupt): drop the chunks not started yet
            for fut in futures:
                fut.cancel()
            raise
        return [r for s in starts for r in results[s]]


def solver_options(options: dict, exclude: tuple[str, ...] = ()) -> dict:
    """``options`` unchanged, after checking that each is a keyword of :func:`~dfloop.predict_limit_cycles`
    (``exclude``: those the caller sets itself): an unknown one is a ValueError before any work (inside a batch
    it would come out as a RuntimeError naming a TypeError)."""
    known = [p.name for p in inspect.signature(predict_limit_cycles).parameters.values()
             if p.kind is p.KEYWORD_ONLY and p.name not in exclude]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ValueError(f"unknown keyword argument(s) {', '.join(map(repr, unknown))}; the solver options are "
                         f"{', '.join(known)}")
    return options


def _predict_pair(loop, options: dict, keep: Callable | None = None):
    if not (isinstance(loop, (tuple, list)) and len(loop) == 2):
        raise ValueError(f"a loop must be a pair (G, N); got {type(loop).__name__}")
    G, N = loop
    prepare_compiled()  # a batch amortises the one-time compile of the solver's kernels (announced)
    result = predict_limit_cycles(G, N, **options)
    return result if keep is None else keep(result)


_STREAM_CHUNK = 256  # loops per task when their number is not known in advance
_IN_FLIGHT = 8  # chunks submitted ahead of the one awaited (bounds the memory of a streamed batch)


def _stream(fn: Callable, items: Iterable, executor, chunksize: int, progress, label: str, timeout, total):
    """``[fn(x) for x in items]`` consuming ``items`` lazily: at most ``_IN_FLIGHT`` chunks are held at once,
    so a generator of 10^5 loops never exists as a list (only the kept results do)."""
    it = iter(items)
    out: list = []
    deadline = None if timeout is None else time.monotonic() + timeout
    with progress_bar(label, total, enabled=progress) as bar:
        if executor is None:
            for i, item in enumerate(it):
                out.extend(_run_chunk(fn, i, [item], label))
                bar.update(1)
            return out
        pending: collections.deque = collections.deque()
        start = 0

        def submit() -> bool:
            nonlocal start
            chunk = list(itertools.islice(it, chunksize))
            if chunk:
                pending.append(executor.submit(_run_chunk, fn, start, chunk, label))
                start += len(chunk)
            return bool(chunk)

        try:
            while len(pending) < _IN_FLIGHT and submit():
                pass
            while pending:
                left = None if deadline is None else max(deadline - time.monotonic(), 0.0)
                try:
                    part = pending[0].result(timeout=left)
                except cf.TimeoutError:
                    raise TimeoutError(f"{label}: {start - len(out)} submitted items unfinished after "
                                       f"timeout={timeout} s; pass a larger timeout (or None to wait)") from None
                pending.popleft()
                out.extend(part)
                bar.update(len(part))
                submit()
        except BaseException:
            for fut in pending:
                fut.cancel()
            raise
        return out


def predict_many(loops: Iterable, *, executor: cf.Executor | None = None, chunksize: int | None = None,
                 progress: bool | None = None, timeout: float | None = None, keep: Callable | None = None,
                 total: int | None = None, **options) -> list:
    """:func:`~dfloop.predict_limit_cycles` for many loops (Monte Carlo over plant uncertainty, design grids).

    Loops whose G is rational (tf/ss, optionally delayed) and whose element has a compiled form run on the
    compiled pipeline (:mod:`dfloop.solve.compiled`), whatever the executor.

    Parameters
    ----------
    loops : iterable of (G, N)
        Plant and element of each loop, as for :func:`~dfloop.predict_limit_cycles`. A sequence is checked
        whole before any work; any other iterable (a generator of 10^5 sampled loops) is streamed: read in
        chunks as the executor takes them, never held whole.
    executor : concurrent.futures.Executor, optional
        Where to run: a process or thread pool, or a Dask cluster's ``client.get_executor()``. None runs
        in this process. The results are identical either way (same code, same inputs).
    chunksize : int, optional
        Loops per task (default: a sequence in about 64 tasks, a stream in tasks of 256 loops).
    progress : bool or None
        Progress bar; None shows it only when the batch takes more than a second.
    timeout : float, optional
        Seconds to wait for the whole batch on the executor (None: no limit).
    keep : callable, optional
        Applied to each loop's :class:`LimitCycles` where it is computed; the batch returns what it returns
        (e.g. the amplitude of the stable cycle), so a large batch keeps only that in memory and sends only
        that back from the workers. Must pickle for a process-based executor (a module-level function).
    total : int, optional
        How many loops a generator will yield: only for the progress bar's count and time left.
    **options
        Passed to :func:`~dfloop.predict_limit_cycles` for every loop (``omega``, ``amplitude``, ``grid``,
        ``tol``, ...).

    Returns
    -------
    list
        One result per loop (a LimitCycles, or ``keep`` of it), in the order of ``loops``. A loop that fails
        raises, naming its index.
    """
    solver_options(options)
    if keep is not None and not callable(keep):
        raise ValueError(f"keep must be a callable applied to each result, or None; got {_checks.show(keep)}")
    fn = partial(_predict_pair, options=options, keep=keep)
    if not isinstance(loops, (list, tuple)):
        try:
            iter(loops)
        except TypeError:
            raise ValueError(f"loops must be an iterable of (G, N) pairs; got {_checks.show(loops)}") from None
        if executor is not None and not callable(getattr(executor, "submit", None)):
            raise ValueError(f"executor must be a concurrent.futures.Executor (with submit); got "
                             f"{type(executor).__name__}")
        size = _STREAM_CHUNK if chunksize is None else _checks.integer_at_least("chunksize", chunksize, 1)
        if total is not None:
            total = _checks.integer_at_least("total", total, 0)
        elif hasattr(loops, "__len__"):
            total = len(loops)
        return _stream(fn, loops, executor, size, _checks.flag("progress", progress, none=True), "predict_many",
                       timeout, total)
    for i, loop in enumerate(loops):
        if not (isinstance(loop, (tuple, list)) and len(loop) == 2):
            raise ValueError(f"loops[{i}] must be a pair (G, N); got {type(loop).__name__}")
    return run_batch(fn, loops, executor=executor, chunksize=chunksize, progress=progress, label="predict_many",
                     timeout=timeout)
