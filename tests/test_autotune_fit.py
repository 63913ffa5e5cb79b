"""Estimation from recorded relay experiments: the CSV format, the model-free reading, and the exact-orbit fit with
its confidence intervals (exact on noise-free records; coverage over noise seeds on noisy ones)."""
import math

import numpy as np
import pytest

from dfloop.autotune import ProcessModel
from dfloop.autotune.fit import fit_relay_record
from dfloop.autotune.record import RelayRecord, load_relay_record, write_relay_record
from dfloop.autotune.synthetic import synthetic_record

FOPDT = ProcessModel(2.0, (3.0,), 1.0)
SOPDT = ProcessModel(2.0, (4.0, 1.0), 1.0)


def test_csv_round_trip_and_malformed_files(tmp_path):
    rec = synthetic_record(FOPDT, high=1.2, low=-0.8, hysteresis=0.05, cycles=4, noise=0.01, meta={"site": "test"})
    path = write_relay_record(tmp_path / "r.csv", rec, digits=17)
    back = load_relay_record(path)
    assert np.array_equal(back.t, rec.t) and np.array_equal(back.u, rec.u) and np.array_equal(back.y, rec.y)
    assert (back.high, back.low, back.hysteresis) == (1.2, -0.8, 0.05) and back.meta["site"] == "test"
    bad = tmp_path / "bad.csv"
    bad.write_text("t,u,y\n0,1,0\n1,1,x\n")
    with pytest.raises(ValueError, match=r"bad.csv:3: a row must be three numbers"):
        load_relay_record(bad)
    bad.write_text("time,u,y\n0,1,0\n")
    with pytest.raises(ValueError, match="header must be 't,u,y'"):
        load_relay_record(bad)
    with pytest.raises(ValueError, match="u must take only the relay levels"):
        RelayRecord(rec.t, np.where(rec.u > 0, 1.0, 0.3), rec.y, 1.0, -0.8, 0.05)
    with pytest.raises(ValueError, match="t must be strictly increasing"):
        RelayRecord(rec.t[::-1], rec.u, rec.y, 1.2, -0.8, 0.05)


def test_record_features_of_a_noise_free_record_are_the_orbits():
    """Period and time high from the switching instants (quantised to dt), amplitude, static gain and a zero noise
    estimate, against the orbit itself."""
    from dfloop.autotune import relay_cycle

    cyc = relay_cycle(SOPDT, 1.2, -0.8, 0.05)
    dt = cyc.period / 397.3                  # not commensurate with the period: the switching phase moves
    rec = synthetic_record(SOPDT, high=1.2, low=-0.8, hysteresis=0.05, cycles=10, dt=dt)
    f = rec.features()
    assert abs(f.period - cyc.period) < 4 * f.period_se < dt / 5      # the +-dt/2 quantisation, averaged
    assert abs(f.high_time - cyc.h1) < 4 * f.high_time_se < dt
    assert f.amplitude == pytest.approx(cyc.amplitude, rel=1e-3)
    # small mean u = (high h1 + low h2) / P: its error from the switching times dominates the gain's
    assert abs(f.static_gain - SOPDT.K) < 2 * f.static_gain_se < 0.05 * SOPDT.K
    assert f.noise_sd < 1e-3 * cyc.amplitude
    with pytest.raises(ValueError, match="skip_cycles"):
        rec.features(skip_cycles=20)


@pytest.mark.parametrize("model", [FOPDT, SOPDT])
def test_noise_free_records_are_fitted_exactly(model):
    rec = synthetic_record(model, high=1.2, low=-0.8, hysteresis=0.05, cycles=6)
    fit = fit_relay_record(rec, model.kind)
    assert fit.model.params == pytest.approx(model.params, rel=1e-7)
    assert fit.residual_sd < 1e-9
    Ku, Tu = model.ultimate_point()
    assert (fit.Ku, fit.Tu) == pytest.approx((Ku, Tu), rel=1e-7)
    # the DF reading of the same record is off by percents: the error the fit removes
    assert abs(fit.features.Ku / Ku - 1) > 0.05


def test_fopdt_intervals_cover_the_truth_at_their_rate():
    """12 noisy recordings (noise sd 0.02, about 3 % of the amplitude, 8 cycles) of a FOPDT under a biased relay:
    each 95 % interval (K, T, L and the ultimate point Ku, Tu) holds the true value in at least 10 of 12 (binomial
    probability of fewer at a true 95 % rate: 2 %), and the standardised errors have a spread near 1. (Over 30
    seeds, measured once: 29-30 of 30 per parameter, spreads 0.99-1.11.)"""
    Ku, Tu = FOPDT.ultimate_point()
    truth = dict(zip(("K", "T", "L", "Ku", "Tu"), FOPDT.params + (Ku, Tu)))
    hits = dict.fromkeys(truth, 0)
    z = {k: [] for k in truth}
    for seed in range(12):
        rec = synthetic_record(FOPDT, high=1.2, low=-0.8, hysteresis=0.05, cycles=8, noise=0.02, seed=seed)
        fit = fit_relay_record(rec)
        est = dict(zip(fit.names, fit.model.params), Ku=fit.Ku, Tu=fit.Tu)
        for k, v in truth.items():
            lo, hi = fit.intervals[k]
            hits[k] += lo <= v <= hi
            z[k].append(math.log(v / est[k]) / (fit.stderr[k] / est[k]))
    assert all(h >= 10 for h in hits.values()), hits
    assert all(0.6 < np.std(v) < 1.5 for v in z.values()), {k: np.std(v) for k, v in z.items()}


def test_sopdt_fit_of_the_shipped_recording():
    """The shipped synthetic recording (examples/data/relay_sopdt.csv, true SOPDT 2 e^{-s}/((4s + 1)(s + 1))): the
    SOPDT fit's intervals hold every true parameter, its residual matches the record's noise, and the FOPDT fit's
    residual is larger (the structure misses the waveform)."""
    from pathlib import Path

    rec = load_relay_record(Path(__file__).resolve().parent.parent / "examples" / "data" / "relay_sopdt.csv")
    fit = fit_relay_record(rec, "SOPDT")
    for k, v in zip(fit.names, SOPDT.params):
        assert fit.intervals[k][0] <= v <= fit.intervals[k][1], (k, v, fit.intervals[k])
    assert fit.residual_sd == pytest.approx(0.02, rel=0.1)
    assert fit.to_dict()["model"]["kind"] == "SOPDT" and "Ku" in repr(fit)
    with pytest.raises(ValueError, match="model must be 'FOPDT' or 'SOPDT'"):
        fit_relay_record(rec, "third order")
