"""Tables you can trust: regime probes, canonical blocks (order-independent content), coexisting branches,
failed samples, resumable builds; each checked against a synthetic closed form or a direct long simulation."""
import math

import numpy as np
import pytest

from dfloop.impact.dynamic_backlash import DynamicBacklash
from dfloop.impact.sampling import FAILED, ImpactSampler
from dfloop.impact.extract import impact_describing_function
from dfloop.errors import EventLimitError
from dfloop.tables import Samples, Table1D, TableSettings

M1, M2, H, F = 1.0, 1.0, 0.1, 50.0
FAST = dict(base_dx=0.025, periods=20)         # blocks of 0.2 in ln beta keep each build small


@pytest.fixture(autouse=True)
def tmp_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("DFLOOP_PROGRESS", "0")
    return tmp_path / "cache"


# ---------------------------------------------------------------------------------------- synthetic truth
WINDOW = (0.413, 0.437)     # a narrow regime window inside an otherwise smooth function


def window_sampler(x):
    inside = (x > WINDOW[0]) & (x < WINDOW[1])
    return Samples(np.exp(1j * x) * (1 + np.where(inside, 0.2, 0.0)), np.where(inside, 2, 1), np.ones(x.shape, bool))


def test_regime_window_between_samples_of_one_regime_is_probed_and_bracketed():
    """Without probes the window hides between two regime-1 samples that pass the value check (the table
    would interpolate across it); with probe_dx below the window width it is found and bracketed."""
    q = np.linspace(WINDOW[0] + 2e-3, WINDOW[1] - 2e-3, 50)
    blind = Table1D.build(window_sampler, 0.0, 1.0, TableSettings(tol=1e-3, base_dx=0.1, block_dx=1.0))
    assert not np.any(blind.regime == 2)
    tv = blind.evaluate(q)
    assert np.all(tv.valid) and np.all(np.abs(tv.value - window_sampler(q).value) > 0.1)   # silently wrong
    probed = Table1D.build(window_sampler, 0.0, 1.0, TableSettings(tol=1e-3, base_dx=0.1, block_dx=1.0,
                                                                   probe_dx=0.02))
    tv = probed.evaluate(q)
    truth = window_sampler(q).value
    assert np.all(np.abs(tv.value - truth)[tv.valid] <= tv.error[tv.valid])
    assert np.count_nonzero(tv.valid) >= 40
    for edge in WINDOW:                       # both edges bracketed, never interpolated across
        i = np.searchsorted(probed.x, edge) - 1
        assert probed.jumps()[i] and probed.x[i + 1] - probed.x[i] <= probed.settings.edge_dx


def test_window_narrower_than_probe_dx_is_found_by_window_probes_and_bracketed():
    """A window narrower than probe_dx (the full-sample probes miss it) but wider than window_dx: the cheap
    prober (here: recognises regime 1 only) sends the probes that fall inside to the sampler, the window is
    bracketed on both sides, and every valid value is within its error of the closed form. Probes are not
    samples: only those inside the window are simulated in full."""
    window = (0.4131, 0.4167)                     # 0.0036 wide
    def sampler(x):
        inside = (x > window[0]) & (x < window[1])
        return Samples(np.exp(1j * x) * (1 + np.where(inside, 0.2, 0.0)), np.where(inside, 2, 1),
                       np.ones(x.shape, bool))

    def prober(xp, xa, xb):
        assert np.all((xa < xp) & (xp < xb))
        s = sampler(xp)
        return s.regime == 1, s

    st = TableSettings(tol=1e-3, base_dx=0.1, block_dx=1.0, probe_dx=0.05, window_dx=0.002)
    blind = Table1D.build(sampler, 0.0, 1.0, st)
    assert not np.any(blind.regime == 2)          # probe_dx alone misses it
    t = Table1D.build(sampler, 0.0, 1.0, st, prober=prober)
    assert t.n_probed >= 1.0 / 0.002 - t.x.size
    q = np.concatenate([np.linspace(*window, 40), np.random.default_rng(2).uniform(0.0, 1.0, 400)])
    tv = t.evaluate(q)
    assert np.all(np.abs(tv.value - sampler(q).value)[tv.valid] <= tv.error[tv.valid])
    for edge in window:
        i = np.searchsorted(t.x, edge) - 1
        assert t.jumps()[i] and t.x[i + 1] - t.x[i] <= st.edge_dx
    new = np.setdiff1d(t.x, blind.x)              # probes outside the window were not sampled: every new
    assert np.all(np.abs(new - 0.415) < 0.1)      # sample brackets the window or rechecks its neighbours


