"""Random loops for the standing fuzz of predict_limit_cycles (tests/test_solve_random.py, benchmarks/fuzz_solver.py).

Each case is a plant (order 1-7, damping down to 1e-6, optional unstable poles, integrators, gains 1e-3..1e3,
optional delay as a callable), an element of any kind, and a window choice (default or explicit). The kinds
``*_resonance`` put a frequency-dependent element (a lead-lag then a backlash; the mass-backlash) behind a sharp
resonance (damping 3e-7..1e-4, gain up to 1e6, one or two real poles more): |G| up to ~1e11 there, so the roots
lie within ~1e-11 (relative) of the edge of the element's dead band; their windows are default, explicit or
narrow around the resonance. ``run_case`` solves it with dfloop and with the independent reference of
``df_reference`` and returns the counts.
"""
from __future__ import annotations

import math
import time
import warnings

import control as ct
import numpy as np

import dfloop as df
from dfloop.describing.numeric import NumericDF
from dfloop.solve import as_plant

import df_reference as ref

KINDS = ["saturation", "deadzone", "relay", "relay_hyst", "backlash", "cubic", "coulomb", "preload", "quantizer",
         "linear_then_static", "mass_backlash", "numeric_static", "numeric_hysteretic", "linear_then_static_resonance",
         "mass_backlash_resonance"]
_RESONANCE = "_resonance"


def resonant_plant(rng: np.random.Generator, n_real: int):
    """A resonance of damping 10^U(-6.5, -4) at w_n in [0.3, 3] rad/s, static gain 10^U(-3, 6), with ``n_real``
    real poles in [0.1, 10] rad/s more (the phase lag a dead-band edge root needs: N's phase there is about
    -90 degrees for the lead-lag and backlash, +90 for the mass-backlash)."""
    zeta, wn = 10 ** rng.uniform(-6.5, -4), 10 ** rng.uniform(-0.5, 0.5)
    real = [-10 ** rng.uniform(-1, 1) for _ in range(n_real)]
    poles = [complex(-zeta * wn, wn * math.sqrt(1 - zeta ** 2)), complex(-zeta * wn, -wn * math.sqrt(1 - zeta ** 2))]
    poles += real
    gain = 10 ** rng.uniform(-3, 6) * wn ** 2 * abs(np.prod(real))
    return ct.tf([gain], np.real(np.poly(poles))), np.array(poles, complex), np.array([], complex), 0.0, wn


def random_plant(rng: np.random.Generator, order_max: int = 7):
    order = int(rng.integers(1, order_max + 1))
    poles = []
    if rng.random() < 0.2:
        poles.append(0.0)
    while len(poles) < order:
        if order - len(poles) >= 2 and rng.random() < 0.5:
            zeta = 10 ** rng.uniform(-6, -0.1) if rng.random() < 0.3 else rng.uniform(0.05, 0.9)
            wn = 10 ** rng.uniform(-1, 1)
            poles += [complex(-zeta * wn, wn * math.sqrt(1 - zeta ** 2)), complex(-zeta * wn, -wn * math.sqrt(1 - zeta ** 2))]
        else:
            unstable = rng.random() < 0.1
            poles.append(rng.uniform(0.05, 1.0) if unstable else -10 ** rng.uniform(-1, 1))
    zeros = [-10 ** rng.uniform(-1, 1) for _ in range(int(rng.integers(0, order)))]
    gain = 10 ** rng.uniform(-1, 2) * abs(np.prod([p for p in poles if p != 0]) or 1.0) / abs(np.prod(zeros) or 1.0)
    G = ct.tf(gain * np.real(np.poly(zeros)) if zeros else [gain], np.real(np.poly(poles)))
    T = float(rng.choice([0.0, 0.0, 0.0, 0.1, 0.5, 2.0]))
    return G, np.array(poles, complex), np.array(zeros, complex), T


