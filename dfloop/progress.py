"""Progress reporting for long work (table builds, sweeps, batches, scene stages).

One small protocol: a *progress sink* is a context manager with ``update(n=1, stage=None)`` and
``set_total(total)``. :func:`progress_bar` makes one:

- on a terminal, a tqdm bar with rate and an estimate of the time left;
- otherwise (a log file, CI, a pipe), plain lines without carriage returns, at most one every few seconds
  plus one at the end, so logs stay readable;
- ``enabled=False`` (or ``DFLOOP_PROGRESS=0`` in the environment), nothing at all.

``enabled=None`` (the default) means "on when the work is long enough to matter": the first line appears only
after ``delay`` seconds, so quick calls print nothing.

The estimate of the time left counts work, not start-up: the rate is measured from the first completed unit on,
so a one-time cost before it (numba compiling the impact kernels on first use, loading a cache) does not inflate
the per-unit time. Such a cost is announced instead, once, by :func:`announce` (e.g. ``compiling once for this
installation, about 16 s``), when :func:`compile_pending` says the compiled code is not cached yet.
"""
from __future__ import annotations

import os
import sys
import time
from typing import TextIO

__all__ = ["progress_bar", "ProgressSink", "NullProgress", "announce", "announce_compile", "compile_pending"]

_ANNOUNCED: set = set()  # the compile announcements made in this process
_READY: set[str] = set()   # what was found compiled or cached in this process (checked once)


class NullProgress:
    """A progress sink that reports nothing."""

    def __enter__(self) -> "NullProgress":
        return self

    def __exit__(self, *exc) -> None:
        return None

    def update(self, n: int = 1, stage: str | None = None) -> None:
        """Count ``n`` more units of work done (ignored)."""

    def set_total(self, total: int | None, estimated: bool | None = None) -> None:
        """Change the expected amount of work (ignored); ``estimated`` marks it as a forecast."""

    def close(self) -> None:
        """Finish (nothing to do)."""


class ProgressSink(NullProgress):
    """Plain-line progress for non-terminal streams: ``label: n/total (stage), t elapsed, ~t left``; a total
    that is a forecast (``estimated``) shows as ``n/~total``."""

    def __init__(self, label: str, total: int | None, stream: TextIO, delay: float, interval: float = 5.0,
                 estimated: bool = False):
        self.label, self.total, self.stream = label, total, stream
        self.estimated = estimated
        self.delay, self.interval = delay, interval
        self.n, self.stage = 0, None
        self.t0 = time.monotonic()
        self._first = None   # (time, count) at the first completed unit: the rate is measured from there on
        self._last = None

    def set_total(self, total: int | None, estimated: bool | None = None) -> None:
        self.total = total
        if estimated is not None:
            self.estimated = estimated

    def _line(self) -> str:
        elapsed = time.monotonic() - self.t0
        count = f"{self.n}/{'~' if self.estimated else ''}{self.total}" if self.total else f"{self.n}"
        left = ""
        if self.total and 0 < self.n < self.total and self._first is not None:
            t1, n1 = self._first
            if self.n > n1:  # per-unit time from the units done after the first one (start-up excluded)
                left = f", ~{(time.monotonic() - t1) * (self.total - self.n) / (self.n - n1):.0f} s left"
        stage = f" ({self.stage})" if self.stage else ""
        return f"{self.label}: {count}{stage}, {elapsed:.0f} s elapsed{left}"

    def update(self, n: int = 1, stage: str | None = None) -> None:
        self.n += n
        if stage is not None:
            self.stage = stage
        now = time.monotonic()
        if self._first is None and self.n > 0:
            self._first = (now, self.n)
        if now - self.t0 < self.delay:
            return
        if self._last is None or now - self._last >= self.interval:
            self._last = now
            print(self._line(), file=self.stream, flush=True)

    def close(self) -> None:
        if self._last is not None:  # only close with a line when something was printed
            if self.estimated:      # the work is done: its amount is known now
                self.total, self.estimated = self.n, False
            print(self._line() + ", done", file=self.stream, flush=True)
            self._last = None

    def __exit__(self, *exc) -> None:
        self.close()


