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
from .solve.predict import predict_chunk
from .solve.compiled import prepare as prepare_compiled

__all__ = ["predict_many", "run_batch", "solver_options"]

_CHUNKS_PER_BATCH = 64  # default chunk size: about this many tasks per batch
_EXECUTOR_CHUNK = 128   # predict_many on an executor: loops per task at least this (or an eighth of the batch)


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
    return _batch(partial(_run_chunk, fn, label=label), items, executor, chunksize, progress, label, timeout, 1)


def _batch(chunk_fn: Callable, items: Iterable, executor, chunksize, progress, label: str, timeout, local: int) -> list:
    """:func:`run_batch` with a function of whole chunks, ``chunk_fn(start, chunk) -> list`` (arguments checked)."""
    try:
        items = list(items)
    except TypeError:
        raise ValueError(f"items must be an iterable of work items; got {_checks.show(items)}") from None
    if chunksize is not None:
        chunksize = _checks.integer_at_least("chunksize", chunksize, 1)
    progress = _checks.flag("progress", progress, none=True)
    if timeout is not None and not (isinstance(timeout, (int, float)) and not isinstance(timeout, bool)
                                    and timeout > 0):
        raise ValueError(f"timeout must be a positive number of seconds or None; got {timeout!r}")
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise ValueError(f"executor must be a concurrent.futures.Executor (with submit); got "
                         f"{type(executor).__name__}")
    return _run_chunks(chunk_fn, items, executor, chunksize, progress, label, timeout, local)


def _run_chunks(chunk_fn: Callable, items: list, executor, chunksize, progress, label: str, timeout,
                local: int) -> list:
    """``chunk_fn(start, items[start:start + c])`` over the chunks of ``items``, on ``executor`` (chunks of
    ``chunksize``, default about 64 tasks) or in this process (chunks of ``local`` items), results in item order."""
    n = len(items)
    with progress_bar(label, n, enabled=progress) as bar:
        if executor is None:
            out = []
            c = local if chunksize is None or local == 1 else chunksize
            for s in range(0, n, c):
                out.extend(chunk_fn(s, items[s:s + c]))
                bar.update(min(c, n - s))
            return out
        c = _chunk_size(chunksize, n)
        starts = range(0, n, c)
        futures = {executor.submit(chunk_fn, s, items[s:s + c]): s for s in starts}
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


def _labelled(label: str, index: int, exc: BaseException) -> Exception:
    """The exception a batch raises for a failed item: ValueError or RuntimeError naming its index."""
    if isinstance(exc, ValueError):
        return ValueError(f"{label}, item {index}: {exc}")
    return RuntimeError(f"{label}, item {index}: {type(exc).__name__}: {exc}")


def _predict_loops(start: int, chunk: Sequence, options: dict, keep: Callable | None = None,
                   label: str = "predict_many") -> list:
    """``[keep(predict_limit_cycles(G, N, **options)) for G, N in chunk]``, the loops the compiled driver applies to
    in one call of it, run by threads over the cores (:func:`dfloop.solve.predict.predict_chunk`: the same
    results); a failure names the loop's index in the whole batch."""
    for i, loop in enumerate(chunk):
        if not (isinstance(loop, (tuple, list)) and len(loop) == 2):
            raise ValueError(f"{label}, item {start + i}: a loop must be a pair (G, N); got {type(loop).__name__}")
    prepare_compiled()  # a batch amortises the one-time compile of the solver's kernels (announced)

    def failed(k, exc):
        raise _labelled(label, start + k, exc) from exc

    results = predict_chunk(chunk, errors=failed, **options)
    if keep is None:
        return results
    out = []
    for k, r in enumerate(results):
        try:
            out.append(keep(r))
        except Exception as exc:  # noqa: BLE001 - re-raised with the index; the type is named in the text
            raise _labelled(label, start + k, exc) from exc
    return out


_STREAM_CHUNK = 256  # loops per task (per compiled driver call) of a stream, and per call in this process
_IN_FLIGHT = 8  # chunks submitted ahead of the one awaited (bounds the memory of a streamed batch)


def _stream(chunk_fn: Callable, items: Iterable, executor, chunksize: int, progress, label: str, timeout, total):
    """``chunk_fn(start, chunk)`` over chunks of ``chunksize`` items read lazily from ``items``: at most
    ``_IN_FLIGHT`` chunks are held at once (one in this process), so a generator of 10^5 loops never exists as a
    list (only the kept results do)."""
    it = iter(items)
    out: list = []
    deadline = None if timeout is None else time.monotonic() + timeout
    with progress_bar(label, total, enabled=progress) as bar:
        if executor is None:
            start = 0
            while True:
                chunk = list(itertools.islice(it, chunksize))
                if not chunk:
                    return out
                out.extend(chunk_fn(start, chunk))
                start += len(chunk)
                bar.update(len(chunk))
        pending: collections.deque = collections.deque()
        start = 0

        def submit() -> bool:
            nonlocal start
            chunk = list(itertools.islice(it, chunksize))
            if chunk:
                pending.append(executor.submit(chunk_fn, start, chunk))
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
        Loops per task (default: a sequence in about 64 tasks of at least 128 loops each, or in 8 tasks when it is
        smaller than 1024 loops; a stream in tasks of 256 loops).
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
    chunk_fn = partial(_predict_loops, options=options, keep=keep, label="predict_many")
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
        return _stream(chunk_fn, loops, executor, size, _checks.flag("progress", progress, none=True),
                       "predict_many", timeout, total)
    for i, loop in enumerate(loops):
        if not (isinstance(loop, (tuple, list)) and len(loop) == 2):
            raise ValueError(f"loops[{i}] must be a pair (G, N); got {type(loop).__name__}")
    if chunksize is None and executor is not None:
        # a task runs its loops in one compiled call: at least _EXECUTOR_CHUNK loops (or an eighth of the batch)
        # per task, so a task's overhead does not dominate (bench_batch.py: 16 loops per task took 1.5-2x longer)
        chunksize = max(math.ceil(len(loops) / _CHUNKS_PER_BATCH), min(_EXECUTOR_CHUNK, math.ceil(len(loops) / 8)), 1)
    return _batch(chunk_fn, loops, executor, chunksize, progress, "predict_many", timeout, _STREAM_CHUNK)
