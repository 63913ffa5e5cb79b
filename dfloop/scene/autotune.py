"""The ``[autotune]`` stage of a scene: the relay experiment on the scene's plant (its element is the relay),
tuning rules checked on the plant, and optionally the fit of a recorded experiment (:mod:`dfloop.autotune`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["AutotuneReport", "run_autotune"]


@dataclass
class AutotuneReport:
    """What the ``[autotune]`` stage produced: the experiment, the tunings with their closed-loop checks, and the
    fit of a recording (None without ``record``)."""

    experiment: Any
    tunings: list = field(default_factory=list)
    checks: list = field(default_factory=list)
    sources: list = field(default_factory=list)
    fit: Any = None

    def __repr__(self) -> str:
        return "\n".join(self.to_markdown_lines())

    def to_markdown_lines(self) -> list[str]:
        lines = ["```", repr(self.experiment), "```", ""]
        if self.fit is not None:
            lines += ["Fit of the recording:", "", "```", repr(self.fit), "```", ""]
        lines += ["| rule | from | Kp | Ti [s] | Td [s] | gain margin | phase margin [deg] | Ms | overshoot |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for t, c, src in zip(self.tunings, self.checks, self.sources):
            ti = "inf" if math.isinf(t.Ti) else f"{t.Ti:.4g}"
            lines.append(f"| {t.rule} | {src} | {t.Kp:.4g} | {ti} | {t.Td:.4g} | {c['gain_margin']:.3g} | "
                         f"{c['phase_margin']:.3g} | {c['Ms']:.3g} | {100 * c['overshoot']:.1f} % |")
        return lines

    def to_dict(self) -> dict:
        return {"experiment": self.experiment.to_dict(), "tunings": [t.to_dict() for t in self.tunings],
                "checks": list(self.checks), "sources": list(self.sources),
                "fit": None if self.fit is None else self.fit.to_dict()}


def run_autotune(scene: Any) -> AutotuneReport:
    """Run the scene's ``[autotune]`` (see :class:`dfloop.scene.schema.Autotune`).

    The relay experiment runs on the plant (a DelayedSystem gives the dead time; with a delay or a bias the plant
    must be a first- or second-order lag). Rules from the ultimate point (``zn-*``) use the experiment's reading
    (the exact orbit's Ku, Tu) or, with a recording, the fitted model's; model rules (``simc-*``, ``amigo-*``) use
    the fitted model, or the plant itself when it is a first- or second-order lag with dead time. Every controller is
    checked on the scene's plant (:func:`dfloop.autotune.closed_loop_check`).
    """
    from dfloop.autotune import closed_loop_check, process_model, relay_experiment, tune
    from dfloop.autotune.fit import fit_relay_record
    from dfloop.autotune.record import load_relay_record

    spec = scene.autotune
    plant = scene.plant
    G, delay = getattr(plant, "system", plant), float(getattr(plant, "delay", 0.0))
    exp = relay_experiment(G, scene.element, delay=delay, bias=spec.bias)
    report = AutotuneReport(exp)
    model, Ku, Tu, source = None, exp.Ku_experiment, exp.Tu_experiment, "experiment"
    if spec.record is not None:
        path = Path(spec.record)
        if not path.is_absolute() and scene.source is not None:
            path = Path(scene.source).parent / path
        report.fit = fit_relay_record(load_relay_record(path), spec.model)
        model, Ku, Tu, source = report.fit.model, report.fit.Ku, report.fit.Tu, f"{spec.model} fit"
    else:
        try:
            model = process_model(G, delay)
        except ValueError:
            model = None
    for rule in spec.rules:
        if rule.startswith("zn"):
            t, src = tune(rule, Ku=Ku, Tu=Tu), source
        elif model is not None:
            t, src = tune(rule, model=model), source if spec.record is not None else "plant model"
        else:
            from .errors import Problem, SceneError

            raise SceneError(scene.source, Problem("autotune.rules", f"rule {rule!r} needs a process model: give a "
                                                   "record to fit, or a first- or second-order plant"))
        report.tunings.append(t)
        report.sources.append(src)
        report.checks.append(closed_loop_check(t.controller, G, delay=delay, t_end=spec.t_end))
    return report