def test_branch_continuation_flags_the_whole_coexistence_region_and_no_more():
    """Closed form: a second branch coexists for x in [0.30, 0.62]; the sampler's own search finds it only at
    samples with x in [0.45, 0.5]. Continued from there, every sample inside the region gets the spread
    (not valid) and none outside (valid, within its error of the closed form)."""
    region, seen = (0.30, 0.62), (0.45, 0.5)

    def sampler(x):
        s = smooth_sampler(x)
        found = (x >= seen[0]) & (x <= seen[1])
        return Samples(s.value, s.regime, s.regular, {}, np.where(found, 0.5, 0.0))

    calls = []

    def follow(x_from, x_to, value_to):
        calls.append(x_to.size)
        assert np.all(np.abs(x_to - x_from) > 0)
        return np.where((x_to >= region[0]) & (x_to <= region[1]), 0.5, 0.0)

    t = Table1D.build(sampler, 0.0, 1.0, TableSettings(tol=1e-5, block_dx=1.0), follow=follow)
    inside = (t.x >= region[0]) & (t.x <= region[1])
    assert np.all(t.spread[inside] == 0.5) and np.all(t.spread[~inside] == 0.0)
    q = np.random.default_rng(4).uniform(0.0, 1.0, 500)
    tv = t.evaluate(q)
    assert not np.any(tv.valid[(q > region[0]) & (q < region[1])])
    assert np.all(np.abs(tv.value - smooth_sampler(q).value)[tv.valid] <= tv.error[tv.valid])
    out = (q < region[0] - 0.05) | (q > region[1] + 0.05)
    assert np.all(tv.valid[out])
    assert sum(calls) <= np.count_nonzero(inside) + 2      # each sample continued to once, ends included


def smooth_sampler(x):
    return Samples(np.exp(1j * x) * (1 + 0.3 * np.sin(3 * x)), np.ones(x.shape, int), np.ones(x.shape, bool),
                   {"x": x.copy()})


def test_extending_in_any_order_gives_identical_content():
    s = TableSettings(tol=1e-6, base_dx=0.1, block_dx=0.5, origin=0.0)
    direct = Table1D.build(smooth_sampler, -1.0, 3.0, s)
    pieces = Table1D.build(smooth_sampler, 2.2, 2.4, s)
    pieces.extend(smooth_sampler, 0.1, 0.3)
    pieces.extend(smooth_sampler, -1.0, 3.0)
    for name in ("x", "value", "regime", "err", "block"):
        np.testing.assert_array_equal(getattr(pieces, name), getattr(direct, name))
    q = np.random.default_rng(3).uniform(-1.0, 3.0, 2000)
    a, b = direct.evaluate(q), pieces.evaluate(q)
    np.testing.assert_array_equal(a.value, b.value)
    np.testing.assert_array_equal(a.error, b.error)
    assert np.all(np.abs(a.value - smooth_sampler(q).value)[a.valid] <= a.error[a.valid])


def test_spread_and_uncertainty_enter_the_error_and_spread_invalidates():
    def sampler(x):
        s = smooth_sampler(x)
        return Samples(s.value, s.regime, s.regular, {}, np.where(x > 1.0, 0.05, 0.0), np.full(x.shape, 1e-3))

    t = Table1D.build(sampler, 0.0, 2.0, TableSettings(tol=1e-5, block_dx=1.0))
    tv = t.evaluate(np.array([0.5, 1.5]))
    assert tv.valid.tolist() == [True, False]
    assert tv.error[0] >= 1e-3 and tv.error[1] >= 0.05 + 1e-3


def test_query_in_a_block_never_built_is_refused():
    t = Table1D.build(smooth_sampler, 0.1, 0.2, TableSettings(block_dx=0.5))
    t.extend(smooth_sampler, 2.1, 2.2)
    with pytest.raises(ValueError, match="extend the table"):
        t.evaluate(1.2)


# ---------------------------------------------------------------------------------------- the impact model
@pytest.fixture(scope="module")
def eps08():
    """eps = 0.8 near the no-impact limit: period-3/5 windows and coexisting motions (default settings)."""
    return DynamicBacklash(M1, M2, H, 0.8, cache=False, progress=False)


def direct(eps, w, force=F, **kw):
    """1000 transient periods, then 36: enough to detect every period up to MAX_DETECTED_PERIOD = 12."""
    return impact_describing_function(M1, M2, H, eps, force, w, transient_periods=1000, periods=36, **kw)


