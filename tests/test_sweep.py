"""Parameter sweeps (dfloop.sweep, module dfloop.continuation): branches, folds and window edges against closed
forms and independent
root finding."""
import csv
import math

import control as ct
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

import dfloop
from dfloop.continuation import sweep
from dfloop.solve import graphical_stability

G0 = ct.tf([1], [1, 3, 2, 0])  # 1/(s (s+1)(s+2)): phase crossover sqrt(2) rad/s, |G0| = 1/6 there
W_PC, G_PC = math.sqrt(2.0), 1.0 / 6.0
M, D = 1.0, 0.1  # relay level and dead zone
K_STAR = math.pi * D / (2 * M * G_PC)  # N's maximum 2M/(pi d) equals 1/(K |G0|): the two cycles merge
H = 0.2  # backlash clearance


def relay_loop(K):
    return K * G0, dfloop.Relay(M=M, dead_zone=D)


def backlash_loop(K):
    return K * G0, dfloop.Backlash(H)


def relay_amplitudes(K):
    """Closed-form roots of 4M/(pi A) sqrt(1 - (d/A)^2) = 1/(K |G0|): (unstable small, stable large)."""
    q = (math.pi * D / (4 * M * K * G_PC)) ** 2  # u (1 - u) with u = (d/A)^2
    u = np.array([(1 + math.sqrt(1 - 4 * q)) / 2, (1 - math.sqrt(1 - 4 * q)) / 2])
    return D / np.sqrt(u)


# independent computation for the backlash loop: the DF condition along the Nyquist curve of G0. At each
# w below the phase crossover, arg(-1/N(X)) = arg G0(jw) fixes X (arg(-1/N) is monotone in X), and the gain
# that makes it a cycle is K(w) = 1/(|G0(jw)| |N(X)|). Two cycles exist for K above min K(w); they merge at
# the minimum (the tangency), found here by brentq on dK/dw = 0.
_BL = dfloop.Backlash(H)


def _g0(w):
    return 1.0 / ((1j * w) * (1j * w + 1) * (1j * w + 2))


def _x_of_w(w):
    target = np.angle(_g0(w))
    return brentq(lambda x: float(np.angle(-1.0 / _BL(x))) - target, H / 2 * (1 + 1e-13), 1e9, xtol=1e-15,
                  rtol=1e-15, maxiter=500)


def _k_of_w(w):
    return 1.0 / (abs(_g0(w)) * abs(complex(_BL(_x_of_w(w)))))


def _dk_dw(w, h=1e-5):
    return (_k_of_w(w * (1 + h)) - _k_of_w(w * (1 - h))) / (2 * w * h)


W_FOLD = brentq(_dk_dw, 0.4, 0.9, xtol=1e-13)
K_FOLD = _k_of_w(W_FOLD)


def _cycles_at(K):
    """The two backlash cycles (w, X) at gain K, from K(w) = K on each side of the tangency."""
    ws = [brentq(lambda w: _k_of_w(w) - K, lo, hi, xtol=1e-14) for lo, hi in ((0.05, W_FOLD), (W_FOLD, 1.41))]
    return [(w, _x_of_w(w)) for w in ws]


def test_relay_dead_zone_fold_and_branches_match_closed_form():
    values = np.linspace(0.7, 2.5, 10) * K_STAR  # the fold lies between two values
    res = sweep(relay_loop, values, parameter="K", progress=False)
    folds = res.folds()
    assert len(folds) == 1 and len(res.events) == 1
    f = folds[0]
    assert abs(f.parameter / K_STAR - 1) < 1e-10
    assert abs(f.amplitude / (D * math.sqrt(2)) - 1) < 1e-8  # N is maximal at A = d sqrt(2)
    assert abs(f.frequency / W_PC - 1) < 1e-9
    assert len(res.branches) == 2 and set(f.branches) == {0, 1}
    kinds = {b.kind: b for b in res.branches}
    assert set(kinds) == {"stable", "unstable"}
    for kind, col in (("unstable", 0), ("stable", 1)):  # the classical result: the larger cycle is stable
        b = kinds[kind]
        p, A, w = b.at_values()
        assert np.array_equal(p, values[values > K_STAR])  # a point at every value past the fold, none before
        ref = np.array([relay_amplitudes(K)[col] for K in p])
        np.testing.assert_allclose(A, ref, rtol=1e-9)
        np.testing.assert_allclose(w, W_PC, rtol=1e-9)
        np.testing.assert_allclose(b.frequency, W_PC, rtol=1e-9)  # every continuation step is a root too
        assert b.start == "fold" and b.end == "sweep end"
        assert np.all(np.diff(b.parameter) >= 0)
    assert np.all(kinds["stable"].amplitude[1:] > D * math.sqrt(2))
    assert np.all(kinds["unstable"].amplitude[1:] < D * math.sqrt(2))
    assert not res.notes


