"""A tabulated N certified at the point of use (issue 16): exact_cycle states the table's error at the cycle and
re-simulates N there; a value the re-simulation replaces gets its root refined with direct values, and the verdict
never calls a prediction an artefact on a table value that is not certain. Truths: impact_describing_function
called here on its own (the direct simulation), 1 + G(jw) N(F, w) evaluated here."""
import math

import control as ct
import numpy as np
import pytest

from dfloop.describing.base import DescribingFunction
from dfloop.describing.time_model import Impact
from dfloop.exact import ExactCycle, exact_cycle, table_certificate
from dfloop.impact.extract import impact_describing_function
from dfloop.solve.verdict import classify, exact_kind

PD = ct.tf([33.028, 425.06], [1.11979e-4, 2.11640e-2, 1.0])   # models/dynamic_backlash_pd.toml
F0, W0 = 31.7521, 31.5001                                       # its predicted cycle (the table's root)


class _Table(DescribingFunction):
    """A dynamic-backlash stand-in whose 'table' is the direct value times ``bias`` with an error estimate: no
    table is built; its time model is the impact element's (so its direct value is the true N)."""

    frequency_dependent = True

    def __init__(self, bias=1.0, error=1e-9, valid=True):
        self.bias, self.error, self.ok = bias, error, valid

    def _evaluate(self, A, omega):
        direct = np.vectorize(lambda a, w: impact_describing_function(1.0, 1.0, 0.1, 0.5, a, w).N, otypes=[complex])
        return direct(A, omega) * self.bias

    def error_estimate(self, A, omega=None):
        return np.full(np.broadcast(A, omega).shape, self.error)

    def validity(self, A, omega=None):
        return np.full(np.broadcast(A, omega).shape, self.ok)

    def time_model(self, amplitude):
        return Impact("stand-in", 1.0, 1.0, 0.1, 0.5, (), 1e-9)


def _R(F, w):
    return 1.0 + complex(PD(1j * w)) * impact_describing_function(1.0, 1.0, 0.1, 0.5, F, w).N


def test_a_right_table_value_is_confirmed_by_re_simulation():
    cert = table_certificate(PD, _Table(), F0, W0)
    assert cert["status"] == "confirmed" and cert["valid"]
    assert cert["difference"] <= 3 * cert["error"]
    assert cert["direct"] == pytest.approx(impact_describing_function(1.0, 1.0, 0.1, 0.5, F0, W0).N, rel=1e-12)


def test_a_wrong_table_value_is_replaced_and_the_root_refined_with_direct_values():
    cert = table_certificate(PD, _Table(bias=1.05, error=1e-6), F0, W0)
    assert cert["status"] == "replaced" and cert["refined"] is not None, cert
    F, w = cert["refined"]
    assert abs(_R(F, w)) < 1e-8                               # a root of the direct equation
    assert abs(math.log(F / F0)) < 0.2 and abs(math.log(w / W0)) < 0.1    # the cycle, not another root
    assert abs(_R(F0, W0)) < 1e-4                             # the table's root (bias 1) is the same cycle


def _artefact(cert):
    return ExactCycle(False, "no periodic orbit near the prediction: the motions decay to rest", (F0, W0), "impact",
                      extra={"outcome": "rest", "table": cert})


def test_the_verdict_accounts_for_the_table():
    cycle = type("C", (), {"amplitude": F0, "frequency": W0})()
    good = table_certificate(PD, _Table(), F0, W0)
    cycle.exact = _artefact(good)
    v = classify(cycle)
    assert v.kind == "artefact" and "re-simulated at the cycle: confirmed" in v.detail
    for cert in (table_certificate(PD, _Table(bias=1.05, error=1e-6), F0, W0),
                 {**good, "valid": False}):
        cycle.exact = _artefact(cert)
        v = classify(cycle)
        assert v.kind == "not checked" and exact_kind(cycle.exact) == "not checked"
        assert "tabulated N at the prediction is not certain" in v.detail
    cycle.exact = _artefact(table_certificate(PD, _Table(bias=1.05, error=1e-6), F0, W0))
    assert "the root with the direct N: A=" in classify(cycle).detail


def test_exact_cycle_attaches_the_certificate_and_the_verdict_states_it():
    import dfloop as df

    e = df.exact_cycle(PD, _Table(), (F0, W0))
    assert e.success and e.extra["table"]["status"] == "confirmed"
    cycle = type("C", (), {"amplitude": F0, "frequency": W0, "exact": e})()
    v = classify(cycle)
    assert v.kind == "confirmed" and "N from a table: error estimate 1.0e-06 relative" in v.detail
    # a closed-form element carries no certificate
    assert "table" not in df.exact_cycle(ct.tf([5.0], [1.0, 1.0, 0.0]), df.Backlash(h=1.0), (1.5, 1.8)).extra


def test_the_confidence_of_a_tabulated_cycle_carries_the_certificate_and_the_true_distortion():
    """cycle_confidence of a dynamic-backlash cycle: the table certified at the cycle, and the distortion from the
    re-simulated motion's harmonics. Truth: the exact closed-loop orbit (exact_cycle on the impact engine), whose
    input harmonics the one-pass estimate must reproduce (filter hypothesis: same order of harmonics)."""
    from dfloop.solve.confidence import cycle_confidence

    conf = cycle_confidence(PD, _Table(), F0, W0)
    assert conf.available and conf.table["status"] == "confirmed"
    assert abs(conf.amplitude_error) < 1e-6 and abs(conf.frequency_error) < 1e-6   # a right table: no table error
    orbit = exact_cycle(PD, _Table(), (F0, W0))
    assert orbit.success
    X = orbit.harmonics
    true_distortion = np.sqrt(np.sum(np.abs(X[1:]) ** 2)) / abs(X[0])
    assert conf.distortion == pytest.approx(true_distortion, rel=0.05)
    for k in (3, 5):                                        # the odd harmonics that carry the distortion
        assert abs(conf.harmonics[k - 1]) / F0 == pytest.approx(abs(X[k - 1]) / abs(X[0]), rel=0.05)
    assert "confirmed" in repr(conf)


def test_the_confidence_of_a_wrong_table_value_estimates_the_shift_to_the_direct_root():
    """A table 5 % off: at its own root (found here by Newton on 1 + G (1.05 N_direct)) the confidence says
    'replaced', and its estimated errors are the shift to the root of the direct equation, (F0, W0)."""
    from dfloop.solve.confidence import cycle_confidence

    u = np.log([F0, W0])
    for _ in range(8):       # Newton in (ln F, ln w) on the biased equation, forward differences
        r = 1.0 + 1.05 * (_R(*np.exp(u)) - 1.0)            # 1 + G (1.05 N_direct)
        J = np.empty((2, 2))
        for k in range(2):
            e = np.zeros(2)
            e[k] = 1e-6
            rk = 1.0 + 1.05 * (_R(*np.exp(u + e)) - 1.0)
            J[:, k] = [(rk - r).real / 1e-6, (rk - r).imag / 1e-6]
        u = u - np.linalg.solve(J, [r.real, r.imag])
    Fb, wb = np.exp(u)
    assert abs(1.0 + 1.05 * (_R(Fb, wb) - 1.0)) < 1e-8
    conf = cycle_confidence(PD, _Table(bias=1.05, error=1e-6), Fb, wb)
    assert conf.table["status"] == "replaced"
    assert conf.amplitude_error == pytest.approx(Fb / F0 - 1, rel=0.05)     # linearised balance vs the true shift
    assert conf.frequency_error == pytest.approx(wb / W0 - 1, rel=0.05)
