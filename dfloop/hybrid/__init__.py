"""dfloop.hybrid: the exact engines of closed loops, behind one interface.

An element says how it behaves in time (:meth:`~dfloop.describing.base.DescribingFunction.time_model`, with the
vocabulary of :mod:`dfloop.describing.time_model`); :func:`loop_model` is the one place that turns a plant and
that time model into a loop model:

- piecewise affine -> :class:`HybridLoop`: z' = A_m z per mode, matrix exponentials, switches located to
  rounding level (relays, saturation, dead zone, backlash, quantizer, ...);
- smooth -> :class:`SmoothLoop`: DOP853 with the variational equation (cubic stiffness: compiled,
  :mod:`.smooth_compiled`; a user's f: scipy's solve_ivp);
- impact -> :class:`ImpactLoop`: the compiled linear-mode impact engine (dynamic backlash);
- sampled -> :class:`SampledLoop`: fixed step (an element with only an operator; not exact);
- a plant with a pure delay (:func:`dfloop.solve.delay.delayed`) and a piecewise-constant element ->
  :class:`DelayLoop`: the exact delay flow (element switches delayed exactly). Its state holds the pending
  switches of the delay line, so it has its own orbit finder and run (:func:`delay_orbit`,
  :func:`delay_simulation`); ``delay`` > 0 says so (0 for every other loop model);
- a plant with a pure delay and another static element (sloped pieces or smooth) -> :class:`DDELoop`: the delay
  differential equation, discretised (4th-order periodic method of steps, :mod:`dfloop.hybrid.dde`);
- a plant with a pure delay and an element with memory (backlash) ->
  :class:`~dfloop.hybrid.dde_memory.MemoryDDELoop`: the delay equation with the element's state in the history,
  its switches located on it (:mod:`dfloop.hybrid.dde_memory`);
- a plant with a pure delay and an impact element -> :class:`~dfloop.hybrid.delay_impact.DelayImpactLoop`: a
  method of steps on the impact engine (:mod:`dfloop.hybrid.delay_impact`);
- a plant with a pure delay and an element known only through an operator ->
  :class:`~dfloop.hybrid.delay_sampled.DelaySampledLoop`: fixed step with the delay line exact (not exact; no
  orbit finder, :mod:`dfloop.hybrid.delay_sampled`).

  The delay loops are served by the same two functions, :func:`delay_orbit` and :func:`delay_simulation`. A
  constant input rides on the shifted element (:mod:`dfloop.hybrid.constant`), so every delay engine but the
  impact one takes it unchanged.

A digital loop (a discrete-time plant) is a map, not a flow: :mod:`dfloop.hybrid.discrete` finds its orbits, and
:func:`dfloop.hybrid.discrete.sample_delayed` turns a delayed plant behind a zero-order hold into its exact sampled
map; :mod:`dfloop.hybrid.discrete_run` runs it sample by sample (``simulate_loop``, ``verify_cycle``).

Every other loop model has ``size``, ``x_row``, ``method``, ``exact`` (flows carry a monodromy), ``settle_periods``
(periods to run before shooting), ``plant`` (A, B), ``start(s0, x_history)``, ``admissible_mode(z, mode)``,
``flow(z, mode, t_end, monodromy=, max_events=)`` -> :class:`Flow`, ``signals(flow, t)`` -> (x, y),
``fourier(flow, T, w, K)`` and (when ``exact``) ``field(z, mode)`` and ``states(flow, t)``.
:mod:`dfloop.hybrid.shooting` finds periodic orbits of any exact loop model (autonomous, or at a fixed forcing
period: :func:`forced_orbit`, used by :mod:`dfloop.hybrid.forced`) and :func:`simulate` runs any of them. A constant
input (``loop_model(..., r0=, load=)``) rides on the constant state of piecewise-affine and smooth loops.
"""
from .dde import DDELoop
from .delay import DelayLoop, delay_orbit, delay_simulation
from .impact import ImpactLoop
from .loop import Flow, HybridError, HybridLoop, plant_matrices
from .model import harmonic_balance_state, input_history, loop_model, start_on_prediction
from .run import LoopSimulation, simulate
from .sampled import SampledLoop
from .shooting import Orbit, ShootingError, forced_orbit, periodic_orbit
from .smooth import SmoothLoop

__all__ = ["DDELoop", "DelayLoop", "delay_orbit", "delay_simulation", "Flow", "HybridError", "HybridLoop", "SmoothLoop", "ImpactLoop", "SampledLoop", "plant_matrices",
           "loop_model", "harmonic_balance_state", "input_history", "start_on_prediction", "LoopSimulation", "simulate",
           "Orbit", "ShootingError", "periodic_orbit", "forced_orbit"]
