"""The table cache on disk: what it holds per code version, and clearing it (``dfloop cache info|clear``).

Every cache file records the code version that wrote it (:func:`dfloop.tables.cache.code_version`); a file of
another version is never read again (its key differs), so it only takes space: ``clear_cache(stale=True)``
removes exactly those, and files that no longer parse. Only dfloop's own files are touched: ``*.npz`` tables and
``*.tmp`` leftovers of interrupted writes, directly in :func:`dfloop.tables.cache.cache_dir`.
"""
from __future__ import annotations

import json
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


def cache_info() -> CacheInfo:
    """What the cache directory holds, per code version."""
    directory = cache_dir()
    return CacheInfo(directory, code_version(), _files(directory))


def clear_cache(stale: bool = False) -> list[CacheFile]:
    """Remove the cache's files; with ``stale=True`` only the files of other code versions and unreadable
    ones (sparing ``*.tmp`` files younger than ``WRITE_GRACE``, possibly being written). Returns those removed."""
    info = cache_info()
    if stale:
        now = time.time()
        removed = [f for f in info.stale
                   if f.path.suffix != ".tmp" or now - f.path.stat().st_mtime > WRITE_GRACE]
    else:
        removed = info.files
    for f in removed:
        f.path.unlink(missing_ok=True)
    return removed
