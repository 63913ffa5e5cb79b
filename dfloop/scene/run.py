"""Running scenes: predict the cycles, then only the stages the scene asks for, each timed and reported."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .load import Scene

__all__ = ["SceneReport", "run_scene", "predict_cycles"]


def predict_cycles(scene: Scene) -> Any:
    """The one call that predicts a scene's cycles: ``predict_limit_cycles`` on the scene's loop and windows.

    ``[analysis] exact = true`` is passed through as ``exact=True``: each predicted cycle carries its exact
    orbit (``cycle.exact``, :func:`dfloop.exact_cycle`) besides its confidence (``cycle.confidence``).
    """
    from dfloop.solve import predict_limit_cycles

    return predict_limit_cycles(scene.plant, scene.element, omega=scene.omega, amplitude=scene.amplitude,
                                exact=bool(scene.exact))


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:+.3g} %"


def comparison_table(cycles: Any) -> list[str]:
    """Markdown rows, one per cycle: predicted A and w, the confidence (distortion, estimated errors) and, for
    cycles carrying an exact orbit, its A, w, Floquet stability (largest non-trivial |multiplier|) and the
    DF's relative errors (predicted - exact) / exact, and its verdict (confirmed / artefact / not checked, the
    reason of a "not checked"). Amplitudes in the element's input unit, w in rad/s."""
    rows = ["| # | predicted A | predicted w [rad/s] | distortion | est. error A | est. error w | exact A | "
            "exact w [rad/s] | exact stability (max non-trivial abs multiplier) | DF error A | DF error w | verdict |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for i, c in enumerate(cycles):
        conf = c.confidence
        if conf is not None and conf.available:
            confidence = [f"{100 * conf.distortion:.3g} %", _percent(conf.amplitude_error),
                          _percent(conf.frequency_error)]
        else:
            confidence = ["unavailable", "-", "-"]
        ex = c.exact
        if ex is None:
            exact = ["-"] * 5
        elif not ex.success:
            exact = ["no orbit: " + ex.message.replace("|", "\\|").replace("\n", " "), "-", "-", "-", "-"]
        else:
            exact = [f"{ex.amplitude:.8g}", f"{ex.frequency:.8g}",
                     f"{'stable' if ex.stable else 'unstable'} ({ex.largest_multiplier:.4g})",
                     _percent(ex.amplitude_error), _percent(ex.frequency_error)]
        verdict = c.verdict   # confirmed / artefact / not checked (dfloop.solve.verdict)
        reason = "" if verdict.kind == "confirmed" or ex is not None and not ex.success else f" ({verdict.detail})"
        rows.append("| " + " | ".join([str(i), f"{c.amplitude:.6g}", f"{c.frequency:.6g}", *confidence, *exact,
                                       verdict.kind + reason.replace("|", "\\|")]) + " |")
    return rows


def run_sweep(scene: Scene) -> Any:
    """The scene's ``[sweep]``: every cycle followed over the swept values (:func:`dfloop.sweep`)."""
    from dfloop.continuation import sweep

    return sweep(scene.loop_at, scene.sweep_values, omega=scene.omega, amplitude=scene.amplitude, executor=None,
                 parameter=scene.sweep.parameter)


@dataclass
class SceneReport:
    """What a scene run produced: cycles, verifications, files, and the stages that ran with their times."""

    scene: Scene
    cycles: Any = None
    verifications: list[Any] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    stages: list[tuple[str, float]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    sweep: Any = None
    figure: Any = None

    def to_markdown(self) -> str:
        lines = [f"# {self.scene.title}", "", f"Scene `{self.scene.source}`; element `{self.scene.element!r}`.", ""]
        if self.cycles is not None:
            lines += ["## Predicted limit cycles", "", "```", repr(self.cycles), "```", ""]
            if len(self.cycles):
                lines += ["## Prediction, confidence and exact orbit", "", *comparison_table(self.cycles), ""]
        if self.verifications:
            lines += ["## Closed-loop verification", "", "```"]
            lines += [repr(v) for v in self.verifications]
            lines += ["```", ""]
        if self.sweep is not None:
            lines += ["## Sweep", "", "```", repr(self.sweep), "```", ""]
        if self.figure is not None:
            lines += ["## Figure", "", "```", repr(self.figure), "```", ""]
        lines += ["## Stages run", "", "| stage | time (s) |", "|---|---|"]
        lines += [f"| {name} | {seconds:.3f} |" for name, seconds in self.stages]
        lines += [""] + [f"- {note}" for note in self.notes] if self.notes else []
        if self.files:
            lines += ["", "## Files", ""] + [f"- `{p.name}`" for p in self.files]
        return "\n".join(lines) + "\n"


def _save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def run_scene(scene: Scene, out_dir: str | Path = "out", log: Callable[[str], None] = print,
              progress: bool | None = None) -> SceneReport:
    """Run a scene's stages: predict cycles, verify them if asked, sweep if asked, draw the plots asked for,
    write a report.

    Parameters
    ----------
    scene : Scene
        From :func:`load_scene`.
    out_dir : str or Path
        Where the plots, the CSV of a sweep and ``<name>_report.md`` go (created if needed).
    log : callable
        Receives one line per stage and result (``print`` by default).
    progress : bool or None
        A progress bar over the stages (:func:`dfloop.progress.progress_bar`: tqdm on a terminal, plain lines
        otherwise); None shows it only when the run lasts more than a second, False never.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dfloop.progress import progress_bar

    from .figure import figure_data, figure_spec

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    report = SceneReport(scene)
    figure = figure_spec(scene)
    predict = scene.data.get("analysis", {}).get("predict", True)
    plots = scene.plots if predict else ()
    planned = predict + len(plots) + (scene.sweep is not None) + (figure is not None)

    with progress_bar(scene.name, planned, enabled=progress) as bar:

        def stage(name: str, fn: Callable[[], Any]) -> Any:
            bar.update(0, stage=name)
            t0 = time.perf_counter()
            result = fn()
            report.stages.append((name, time.perf_counter() - t0))
            bar.update(1, stage=name)
            log(f"[{scene.name}] {name}: {report.stages[-1][1]:.2f} s")
            return result

        if predict:
            report.cycles = stage("predict limit cycles", lambda: predict_cycles(scene))
            log(repr(report.cycles))
        simulations = getattr(scene.element, "n_simulations", None)
        if simulations is not None:  # tabulated elements: how much of the table this run had to simulate
            report.notes.append(f"{type(scene.element).__name__}: {simulations} motions simulated in this run "
                                f"({'table served from the cache' if simulations == 0 else 'table built and cached'})")
            log(f"[{scene.name}] {report.notes[-1]}")
        if scene.verify and predict:
            from dfloop.verify import verify_cycle

            bar.set_total(planned + len(report.cycles))
            for cycle in report.cycles:
                report.verifications.append(stage(
                    f"verify cycle at w = {cycle.frequency:.4g} rad/s",
                    lambda c=cycle: verify_cycle(scene.plant, scene.element, c,
                                                 perturbation=scene.verify_perturbation)))
                log(repr(report.verifications[-1]))
        if scene.sweep is not None:
            report.sweep = stage(f"sweep {scene.sweep.parameter} over {len(scene.sweep_values)} values",
                                 lambda: run_sweep(scene))
            log(repr(report.sweep))
            if scene.sweep.csv:
                report.sweep.to_csv(out / f"{scene.name}_sweep.csv")
                report.files.append(out / f"{scene.name}_sweep.csv")
            drawn = report.sweep.plot()  # axes, a tuple of axes, or a plot object with .figure
            first = drawn[0] if isinstance(drawn, (tuple, list)) else drawn
            report.files.append(_save(getattr(first, "figure", None) or plt.gcf(), out / f"{scene.name}_sweep.png"))
        if figure is not None:
            report.figure = stage(f"figure ({figure.kind})", lambda: figure_data(scene))
            log(repr(report.figure))
            drawn = np.atleast_1d(report.figure.plot())
            report.files.append(_save(drawn.flat[0].figure, out / f"{scene.name}_figure.png"))
        if "nyquist" in plots:
            from dfloop.plot.nyquist import plot_nyquist

            def nyquist() -> Path:
                fig, ax = plt.subplots(figsize=(6.5, 5.5))
                plot_nyquist(scene.plant, scene.element, cycles=report.cycles, ax=ax)
                ax.set_title(scene.title)
                return _save(fig, out / f"{scene.name}_nyquist.png")

            report.files.append(stage("plot nyquist", nyquist))
        if "residual" in plots:
            from dfloop.plot.nyquist import plot_residual_map

            def residual() -> Path:
                fig, ax = plt.subplots(figsize=(6.5, 5.0))
                plot_residual_map(scene.plant, scene.element, cycles=report.cycles, ax=ax)
                return _save(fig, out / f"{scene.name}_residual.png")

            report.files.append(stage("plot residual map", residual))
    path = out / f"{scene.name}_report.md"
    path.write_text(report.to_markdown())
    report.files.append(path)
    log(f"[{scene.name}] report written to {path}")
    return report