def random_element(rng: np.random.Generator, kind: str):
    s = 10 ** rng.uniform(-2, 1)
    if kind == "saturation":
        return df.Saturation(s, k=10 ** rng.uniform(-1, 1))
    if kind == "deadzone":
        return df.DeadZone(s, k=10 ** rng.uniform(-1, 1))
    if kind == "relay":
        return df.Relay(10 ** rng.uniform(-1, 1), dead_zone=float(rng.choice([0.0, s])))
    if kind == "relay_hyst":
        return df.Relay(10 ** rng.uniform(-1, 1), hysteresis=s)
    if kind == "backlash":
        return df.Backlash(h=s, k=10 ** rng.uniform(-1, 1))
    if kind == "cubic":
        return df.CubicStiffness(10 ** rng.uniform(-1, 1), float(rng.choice([1, -1])) * 10 ** rng.uniform(-2, 1))
    if kind == "coulomb":
        return df.CoulombViscousFriction(10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1))
    if kind == "preload":
        return df.PreloadedSpring(10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1))
    if kind == "quantizer":
        return df.Quantizer(s)
    if kind == "linear_then_static":
        z, p = 10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1)
        return df.LinearThenStatic(ct.tf([1 / z, 1], [1 / p, 1]), df.Backlash(h=s))
    if kind == "mass_backlash":
        return df.MassBacklash(10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-1, 1), h=s)
    if kind == "numeric_static":
        return NumericDF(df.Saturation(s))
    if kind == "numeric_hysteretic":
        return NumericDF(df.Backlash(h=s).operator(), hysteretic=True)  # N = 0 below s/2 (not in its domain)
    raise ValueError(kind)


def _marks(N):
    """Amplitudes where N has an edge or a kink, from the element's parameters (known to the test, not asked
    of the element): there the scan is dense in ln |A - mark|."""
    base = getattr(N, "static", N)
    for cls, attr, f in ((df.Saturation, "limit", 1.0), (df.DeadZone, "delta", 1.0), (df.Backlash, "h", 0.5),
                         (df.Relay, "on_level", 1.0), (df.Quantizer, "step", 0.5)):
        if isinstance(base, cls):
            return [f * getattr(base, attr)]
    if isinstance(base, NumericDF):
        el = base.element
        if hasattr(el, "h"):  # a play operator: N = 0 below h/2
            return [0.5 * el.h]
        op = getattr(el, "__self__", None)  # a static element's bound output method
        if isinstance(op, df.Saturation):
            return [op.limit]
    return []


