"""DynamicBacklash: table against direct simulation, similarity law, no-impact limit, cache, bad input."""
import math

import numpy as np
import pytest

from dfloop.errors import CacheWarning
from dfloop.tables import cache
from dfloop.impact.dynamic_backlash import DynamicBacklash, prepare_many
from dfloop.impact.sampling import ImpactSampler
from dfloop.impact.extract import impact_describing_function

M1, M2, H, EPS = 1.0, 1.0, 0.1, 0.5
KW = dict(periods=20, starts=0)     # adaptive transient (the default); coexistence probes: tests/test_table_trust.py
REF = dict(transient_periods=600, periods=20)           # direct reference: a long fixed transient


@pytest.fixture(autouse=True)
def tmp_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def direct(F, w, eps=EPS, m1=M1, m2=M2, h=H, **kw):
    return impact_describing_function(m1, m2, h, eps, F, w, **(kw or REF))


def test_table_matches_direct_simulation_off_grid():
    db = DynamicBacklash(M1, M2, H, EPS, **KW)
    F = 50.0
    # beta in (0.27, 0.5): the period-1 regime right below the no-impact limit (w in 31.6 .. 43 rad/s)
    w = np.random.default_rng(4).uniform(math.sqrt(F / (M2 * H * 0.5)), math.sqrt(F / (M2 * H * 0.27)), 12)
    n = db(F, w)
    valid = db.validity(F, w)
    err = db.error_estimate(F, w)
    # invalid points lie only in the narrow brackets (edge_dx in ln beta) around regime changes
    assert np.count_nonzero(valid) >= 9
    u = np.log(F / (M2 * H * w[~valid] ** 2))
    t = db.table
    i = np.searchsorted(t.x, u) - 1
    assert np.all(t.jumps()[i]) and np.all(t.x[i + 1] - t.x[i] <= t.settings.edge_dx)
    for wi, ni, ei in zip(w[valid], n[valid], err[valid]):
        ref = direct(F, wi)
        assert ref.period >= 1
        # -1/N accurate to 1e-4 relative, and the error estimate covers the actual interpolation error
        assert abs(1 / ni - 1 / ref.N) <= 1e-4 * abs(1 / ref.N)
        assert abs(ni - ref.N) <= max(ei, 1e-12 * abs(ref.N))


def test_similarity_law_one_table_serves_every_force():
    db = DynamicBacklash(M1, M2, H, EPS, **KW)
    beta = 0.4
    for F in (10.0, 37.0):
        w = math.sqrt(F / (M2 * H * beta))
        ref = direct(F, w)
        assert abs(db(F, w) - ref.N) <= 1e-4 * abs(ref.N)
    # -1/N is proportional to F at fixed beta (the paper's remark on Fig. 6)
    F1, F2 = 10.0, 40.0
    w1, w2 = math.sqrt(F1 / (M2 * H * beta)), math.sqrt(F2 / (M2 * H * beta))
    r = db.negative_inverse(F2, w2) / db.negative_inverse(F1, w1)
    assert abs(r - 4.0) <= 1e-12 * 4.0


def test_mass_and_clearance_scaling_reuse_the_table():
    a = DynamicBacklash(1.0, 1.0, 0.1, EPS, **KW)
    b = DynamicBacklash(2.0, 2.0, 0.05, EPS, **KW)       # same m1/m2: the cached 1-D table is shared
    F, w = 20.0, 25.0                                     # M2 h = 0.1 in both: the same beta = 0.32
    na = a(F, w)
    nb = b(F, w)
    assert a.n_simulations > 0 and b.n_simulations == 0
    assert nb == pytest.approx(na / 2.0, rel=1e-14)      # N = D(beta) / (M2 w^2)
    ref = direct(F, w, m1=2.0, m2=2.0, h=0.05)
    assert abs(nb - ref.N) <= 1e-4 * abs(ref.N)


def test_zero_exactly_above_no_impact_limit():
    db = DynamicBacklash(M1, M2, H, EPS, **KW)
    F = np.array([10.0, 50.0])
    wL = 2 * np.sqrt(F / (H * M2))
    w = np.concatenate([wL, wL * 1.5, wL * 10])
    FF = np.tile(F, 3)
    assert np.all(db(FF, w) == 0)
    assert np.all(db.validity(FF, w))
    assert np.all(db.error_estimate(FF, w) == 0)
    assert db.n_simulations == 0                  # nothing simulated for w >= w_L
    lo, hi = db.amplitude_domain(np.array([20.0]))
    assert lo[0] == pytest.approx(M2 * H * 400 / 4)
    # just below w_L the masses collide: N != 0, matching the simulation
    w_in = wL[1] * 0.99
    assert abs(db(50.0, w_in) - direct(50.0, w_in).N) <= 1e-4 * abs(direct(50.0, w_in).N)


