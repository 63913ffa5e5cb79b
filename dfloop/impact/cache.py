"""Disk cache of tables: one ``.npz`` file per key, holding the arrays, the key, provenance and a checksum.

A file is trusted only if it parses, its stored key equals the requested key and the SHA-256 checksum
of its content matches; anything else (missing, truncated, edited, built by other code) reads as a miss
and is rebuilt by the caller. Writes are atomic (temporary file, then rename).

Cache directory: ``$DFLOOP_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/dfloop`` or ``~/.cache/dfloop``.
"""
from __future__ import annotations

import datetime
import hashlib
import io
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

__all__ = ["cache_dir", "code_version", "cache_key", "save_table", "load_table", "TableFile"]

_SOURCES = ("table.py", "dynamic_backlash.py", "kernel.py", "effects.py", "extract.py", "cache.py")


def cache_dir() -> Path:
    """The cache directory (created on demand by :func:`save_table`)."""
    env = os.environ.get("DFLOOP_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "dfloop"


def code_version() -> str:
    """dfloop's version plus a hash of the sources that determine a table's content."""
    import dfloop

    here = Path(__file__).parent
    h = hashlib.sha256()
    for name in _SOURCES:
        p = here / name
        if p.exists():
            h.update(name.encode())
            h.update(p.read_bytes())
    return f"{dfloop.__version__}+{h.hexdigest()[:16]}"


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


def save_table(path, arrays: dict[str, np.ndarray], key: str, params: dict, settings: dict) -> Path:
    """Write arrays with key, parameters, build settings, code version and date (atomic)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"key": key, "params": params, "settings": settings, "code_version": code_version(),
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    meta_json = _canonical(meta)
    payload = {f"a.{k}": np.asarray(v) for k, v in arrays.items()}
    payload["meta"] = np.array(meta_json)
    payload["checksum"] = np.array(_checksum(meta_json, arrays))
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **payload)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def load_table(path, key: str | None = None) -> TableFile | None:
    """Read a cache file; None if missing, unreadable, checksum-mismatched or built for another key."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with np.load(io.BytesIO(path.read_bytes()), allow_pickle=False) as z:
            meta_json = str(z["meta"])
            checksum = str(z["checksum"])
            arrays = {k[2:]: z[k] for k in z.files if k.startswith("a.")}
        meta = json.loads(meta_json)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, json.JSONDecodeError):
        return None
    if checksum != _checksum(meta_json, arrays):
        return None
    if key is not None and meta.get("key") != key:
        return None
    return TableFile(arrays, meta)
