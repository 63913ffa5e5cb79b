"""The cache is an accelerator, never a point of failure: every fault falls back to computing in memory.

Each test injects one fault (a cache path that is a regular file, a full disk, a read-only directory, an
unreadable file, a corrupted or stale file, two writers at once) and checks that N equals a cache-free
evaluation of the same table exactly (the table build is deterministic) and that exactly one CacheWarning
names the fault and the path. Faults are injected by monkeypatching the operating-system calls (the tests
run as root here, where file permissions do not bite).
"""
import errno
import multiprocessing
import os
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from dfloop.errors import CacheWarning
from dfloop.tables import cache
from dfloop.impact.dynamic_backlash import DynamicBacklash

F, W = 50.0, np.array([34.0, 36.0, 40.0])
SMALL = dict(tol=1e-2, transient_periods=10, periods=4, base_dx=0.3, min_dx=1e-2)  # a table in ~20 ms


def element(**kw):
    return DynamicBacklash(1.0, 1.0, 0.1, 0.5, **SMALL, **kw)


@pytest.fixture(scope="module")
def reference():
    """N from a cache-free build of the same table."""
    return element(cache=False)(F, W)


@pytest.fixture(autouse=True)
def fresh_reports(monkeypatch, tmp_path):
    monkeypatch.setattr(cache, "_REPORTED", set())
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "cache"))


def evaluate_recording(db, *args):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        n = db(*args)
    return n, [w for w in caught if issubclass(w.category, CacheWarning)], caught


def test_healthy_cache_gives_no_warning_and_the_same_n(reference, tmp_path):
    """The cache directory does not exist yet (a missing directory is created, silently)."""
    n, cw, caught = evaluate_recording(element(), F, W)
    np.testing.assert_array_equal(n, reference)
    assert cw == [] and [str(w.message) for w in caught] == []
    second = element()
    n2, cw2, _ = evaluate_recording(second, F, W)
    np.testing.assert_array_equal(n2, reference)
    assert cw2 == [] and second.n_simulations == 0  # served by the cache, no simulation


def test_cache_dir_is_a_regular_file(reference, tmp_path, monkeypatch):
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("a file where the cache directory should be")
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(blocker))
    db = element()
    n, cw, _ = evaluate_recording(db, F, W)
    np.testing.assert_array_equal(n, reference)
    assert len(cw) == 1
    assert str(blocker) in str(cw[0].message) and "FileExistsError" in str(cw[0].message)
    # extending the table saves again: the same fault is not reported twice (the cache-free reference
    # follows the same sequence of requests: a table's content may depend on the order of its windows)
    n_more, cw_more, _ = evaluate_recording(db, F, np.array([28.0, 30.0]))
    same_order = element(cache=False)
    same_order(F, W)
    np.testing.assert_array_equal(n_more, same_order(F, np.array([28.0, 30.0])))
    assert cw_more == []
    assert blocker.read_text().startswith("a file")  # untouched


def _full_disk_savez(f, **payload):
    f.write(b"PK\x03\x04 half a file")
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _read_only_mkstemp(*args, **kwargs):
    raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), kwargs.get("dir"))


def _vanished_replace(src, dst):
    raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), dst)


@pytest.mark.parametrize("target,fake,reason", [
    ("numpy.savez", _full_disk_savez, "No space left on device"),
    ("tempfile.mkstemp", _read_only_mkstemp, "Permission denied"),
    ("os.replace", _vanished_replace, "No such file or directory"),
], ids=["full-disk", "read-only-directory", "directory-removed-during-write"])
def test_write_fault_falls_back_to_memory(reference, tmp_path, monkeypatch, target, fake, reason):
    module, name = target.split(".")
    monkeypatch.setattr({"numpy": np, "tempfile": cache.tempfile, "os": cache.os}[module], name, fake)
    db = element()
    n, cw, _ = evaluate_recording(db, F, W)
    np.testing.assert_array_equal(n, reference)
    assert len(cw) == 1
    message = str(cw[0].message)
    assert "could not write" in message and str(db.cache_path) in message and reason in message
    leftovers = list((tmp_path / "cache").iterdir()) if (tmp_path / "cache").exists() else []
    assert leftovers == []  # no partial file and no temporary left behind