def test_irregular_region_flagged():
    db = DynamicBacklash(M1, M2, H, EPS, **KW)
    F, w = 50.0, 25.0          # paper Fig. 12: eps = 0.5 at 25 rad/s (beta = 0.8) is irregular
    assert direct(F, w).period == 0
    assert not db.validity(F, w)


def test_second_build_is_served_from_cache(tmp_cache):
    F, w = [10.0, 50.0], [20.0, 100.0]
    a = DynamicBacklash(M1, M2, H, EPS, **KW).prepare(F, w)
    assert a.n_simulations > 0
    assert a.cache_path.parent == tmp_cache and a.cache_path.is_file()
    b = DynamicBacklash(M1, M2, H, EPS, **KW).prepare(F, w)
    assert b.n_simulations == 0
    q = np.linspace(20.0, 60.0, 97)
    np.testing.assert_array_equal(a(30.0, q), b(30.0, q))
    np.testing.assert_array_equal(a.error_estimate(30.0, q), b.error_estimate(30.0, q))
    # a different parameter is a different key
    c = DynamicBacklash(M1, M2, H, 0.6, **KW).prepare(30.0, 25.0)
    assert c.n_simulations > 0


def test_corrupted_or_stale_cache_is_rebuilt(tmp_cache, monkeypatch):
    F, w = 50.0, [32.0, 40.0]
    a = DynamicBacklash(M1, M2, H, EPS, **KW).prepare(F, w)
    path = a.cache_path
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.warns(CacheWarning, match="corrupted file"):
        b = DynamicBacklash(M1, M2, H, EPS, **KW).prepare(F, w)
    assert b.n_simulations > 0                          # corrupted: rebuilt, not trusted
    np.testing.assert_allclose(b(F, w), a(F, w), rtol=1e-12)
    monkeypatch.setattr(cache, "code_version", lambda: "other-code")
    c = DynamicBacklash(M1, M2, H, EPS, **KW).prepare(F, w)
    assert c.n_simulations > 0                          # stale (other code version): rebuilt


def test_save_and_load_with_provenance(tmp_path):
    a = DynamicBacklash(M1, M2, H, EPS, cache=False, **KW).prepare(50.0, [33.0, 40.0])
    path = a.save(tmp_path / "t.npz")
    f = cache.load_table(path)
    assert f.meta["params"]["m1"] == M1 and f.meta["params"]["restitution"] == EPS
    assert f.meta["code_version"] == cache.code_version() and "date" in f.meta
    assert f.meta["settings"]["settings"]["tol"] == 1e-5
    b = DynamicBacklash(M1, M2, H, EPS, cache=False, **KW)
    assert b.load(path)
    assert b.n_simulations == 0
    np.testing.assert_array_equal(a(50.0, 35.0), b(50.0, 35.0))
    other = DynamicBacklash(M1, M2, H, 0.7, cache=False, **KW)
    with pytest.warns(CacheWarning, match="built for another key"):
        assert not other.load(path)                     # built for other parameters: refused


def test_prepare_many_uses_threads_and_matches_single():
    els = prepare_many([DynamicBacklash(M1, M2, H, e, **KW) for e in (0.3, 0.7)], 50.0, [33.0, 40.0])
    for e, el in zip((0.3, 0.7), els):
        for w in (34.0, 36.0):
            ref = direct(50.0, w, eps=e).N
            assert abs(el(50.0, w) - ref) <= 1e-4 * abs(ref)


@pytest.mark.parametrize("kw, name", [(dict(m1=0.0), "m1"), (dict(m2=-1.0), "m2"), (dict(h=0.0), "h"),
                                      (dict(restitution=1.5), "restitution"), (dict(m1=float("nan")), "m1"),
                                      (dict(restitution=float("nan")), "restitution"), (dict(tol=0.0), "tol")])
def test_bad_parameters(kw, name):
    args = dict(m1=M1, m2=M2, h=H, restitution=EPS)
    args.update(kw)
    with pytest.raises(ValueError, match=name):
        DynamicBacklash(**args)


def test_bad_inputs_and_window():
    db = DynamicBacklash(M1, M2, H, EPS, beta_max=2.0, **KW)
    with pytest.raises(ValueError, match="F"):
        db(-1.0, 10.0)
    with pytest.raises(ValueError, match="omega"):
        db(10.0, 0.0)
    with pytest.raises(ValueError, match="omega"):
        db(10.0)
    assert np.isnan(db(np.nan, 30.0))


