"""The Newton homotopy from the predicted orbit (dfloop.hybrid.shooting.homotopy_orbit): where Newton from the
start stalls it can find the orbit, and every orbit it returns is a true one. Truths: an event-located DOP853
integration of one period from the orbit's start with the element written in the test (tests/loop_reference.py,
rtol 1e-12), and the orbit Newton finds from the DF prediction itself."""
import control as ct
import numpy as np
import pytest

import dfloop as df
from dfloop.hybrid import ShootingError, loop_model
from dfloop.hybrid.shooting import periodic_orbit
from loop_reference import Reference, element_of

# starts far from the prediction (amplitude x 1.6, frequency x 0.6 or x 1.5) where Newton stalls
CASES = {
    "dead zone (unstable cycle), 12/(s+1)^3": (ct.tf([12], [1, 3, 3, 1]), df.DeadZone(0.5), 0, 1.6, 0.6),
    "backlash h=0.2, 1.5/(s(s+1)^2)": (ct.tf([1.5], [1, 2, 1, 0]), df.Backlash(h=0.2), 1, 1.6, 1.5),
}


@pytest.mark.parametrize("name", list(CASES))
def test_homotopy_finds_the_orbit_newton_misses_and_it_is_a_true_orbit(name):
    G, N, pick, fa, fw = CASES[name]
    c = df.predict_limit_cycles(G, N)[pick]
    start = (c.amplitude * fa, c.frequency * fw)
    loop = loop_model(G, N, *start)
    with pytest.raises(ShootingError):        # Newton alone (both node sets) stalls from this start
        periodic_orbit(loop, N, *start, tol=1e-11, max_iterations=40, settle_periods=0.0, nodes=8,
                       max_events=10_000, homotopy=False)
    e = df.exact_cycle(G, N, start, globalise=False, max_deviation=3.0)
    assert e.success and e.extra["path"] == "homotopy", e.message
    # the same orbit Newton finds from the DF prediction itself
    ref_orbit = df.exact_cycle(G, N, c)
    assert ref_orbit.success and ref_orbit.extra["path"] == "newton"
    assert e.frequency == pytest.approx(ref_orbit.frequency, rel=1e-9)
    assert e.amplitude == pytest.approx(ref_orbit.amplitude, rel=1e-9)
    # independent: one period of an event-located integration from the orbit's start returns to it
    loop = loop_model(G, N, e.amplitude, e.frequency)
    A, B = loop.plant
    C = -loop.x_row[:loop.n]
    ref = Reference(A, B, C, element_of(N))
    z0 = e.extra["z0"]
    s0 = z0[:loop.n]
    if ref.kind == "backlash":
        mode, el = {0: 0, 1: 1, 2: -1}[int(e.extra["mode0"])], float(z0[loop.n])
    else:
        mode, el = ref.initial_mode(s0), 0.0
    s1, mode1, _, events, _ = ref.run(s0, mode, e.period, e=el)
    assert np.linalg.norm(s1 - s0) <= 1e-9 * np.linalg.norm(s0)
    assert mode1 == mode and len(events) == e.switching_times.size


def test_homotopy_invents_no_orbit_where_there_is_none():
    """The backlash servo's inner DF cycle has no true orbit (every motion that engages the play grows to the outer
    cycle, tests/test_globalise.py): Newton and then the homotopy from the prediction both fail, and the answer
    says so (no orbit, the homotopy's end in the message)."""
    G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)
    inner, _ = df.predict_limit_cycles(G, N)
    e = df.exact_cycle(G, N, inner, globalise=False)
    assert not e.success and e.amplitude is None
    assert "the homotopy from the predicted orbit" in e.message and "lam" in e.message
