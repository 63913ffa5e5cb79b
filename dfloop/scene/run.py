"""Running scenes: predict the cycles, then only the stages the scene asks for, each timed and reported."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .load import Scene

__all__ = ["SceneReport", "run_scene", "predict_cycles", "predict_biased", "run_forced"]


def predict_cycles(scene: Scene) -> Any:
    """The one call that predicts a scene's cycles: ``predict_limit_cycles`` on the scene's loop and windows.

    ``[analysis] exact = true`` is passed through as ``exact=True``: each predicted cycle carries its exact
    orbit (``cycle.exact``, :func:`dfloop.exact_cycle`) besides its confidence (``cycle.confidence``).
    """
    from dfloop.solve import predict_limit_cycles

    return predict_limit_cycles(scene.plant, scene.element, omega=scene.omega, amplitude=scene.amplitude,
                                exact=bool(scene.exact))


def predict_biased(scene: Scene) -> Any:
    """A scene with a constant input (``[loop]``): every biased cycle (:func:`dfloop.biased.biased_cycles`), each
    with its confidence and, with ``[analysis] exact = true``, its exact orbit."""
    from dfloop.biased import biased_cycles

    window = scene.amplitude
    if window is None:
        raise ValueError("[loop] reference / load need [analysis] amplitude = [lo, hi] (the biased solver's window)")
    options = {} if scene.omega is None else {"omega": scene.omega}
    return biased_cycles(scene.plant, scene.element, r0=scene.reference, load=scene.load, amplitude=window,
                         exact=bool(scene.exact), **options)


def run_forced(scene: Scene) -> tuple[Any, Any, Any]:
    """A scene's ``[forced]``: the DF forced response over ``num`` frequencies, its exact orbits (``exact``) and the
    jump-resonance region (``region``): (ForcedResponse, ExactForcedResponse or None, JumpRegion or None)."""
    import numpy as np

    from dfloop.solve.forced import forced_response, jump_region

    spec = scene.forced
    window = spec.amplitude or scene.amplitude or (1e-3 * spec.forcing, 100 * spec.forcing)
    omega = np.linspace(spec.omega[0], spec.omega[1], spec.num)
    response = forced_response(scene.plant, scene.element, spec.forcing, omega, amplitude=tuple(window))
    exact = None
    if spec.exact:
        from dfloop.hybrid.forced import exact_forced_response

        exact = exact_forced_response(scene.plant, scene.element, response, every=spec.every)
    region = None if spec.region is None else jump_region(scene.plant, scene.element, spec.region, omega,
                                                          amplitude=tuple(window))
    return response, exact, region


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:+.3g} %"


def comparison_table(cycles: Any) -> list[str]:
    """Markdown rows, one per cycle: predicted A and w, the confidence (distortion, estimated errors) and, for
    cycles carrying an exact orbit, its A, w, Floquet stability (largest non-trivial |multiplier|) and the
    DF's relative errors (predicted - exact) / exact, and its verdict (confirmed / artefact / not checked, the
    reason of a "not checked"). Amplitudes in the element's input unit, w in rad/s."""
    from dfloop.solve.result import exact_words

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
            exact = [exact_words(c, long=True).replace("|", "\\|").replace("\n", " "), "-", "-", "-", "-"]
        else:
            exact = [f"{ex.amplitude:.8g}", f"{ex.frequency:.8g}",
                     f"{'stable' if ex.stable else 'unstable'} ({ex.largest_multiplier:.4g})",
                     _percent(ex.amplitude_error), _percent(ex.frequency_error)]
        verdict = c.verdict   # confirmed / artefact / not checked (dfloop.solve.verdict)
        reason = "" if verdict.kind == "confirmed" or ex is not None and not ex.success else f" ({verdict.detail})"
        rows.append("| " + " | ".join([str(i), f"{c.amplitude:.6g}", f"{c.frequency:.6g}", *confidence, *exact,
                                       verdict.kind + reason.replace("|", "\\|")]) + " |")
    return rows