def test_beyond_beta_max_rigid_body_value_within_its_exact_bound():
    """beta = 500 > beta_max = 2: no table there; the value is the rigid-body one, flagged, and the
    reported error bound holds against a direct simulation."""
    db = DynamicBacklash(M1, M2, H, EPS, beta_max=2.0, **KW)
    F, w = 50.0, 1.0
    n, err, ok = db(F, w), db.error_estimate(F, w), db.validity(F, w)
    assert n == pytest.approx(-1.0 / ((M1 + M2) * w**2), rel=1e-15)
    assert not ok
    assert err == pytest.approx((M2 / (M1 + M2)) * (2 * H / np.pi) / F, rel=1e-15)
    direct = impact_describing_function(M1, M2, H, EPS, F, w, transient_periods=20, periods=10).N
    assert abs(direct - n) <= err
    assert abs(direct - n) > 1e-3 * err     # the bound is not vacuous: the true value does differ
    assert db.amplitude_domain(w)[1] == np.inf


def test_effects_keep_the_hard_window_limit():
    db = DynamicBacklash(M1, M2, H, EPS, effects=(_Marker(),), beta_max=2.0, **KW)
    assert db.amplitude_domain(1.0)[1] == pytest.approx(2.0 * M2 * H)
    with pytest.raises(ValueError, match="beta_max"):
        db(50.0, 1.0)                                   # with effects: raises, no extrapolation


class _Marker:
    """Stands for an effect that breaks the similarity law while the physics stays the paper's (test only)."""

    keeps_similarity = False

    def __repr__(self):
        return "_Marker()"


def test_two_dimensional_table_matches_direct_simulation(monkeypatch):
    # The effects engine is slow; the 2-D machinery (coordinates, scaling, refinement in w) is checked
    # on the paper's physics routed through the 2-D path, against direct simulation at off-grid points.
    from dfloop.impact import extract

    def paper_physics(self, force, omega):
        return extract.impact_describing_function_batch(self.m1, self.m2, self.h, self.restitution, force, omega,
                                                        transient_periods=self.transient_periods,
                                                        periods=self.periods)

    monkeypatch.setattr(ImpactSampler, "extract", paper_physics)
    db = DynamicBacklash(M1, M2, H, EPS, effects=(_Marker(),), **KW)
    assert not db.similarity
    F = np.array([40.0, 50.0, 44.0, 47.0])
    w = np.array([34.0, 38.0, 36.5, 35.2])
    db.prepare(F, w)
    assert type(db.table).__name__ == "Table2D"
    n, valid, err = db(F, w), db.validity(F, w), db.error_estimate(F, w)
    for Fi, wi, ni, vi, ei in zip(F, w, n, valid, err):
        ref = direct(Fi, wi).N
        if vi:
            assert abs(ni - ref) <= max(1e-4 * abs(ref), ei)
    assert np.count_nonzero(valid) >= 3
    # the 2-D table is cached under its own key, with masses and clearance in it
    again = DynamicBacklash(M1, M2, H, EPS, effects=(_Marker(),), **KW).prepare(F, w)
    assert again.n_simulations == 0
    assert DynamicBacklash(M1, M2, 2 * H, EPS, effects=(_Marker(),), **KW).cache_path != db.cache_path


def test_effects_make_the_table_two_dimensional_and_enter_the_key():
    from dfloop.impact.effects import LoadSpring, ViscousDamping

    plain = DynamicBacklash(M1, M2, H, EPS)
    a = DynamicBacklash(M1, M2, H, EPS, effects=(ViscousDamping(0.5),))
    b = DynamicBacklash(M1, M2, H, EPS, effects=(ViscousDamping(0.6),))
    c = DynamicBacklash(M1, M2, H, EPS, effects=(LoadSpring(10.0),))
    assert plain.similarity and not a.similarity
    assert len({plain.cache_path, a.cache_path, b.cache_path, c.cache_path}) == 4
    assert a.parameters()["h"] == H and "mass_ratio" not in a.parameters()
    with pytest.raises(ValueError, match="2-D"):
        a.similarity_table(1.0)


@pytest.mark.parametrize("effects", [("damping",), "damping", [3.0], 5])
def test_effects_that_are_not_effect_objects_are_rejected_at_construction(effects):
    with pytest.raises(ValueError, match="effects"):
        DynamicBacklash(M1, M2, H, EPS, effects=effects)


def test_eps_is_an_alias_of_restitution_and_the_label_uses_restitution(monkeypatch):
    a = DynamicBacklash(M1, M2, H, eps=0.5, cache=False)
    assert a.restitution == 0.5 and a.parameters() == DynamicBacklash(M1, M2, H, 0.5, cache=False).parameters()
    with pytest.raises(ValueError, match="restitution"):
        DynamicBacklash(M1, M2, H, 0.5, eps=0.5)
    with pytest.raises(ValueError, match="restitution"):
        DynamicBacklash(M1, M2, H)
    labels = []
    from dfloop.tables import store as mod

    real = mod.progress_bar

    def spy(label, total=None, **kw):
        labels.append(label)
        return real(label, total, **kw)

    monkeypatch.setattr(mod, "progress_bar", spy)
    DynamicBacklash(M1, M2, H, eps=0.5, cache=False, starts=0, base_dx=0.025)(50.0, 40.0)
    assert labels == ["DynamicBacklash(restitution=0.5) table"]


