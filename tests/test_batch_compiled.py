"""predict_many on the compiled driver: chunks of loops in one parallel call (dfloop.solve.predict.predict_chunk).

The truth is predict_limit_cycles called on each loop by itself: the batch must return exactly its results (the
same code computes them), whether the loops run in this process, streamed from a generator or in chunks on an
executor, including loops the driver leaves to the Python driver and loops it cannot take at all.
"""
from __future__ import annotations

import math
import sys
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import control as ct
import numpy as np

import dfloop as df
from dfloop.batch import predict_many
from dfloop.solve.delay import delayed

sys.path.insert(0, str(Path(__file__).parents[1] / "examples"))
from monte_carlo_servo import sample, stable_amplitude  # noqa: E402


def _rows(result):
    return [(c.amplitude, c.frequency, c.stability, c.residual, c.loeb_determinant, c.G, c.N, c.on_edge)
            for c in result]


def _mixed():
    loops = list(sample(40, 3))
    loops += [(ct.tf([0.2947], [1, 1.547]), df.DeadZone(0.906166742393567, 0.11706236171721078)),  # fallback
              (lambda w: 4 / (1j * w + 1) ** 3, df.Saturation(1.0)),  # a callable: the Python driver only
              (ct.ss(ct.tf([4], [1, 2, 2, 1])), df.PreloadedSpring(0.5, k=0.2)),
              (delayed(ct.tf([2], [1, 1]), 0.5), df.CoulombViscousFriction(1.0, c=0.1))]
    return loops


def test_batch_results_are_the_single_calls(monkeypatch):
    monkeypatch.setenv("DFLOOP_COMPILED", "driver")
    loops = _mixed()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = [df.predict_limit_cycles(G, N) for G, N in loops[:-3]]
        got = predict_many(loops[:-3], progress=False)
        got_stream = predict_many(iter(loops[:-3]), chunksize=7, progress=False)
        with ThreadPoolExecutor(2) as ex:
            got_ex = predict_many(loops[:-3], executor=ex, chunksize=9, progress=False)
    assert sum(len(r) for r in ref) >= 40  # cycles, not only empty results
    for r, a, b, c in zip(ref, got, got_stream, got_ex):
        assert _rows(a) == _rows(b) == _rows(c) == _rows(r)
        assert a.grid_report == r.grid_report and a.window_source == r.window_source
    tail = loops[-3:]  # the callable needs a window: these run with one
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = predict_many(tail, omega=(0.05, 50.0), progress=False)
        ref = [df.predict_limit_cycles(G, N, omega=(0.05, 50.0)) for G, N in tail]
    assert [_rows(r) for r in got] == [_rows(r) for r in ref]


def test_batch_keep_and_the_python_path_agree(monkeypatch):
    """The probability of a stable cycle over sampled servo loops: the compiled batch against the Python driver
    (DFLOOP_COMPILED=0), loop by loop to 1e-12."""
    monkeypatch.setenv("DFLOOP_COMPILED", "driver")
    fast = np.array(predict_many(sample(60, 5), keep=stable_amplitude, progress=False))
    monkeypatch.setenv("DFLOOP_COMPILED", "0")
    slow = np.array([stable_amplitude(df.predict_limit_cycles(G, N)) for G, N in sample(60, 5)])
    assert np.array_equal(np.isnan(fast), np.isnan(slow))
    ok = ~np.isnan(fast)
    assert ok.sum() >= 20
    assert np.all(np.abs(fast[ok] / slow[ok] - 1) <= 1e-12)
    assert not math.isnan(float(np.nanmax(fast)))


_FORKED = """
import multiprocessing, sys
import numpy as np
from concurrent.futures import ProcessPoolExecutor
sys.path.insert(0, {examples!r})
from dfloop.batch import predict_many
from monte_carlo_servo import sample, stable_amplitude
loops = list(sample(48, 11))
here = predict_many(loops, keep=stable_amplitude, progress=False)  # 48 loops: the batch's threads are started
with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as ex:
    there = predict_many(loops, keep=stable_amplitude, executor=ex, chunksize=24, progress=False)
assert np.array_equal(np.array(here), np.array(there), equal_nan=True), (here, there)
assert np.isfinite(here).sum() >= 10
print("same")
"""


def test_a_forked_worker_runs_batches_after_its_parent_did():
    """The batch's threads do not survive a fork: a process pool forked after its parent ran a batch on them
    starts its own, and gets the parent's results (not a batch waiting forever on threads that are not there). Run
    in a fresh interpreter, killed if it waits."""
    import os
    import subprocess

    code = _FORKED.format(examples=str(Path(__file__).parents[1] / "examples"))
    env = dict(os.environ, DFLOOP_COMPILED="driver")
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and done.stdout.strip() == "same", done.stderr[-2000:]