def _amplitude_scan(N, lo, hi, n=3000):
    """Dense amplitude scan of (lo, hi) for the reference: log-spaced, the element's breakpoints added."""
    A = np.geomspace(lo, hi, n)
    for m in _marks(N) + ([lo] if lo > 0 else []):  # near an edge N rises like a power of A - m
        t = np.geomspace(1e-12, 1.0, n // 3)
        A = np.concatenate([A, m * (1 + t), m * (1 - t / 2)])
    base = getattr(N, "static", N)
    if isinstance(base, df.Quantizer):
        c = (np.arange(1, int(hi / base.step) + 2) - 0.5) * base.step
        c = c[(c > lo) & (c < hi)]
        t = np.geomspace(1e-12, 0.2, 40)  # N rises like sqrt(A - c) just above each threshold c
        A = np.concatenate([A, (c[:, None] * (1 + t)).ravel(), c * (1 - 1e-12), (c[:-1] + c[1:]) / 2])
    return np.unique(A[(A >= lo) & (A <= hi)])


def _span(N, kind):
    """A generous amplitude range (the element's input unit) holding every root the fuzz can produce."""
    base = getattr(N, "static", N)
    scale = {df.Saturation: "limit", df.DeadZone: "delta", df.Backlash: "h", df.Quantizer: "step"}
    for cls, attr in scale.items():
        if isinstance(base, cls):
            return getattr(base, attr)
    return 1.0


def reference_roots(G, poles, zeros, T, N, kind, omega, amplitude):
    """Reference roots in the given windows (amplitude None: the element's whole domain up to 1e7 scales)."""
    g = as_plant(G) if T == 0 else None
    Gf = (lambda w: g(w)) if T == 0 else (lambda w: np.exp(-1j * w * T) * as_plant(G)(w))
    w_scan = ref.frequency_scan(omega[0], omega[1], poles, zeros, T)
    if kind in ("linear_then_static", "mass_backlash"):
        glin = as_plant(N.linear) if kind == "linear_then_static" else (lambda w: -1.0 / ((N.m1 + N.m2) * w ** 2) + 0j)
        lin_poles = [] if kind == "mass_backlash" else list(np.roots(N.linear.den[0][0]))
        w_scan = np.unique(np.concatenate([w_scan, ref.frequency_scan(omega[0], omega[1], lin_poles, [], 0.0, 2000)]))
        Ns = N.static
        lo = Ns.amplitude_domain()[0] * (1 + 1e-12)
        X_scan = _amplitude_scan(Ns, float(lo), float(lo) * 1e9)
        F_window = amplitude if amplitude is not None else (0.0, np.inf)
        return ref.composite_roots(Gf, glin, lambda X: Ns(X), w_scan, X_scan, F_window)
    if amplitude is None:
        lo, hi = (float(x) for x in N.amplitude_domain())
        s = _span(N, kind)
        lo = lo * (1 + 1e-12) if lo > 0 else s * 1e-12
        hi = hi * (1 - 1e-9) if math.isfinite(hi) else s * 1e7
        if kind == "quantizer":
            # |N - 1| <= step / (2 A) (measured on a dense scan with every threshold): roots need
            # |G| step / (2 A) >= |1 + G|, so none beyond step max|G| / (2 min|1 + G|) (on the scan)
            gs = Gf(w_scan)
            reach = 0.5 * s * np.max(np.abs(gs)) / max(np.min(np.abs(1 + gs)), 1e-300) * 1.5
            if reach > 3000 * s:
                return None  # beyond what the reference scans with every threshold
            hi = min(hi, reach)
        amplitude = (lo, hi)
    dlo, dhi = (float(x) for x in N.amplitude_domain())
    amplitude = (max(amplitude[0], dlo * (1 + 1e-12)), min(amplitude[1], dhi * (1 - 1e-9)))
    if amplitude[0] >= amplitude[1]:
        return []
    n = 400 if kind == "numeric_hysteretic" else 3000  # a Python operator costs ~6 ms per amplitude
    return ref.amplitude_roots(Gf, lambda A: N(A), w_scan, _amplitude_scan(N, *amplitude, n=n))


def run_case(seed: int, default_windows: bool | None = None, kind: str | None = None):
    """Solve one random case with dfloop and the reference; returns a dict of counts and details."""
    rng = np.random.default_rng(seed)
    G, poles, zeros, T = random_plant(rng)
    drawn = KINDS[int(rng.integers(len(KINDS)))]
    kind = drawn if kind is None else kind
    resonance = kind.endswith(_RESONANCE)
    if resonance:
        kind = kind[:-len(_RESONANCE)]
        G, poles, zeros, T, wn = resonant_plant(rng, 2 if kind == "mass_backlash" else 1)
    N = random_element(rng, kind)
    if default_windows is None:
        default_windows = bool(rng.random() < 0.5) and T == 0
    narrow = resonance and not default_windows and rng.random() < 0.5
    if default_windows:
        omega, amplitude = None, None
    elif narrow:  # around the resonance only, the element's amplitude window by default
        d = 10 ** rng.uniform(-4, -1)
        omega, amplitude = (wn * (1 - d), wn * (1 + d)), None
    else:
        omega = (10 ** rng.uniform(-2, -0.5), 10 ** rng.uniform(0.5, 1.5))
        s = _span(N, kind)
        if kind == "mass_backlash":
            s = s * (N.m1 + N.m2)
        amplitude = (s * 10 ** rng.uniform(-1, 0.2), s * 10 ** rng.uniform(0.5, 2))
    plant = G if T == 0 else (lambda w, G=G, T=T: np.exp(-1j * w * T) * as_plant(G)(w))
    if T and omega is None:
        omega = (0.05, 20.0)
    out = {"seed": seed, "kind": kind + (_RESONANCE if resonance else ""), "G": G, "T": T, "N": N, "omega": omega,
           "amplitude": amplitude, "misses": [], "extras": [], "extras_verified": [], "bad_residual": [],
           "error": None}
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cyc = df.predict_limit_cycles(plant, N, omega=omega, amplitude=amplitude)
    except df.ContinuumError:
        out["error"] = "continuum"
        out["time"] = time.perf_counter() - t0
        return out
    except ValueError as exc:
        if "lies outside N's amplitude domain" in str(exc):  # documented refusal of a window beyond N's domain
            out["error"] = "outside domain"
            out["time"] = time.perf_counter() - t0
            return out
        out["error"] = f"{type(exc).__name__}: {exc}"
        out["time"] = time.perf_counter() - t0
        return out
    except Exception as exc:  # counted, reported by the caller
        out["error"] = f"{type(exc).__name__}: {exc}"
        out["time"] = time.perf_counter() - t0
        return out
    out["time"] = time.perf_counter() - t0
    out["result"] = cyc
    w_win = cyc.omega_window
    found = [(c.amplitude, c.frequency) for c in cyc]
    want = reference_roots(G, poles, zeros, T, N, kind, w_win, amplitude)
    if want is None:
        out["error"] = "reference out of reach"
        return out
    # a reference root on the window's edge (to 1e-9) is outside for the solver's purposes
    want = [r for r in want if w_win[0] * (1 + 1e-9) < r[1] < w_win[1] * (1 - 1e-9)]
    if amplitude is not None:
        want = [r for r in want if amplitude[0] * (1 + 1e-9) < r[0] < amplitude[1] * (1 - 1e-9)]
    if not N.frequency_dependent:  # the solver searches N's domain from its lower end (1 + 1e-9) (documented)
        d_lo = float(N.amplitude_domain()[0])
        want = [r for r in want if r[0] > d_lo * (1 + 1e-9)]

    def residual(A, w):
        gw = complex(plant(np.array([w]))[0]) if T else complex(G(1j * w))
        return 1 + gw * complex(N(A, w) if N.frequency_dependent else N(A))

    misses, extras = ref.match(want, found)
    # a returned root the reference does not have, but whose residual from python-control's G and the element is
    # at rounding level (relative 1e-9), is a root the reference's scans missed: counted apart, not as an extra
    verified = [x for x in extras if abs(residual(*x)) <= 1e-9 * (2 + abs(residual(*x)))]
    out["misses"], out["extras"] = misses, [x for x in extras if x not in verified]
    out["extras_verified"] = verified
    for c in cyc:
        r = residual(c.amplitude, c.frequency)
        if abs(r) <= 1e-6 * (2 + abs(r)):
            continue
        # beyond 1e-6 only at the floor rounding sets: R changes that much within 8 float steps of ln A or ln w
        # (a root 1e-11 from a dead-band edge under |G| = 1e10); measured here on R itself, not on the solver
        la, lw = math.log(c.amplitude), math.log(c.frequency)
        ua, uw = (8 * max(np.spacing(abs(x)), np.finfo(float).eps) for x in (la, lw))
        floor = 4 * (abs(residual(math.exp(la + ua), c.frequency) - residual(math.exp(la - ua), c.frequency))
                     + abs(residual(c.amplitude, math.exp(lw + uw)) - residual(c.amplitude, math.exp(lw - uw))))
        if abs(r) > floor:
            out["bad_residual"].append((c.amplitude, c.frequency, abs(r) / (1 + abs(r - 1))))
    out["n_reference"] = len(want)
    return out
