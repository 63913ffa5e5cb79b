"""One vocabulary for results: what a repr prints is an attribute; every result has to_dict() and to_csv().

Independent truths: the relay loop 1/(s(s+1)(s+2)) has the closed-form DF cycle A = 4/(6 pi), w = sqrt(2)
(G(j sqrt 2) = -1/6); the exact orbit's CSV samples give back its fundamental by a DFT computed here; CSV files
read back bit for bit.
"""
from __future__ import annotations

import math
import re

import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.solve.confidence import Confidence
from dfloop.export import read_csv
from dfloop.exact import ExactCycle
from dfloop.verify import Verification, verify_cycle

G_RELAY = ct.tf([1.0], [1.0, 3.0, 2.0, 0.0])


@pytest.fixture(scope="module")
def relay_cycles():
    return df.predict_limit_cycles(G_RELAY, df.Relay(M=1.0), exact=True)


def _names(text: str) -> set[str]:
    """Every ``name=`` a printout shows (the names a user will try as attributes)."""
    return set(re.findall(r"\b([A-Za-z_]\w*)=", text))


def test_printed_names_are_attributes(relay_cycles):
    c = relay_cycles[0]
    v = verify_cycle(G_RELAY, df.Relay(M=1.0), c, periods=30)
    for obj in (c, c.exact, v):
        shown = _names(str(obj)) | _names(repr(obj))
        assert shown, obj
        for name in shown:
            assert hasattr(obj, name), f"{type(obj).__name__} prints {name}= but has no attribute {name!r}"
    assert c.amplitude == pytest.approx(4 / (6 * math.pi), rel=1e-9)
    assert c.frequency == pytest.approx(math.sqrt(2), rel=1e-9)


def test_verification_says_each_outcome_once(relay_cycles):
    v = verify_cycle(G_RELAY, df.Relay(M=1.0), relay_cycles[0], periods=30)
    text = repr(v)
    assert text.count("from inside") == 1 and text.count("from outside") == 1
    assert "<=" not in text


def test_backlash_servo_rest_is_reported_where_it_is():
    """Backlash h = 1 around 5/(s(s+1)): from inside the unstable inner cycle the loop stops; the message says
    where x rests (checked against the run's own final sample), not a bound |x| <= ...."""
    from dfloop.verify import simulate_loop

    G, N = ct.tf([5.0], [1.0, 1.0, 0.0]), df.Backlash(h=1.0)
    inner = df.predict_limit_cycles(G, N)[0]
    v = verify_cycle(G, N, inner, periods=40)
    run = simulate_loop(G, N, inner.amplitude * (1 - v.perturbation), inner.frequency, periods=40)
    assert not v.inside.oscillating
    assert f"came to rest at x = {run.x[-1]:.4g}" in v.message
    assert "|x|" not in v.message


def test_limit_cycles_round_trip(relay_cycles, tmp_path):
    d = relay_cycles.to_dict()
    (row,) = d["cycles"]
    assert row["amplitude"] == pytest.approx(4 / (6 * math.pi), rel=1e-9)
    assert row["G_real"] == pytest.approx(-1 / 6, rel=1e-9) and abs(row["G_imag"]) < 1e-12
    assert row["exact_success"] is True and row["exact_amplitude"] == relay_cycles[0].exact.amplitude
    assert d["omega_window"] == list(relay_cycles.omega_window)
    path = tmp_path / "cycles.csv"
    relay_cycles.to_csv(path)
    assert read_csv(path) == d["cycles"]          # bit for bit, every column
    relay_cycles[0].to_csv(tmp_path / "one.csv")
    assert read_csv(tmp_path / "one.csv") == [row]