def test_damped_two_dimensional_table_matches_direct_simulation_within_its_error_estimate():
    # the effects engine end to end (issue 9): ViscousDamping breaks the similarity law, the table is 2-D and
    # each line spans only the ln beta range of its own frequencies; valid values within their estimate
    from dfloop.impact.effects import ViscousDamping

    damping = (ViscousDamping(5.0),)
    db = DynamicBacklash(M1, M2, H, EPS, effects=damping, **KW)
    db.prepare([30.0, 40.0], [28.0, 32.0])
    assert type(db.table).__name__ == "Table2D"
    rng = np.random.default_rng(11)
    F, w = rng.uniform(30.0, 40.0, 5), rng.uniform(28.0, 32.0, 5)
    n, valid, err = db(F, w), db.validity(F, w), db.error_estimate(F, w)
    assert np.count_nonzero(valid) >= 3
    assert np.all(np.isfinite(err))
    for Fi, wi, ni, ei in zip(F[valid], w[valid], n[valid], err[valid]):
        ref = direct(Fi, wi, effects=damping, **REF)
        assert ref.period >= 1
        assert abs(ni - ref.N) <= max(ei, 1e-12 * abs(ref.N))
        assert abs(1 / ni - 1 / ref.N) <= 1e-4 * abs(1 / ref.N)


def test_damped_table_across_kinks_and_refinement_in_w_valid_values_within_their_estimate():
    # w 6.5-9 rad/s, F 7-12 N: bifurcations of the period-1 motion (kinks of N at one regime label) cross
    # the lines; checks in w accept them as isolated failures, with the error measured there: every valid
    # value is within its error_estimate of a 600-period direct simulation (random sample)
    from dfloop.impact.effects import ViscousDamping

    damping = (ViscousDamping(5.0),)
    db = DynamicBacklash(M1, M2, H, EPS, effects=damping, **KW)
    rng = np.random.default_rng(4)
    F, w = rng.uniform(7.0, 12.0, 12), rng.uniform(6.5, 9.0, 12)
    n, valid, err = db(F, w), db.validity(F, w), db.error_estimate(F, w)
    tol = db.table.y_settings.tol
    assert any(np.any(rel > tol) for _, rel in db.table.yprof)     # the case is exercised
    assert np.count_nonzero(valid) >= 4
    for Fi, wi, ni, ei in zip(F[valid], w[valid], n[valid], err[valid]):
        ref = direct(Fi, wi, effects=damping, **REF)
        assert ref.period >= 1
        assert abs(ni - ref.N) <= ei


def test_interrupted_two_dimensional_build_resumes_from_the_lines_saved(monkeypatch):
    # the 2-D path (paper physics routed through it, fast) is saved after every line: an interrupted build
    # leaves a cache file, and the next build samples only what is missing and gives the same N within its
    # error estimate
    from dfloop.impact import extract

    def paper_physics(self, force, omega, initial=None):
        return extract.impact_describing_function_batch(self.m1, self.m2, self.h, self.restitution, force, omega,
                                                        transient_periods=self.transient_periods,
                                                        periods=self.periods)

    monkeypatch.setattr(ImpactSampler, "extract", paper_physics)
    F, w = np.array([38.0, 46.0, 42.0]), np.array([12.0, 45.0, 36.0])     # three lines, two at a time
    full = DynamicBacklash(M1, M2, H, EPS, effects=(_Marker(),), cache=False, **KW)
    n_full, err_full = full(F, w), full.error_estimate(F, w)
    calls = {"n": 0}

    def flaky(self, force, omega, initial=None):
        calls["n"] += 1
        if calls["n"] > 44:          # after the first line was saved (35-37 calls), before the next (51-54)
            raise KeyboardInterrupt
        return paper_physics(self, force, omega, initial)

    monkeypatch.setattr(ImpactSampler, "extract", flaky)
    with pytest.raises(KeyboardInterrupt):
        DynamicBacklash(M1, M2, H, EPS, effects=(_Marker(),), **KW)(F, w)
    monkeypatch.setattr(ImpactSampler, "extract", paper_physics)
    resumed = DynamicBacklash(M1, M2, H, EPS, effects=(_Marker(),), **KW)
    assert resumed.cache_path.exists()
    n = resumed(F, w)
    assert 0 < resumed.n_simulations < full.n_simulations
    assert np.all(np.abs(n - n_full) <= err_full + resumed.error_estimate(F, w))
