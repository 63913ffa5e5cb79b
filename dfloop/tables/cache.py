"""Disk cache of tables: one ``.npz`` file per key, holding the arrays, the key, provenance and a checksum.

A file is trusted only if it parses, its stored key equals the requested key and the SHA-256 checksum
of its content matches; anything else (missing, truncated, edited, built by other code) reads as a miss
and is rebuilt by the caller. Writes are atomic (temporary file in the same directory, then ``os.replace``),
so two processes writing the same table at once leave one complete file, never a mixture.

The cache is an accelerator, never a point of failure: a file that cannot be read or written (full disk,
read-only or missing directory, ``DFLOOP_CACHE_DIR`` naming a regular file, permissions) or that fails its
checks is a miss, and the caller computes in memory. Each such fault gives one
:class:`dfloop.errors.CacheWarning` naming what failed and the path (a write failure once per directory
and kind of error in a process, so a build that saves repeatedly does not repeat it).

Cache directory: ``$DFLOOP_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/dfloop`` or ``~/.cache/dfloop``.
``DFLOOP_CACHE_DIR`` set but empty (or blank) is refused everywhere, here as in ``dfloop cache`` and ``dfloop
run``: a ``ValueError`` naming it (an empty value would otherwise silently mean the default directory).
"""
from __future__ import annotations

import datetime
import hashlib
import io
import json
import os
import tempfile
import time
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import CacheWarning, DfloopError

__all__ = ["cache_dir", "code_version", "cache_key", "save_table", "load_table", "TableFile"]

_STALE_SECONDS = 3600.0  # temporaries older than this are left over from a killed writer
_REPORTED: set[tuple] = set()  # write/read failures already reported (one warning per directory and kind)
# the modules whose code decides a cached table's content, relative to the dfloop package: the generic tables
# and the exact impact simulations behind DynamicBacklash (tests/test_cache.py checks that every module they
# import is listed). A change in any of them changes code_version(), hence every key: old files become stale.
SOURCES = ("tables/table1d.py", "tables/table2d.py", "tables/store.py", "tables/cache.py",
           "impact/dynamic_backlash.py", "impact/sampling.py", "impact/kernel.py", "impact/model.py",
           "impact/_core.py", "impact/_flight.py", "impact/effects.py", "impact/_effects_core.py", "impact/_engine.py",
           "impact/extract.py", "impact/limits.py", "impact/sampled_model.py")


def cache_dir() -> Path:
    """The cache directory (created on demand by :func:`save_table`).

    Raises
    ------
    DfloopError
        (a ValueError) when ``DFLOOP_CACHE_DIR`` is set but empty or blank: set it to a directory, or unset it.
    """
    env = os.environ.get("DFLOOP_CACHE_DIR")
    if env is not None and not env.strip():
        raise DfloopError(f"DFLOOP_CACHE_DIR is set but empty ({env!r}); set it to a directory, or unset it for the "
                          "default (~/.cache/dfloop, or $XDG_CACHE_HOME/dfloop)")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "dfloop"


def code_version() -> str:
    """dfloop's version plus a hash of the sources that determine a table's content."""
    here = Path(__file__).parent.parent
    h = hashlib.sha256()
    for name in SOURCES:
        p = here / name
        if p.exists():
            h.update(name.encode())
            h.update(p.read_bytes())
    return f"{__version__}+{h.hexdigest()[:16]}"


def _canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=repr)


def cache_key(params: dict) -> str:
    """Hex key of a table: SHA-256 of every parameter (JSON, sorted) and the code version."""
    return hashlib.sha256(_canonical({"params": params, "code": code_version()}).encode()).hexdigest()