def run_sweep(scene: Scene, executor: Any = None) -> Any:
    """The scene's ``[sweep]``: every cycle followed over the swept values (:func:`dfloop.sweep`), the parameter
    named as the scene says (or as derived from its path: :func:`dfloop.scene.parameters.parameter_label`)."""
    from dfloop.continuation import sweep

    from .parameters import parameter_label

    label = parameter_label(scene.data, scene.sweep.parameter, scene.sweep.name, scene.sweep.unit)
    return sweep(scene.loop_at, scene.sweep_values, omega=scene.omega, amplitude=scene.amplitude,
                 executor=executor, parameter=label.name, unit=label.unit)


def sweep_margin(scene: Scene, result: Any) -> Any:
    """The limit-cycle margin of a ``[sweep]`` from its nominal value (the scene's ``nominal``, else the value
    written at the parameter's path), or None when that value is outside the swept range or unknown."""
    from .parameters import nominal_value, parameter_label

    label = parameter_label(scene.data, scene.sweep.parameter, scene.sweep.name, scene.sweep.unit)
    nominal = scene.sweep.nominal if scene.sweep.nominal is not None else nominal_value(scene.data,
                                                                                       scene.sweep.parameter)
    lo, hi = sorted((float(result.values[0]), float(result.values[-1])))
    if nominal is None or not lo <= nominal <= hi:
        return None
    return result.margin(nominal, gain=label.gain and lo > 0)


def run_chart(scene: Scene, executor: Any = None) -> Any:
    """The scene's ``[chart]``: regions and traced boundaries over two parameters (:func:`dfloop.chart.design_chart`),
    with the design point (each axis's ``nominal``, else the scene's value) and its limit-cycle margin."""
    from dfloop.chart import ChartAxis, design_chart

    from .parameters import nominal_value, parameter_label

    axes, nominal = [], []
    for spec in (scene.chart.x_axis, scene.chart.y_axis):
        label = parameter_label(scene.data, spec.parameter, spec.name, spec.unit)
        axes.append(ChartAxis(spec.start, spec.stop, label.name, label.unit, spec.scale,
                              label.gain and min(spec.start, spec.stop) > 0))
        value = spec.nominal if spec.nominal is not None else nominal_value(scene.data, spec.parameter)
        inside = value is not None and min(spec.start, spec.stop) <= value <= max(spec.start, spec.stop)
        nominal.append(value if inside else None)
    return design_chart(scene.chart_loop, axes[0], axes[1], nominal=None if None in nominal else tuple(nominal),
                        samples=scene.chart.samples, resolution=scene.chart.resolution, omega=scene.omega,
                        amplitude=scene.amplitude, exact=scene.chart.exact, executor=executor, progress=False)


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
    margins: list[Any] = field(default_factory=list)
    chart: Any = None
    biased: Any = None
    forced: Any = None
    autotune: Any = None

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
        if self.chart is not None:
            lines += ["## Design chart", "", "```", repr(self.chart), "```", ""]
        if self.sweep is not None or self.chart is not None:
            lines += ["## Limit-cycle margins", ""]
            if self.margins:
                for m in self.margins:
                    lines += ["```", repr(m), "```", ""]
            else:
                lines += ["No nominal value inside the swept range (set `nominal` in `[sweep]` / `[chart]`).", ""]
        if self.figure is not None:
            lines += ["## Figure", "", "```", repr(self.figure), "```", ""]
        if self.autotune is not None:
            lines += ["## Relay experiment and tuning", "", *self.autotune.to_markdown_lines(), ""]
        lines += _constant_input_and_forced_markdown(self)
        lines += ["## Stages run", "", "| stage | time (s) |", "|---|---|"]
        lines += [f"| {name} | {seconds:.3f} |" for name, seconds in self.stages]
        lines += [""] + [f"- {note}" for note in self.notes] if self.notes else []
        if self.files:
            lines += ["", "## Files", ""] + [f"- `{p.name}`" for p in self.files]
        return "\n".join(lines) + "\n"