def test_branches_born_between_two_values_are_traced_back_to_their_fold():
    # only two values, no cycle at the first: the completeness check at the second finds the pair, and
    # continuation backwards finds where it is born; decreasing values give the same fold
    # (also with the fold on a given value, and on the end of the range)
    for values in ([0.5 * K_STAR, 3 * K_STAR], [3 * K_STAR, 0.5 * K_STAR], [0.8 * K_STAR, K_STAR, 1.5 * K_STAR],
                   [2 * K_STAR, K_STAR]):
        res = sweep(relay_loop, values, parameter="K", progress=False)
        (f,) = res.folds()
        assert abs(f.parameter / K_STAR - 1) < 1e-10 and len(res.branches) == 2
        assert "exists for K > " in f.detail
        for b in res.branches:  # arrays follow the order of the sweep
            assert np.all(np.diff(b.parameter) * np.sign(values[1] - values[0]) >= 0)


def test_backlash_gain_fold_matches_independent_tangency():
    values = np.linspace(2.5, 5.5, 7)
    res = sweep(backlash_loop, values, parameter="K", progress=False)
    (f,) = res.folds()
    assert abs(f.parameter / K_FOLD - 1) < 1e-10
    assert abs(f.frequency / W_FOLD - 1) < 1e-7  # W_FOLD: brentq on a difference quotient of K(w)
    assert abs(f.amplitude / _x_of_w(W_FOLD) - 1) < 1e-7
    assert len(res.branches) == 2
    for b in res.branches:
        p, A, w = b.at_values()
        assert np.array_equal(p, values[values > K_FOLD])
        side = 0 if b.frequency[-1] < W_FOLD else 1  # low-frequency cycle or high-frequency cycle
        ref = np.array([_cycles_at(K)[side] for K in p])
        np.testing.assert_allclose(w, ref[:, 0], rtol=1e-8)
        np.testing.assert_allclose(A, ref[:, 1], rtol=1e-8)
        # stability against the classical graphical rule (a different criterion from Loeb's)
        for K, Ak, wk in zip(p, A, w):
            assert graphical_stability(K * G0, _BL, Ak, wk) == (b.kind == "stable")
    assert {b.kind for b in res.branches} == {"stable", "unstable"}


def test_window_entry_is_located_on_the_edge():
    # as K falls from 5.9 the stable backlash cycle's amplitude falls through X = 10: there the gain is
    # K = 1/(|G0(jw)| |N(10)|) with arg G0(jw) = arg(-1/N(10))
    x_edge = 10.0
    n_edge = complex(_BL(x_edge))
    w_edge = brentq(lambda w: np.angle(_g0(w)) - np.angle(-1 / n_edge), 0.5, 1.414, xtol=1e-15)
    k_edge = 1 / (abs(_g0(w_edge)) * abs(n_edge))
    res = sweep(backlash_loop, [5.9, 3.0], amplitude=(0.1001, x_edge), parameter="K", progress=False)
    (entry,) = [e for e in res.events if e.kind == "entry"]
    assert abs(entry.amplitude / x_edge - 1) < 1e-12
    assert abs(entry.parameter / k_edge - 1) < 1e-9
    assert abs(entry.frequency / w_edge - 1) < 1e-9
    b = res.branches[entry.branches[0]]
    assert b.kind == "stable" and b.start.startswith("enters the amplitude window's upper edge")
    assert b.amplitude[0] == pytest.approx(x_edge, rel=1e-12)
    (f,) = res.folds()
    assert abs(f.parameter / K_FOLD - 1) < 1e-6