def test_unreadable_file_falls_back_and_is_reported_once(reference, monkeypatch):
    element()(F, W)  # a valid cache file
    real = Path.read_bytes

    def deny(self):
        if self.suffix == ".npz":
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", deny)
    db = element()
    n, cw, _ = evaluate_recording(db, F, W)
    np.testing.assert_array_equal(n, reference)
    assert db.n_simulations > 0  # rebuilt in memory
    assert len(cw) == 1 and "could not read" in str(cw[0].message) and str(db.cache_path) in str(cw[0].message)


@pytest.mark.parametrize("damage", ["flip", "truncate", "garbage", "other-key"])
def test_corrupted_or_stale_file_is_rebuilt_with_one_warning(reference, damage):
    first = element()
    first(F, W)
    path = first.cache_path
    good = path.read_bytes()
    if damage == "flip":
        bad = bytearray(good)
        bad[len(good) // 2] ^= 0x5A
        path.write_bytes(bytes(bad))
    elif damage == "truncate":
        path.write_bytes(good[: len(good) // 3])
    elif damage == "garbage":
        path.write_bytes(b"\x00" * 100)
    else:
        f = cache.load_table(path)
        cache.save_table(path, f.arrays, "0" * 64, f.meta["params"], f.meta["settings"])
    db = element()
    n, cw, _ = evaluate_recording(db, F, W)
    np.testing.assert_array_equal(n, reference)
    assert len(cw) == 1 and str(path) in str(cw[0].message)
    assert ("stale" if damage == "other-key" else "corrupted") in str(cw[0].message)
    # the rebuild replaced the bad file: the next reader is served silently
    again = element()
    n2, cw2, _ = evaluate_recording(again, F, W)
    np.testing.assert_array_equal(n2, reference)
    assert cw2 == [] and again.n_simulations == 0


def test_explicit_save_can_raise(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OSError):
        cache.save_table(blocker / "t.npz", {"x": np.zeros(2)}, "k", {}, {}, on_error="raise")
    with pytest.warns(CacheWarning, match="could not write"):
        assert cache.save_table(blocker / "t.npz", {"x": np.zeros(2)}, "k", {}, {}) is None
    with pytest.raises(ValueError, match="on_error"):
        cache.save_table(tmp_path / "t.npz", {"x": np.zeros(2)}, "k", {}, {}, on_error="ignore")


def test_stale_temporaries_of_killed_writers_are_removed(tmp_path):
    target = tmp_path / "t.npz"
    old = tmp_path / ".t.npz.abc123.tmp"
    young = tmp_path / ".t.npz.def456.tmp"
    for p in (old, young):
        p.write_bytes(b"partial")
    hours_ago = time.time() - 2 * 3600
    os.utime(old, (hours_ago, hours_ago))
    cache.save_table(target, {"x": np.arange(3.0)}, "k", {}, {})
    assert not old.exists() and young.exists()  # a young one may belong to a live writer
    np.testing.assert_array_equal(cache.load_table(target, "k").arrays["x"], np.arange(3.0))


def _writer(path: str, fill: float, rounds: int) -> None:
    for i in range(rounds):
        cache.save_table(path, {"x": np.full(20000, fill), "i": np.array(i)}, "shared-key", {}, {}, on_error="raise")


def test_two_writers_at_once_never_expose_a_partial_file(tmp_path):
    """Two processes (forked: no second import) rewrite one file while this one reads it."""
    path = tmp_path / "shared.npz"
    ctx = multiprocessing.get_context("fork")
    procs = [ctx.Process(target=_writer, args=(str(path), fill, 25)) for fill in (1.0, 2.0)]
    for p in procs:
        p.start()
    reads = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)  # a torn read would warn "corrupted": fail instead
        deadline = time.monotonic() + 60
        while any(p.is_alive() for p in procs) and time.monotonic() < deadline:
            f = cache.load_table(path, "shared-key")
            if f is not None:
                x = f.arrays["x"]
                assert x[0] in (1.0, 2.0) and np.all(x == x[0])  # one writer's content, whole
                reads += 1
    for p in procs:
        p.join(timeout=60)
    assert [p.exitcode for p in procs] == [0, 0]
    final = cache.load_table(path, "shared-key")
    assert final is not None and int(final.arrays["i"]) == 24
    assert not list(tmp_path.glob("*.tmp")) and not list(tmp_path.glob(".*.tmp"))