def _constant_input_and_forced_markdown(report: SceneReport) -> list[str]:
    """The report's sections of a ``[loop]`` constant input (biased cycles) and of a ``[forced]`` stage."""
    lines = []
    if report.biased is not None:
        s = report.scene
        lines += ["## Biased limit cycles", "", f"Constant input: reference r0 = {s.reference:g}, load = {s.load:g}.",
                  "", "```", repr(report.biased), "```", ""]
    if report.forced is not None:
        response, exact, region = report.forced
        lines += ["## Forced response", "", "```", repr(response), "```", ""]
        if exact is not None:
            lines += ["### Exact orbits at the forcing period", "", "```", repr(exact), "```", ""]
        if region is not None:
            lines += ["### Jump-resonance region", "", "```", repr(region), "```", ""]
    return lines


def _save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def _motions_simulated() -> tuple[int, int]:
    """(table samples, motions simulated) for tables in this process so far ((0, 0) when no tabulated element
    was ever built)."""
    import sys

    module = sys.modules.get("dfloop.impact.dynamic_backlash")
    return (0, 0) if module is None else (module.table_samples(), module.motions_simulated())


def run_scene(scene: Scene, out_dir: str | Path = "out", log: Callable[[str], None] = print,
              progress: bool | None = None) -> SceneReport:
    """Run a scene's stages: predict cycles, verify them if asked, sweep if asked, draw the plots asked for,
    write a report.

    Parameters
    ----------
    scene : Scene
        From :func:`load_scene`.
    out_dir : str or Path
        Where the plots, the CSV of a sweep, ``<name>_report.md`` and ``<name>_report.html`` (one
        self-contained page: :func:`dfloop.scene.html.report_html`) go (created if needed).
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
    biased = predict and scene.biased     # a constant input: the cycles are biased (the symmetric solver's are not)
    predict, plots = predict and not biased, () if biased else plots
    planned = (predict + biased + len(plots) + (scene.sweep is not None) + (scene.chart is not None)
               + (figure is not None) + (scene.forced is not None))
    planned += scene.autotune is not None

    motions_before = _motions_simulated()
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
        if scene.verify and predict:
            from dfloop.verify import verify_cycle

            bar.set_total(planned + len(report.cycles))
            for cycle in report.cycles:
                report.verifications.append(stage(
                    f"verify cycle at w = {cycle.frequency:.4g} rad/s",
                    lambda c=cycle: verify_cycle(scene.plant, scene.element, c,
                                                 perturbation=scene.verify_perturbation)))
                log(repr(report.verifications[-1]))
        if biased:
            report.biased = stage("predict biased cycles", lambda: predict_biased(scene))
            log(repr(report.biased))
            if scene.verify:
                from dfloop.verify import verify_cycle

                bar.set_total(planned + len(report.biased))
                for cycle in report.biased:
                    report.verifications.append(stage(
                        f"verify biased cycle at w = {cycle.frequency:.4g} rad/s",
                        lambda c=cycle: verify_cycle(scene.plant, scene.element, c, r0=scene.reference,
                                                     load=scene.load, perturbation=scene.verify_perturbation)))
                    log(repr(report.verifications[-1]))
        if scene.forced is not None:
            report.forced = stage("forced response", lambda: run_forced(scene))
            for item in report.forced:
                if item is not None:
                    log(repr(item))
            response, exact, region = report.forced
            drawn = response.plot(exact=exact) if exact is not None else response.plot()
            drawn.axes[0, 0].set_title(f"{scene.title}: forced response, R = {response.R:g}", fontsize="medium")
            report.files.append(_save(drawn.figure, out / f"{scene.name}_forced.png"))
            if region is not None:
                report.files.append(_save(region.plot().figure, out / f"{scene.name}_region.png"))
        if scene.sweep is not None:
            from .parameters import parameter_label

            swept = parameter_label(scene.data, scene.sweep.parameter, scene.sweep.name, scene.sweep.unit).name
            report.sweep = stage(f"sweep {swept} over {len(scene.sweep_values)} values",
                                 lambda: run_sweep(scene))
            log(repr(report.sweep))
            margin = sweep_margin(scene, report.sweep)
            if margin is not None:
                report.margins.append(margin)
                log(repr(margin))
            if scene.sweep.csv:
                report.sweep.to_csv(out / f"{scene.name}_sweep.csv")
                report.files.append(out / f"{scene.name}_sweep.csv")
            report.files.append(_save(report.sweep.plot().figure, out / f"{scene.name}_sweep.png"))
        if scene.chart is not None:
            report.chart = stage("design chart", lambda: run_chart(scene))
            log(repr(report.chart))
            if report.chart.margin is not None:
                report.margins.append(report.chart.margin)
            if scene.chart.csv:
                report.chart.to_csv(out / f"{scene.name}_chart.csv")
                report.chart.regions_to_csv(out / f"{scene.name}_chart_regions.csv")
                report.files += [out / f"{scene.name}_chart.csv", out / f"{scene.name}_chart_regions.csv"]
            drawn = report.chart.plot()
            drawn.axes[0, 0].set_title(scene.title, fontsize="medium")
            report.files.append(_save(drawn.figure, out / f"{scene.name}_chart.png"))
        if scene.autotune is not None:
            from .autotune import run_autotune

            report.autotune = stage("relay experiment and tuning", lambda: run_autotune(scene))
            log(repr(report.autotune))
            if report.autotune.fit is not None:
                report.files.append(_save(report.autotune.fit.plot().figure, out / f"{scene.name}_relay_fit.png"))
        if figure is not None:
            report.figure = stage(f"figure ({figure.kind})", lambda: figure_data(scene))
            log(repr(report.figure))
            report.files.append(_save(report.figure.plot().figure, out / f"{scene.name}_figure.png"))
        if "nyquist" in plots:
            from dfloop.plot.nyquist import plot_nyquist

            def nyquist() -> Path:
                fig, ax = plt.subplots(figsize=(6.5, 5.5))
                plot_nyquist(report.cycles, ax)
                ax.set_title(scene.title)
                return _save(fig, out / f"{scene.name}_nyquist.png")

            report.files.append(stage("plot nyquist", nyquist))
        if "residual" in plots:
            from dfloop.plot.nyquist import plot_residual_map

            def residual() -> Path:
                fig, ax = plt.subplots(figsize=(6.5, 5.0))
                plot_residual_map(report.cycles, ax)
                return _save(fig, out / f"{scene.name}_residual.png")

            report.files.append(stage("plot residual map", residual))
    # counted after every stage (prediction, verification, sweep, figure: each may build tables, and a figure
    # builds one per curve family), so the note says what this run did, not what it had done so far
    samples, simulations = (now - before for now, before in zip(_motions_simulated(), motions_before))
    if hasattr(scene.element, "n_simulations") or simulations:
        report.notes.append(f"{type(scene.element).__name__}: {simulations} motions simulated in this run " + (
            "(tables served from the cache)" if simulations == 0 else
            f"for {samples} table samples (tables built and cached)"))
        log(f"[{scene.name}] {report.notes[-1]}")
    path = out / f"{scene.name}_report.md"
    path.write_text(report.to_markdown())
    report.files.append(path)
    from .html import write_report_html  # one self-contained page: tables and figures embedded

    report.files.append(write_report_html(report, out / f"{scene.name}_report.html"))
    log(f"[{scene.name}] report written to {path} and {report.files[-1].name}")
    return report
