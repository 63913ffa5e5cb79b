"""Batches (dfloop.batch) on executors: same results as the serial path, on threads and on a local Dask
cluster of worker processes."""
import math

import control as ct
import numpy as np
import pytest

import dfloop
from dfloop.batch import predict_many, run_batch
from dfloop.chart import ChartAxis, design_chart
from dfloop.continuation import sweep

G0 = ct.tf([1], [1, 3, 2, 0])


def _monte_carlo_loops(n, seed=0):
    """Gain and pole uncertainty around 1/(s(s+1)(s+2)) with a dead-zone relay or a backlash."""
    rng = np.random.default_rng(seed)
    loops = []
    for i in range(n):
        K, p = rng.uniform(1.2, 4.0), rng.uniform(1.5, 2.5)
        N = dfloop.Relay(M=1.0, dead_zone=0.1) if i % 2 else dfloop.Backlash(0.2)
        loops.append((ct.tf([K * p], [1, 1 + p, p, 0]), N))
    return loops


def _same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert list(x) == list(y)  # LimitCycle dataclasses: every float bit-identical
        assert x.amplitude_window == y.amplitude_window and x.omega_window == y.omega_window


def test_relay_batch_against_closed_form_and_threads():
    # relay with dead zone d around K/(s(s+1)(s+2)): cycles at w = sqrt(2) with
    # 4M/(pi A) sqrt(1 - (d/A)^2) = 6/K, i.e. (d/A)^2 = (1 +- sqrt(1 - 4q))/2, q = (6 pi d / (4 M K))^2
    gains = [1.0, 1.5, 2.0, 3.0]
    loops = [(K * G0, dfloop.Relay(M=1.0, dead_zone=0.1)) for K in gains]
    serial = predict_many(loops, progress=False)
    for K, res in zip(gains, serial):
        q = (6 * math.pi * 0.1 / (4 * K)) ** 2
        u = np.array([(1 + math.sqrt(1 - 4 * q)) / 2, (1 - math.sqrt(1 - 4 * q)) / 2])
        np.testing.assert_allclose([c.amplitude for c in res], 0.1 / np.sqrt(u), rtol=1e-9)
        np.testing.assert_allclose([c.frequency for c in res], math.sqrt(2), rtol=1e-9)
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(2) as ex:
        _same(serial, predict_many(loops, executor=ex, chunksize=3, progress=False))


def test_order_kept_and_errors_name_the_item():
    assert run_batch(abs, [-3, 1, -2, 5, -7], executor=None) == [3, 1, 2, 5, 7]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(2) as ex:
        assert run_batch(abs, list(range(-50, 50)), executor=ex, chunksize=7) == [abs(i) for i in range(-50, 50)]
        with pytest.raises(ValueError, match="predict_many, item 1: N must be a dfloop DescribingFunction"):
            predict_many([(G0, dfloop.Backlash(0.2)), (G0, "relay")], executor=ex, chunksize=1)
    with pytest.raises(ValueError, match=r"loops\[1\] must be a pair"):
        predict_many([(G0, dfloop.Backlash(0.2)), G0])
    with pytest.raises(ValueError, match="chunksize"):
        run_batch(abs, [1, 2], executor=ThreadPoolExecutor(1), chunksize=0)
    with pytest.raises(ValueError, match="executor"):
        run_batch(abs, [1, 2], executor=object())
    with pytest.raises(RuntimeError, match="item 2: TypeError"):
        run_batch(abs, [1, 2, "x"])
    import time

    with ThreadPoolExecutor(1) as ex, pytest.raises(TimeoutError, match="1 of 1 items unfinished after timeout=0.05"):
        run_batch(time.sleep, [0.5], executor=ex, timeout=0.05)
    with pytest.raises(ValueError, match="timeout"):
        run_batch(abs, [1], timeout=-1)


def _servo(K, h):
    return K * G0, dfloop.Backlash(h)


_CHART_AXES = (ChartAxis(2.5, 5.5, "gain K"), ChartAxis(0.1, 0.5, "clearance h", "m"))
_CHART_OPTIONS = dict(samples=3, resolution=12, omega=(0.01, 100.0), progress=False)


def test_dask_local_cluster_gives_the_serial_results():
    distributed = pytest.importorskip("distributed")  # in the test extra; CI installs it
    loops = _monte_carlo_loops(24)
    serial = predict_many(loops, progress=False)
    assert sum(len(r) for r in serial) > 0
    values = [1.2, 1.6, 2.0, 2.4]

    def loop_at(K):
        return K * G0, dfloop.Relay(M=1.0, dead_zone=0.1)

    sw_serial = sweep(loop_at, values, progress=False)
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cl, \
            distributed.Client(cl) as client:
        ex = client.get_executor()
        _same(serial, predict_many(loops, executor=ex, chunksize=4, progress=False, timeout=120))
        sw = sweep(loop_at, values, progress=False, executor=ex)
        chart = design_chart(_servo, *_CHART_AXES, executor=ex, **_CHART_OPTIONS)
    chart_serial = design_chart(_servo, *_CHART_AXES, **_CHART_OPTIONS)
    assert len(chart.boundaries) == len(chart_serial.boundaries) > 0
    for a, b in zip(chart_serial.boundaries, chart.boundaries):
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.y, b.y)
    assert chart.region_fractions() == chart_serial.region_fractions()
    _same(sw_serial.cycles, sw.cycles)
    for a, b in zip(sw_serial.branches, sw.branches):
        np.testing.assert_array_equal(a.amplitude, b.amplitude)
        np.testing.assert_array_equal(a.parameter, b.parameter)


def _stable_amplitudes(result):
    """What a large batch keeps of each loop: the amplitudes of its stable cycles."""
    return tuple(c.amplitude for c in result if c.stability == "stable")


def test_streamed_batch_keeps_only_what_is_asked_and_reads_ahead_a_bounded_amount():
    import threading
    from concurrent.futures import ThreadPoolExecutor

    from dfloop import batch

    loops = _monte_carlo_loops(40, seed=3)
    whole = [_stable_amplitudes(r) for r in predict_many(loops, progress=False)]
    assert predict_many(iter(loops), keep=_stable_amplitudes, progress=False, total=len(loops)) == whole
    with pytest.raises(ValueError, match="total"):
        predict_many(iter(loops), total=-1)
    produced, finished, worst, lock = [0], [0], [0], threading.Lock()

    def generate():
        for loop in loops:
            with lock:
                produced[0] += 1
                worst[0] = max(worst[0], produced[0] - finished[0])
            yield loop

    def keep(result):
        with lock:
            finished[0] += 1
        return _stable_amplitudes(result)

    with ThreadPoolExecutor(2) as ex:
        got = predict_many(generate(), executor=ex, chunksize=2, keep=keep, progress=False)
    assert got == whole
    assert worst[0] <= (batch._IN_FLIGHT + 1) * 2  # never the whole stream: chunks in flight plus one
    with pytest.raises(ValueError, match="keep must be a callable"):
        predict_many(loops, keep=3)
    with pytest.raises(ValueError, match="predict_many, item 1: a loop must be a pair"):
        predict_many(iter([loops[0], G0]), progress=False)
