"""Progress lines and start-up announcements say what is true: start-up is not counted as work."""
from __future__ import annotations

import importlib.util
import io
import sys

from dfloop import progress as progress_mod
from dfloop.progress import ProgressSink, announce, compile_pending


class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_time_left_excludes_start_up(monkeypatch):
    """10 units of 1 s each after a 100 s start-up (a first-use compile): after 3 units the time left is 7 s
    (7 units at the measured 1 s per unit), not 100 s / 3 per unit as an average over the elapsed time says."""
    clock = _Clock()
    monkeypatch.setattr(progress_mod.time, "monotonic", clock)
    out = io.StringIO()
    sink = ProgressSink("table", 10, out, delay=0.0, interval=0.0)
    clock.now = 100.0                 # the compile: nothing done yet
    sink.update(1)                    # first unit done at t = 101 (1 s of work after 100 s of start-up)
    clock.now = 101.0
    sink.update(1)
    clock.now = 102.0
    sink.update(1)
    last = out.getvalue().strip().splitlines()[-1]
    assert last == "table: 3/10, 102 s elapsed, ~7 s left"
    assert "left" not in out.getvalue().splitlines()[0]  # one unit alone gives no rate: no estimate


def test_announce_follows_the_switches(monkeypatch):
    out = io.StringIO()
    announce("compiling once", stream=out)
    assert out.getvalue() == "compiling once\n"
    announce("hidden", stream=out, enabled=False)
    monkeypatch.setenv("DFLOOP_PROGRESS", "0")
    announce("hidden", stream=out)
    assert out.getvalue() == "compiling once\n"


def test_compile_pending_tracks_numba_cache(tmp_path):
    """A cache=True function in a fresh directory needs compiling; after its first call it does not, and a new
    process (simulated by re-importing the module) finds it in numba's on-disk cache."""
    src = tmp_path / "nt_jit_probe.py"
    src.write_text("from numba import njit\n\n@njit(cache=True)\ndef f(x):\n    return x + 1\n")

    def load():
        spec = importlib.util.spec_from_file_location("nt_jit_probe", src)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    m = load()
    assert compile_pending(m.f) is True
    assert m.f(1) == 2
    assert compile_pending(m.f) is False
    assert compile_pending(load().f) is False    # fresh dispatcher, compiled code on disk
    assert "nt_jit_probe" not in sys.modules


def test_a_forecast_total_says_so_until_the_work_ends():
    out = io.StringIO()
    sink = ProgressSink("table", 100, out, delay=0.0, interval=0.0, estimated=True)
    sink.update(30)
    sink.set_total(80, estimated=True)
    sink.update(50)
    sink.close()
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("table: 30/~100,") and lines[1].startswith("table: 80/~80,")
    assert lines[-1].startswith("table: 80/80,") and lines[-1].endswith(", done")
