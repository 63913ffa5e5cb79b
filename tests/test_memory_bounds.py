"""The solver's memory bound is enforced: estimated before allocating, refused with the estimate and the knob,
and what can be streamed is streamed (issue 17, item 6).

Peaks are measured with tracemalloc (numpy's data buffers are traced), independently of dfloop's estimate:
the estimate must bound the measured peak of small runs from above, and a refused call must have allocated
(almost) nothing, which is what "refused before allocation" means.
"""
import tracemalloc

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.describing import numeric
from dfloop.solve.grid import BYTES_PER_POINT, check_memory
from dfloop.solve.plant import MAX_ORDER, as_plant
from dfloop.solve.roots import greedy_unique

MiB = 2**20
G = ct.tf([1.0, 2.0], [1.0, 1.0, 4.0])
MB = df.MassBacklash(1.0, 1.0, 0.1)


def traced_peak(call):
    """(result or exception, peak bytes traced during call)."""
    tracemalloc.start()
    try:
        try:
            out = call()
        except Exception as exc:  # noqa: BLE001 - the caller checks what came out
            out = exc
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_grid_beyond_the_bound_is_refused_before_allocation():
    df.predict_limit_cycles(G, MB, grid=(8, 8))  # warm: imports and first-call caches are not the refusal's
    exc, peak = traced_peak(lambda: df.predict_limit_cycles(G, MB, grid=(6000, 7000)))
    assert isinstance(exc, ValueError)
    need = 6000 * 7000 * BYTES_PER_POINT[True] / 2**30  # the case took 5.5 GB before this bound
    assert f"would need {need:.1f} GiB" in str(exc) and "DFLOOP_MEMORY_LIMIT" in str(exc) and "grid=" in str(exc)
    assert peak < 2 * MiB  # one complex 6000 x 7000 array alone is 640 MiB


@pytest.mark.parametrize("case", ["frequency-dependent", "amplitude-only"])
def test_the_estimate_bounds_the_measured_peak(case):
    if case == "frequency-dependent":
        call = lambda: df.predict_limit_cycles(G, MB, grid=(300, 350))  # noqa: E731
    else:  # relay around a delay plant: thousands of frequency nodes and ~500 cycles to merge
        call = lambda: df.predict_limit_cycles(lambda w: np.exp(-1j * w) / (1j * w + 1), df.Relay(1.0),  # noqa: E731
                                               omega=(0.1, 3e3), grid=(64, 256))
    call()
    res, peak = traced_peak(call)
    assert isinstance(res, df.LimitCycles), res
    points = np.prod(res.grid_report.shape)
    per_point = BYTES_PER_POINT[case == "frequency-dependent"]
    assert peak <= per_point * points
    if case == "frequency-dependent":  # and the estimate is not a loose guess that refuses feasible grids
        assert peak >= 0.25 * per_point * points
    else:  # the loop product is read at the candidate cells only: not even one complex na x nv array (16 B/point)
        assert peak < 16 * points


def test_the_bound_is_a_knob(monkeypatch):
    call = lambda: df.predict_limit_cycles(G, MB, grid=(64, 64))  # noqa: E731
    need = 160 * 64 * 64  # bytes of the initial grid alone
    monkeypatch.setenv("DFLOOP_MEMORY_LIMIT", str(0.5 * need / 2**30))
    with pytest.raises(ValueError, match="limit 0.000305 GiB"):
        call()
    monkeypatch.setenv("DFLOOP_MEMORY_LIMIT", "4")
    assert isinstance(call(), df.LimitCycles)
    for bad in ("0", "-1", "nan", "two"):
        monkeypatch.setenv("DFLOOP_MEMORY_LIMIT", bad)
        with pytest.raises(ValueError, match="DFLOOP_MEMORY_LIMIT must be a positive number of GiB"):
            check_memory(2, 2)


def _pairwise_greedy(a, v, radius):
    """Reference: every pair compared (the n x n matrix the solver used to build)."""
    radius = np.broadcast_to(np.asarray(radius, float), a.shape)
    keep = []
    for k in range(a.size):
        if not any(max(abs(a[k] - a[m]), abs(v[k] - v[m])) <= radius[k] + radius[m] for m in keep):
            keep.append(k)
    return np.array(keep, dtype=int)


def test_merging_roots_needs_linear_memory():
    rng = np.random.default_rng(7)
    for _ in range(200):  # clusters, ties in v, zero and mixed radii
        n = int(rng.integers(0, 40))
        a = rng.normal(size=n) * rng.choice([1e-3, 1.0])
        v = np.round(rng.normal(size=n), int(rng.integers(1, 4)))
        radius = rng.random(n) * rng.choice([1e-3, 0.1, 1.0]) if rng.random() < 0.5 else float(rng.choice([0, 1e-2]))
        assert np.array_equal(greedy_unique(a, v, radius), _pairwise_greedy(a, v, radius))
    # 20000 distinct roots (a delay plant over a wide window has ~16000): the pair matrix would be 400 MB
    v = np.sort(rng.uniform(0, 10, 20000))
    a = rng.uniform(-1, 1, v.size)
    keep, peak = traced_peak(lambda: greedy_unique(a, v, 1e-9))
    assert keep.size == v.size - np.count_nonzero(np.diff(v) <= 2e-9) and peak < 5 * MiB


