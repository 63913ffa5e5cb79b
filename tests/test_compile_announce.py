"""First use on a fresh install: the compiled code says at once, on the progress channel, that it compiles once
and about how long; a process that finds it cached says nothing (dfloop.progress.announce_compile)."""
from __future__ import annotations

import io
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from dfloop import progress

ROOT = Path(__file__).resolve().parents[1]


class _Index:
    def __init__(self, entries):
        self.entries = entries

    def _load_index(self):
        return self.entries


class _Dispatcher:
    """The two things compile_pending reads of a numba dispatcher: compiled signatures and the cache index."""

    def __init__(self, signatures, cached):
        self.signatures = signatures
        self._cache = type("C", (), {"_cache_file": _Index({("sig", "cpu"): "file"} if cached else {})})()


def test_announces_once_and_only_when_something_compiles(monkeypatch):
    monkeypatch.setattr(progress, "_ANNOUNCED", set())
    monkeypatch.setattr(progress, "_READY", set())
    monkeypatch.delenv("DFLOOP_PROGRESS", raising=False)
    out = io.StringIO()
    ready = [_Dispatcher(["f8(f8)"], False), _Dispatcher([], True)]
    assert not progress.announce_compile("ready thing", 7, *ready, stream=out)
    assert out.getvalue() == ""
    cold = ready + [_Dispatcher([], False)]
    assert progress.announce_compile("thing", 7, *cold, stream=out)
    assert not progress.announce_compile("thing", 7, *cold, stream=out)  # once per process
    assert out.getvalue() == ("dfloop: thing: compiling once for this installation, about 7 s (later runs load the "
                              "compiled code; `dfloop warmup` does it ahead)\n")


def test_a_ready_answer_is_remembered_and_numbas_index_not_read_again(monkeypatch):
    """Reading numba's cache index costs ~0.4 ms (a file and a pickle): once found ready, never again."""
    monkeypatch.setattr(progress, "_ANNOUNCED", set())
    monkeypatch.setattr(progress, "_READY", set())
    cached = _Dispatcher([], True)
    reads = []
    index = cached._cache._cache_file
    original = index._load_index
    monkeypatch.setattr(index, "_load_index", lambda: reads.append(1) or original(), raising=False)
    for _ in range(5):
        assert not progress.announce_compile("cached thing", 7, cached, stream=io.StringIO())
    assert len(reads) == 1


def _first_predict(cache: str) -> str:
    code = ("import control as ct, dfloop as df; "
            "r = df.predict_limit_cycles(ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)); print(len(r))")
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=cache)
    for name in ("DFLOOP_PROGRESS", "DFLOOP_COMPILED"):
        env.pop(name, None)
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300,
                          check=True)
    assert done.stdout.strip() == "2"  # the backlash servo's two cycles, compiled or loaded
    return done.stderr


def test_fresh_install_says_it_compiles_and_a_cached_one_is_silent():
    with tempfile.TemporaryDirectory() as cache:
        first = _first_predict(cache)
        # a single call compiles the residual's kernels (announced) and does not wait for the driver (said once)
        assert "dfloop: the solver's residual kernels: compiling once for this installation, about" in first
        assert first.count("the compiled solver driver is not compiled") == 1
        assert "compiling" not in _first_predict(cache)