@pytest.fixture(scope="module")
def default_tables():
    """Default tables (no per-case settings), one per eps, built once for the module."""
    return {eps: DynamicBacklash(M1, M2, H, eps, cache=False, progress=False) for eps in (0.5, 0.7, 0.9)}


def _check_against_long_runs(db, eps, F_, w):
    n, err, ok = db(F_, w), db.error_estimate(F_, w), db.validity(F_, w)
    for fi, wi, ni, ei, vi in zip(np.broadcast_to(F_, w.shape), w, n, err, ok):
        if vi:
            ref = direct(eps, wi, force=fi)
            assert ref.regular and abs(ni - ref.N) <= ei, (eps, fi, wi, ni, ref.N, ei)
    return int(np.count_nonzero(ok))


def test_valid_values_within_their_error_of_a_long_direct_simulation_in_narrow_windows(eps08, default_tables):
    """Default tables, dense random w inside and around the narrow regime windows between period-1 samples
    (eps = 0.7: period 5 for w = 33.78-33.85 rad/s, only 0.0045 wide in ln beta, narrower than probe_dx;
    eps = 0.8: period-3/5 windows near 35.3 rad/s and at 43.7-44.4 rad/s): no valid value is farther from
    a 1000-period simulation than its error estimate, and the eps = 0.7 window itself is not valid-and-wrong."""
    rng = np.random.default_rng(11)
    n_valid = 0
    inside = np.linspace(33.78, 33.84, 4)                       # the period-5 window, from rest
    n_valid += _check_against_long_runs(default_tables[0.7], 0.7, F, np.r_[rng.uniform(33.3, 34.3, 12), inside])
    for lo, hi in ((35.0, 35.6), (43.7, 44.4)):
        n_valid += _check_against_long_runs(eps08, 0.8, F, rng.uniform(lo, hi, 10))
    assert n_valid >= 8            # the check is not vacuous


def test_valid_values_within_their_error_on_a_dense_random_sample_of_F_w_eps(eps08, default_tables):
    """Dense random (F, w, eps) over the paper's band (F 10..50 N, w 8..60 rad/s) at four restitutions."""
    rng = np.random.default_rng(2026)
    n_valid = 0
    for eps in (0.5, 0.7, 0.8, 0.9):
        db = eps08 if eps == 0.8 else default_tables[eps]
        F_ = rng.uniform(10.0, 50.0, 12)
        w = np.exp(rng.uniform(math.log(8.0), math.log(60.0), 12))
        for fi, wi in zip(F_, w):
            n_valid += _check_against_long_runs(db, eps, fi, np.array([wi]))
    assert n_valid >= 20


def test_same_N_from_an_empty_cache_and_from_a_cache_filled_in_another_order(tmp_path, monkeypatch):
    w = np.random.default_rng(5).uniform(30.0, 40.0, 25)
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "a"))
    fresh = DynamicBacklash(M1, M2, H, 0.5, starts=0, **FAST)
    n_fresh = fresh(F, w)
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "b"))
    DynamicBacklash(M1, M2, H, 0.5, starts=0, **FAST)(F, 39.0)          # first a narrow window ...
    DynamicBacklash(M1, M2, H, 0.5, starts=0, **FAST)(F, 35.0)          # ... then a wider one
    history = DynamicBacklash(M1, M2, H, 0.5, starts=0, **FAST)
    np.testing.assert_array_equal(history(F, w), n_fresh)
    np.testing.assert_array_equal(history.error_estimate(F, w), fresh.error_estimate(F, w))


def test_interrupted_build_resumes_from_the_saved_blocks(monkeypatch):
    w = np.array([30.0, 34.0, 38.0, 42.0])
    full = DynamicBacklash(M1, M2, H, 0.5, starts=0, cache=False, **FAST)
    n_full = full(F, w)
    calls = {"n": 0}
    original = ImpactSampler.extract

    def flaky(self, force, omega, initial=None, attractor=None):
        calls["n"] += 1
        if calls["n"] > 25:
            raise KeyboardInterrupt
        return original(self, force, omega, initial, attractor)

    monkeypatch.setattr(ImpactSampler, "extract", flaky)
    with pytest.raises(KeyboardInterrupt):
        DynamicBacklash(M1, M2, H, 0.5, starts=0, **FAST)(F, w)
    monkeypatch.setattr(ImpactSampler, "extract", original)
    resumed = DynamicBacklash(M1, M2, H, 0.5, starts=0, **FAST)
    assert resumed.cache_path.exists()
    np.testing.assert_array_equal(resumed(F, w), n_full)
    assert 0 < resumed.n_simulations < full.n_simulations        # only the unfinished blocks were sampled