def test_the_plants_variation_bound_is_streamed_and_still_bounds():
    rng = np.random.default_rng(3)
    poles = -(0.2 + rng.random(200)) + 1j * rng.normal(scale=3.0, size=200)
    plant = as_plant(ct.tf([1.0], np.real(np.poly(np.concatenate([poles, poles.conj()])))))
    w = np.geomspace(0.05, 50, 20001)
    eps, peak = traced_peak(lambda: plant.log_variation(w[:-1], w[1:]))
    assert peak < 40 * MiB  # all at once: 20000 x 400 entries, ~10 work arrays: ~600 MiB
    small = slice(0, 20000, 97)  # the same intervals one at a time
    assert np.array_equal(eps[small], [plant.log_variation(w[i:i + 1], w[i + 1:i + 2])[0] for i in range(0, 20000, 97)])
    # and it is a bound: |ln G(w) - ln G(w0)| sampled inside the intervals never exceeds it
    zeros, p = plant.roots
    for i in range(0, 20000, 499):
        ws = np.linspace(w[i], w[i + 1], 50)
        lg = -np.log(1j * ws[:, None] - p[None, :]).sum(axis=1)  # ln G up to a constant
        lg = lg.real + 1j * np.unwrap(lg.imag)  # the phase followed continuously (fine samples)
        d = np.abs(lg - lg[0])
        assert d.max() <= eps[i] * (1 + 1e-9) + 1e-12


def test_a_plant_beyond_the_order_bound_is_refused_before_conversion():
    n = MAX_ORDER + 1
    sys = ct.ss(-np.eye(n), np.ones((n, 1)), np.ones((1, n)), 0.0)
    exc, peak = traced_peak(lambda: df.predict_limit_cycles(sys, df.Relay(1.0)))
    assert isinstance(exc, ValueError) and f"G has order {n}, above the bound of {MAX_ORDER}" in str(exc)
    assert peak < n * n * 8 / 4  # less than a quarter of one n x n matrix: no conversion, no eigenvalues


def test_an_impact_run_record_stops_at_the_memory_limit(monkeypatch):
    """The record of a long run grows within the limit and stops with an error saying so (its growth was sized
    from the periods left: t_end = 1e5 s asked for ~0.5 GB at once)."""
    from dfloop.errors import EventLimitError
    from dfloop.impact.kernel import simulate

    simulate(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 1.0)  # warm: compilation is not the run's memory
    limit = 4 * MiB
    monkeypatch.setenv("DFLOOP_MEMORY_LIMIT", str(limit / 2**30))
    exc, peak = traced_peak(lambda: simulate(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 1e5))
    assert isinstance(exc, EventLimitError) and "the memory limit" in str(exc) and "DFLOOP_MEMORY_LIMIT" in str(exc)
    assert peak < 3 * limit  # the record, the buffer it grows from, and the kernel's small arrays
    monkeypatch.delenv("DFLOOP_MEMORY_LIMIT")
    traj = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 30.0, 5.0)  # a short run is unaffected
    assert traj.t_end == 5.0


def test_numeric_df_streams_amplitudes_and_shows_progress(monkeypatch):
    calls = []

    class Recorder:
        def __init__(self, label, total):
            calls.append([label, total, 0])

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return None

        def update(self, n=1, stage=None):
            calls[-1][2] += n

    monkeypatch.setattr(numeric, "progress_bar", Recorder)
    el = df.NumericDF(df.Backlash(0.2))  # a hysteretic operator: a Python loop per amplitude
    A = np.geomspace(0.15, 3.0, 3 * numeric._HYSTERETIC_CHUNK + 1)
    together = el(A)
    assert calls == [["NumericDF (hysteretic): 25 amplitudes", A.size, A.size]]
    assert np.array_equal(together, [el(x) for x in A])  # chunks change nothing
    np.testing.assert_allclose(together, df.Backlash(0.2)(A), rtol=1e-12, atol=1e-15)  # the closed form
    static = df.NumericDF(np.tanh, samples=16)
    monkeypatch.setattr(numeric, "_CHUNK_VALUES", 17 * 100)  # 100 amplitudes per chunk
    B = np.geomspace(1e-3, 1e3, 1001)
    chunked = static(B)
    assert calls[-1] == ["NumericDF (static): 1001 amplitudes", 1001, 1001]
    monkeypatch.setattr(numeric, "_CHUNK_VALUES", 10**9)
    assert np.array_equal(chunked, static(B))


def test_the_environment_is_read_as_os_environ_reads_it(monkeypatch):
    """_checks.environ (read on every solver call: the memory bound, DFLOOP_COMPILED) gives what os.environ.get
    gives, for set, changed, non-ASCII and removed variables; and the memory bound follows DFLOOP_MEMORY_LIMIT from
    one call to the next."""
    from dfloop._checks import environ, memory_limit

    name = "DFLOOP_TEST_ENVIRON"
    monkeypatch.delenv(name, raising=False)
    assert environ(name) is None
    for value in ("1", "", "driver", "caf\u00e9 \u2713", "0"):
        monkeypatch.setenv(name, value)
        assert environ(name) == value == __import__("os").environ.get(name)
    monkeypatch.delenv(name)
    assert environ(name) is None
    monkeypatch.setenv("DFLOOP_MEMORY_LIMIT", "0.5")
    assert memory_limit() == 2**29
    monkeypatch.setenv("DFLOOP_MEMORY_LIMIT", "2")
    assert memory_limit() == 2**31
