"""A lazily built adaptive table with its disk cache: load once, build what is missing, save as it grows.

:class:`TableStore` is what a tabulated describing function delegates its table's life to (the element keeps
the physics: what a sample is, which window a request needs). The store

- finds the table in the cache (:mod:`dfloop.tables.cache`) under a key that hashes the element's parameters
  and the code version, the first time a table is needed (:meth:`TableStore.load_cached`);
- runs a build with a progress bar showing the time left, saving after every block or line the build
  completes (:meth:`TableStore.build`), so an interrupted build resumes where it stopped;
- saves to and loads from a path the user chooses, with the provenance (:meth:`TableStore.save`,
  :meth:`TableStore.load`).
"""
from __future__ import annotations

import threading
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .. import _checks
from ..errors import DfloopError
from ..progress import announce, progress_bar
from . import cache as _cache
from .table1d import Table1D
from .table2d import Table2D

__all__ = ["TableStore"]


class TableStore:
    """The table of one tabulated element, in memory and on disk.

    Parameters
    ----------
    name : str
        File-name prefix in the cache directory (``<name>_<key>.npz``).
    parameters : callable () -> dict
        Everything the table's content depends on; the cache key is its SHA-256 with the code version.
    restore : callable (arrays) -> Table1D or Table2D
        A table from the arrays of a saved file (with the element's settings).
    cache : bool
        Load from and save to :func:`dfloop.tables.cache.cache_dir`.
    progress : bool, None or callable
        None: a progress bar with the time left for builds longer than a second; True: from the start; False:
        none; a callable gets ``(n_samples, stage)`` from the table's build instead.
    label : str
        Label of the progress bar.
    provenance : dict, optional
        Recorded with the parameters in every saved file (e.g. masses and clearance that the key leaves out).
    settings : dict, optional
        Build settings recorded in every saved file.

    Attributes
    ----------
    table : Table1D, Table2D or None
        The current table (None before the first build or load).
    loaded_from_cache : bool
        True when the table came from the cache file.
    """

    def __init__(self, name: str, parameters: Callable[[], dict], restore: Callable[[dict], Table1D | Table2D], *,
                 cache: bool = True, progress: bool | None | Callable[[int, str], None] = None, label: str = "table",
                 provenance: dict[str, Any] | None = None, settings: dict[str, Any] | None = None):
        self.name, self.label = str(name), str(label)
        self._parameters, self._restore = parameters, restore
        self._provenance, self._settings = dict(provenance or {}), dict(settings or {})
        self.use_cache = _checks.flag("cache", cache)
        if not (progress is None or isinstance(progress, (bool, np.bool_)) or callable(progress)):
            raise DfloopError("progress must be True, False, None or a callable(n, stage), got "
                              f"{_checks.show(progress)}")
        self.progress = progress
        self.table: Table1D | Table2D | None = None
        self.loaded_from_cache = False

    @property
    def key(self) -> str:
        """Hex cache key: the parameters and the code version (:func:`dfloop.tables.cache.cache_key`)."""
        return _cache.cache_key(self._parameters())

    @property
    def path(self) -> Path:
        """The cache file of this table."""
        return _cache.cache_dir() / f"{self.name}_{self.key[:32]}.npz"

    @property
    def n_sampled(self) -> int:
        """Samples computed by this process for the current table (0 when everything came from the cache)."""
        return 0 if self.table is None else self.table.n_sampled

    def load_cached(self) -> None:
        """Adopt the cached table if there is one and no table is held yet (a miss changes nothing)."""
        if self.table is not None or not self.use_cache:
            return
        f = _cache.load_table(self.path, self.key)
        if f is None:
            return
        self.table = self._restore(f.arrays)
        self.loaded_from_cache = True

    def build(self, extend: Callable[[Callable | None, Callable[[], None], Callable[[], None]], None],
              n_units: int, prior_per_unit: int, *, first_use: str | None = None) -> None:
        """Run ``extend(progress, checkpoint, tick)`` with a progress bar (time left), saving at every checkpoint.

        ``extend`` grows :attr:`table`; it calls ``tick()`` once per sample computed (from any thread) and
        ``checkpoint()`` after each of the ``n_units`` blocks or lines it completes. The bar starts from a prior
        of ``prior_per_unit`` samples per unit and corrects its total from the units done. ``progress`` is the
        user's callable (or None), to be passed to the table's own build. ``first_use`` (if given) is announced
        on the progress channel before any sample: a one-time cost such as a first-use compilation.
        """
        user = self.progress if callable(self.progress) else None
        enabled = None if self.progress is None else (False if user is not None else bool(self.progress))
        lock = threading.Lock()
        count = {"samples": 0, "units": 0}
        if first_use:
            announce(f"{self.label}: {first_use}", enabled=enabled)
        with progress_bar(self.label, n_units * prior_per_unit, enabled=enabled,
                          estimated=True) as bar:   # the total is a forecast, refined per unit
            def tick():
                with lock:
                    count["samples"] += 1
                    bar.update(1)

            def checkpoint():
                count["units"] += 1
                per_unit = count["samples"] / count["units"]
                bar.set_total(int(count["samples"] + max(n_units - count["units"], 0) * per_unit))
                self.store()

            extend(user, checkpoint, tick)
        self.store()

    def store(self) -> None:
        """Save the current table in the cache (no-op without a table or with the cache off)."""
        if self.use_cache and self.table is not None:
            self.save(self.path)

    def save(self, path) -> Path | None:
        """Write the current table with its key, the parameters and provenance, the build settings, the code
        version and the date; returns the path (None when a cache write failed, with a CacheWarning)."""
        if self.table is None:
            raise ValueError("nothing to save: the table has not been built yet (call prepare first)")
        params = self._parameters()
        return _cache.save_table(path, self.table.to_arrays(), _cache.cache_key(params),
                                 dict(params, **self._provenance), self._settings)

    def load(self, path) -> bool:
        """Adopt a table saved by :meth:`save` if it was built for exactly these parameters and this code.

        Returns False (and keeps the current table) when the file is missing, corrupted or stale.
        """
        f = _cache.load_table(path, self.key)
        if f is None:
            return False
        self.table = self._restore(f.arrays)
        return True

    def __repr__(self) -> str:
        return f"TableStore({self.name!r}, cache={self.use_cache}, table={self.table!r})"