def test_exact_cycle_round_trip_and_fundamental(relay_cycles, tmp_path):
    ex = relay_cycles[0].exact
    d = ex.to_dict()
    assert d["amplitude"] == ex.amplitude and d["multipliers"] == ex.multipliers.tolist()
    path = tmp_path / "orbit.csv"
    ex.to_csv(path)
    rows = read_csv(path)
    t = np.array([r["t"] for r in rows])
    x = np.array([r["x"] for r in rows])
    assert np.array_equal(t, ex.t) and np.array_equal(x, ex.x)
    # the fundamental of the written samples (a DFT over the uniformly sampled period) is the orbit's amplitude
    assert abs(2 * np.fft.rfft(x)[1] / x.size) == pytest.approx(ex.amplitude, rel=1e-3)
    failed = ExactCycle(False, "no convergence", (1.0, 1.0), "test")
    with pytest.raises(ValueError, match="no orbit"):
        failed.to_csv(tmp_path / "none.csv")


def test_verification_and_confidence_round_trip(relay_cycles, tmp_path):
    v = verify_cycle(G_RELAY, df.Relay(M=1.0), relay_cycles[0], periods=30)
    assert isinstance(v, Verification)
    v.to_csv(tmp_path / "v.csv")
    (row,) = read_csv(tmp_path / "v.csv")
    assert row == v.to_dict()
    assert row["inside_amplitude"] == v.inside.amplitude and row["verdict"] == "stable"
    conf = relay_cycles[0].confidence
    assert isinstance(conf, Confidence)
    conf.to_csv(tmp_path / "c.csv")
    (crow,) = read_csv(tmp_path / "c.csv")
    d = conf.to_dict()
    assert crow == {k: v for k, v in d.items() if k != "harmonics"}
    assert d["harmonics"][0] == pytest.approx(relay_cycles[0].amplitude)


def test_sweep_to_dict_matches_its_csv(tmp_path):
    from dfloop.continuation import sweep

    res = sweep(lambda K: (ct.tf([K], [1.0, 3.0, 2.0, 0.0]), df.Relay(M=1.0)), [1.0, 2.0, 3.0],
                omega=(0.5, 5.0), progress=False, parameter="K")
    for obj in (res, *res.branches, *res.events):   # what the sweep prints is named as its attributes
        for name in _names(str(obj)) - {"p"}:        # p=...: the parameter's value, named by res.parameter
            assert hasattr(obj, name), f"{type(obj).__name__} prints {name}= but has no attribute {name!r}"
    d = res.to_dict()
    res.to_csv(tmp_path / "s.csv")
    rows = read_csv(tmp_path / "s.csv")
    assert len(rows) == sum(len(b["parameter"]) for b in d["branches"])
    first = d["branches"][0]
    column = next(k for k in rows[0] if k.startswith("amplitude"))   # "amplitude A [unit]"
    assert [r[column] for r in rows[:len(first["amplitude"])]] == first["amplitude"]
    # relay closed form along the branch: A = 4 K / (6 pi) at w = sqrt(2) for every K
    for p, a in zip(first["parameter"], first["amplitude"]):
        assert a == pytest.approx(4 * p / (6 * math.pi), rel=1e-7)


def test_exact_outcome_is_said_in_three_words_and_never_claims_more_than_was_shown():
    """Backlash servo: the outer cycle's exact orbit exists (confirmed, with the orbit's numbers); the inner
    cycle has no orbit near it: the table says 'artefact' only with evidence of where the motions went (the
    search's outcome), otherwise 'not checked' with the reason, never a bare 'no orbit'."""
    from dfloop.solve.result import exact_kind, exact_words

    cycles = df.predict_limit_cycles(ct.tf([5.0], [1.0, 1.0, 0.0]), df.Backlash(h=1.0), exact=True)
    table = repr(cycles)
    assert "exact: no orbit" not in table
    inner, outer = cycles
    assert exact_kind(outer)[0] == "confirmed"
    assert f"confirmed: exact amplitude={outer.exact.amplitude:.6g}" in table
    kind = exact_kind(inner)[0]
    assert not inner.exact.success and kind in ("artefact", "not checked")
    if kind == "artefact":
        assert (inner.exact.extra or {}).get("outcome") in ("another cycle", "rest", "divergence", "not periodic",
                                                            "edge rest")
    assert exact_words(inner).startswith(f"{kind} (") and exact_words(inner) in table
    assert cycles.to_dict()["cycles"][0]["exact_verdict"] == kind