class _TqdmSink(NullProgress):
    def __init__(self, label: str, total: int | None, stream: TextIO, delay: float):
        from tqdm.auto import tqdm

        self.bar = tqdm(total=total, desc=label, file=stream, delay=delay, leave=False, dynamic_ncols=True)
        self._started = False

    def set_total(self, total: int | None, estimated: bool | None = None) -> None:
        self.bar.total = total
        self.bar.refresh()

    def update(self, n: int = 1, stage: str | None = None) -> None:
        if stage is not None:
            self.bar.set_postfix_str(stage, refresh=False)
        if not self._started and n > 0:
            # tqdm's rate starts at the bar's creation: restart its clock at the first completed unit so the
            # time left excludes start-up (compilation); the elapsed time shown is then the work's
            self._started = True
            self.bar.reset(self.bar.total)   # new clock and rate (tqdm's own method), then the units done
            self.bar.n = self.bar.last_print_n = n
            self.bar.refresh()
            return
        self.bar.update(n)

    def close(self) -> None:
        self.bar.close()

    def __exit__(self, *exc) -> None:
        self.close()


def progress_bar(label: str, total: int | None = None, *, enabled: bool | None = None,
                 stream: TextIO | None = None, delay: float = 1.0, estimated: bool = False) -> NullProgress:
    """A progress sink for ``total`` units of work labelled ``label``.

    Parameters
    ----------
    label : str
        What is being done, e.g. ``"DynamicBacklash(restitution=0.5) table"``.
    total : int or None
        Expected number of units (None when unknown; :meth:`set_total` may set it later).
    enabled : bool or None
        False reports nothing; True and None report (None after ``delay`` seconds only, so quick work is
        silent). The environment variable ``DFLOOP_PROGRESS=0`` turns every bar off.
    stream : text stream, optional
        Where to write; ``sys.stderr`` by default.
    delay : float
        Seconds of work before the first report.
    estimated : bool
        ``total`` is a forecast (plain lines show ``n/~total``), until the work ends or ``set_total`` says
        otherwise.
    """
    if enabled is False or os.environ.get("DFLOOP_PROGRESS", "1") == "0":
        return NullProgress()
    stream = sys.stderr if stream is None else stream
    if getattr(stream, "isatty", lambda: False)():
        return _TqdmSink(label, total, stream, delay)
    return ProgressSink(label, total, stream, delay, estimated=estimated)


def announce(message: str, *, enabled: bool | None = None, stream: TextIO | None = None) -> None:
    """Print one line about a one-time cost before it is paid (e.g. first-use compilation).

    Follows the same switches as :func:`progress_bar`: nothing when ``enabled`` is False or
    ``DFLOOP_PROGRESS=0``; ``stream`` is ``sys.stderr`` by default.
    """
    if enabled is False or os.environ.get("DFLOOP_PROGRESS", "1") == "0":
        return
    print(message, file=sys.stderr if stream is None else stream, flush=True)


def compile_pending(*dispatchers) -> bool | None:
    """Whether calling these numba functions (``@njit(cache=True)``) will compile them first.

    True when one of them has neither a compiled signature in this process nor an entry in numba's on-disk
    cache (a fresh installation, or sources changed since), False when all are ready, None when numba's cache
    cannot be inspected (an unknown numba version): say nothing then.
    """
    try:
        for d in dispatchers:
            if d.signatures:
                continue
            cache = getattr(d, "_cache", None)
            index = cache._cache_file._load_index()  # numba's cache index: {(signature, target): file}
            if not index:
                return True
        return False
    except Exception:  # noqa: BLE001 - numba internals differ between versions: unknown, not an error
        return None


def announce_compile(what: str, seconds: float, *dispatchers, enabled: bool | None = None,
                     stream: TextIO | None = None) -> bool:
    """Say once per process, before the call that pays it, that ``what`` compiles numba code once for this
    installation and about how long it takes (``seconds``, measured by benchmarks/bench_startup.py), when
    :func:`compile_pending` says one of ``dispatchers`` is neither compiled nor cached. Returns whether it spoke.

    The line reads ``dfloop: <what>: compiling once for this installation, about <seconds> s (later runs load the
    compiled code; `dfloop warmup` does it ahead)``.
    """
    if what in _ANNOUNCED or what in _READY:
        return False
    if not compile_pending(*dispatchers):
        _READY.add(what)       # compiled or cached stays so for the process: never read numba's index again
        return False
    _ANNOUNCED.add(what)
    announce(f"dfloop: {what}: compiling once for this installation, about {seconds:.0f} s (later runs load the "
             "compiled code; `dfloop warmup` does it ahead)", enabled=enabled, stream=stream)
    return True