def _checksum(meta_json: str, arrays: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256(meta_json.encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(name.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


class TableFile:
    """Content of a cache file: ``arrays`` (dict) and ``meta`` (key, parameters, provenance)."""

    def __init__(self, arrays: dict[str, np.ndarray], meta: dict):
        self.arrays, self.meta = arrays, meta

    def __repr__(self) -> str:
        return f"TableFile(arrays={len(self.arrays)}, key={self.meta.get('key', '')[:12]}..., date={self.meta.get('date')})"


def _warn(message: str, dedupe_key: tuple | None = None) -> None:
    """Issue one :class:`CacheWarning`; with ``dedupe_key``, only the first time for this key in this process."""
    if dedupe_key is not None:
        if dedupe_key in _REPORTED:
            return
        _REPORTED.add(dedupe_key)
    warnings.warn(f"dfloop cache: {message}; computing in memory (results are unaffected)", CacheWarning,
                  stacklevel=3)


def _reason(err: BaseException) -> str:
    text = f"{type(err).__name__}: {err}"
    return text if len(text) <= 200 else text[:197] + "..."


def _remove_stale_temporaries(path: Path) -> None:
    """Delete temporaries of ``path`` older than an hour (a writer killed mid-write); errors are ignored."""
    limit = time.time() - _STALE_SECONDS
    try:
        for tmp in path.parent.glob(f".{path.name}.*.tmp"):
            try:
                if tmp.stat().st_mtime < limit:
                    tmp.unlink()
            except OSError:
                pass
    except OSError:
        pass


def _write_atomic(path: Path, payload: dict[str, np.ndarray]) -> None:
    """Write ``payload`` as .npz to a temporary file next to ``path``, then rename it over ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **payload)
        os.replace(tmp, path)
    finally:
        try:
            os.unlink(tmp)
        except OSError:  # renamed already (the normal case), or the directory is gone
            pass


def save_table(path, arrays: dict[str, np.ndarray], key: str, params: dict, settings: dict, *,
               on_error: str = "warn") -> Path | None:
    """Write arrays with key, parameters, build settings, code version and date, atomically.

    The file appears complete or not at all (temporary file in the same directory, then ``os.replace``), so
    concurrent writers and readers never see a partial file; with two writers of one key the last one wins.

    Parameters
    ----------
    on_error : {"warn", "raise"}
        What a failure to write does (full disk, read-only or missing directory, a directory path that is a
        regular file, ...). ``"warn"`` (the cache's use): one :class:`dfloop.errors.CacheWarning` per
        directory and kind of failure in a process, and None is returned. ``"raise"``: the ``OSError``
        propagates (an explicit save to a path the user chose).

    Returns
    -------
    pathlib.Path or None
        The path written, or None when it could not be written (``on_error="warn"``).
    """
    if on_error not in ("warn", "raise"):
        raise DfloopError(f"on_error must be 'warn' or 'raise', got {on_error!r}")
    path = Path(path)
    meta = {"key": key, "params": params, "settings": settings, "code_version": code_version(),
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    meta_json = _canonical(meta)
    payload = {f"a.{k}": np.asarray(v) for k, v in arrays.items()}
    payload["meta"] = np.array(meta_json)
    payload["checksum"] = np.array(_checksum(meta_json, arrays))
    try:
        _write_atomic(path, payload)
    except OSError as err:
        if on_error == "raise":
            raise
        _warn(f"could not write {path} ({_reason(err)})", ("write", str(path.parent), type(err).__name__,
                                                           getattr(err, "errno", None)))
        return None
    _remove_stale_temporaries(path)
    return path


def load_table(path, key: str | None = None, *, on_error: str = "warn") -> TableFile | None:
    """Read a cache file; None when it is missing, unreadable, corrupted or built for another key.

    A missing file (or a missing cache directory) is a plain miss. A file that cannot be read (permissions,
    a directory in its place, an I/O error) or whose content fails the checks (truncated, edited, checksum
    or key mismatch) is also a miss, reported by one :class:`dfloop.errors.CacheWarning` saying what and
    where (``on_error="warn"``, the default; ``"ignore"`` reports nothing). The caller then rebuilds the
    table, and its next save replaces the bad file.
    """
    if on_error not in ("warn", "ignore"):
        raise DfloopError(f"on_error must be 'warn' or 'ignore', got {on_error!r}")
    path = Path(path)
    report = _warn if on_error == "warn" else (lambda *a, **k: None)
    try:
        data = path.read_bytes()
    except (FileNotFoundError, NotADirectoryError):
        return None  # a miss; a cache "directory" that is a regular file is reported when writing
    except OSError as err:
        report(f"could not read {path} ({_reason(err)})", ("read", str(path.parent), type(err).__name__,
                                                           getattr(err, "errno", None)))
        return None
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            meta_json = str(z["meta"])
            checksum = str(z["checksum"])
            arrays = {k[2:]: z[k] for k in z.files if k.startswith("a.")}
        meta = json.loads(meta_json)
        if not isinstance(meta, dict):
            raise ValueError("metadata is not a mapping")
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as err:
        report(f"corrupted file {path} ignored and rebuilt ({_reason(err)})")
        return None
    if checksum != _checksum(meta_json, arrays):
        report(f"corrupted file {path} ignored and rebuilt (checksum mismatch)")
        return None
    if key is not None and meta.get("key") != key:
        report(f"stale file {path} ignored and rebuilt (built for another key)")
        return None
    return TableFile(arrays, meta)