def test_event_limit_sample_is_recorded_invalid_and_the_build_goes_on():
    """With a tiny event bound the chattering samples (large beta) fail; exactly those whose direct run
    raises EventLimitError are failed in the table, flagged not valid with an infinite error estimate."""
    db = DynamicBacklash(M1, M2, H, 0.5, starts=0, cache=False, max_events=400, transient_periods=5, periods=6,
                         base_dx=0.1)
    table = db.similarity_table(20.0)
    failed = table.regime == FAILED
    assert 0 < np.count_nonzero(failed) < failed.size
    for u, f in zip(table.x[::7], failed[::7]):
        beta = math.exp(u)
        try:
            impact_describing_function(M1 / M2, 1.0, 1.0, 0.5, beta, 1.0, transient_periods=5, periods=6,
                                       max_events=400)
            raised = False
        except EventLimitError:
            raised = True
        assert raised == f
    w = np.sqrt(F / (M2 * H * np.exp(table.x[failed][:3])))
    assert not np.any(db.validity(F, w)) and np.all(np.isinf(db.error_estimate(F, w)))


def test_coexisting_branches_are_kept_and_make_N_not_unique(eps08):
    """Where a probed start settles on another periodic motion than rest does, the value from rest stays, the
    other branch is stored, validity is False and the error estimate reaches the other branch. Independent
    check: 1000-period simulations from rest and from that start settle on two different motions with the
    stored values."""
    from dfloop.impact.sampling import STARTS

    db = eps08
    t = db.similarity_table(0.27)
    alts = np.array([t.extra[f"start{k}.re"] + 1j * t.extra[f"start{k}.im"] for k in range(db.starts)])
    found = np.any(np.abs(alts - t.value) > 1e-4 * np.abs(t.value), axis=0)   # by one of the starts
    multi = np.flatnonzero(found & t.regular)                         # rest periodic, another start too
    assert multi.size > 0
    for i in multi[:: max(1, multi.size // 3)]:
        force = math.exp(t.x[i]) * M2 * H                   # the table's similarity runs: w = 1 rad/s, D = N
        alts = [complex(t.extra[f"start{k}.re"][i], t.extra[f"start{k}.im"][i]) for k in range(db.starts)]
        k = int(np.argmax([abs(a - t.value[i]) for a in alts]))
        assert abs(alts[k] - t.value[i]) == pytest.approx(t.spread[i], rel=1e-12)
        gap, u_rel = STARTS[k]
        long = dict(transient_periods=1000, periods=36)     # periods up to 12 detectable
        rest = impact_describing_function(M1, M2, H, 0.8, force, 1.0, **long)
        other = impact_describing_function(M1, M2, H, 0.8, force, 1.0, initial=(0.0, 0.0, gap * H, u_rel * force / M2),
                                           **long)
        assert rest.regular and other.regular
        assert abs(rest.N - t.value[i]) <= 1e-5 * abs(rest.N)
        assert abs(other.N - alts[k]) <= 1e-5 * abs(other.N)
        assert abs(other.N - rest.N) > 1e-3 * abs(rest.N)      # two attractors indeed
        w = math.sqrt(F / (M2 * H * math.exp(t.x[i])))
        assert not db.validity(F, w) and db.error_estimate(F, w) * M2 * w ** 2 >= t.spread[i]


def test_adjacent_blocks_join_without_a_gap_for_any_origin_and_width():
    """Block edges are computed once per edge, so adjacent blocks share their edge exactly and every
    point between them is served (regression: rounding of a + block_dx once left a 1-ulp 'gap')."""
    for origin, dx in ((math.log(0.25) + 1e-9, 0.8), (0.1, 0.3), (-0.7, 0.7)):
        t = Table1D.build(smooth_sampler, origin, origin + 12 * dx, TableSettings(block_dx=dx, base_dx=dx / 4,
                                                                                   origin=origin))
        seam = np.flatnonzero(t.seams())
        assert seam.size == 11 and np.all(t.x[seam] == t.x[seam + 1])
        q = np.linspace(origin, origin + 12 * dx, 5001)
        tv = t.evaluate(q)
        assert np.all(np.abs(tv.value - smooth_sampler(q).value)[tv.valid] <= tv.error[tv.valid])