def test_csv_plot_and_repr(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    res = sweep(relay_loop, np.linspace(0.9, 1.6, 4) * K_STAR, parameter="K", unit="V/V", progress=False)
    path = tmp_path / "sweep.csv"
    res.to_csv(path)
    with open(path) as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["branch", "K [V/V]", "amplitude A", "frequency [rad/s]", "stability", "point"]
    body = rows[1:]
    assert len(body) == sum(b.parameter.size for b in res.branches)
    for b in res.branches:
        mine = [r for r in body if int(r[0]) == b.index]
        np.testing.assert_array_equal([float(r[1]) for r in mine], b.parameter)  # repr round-trips exactly
        np.testing.assert_array_equal([float(r[2]) for r in mine], b.amplitude)
        assert mine[0][5] == "fold" and mine[-1][5] == "sweep end"
        assert sum(r[5] == "value" for r in mine) == 3 - 1  # values past the fold, the last one is the end
    text = repr(res)
    assert "fold at K=0.942477" in text and "stable and an unstable" in text
    ax_a, ax_w = res.plot().axes[:, 0]
    styles = {line.get_linestyle() for line in ax_a.get_lines() if line.get_label() in ("stable cycles",
                                                                                         "unstable cycles")}
    assert styles == {"-", "--"}
    assert "fold" in [line.get_label() for line in ax_a.get_lines()]
    assert ax_w.get_xlabel() == "K [V/V]" and "[rad/s]" in ax_w.get_ylabel()
    matplotlib.pyplot.close("all")


def test_executor_gives_the_serial_result():
    from concurrent.futures import ThreadPoolExecutor

    values = np.linspace(1.2, 2.0, 3) * K_STAR
    serial = sweep(relay_loop, values, progress=False)
    with ThreadPoolExecutor(2) as ex:
        threaded = sweep(relay_loop, values, progress=False, executor=ex)
    assert len(serial.branches) == len(threaded.branches)
    for a, b in zip(serial.branches, threaded.branches):
        np.testing.assert_array_equal(a.amplitude, b.amplitude)
        np.testing.assert_array_equal(a.parameter, b.parameter)
    assert [list(c) for c in serial.cycles] == [list(c) for c in threaded.cycles]


def test_bad_input():
    with pytest.raises(ValueError, match="values must be strictly"):
        sweep(relay_loop, [1.0, 2.0, 1.5])
    with pytest.raises(ValueError, match="at least 2"):
        sweep(relay_loop, [1.0])
    with pytest.raises(ValueError, match="values must be finite"):
        sweep(relay_loop, [1.0, np.nan])
    with pytest.raises(ValueError, match="omega window"):
        sweep(relay_loop, [1.0, 2.0], omega=(2.0, 1.0))
    with pytest.raises(ValueError, match="max_steps"):
        sweep(relay_loop, [1.0, 2.0], max_steps=0)
    with pytest.raises(ValueError, match=r"loop_at\(1.0\) must return a pair"):
        sweep(lambda K: K * G0, [1.0, 2.0], progress=False)
    with pytest.raises(RuntimeError, match="max_steps=2"):
        sweep(relay_loop, [1.2 * K_STAR, 2 * K_STAR], max_steps=2, progress=False)


def _relay_roots(c):
    """Closed-form amplitudes (small, large) where the dead-zone relay's N(A) equals c <= 2M/(pi d)."""
    q = (math.pi * D * c / (4 * M)) ** 2
    r = math.sqrt(max(1 - 4 * q, 0.0))
    return D / math.sqrt((1 + r) / 2), D / math.sqrt((1 - r) / 2)


def test_isola_is_closed_by_two_folds():
    # K(p) = K*(0.9 + p(1 - p)) exceeds K* for p(1 - p) > 0.1: a closed curve of cycles (an isola) born and
    # dying at the folds p = (1 -+ sqrt(0.6))/2
    res = sweep(lambda p: (K_STAR * (0.9 + p * (1 - p)) * G0, dfloop.Relay(M=M, dead_zone=D)),
                np.linspace(0, 1, 6), progress=False)
    folds = res.folds()
    ref = [(1 - math.sqrt(0.6)) / 2, (1 + math.sqrt(0.6)) / 2]
    assert len(folds) == 2 and len(res.events) == 2
    np.testing.assert_allclose([f.parameter for f in folds], ref, rtol=1e-10)
    assert sorted(b.kind for b in res.branches) == ["stable", "unstable"]
    for b in res.branches:
        assert b.start == b.end == "fold"
        p, A, _ = b.at_values()
        col = 1 if b.kind == "stable" else 0
        np.testing.assert_allclose(A, [_relay_roots(1 / ((0.9 + x * (1 - x)) * K_STAR * G_PC))[col] for x in p],
                                   rtol=1e-9)


def test_stability_change_at_a_branch_point():
    # K(p) = K*/(1 - (p - 1/2)^2 / 2): N(A) = N_max (1 - (p - 1/2)^2 / 2) has two roots that cross at p = 1/2,
    # A = d sqrt(2) (two curves in an X); each changes stability there
    res = sweep(lambda p: (K_STAR / (1 - 0.5 * (p - 0.5) ** 2) * G0, dfloop.Relay(M=M, dead_zone=D)),
                np.linspace(0, 1, 6), progress=False)
    changes = [e for e in res.events if e.kind == "stability change"]
    assert len(changes) == 2 and not res.folds()
    for e in changes:
        assert abs(e.parameter - 0.5) < 1e-5 and abs(e.amplitude / (D * math.sqrt(2)) - 1) < 1e-5
    assert len(res.branches) == 4
    for b in res.branches:
        p, A, _ = b.at_values()
        n_max = 2 * M / (math.pi * D)
        col = 1 if b.kind == "stable" else 0  # the larger root is the stable one on either side
        np.testing.assert_allclose(A, [_relay_roots(n_max * (1 - 0.5 * (x - 0.5) ** 2))[col] for x in p], rtol=1e-9)


def test_frequency_dependent_element_has_the_same_fold():
    # force -> mass 1/(2 s^2) -> backlash, under the controller C = 2K s/((s+1)(s+2)): C G_m = K/(s(s+1)(s+2)),
    # so the loop is the backlash loop above with X = F/(2 w^2), seen through a frequency-dependent N(F, w)
    res = sweep(lambda K: (ct.tf([2 * K, 0], [1, 3, 2]), dfloop.MassBacklash(1.0, 1.0, H)), [5.5, 3.0, 2.5],
                parameter="K", progress=False)
    (f,) = res.folds()
    assert abs(f.parameter / K_FOLD - 1) < 1e-10
    assert abs(f.frequency / W_FOLD - 1) < 1e-7
    assert abs(f.amplitude / (2 * W_FOLD**2 * _x_of_w(W_FOLD)) - 1) < 1e-7
    for b in res.branches:
        p, F, w = b.at_values()
        side = 0 if b.frequency[0] < W_FOLD else 1
        ref = np.array([_cycles_at(K)[side] for K in p])
        np.testing.assert_allclose(w, ref[:, 0], rtol=1e-8)
        np.testing.assert_allclose(F, 2 * ref[:, 0] ** 2 * ref[:, 1], rtol=1e-8)


def test_delay_sweep_exits_through_the_frequency_edge_and_folds_in_closed_form():
    # relay with dead zone d = 0.05 around e^{-sT}/(s(s+1)), T swept: cycles sit on phase crossovers,
    # w T + pi/2 + atan w = (2m + 1) pi. The first crossover leaves the window's lower edge w = 0.5 at
    # T = (pi/2 - atan 0.5)/0.5; a pair is born at the second crossover (m = 1) when 1/|G| = w sqrt(1 + w^2)
    # reaches max N = 2M/(pi d), i.e. at w^2 = (sqrt(1 + 4 c^2) - 1)/2, c = 2M/(pi d), T = (5pi/2 - atan w)/w
    d = 0.05

    def loop_at(T):
        return (lambda w: np.exp(-1j * w * T) / (1j * w * (1j * w + 1))), dfloop.Relay(M=M, dead_zone=d)

    res = sweep(loop_at, [0.5, 3.0], omega=(0.5, 5.0), progress=False, parameter="T", unit="s")
    exits = [e for e in res.events if e.kind == "exit"]
    assert len(exits) == 2  # the stable and the unstable cycle of the first crossover leave together
    for e in exits:
        assert e.frequency == pytest.approx(0.5, rel=1e-12)
        assert abs(e.parameter / ((math.pi / 2 - math.atan(0.5)) / 0.5) - 1) < 1e-10
    (f,) = res.folds()
    c = 2 * M / (math.pi * d)
    w_f = math.sqrt((math.sqrt(1 + 4 * c * c) - 1) / 2)
    assert abs(f.frequency / w_f - 1) < 1e-8
    assert abs(f.parameter / ((2.5 * math.pi - math.atan(w_f)) / w_f) - 1) < 1e-10
    assert abs(f.amplitude / (d * math.sqrt(2)) - 1) < 1e-7
    assert sorted(b.kind for b in res.branches) == ["stable", "stable", "unstable", "unstable"]


def test_no_cycle_below_the_fold_gives_an_empty_result(tmp_path):
    res = sweep(backlash_loop, [0.5, 0.9 * K_FOLD], progress=False)
    assert not res.branches and not res.events and all(len(c) == 0 for c in res.cycles)
    assert "no limit cycle in the window" in repr(res)
    res.to_csv(tmp_path / "empty.csv")
    assert (tmp_path / "empty.csv").read_text().count("\n") == 1  # the header only


def test_dfloop_sweep_is_the_continuation_function():
    import dfloop

    assert dfloop.sweep is sweep


@settings(max_examples=6, deadline=None, derandomize=True)
@given(m=st.floats(0.5, 5.0), d=st.floats(0.01, 1.0), n=st.integers(2, 6), lo=st.floats(0.3, 0.95),
       hi=st.floats(1.05, 4.0), descending=st.booleans())
def test_relay_fold_for_any_level_dead_zone_and_grid(m, d, n, lo, hi, descending):
    k_star = math.pi * d / (2 * m * G_PC)
    values = np.linspace(lo, hi, n)[::-1 if descending else 1] * k_star
    res = sweep(lambda K: (K * G0, dfloop.Relay(M=m, dead_zone=d)), values, progress=False)
    (f,) = res.folds()
    assert abs(f.parameter / k_star - 1) < 1e-9 and len(res.events) == 1
    assert abs(f.amplitude / (d * math.sqrt(2)) - 1) < 1e-7
    for b in res.branches:
        p, A, _ = b.at_values()
        q = (math.pi * d / (4 * m * p * G_PC)) ** 2
        u = (1 + (1 if b.kind == "unstable" else -1) * np.sqrt(1 - 4 * q)) / 2
        np.testing.assert_allclose(A, d / np.sqrt(u), rtol=1e-9)


def test_python_control_nonlinearity_is_accepted_and_bad_elements_named():
    # python-control's saturation becomes dfloop's Saturation: the same sweep, bit for bit
    sat = ct.saturation_nonlinearity(1.0)
    plant = ct.tf([1], [1, 3, 2, 0])
    a = sweep(lambda K: (K * plant, sat), [8.0, 12.0], progress=False)
    b = sweep(lambda K: (K * plant, dfloop.Saturation(1.0)), [8.0, 12.0], progress=False)
    assert len(a.branches) == 1 and a.branches[0].kind == "stable"
    np.testing.assert_array_equal(a.branches[0].amplitude, b.branches[0].amplitude)
    with pytest.raises(ValueError, match=r"loop_at\(1.0\): N must be a dfloop DescribingFunction"):
        sweep(lambda K: (K * plant, "relay"), [1.0, 2.0], progress=False)
