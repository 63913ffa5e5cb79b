"""The table cache on disk: what it holds per code version, and clearing it (``dfloop cache info|clear``).

Every cache file records the code version that wrote it (:func:`dfloop.tables.cache.code_version`); a file of
another version is never read again (its key differs), so it only takes space: ``clear_cache(stale=True)``
removes exactly those, and files that no longer parse. Only dfloop's own files are touched: ``*.npz`` tables and
``*.tmp`` leftovers of interrupted writes, directly in :func:`dfloop.tables.cache.cache_dir`.

``DFLOOP_CACHE_DIR`` set to an empty string is refused here (``ValueError``): it would otherwise mean the default
directory, and clearing the wrong directory is not a mistake to make silently. Unset it for the default.
"""
from __future__ import annotations

import json
import os
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .tables.cache import cache_dir, code_version

__all__ = ["CacheFile", "CacheInfo", "cache_info", "clear_cache"]

UNREADABLE = "unreadable"
WRITE_GRACE = 600.0  # seconds: a younger *.tmp may be a write in progress, which clear_cache(stale=True) spares
_PATTERNS = ("*.npz", "*.tmp")


@dataclass(frozen=True)
class CacheFile:
    """One file of the cache: path, size (bytes) and the code version that wrote it (``"unreadable"`` if its
    metadata cannot be read, e.g. a truncated file or a leftover temporary file)."""

    path: Path
    size: int
    version: str


def _version(path: Path) -> str:
    if path.suffix != ".npz":
        return UNREADABLE
    try:
        with np.load(path, allow_pickle=False) as z:  # reads only the small "meta" member
            return str(json.loads(str(z["meta"]))["code_version"])
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile):
        return UNREADABLE


def _files(directory: Path) -> list[CacheFile]:
    if not directory.is_dir():
        return []
    paths = sorted({p for pattern in _PATTERNS for p in directory.glob(pattern) if p.is_file()})
    return [CacheFile(p, p.stat().st_size, _version(p)) for p in paths]


@dataclass
class CacheInfo:
    """The cache's content: its directory, the current code version, and every file.

    ``by_version()`` groups the files: ``{version: (number of files, bytes)}``.
    """

    directory: Path
    current: str
    files: list[CacheFile] = field(default_factory=list)

    @property
    def size(self) -> int:
        """Total bytes."""
        return sum(f.size for f in self.files)

    @property
    def stale(self) -> list[CacheFile]:
        """Files no current call can read: other code versions and unreadable files."""
        return [f for f in self.files if f.version != self.current]

    def by_version(self) -> dict[str, tuple[int, int]]:
        groups: dict[str, tuple[int, int]] = {}
        for f in self.files:
            n, size = groups.get(f.version, (0, 0))
            groups[f.version] = (n + 1, size + f.size)
        return groups

    def __repr__(self) -> str:
        lines = [f"cache {self.directory}: {len(self.files)} files, {_size(self.size)}"]
        for version, (n, size) in sorted(self.by_version().items()):
            mark = " (current)" if version == self.current else " (stale)"
            lines.append(f"  {version}{mark}: {n} files, {_size(size)}")
        if not self.files:
            lines.append(f"  empty; current code version {self.current}")
        return "\n".join(lines)


def _size(n: int) -> str:
    for unit in ("B", "KiB", "MiB"):
        if n < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"


def _directory() -> Path:
    """The cache directory; ``DFLOOP_CACHE_DIR=""`` (set but empty) raises ValueError naming it."""
    env = os.environ.get("DFLOOP_CACHE_DIR")
    if env is not None and not env.strip():
        raise ValueError(f"DFLOOP_CACHE_DIR is set but empty ({env!r}); set it to a directory, or unset it for the "
                         "default (~/.cache/dfloop, or $XDG_CACHE_HOME/dfloop)")
    return cache_dir()


def cache_info() -> CacheInfo:
    """What the cache directory holds, per code version.

    Raises
    ------
    ValueError
        When ``DFLOOP_CACHE_DIR`` is set but empty.
    OSError
        When the directory cannot be listed (e.g. no read permission).
    """
    directory = _directory()
    return CacheInfo(directory, code_version(), _files(directory))


def _to_clear(stale: bool) -> list[CacheFile]:
    info = cache_info()
    if not stale:
        return list(info.files)
    now = time.time()
    return [f for f in info.stale if f.path.suffix != ".tmp" or now - f.path.stat().st_mtime > WRITE_GRACE]


def clear_cache(stale: bool = False, files: list[CacheFile] | None = None, *, dry_run: bool = False,
                errors: list[tuple[CacheFile, OSError]] | None = None) -> list[CacheFile]:
    """Remove cache files and return those removed (or, with ``dry_run=True``, those that would be).

    Parameters
    ----------
    stale : bool
        Remove only the files of other code versions and unreadable ones (sparing ``*.tmp`` files younger than
        ``WRITE_GRACE``, possibly being written); otherwise every dfloop file of the cache.
    files : list of CacheFile, optional
        Remove exactly these (e.g. the list shown to a user for confirmation) instead of listing again: a table
        written in between is not removed unseen. Each must lie directly in the cache directory.
    dry_run : bool
        Remove nothing; return the files that would be removed (what ``dfloop cache clear`` lists before
        asking for confirmation).
    errors : list, optional
        Where to collect ``(file, OSError)`` for files that could not be removed (read-only cache); every other
        file is still removed. Without it, such a failure raises the ``OSError`` after the others are removed,
        its message naming how many failed and the first one.
    """
    if files is None:
        files = _to_clear(stale)
    else:
        directory = _directory().resolve()
        outside = [f for f in files if f.path.resolve().parent != directory]
        if outside:
            raise ValueError(f"files must lie in the cache directory {directory}; got {outside[0].path}")
    if dry_run:
        return list(files)
    removed, failed = [], []
    for f in files:
        try:
            f.path.unlink(missing_ok=True)
        except OSError as exc:
            failed.append((f, exc))
        else:
            removed.append(f)
    if failed and errors is None:
        f, exc = failed[0]
        raise type(exc)(exc.errno, f"could not remove {len(failed)} of {len(files)} cache files ({len(removed)} "
                        f"removed); first: {f.path}: {exc.strerror or exc}")
    if errors is not None:
        errors.extend(failed)
    return removed
