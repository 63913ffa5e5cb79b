"""One self-contained HTML page per scene run: what a reader opens in a browser, offline, without a server.

The page holds the table of cycles (predicted, confidence, exact orbit, closed-loop verification side by side),
every figure of the run embedded as a base64 PNG (the Nyquist picture, the residual map, a sweep, a study
figure, and one time-response plot per verification), the settings the run used (windows, grid, analysis
options) and the time each stage took. No external file, script, font or style sheet is referenced.
"""
from __future__ import annotations

import base64
import html
import io
from pathlib import Path
from typing import Any

__all__ = ["report_html", "write_report_html"]

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0 auto; padding: 1em 1.5em;
       max-width: 1200px; color: #222; line-height: 1.4; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; } h2 { font-size: 1.2em; margin-top: 1.6em;
     border-bottom: 1px solid #ddd; }
.source { color: #666; font-size: 0.9em; overflow-wrap: anywhere; }
.scroll { overflow-x: auto; max-width: 100%; }
table { border-collapse: collapse; font-size: 0.88em; }
th, td { border: 1px solid #ccc; padding: 0.3em 0.5em; text-align: right; vertical-align: top; }
th { background: #f3f3f3; text-align: center; }
td.text { text-align: left; max-width: 22em; overflow-wrap: anywhere; }
tr.group th { background: #e6ecf5; }
.stable { color: #1a7f37; font-weight: 600; } .unstable { color: #b42318; font-weight: 600; }
.marginal, .inconclusive { color: #b26b00; font-weight: 600; }
figure { margin: 1em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption { color: #555; font-size: 0.9em; }
pre { background: #f7f7f7; padding: 0.6em; overflow-x: auto; font-size: 0.85em; white-space: pre-wrap;
      overflow-wrap: anywhere; }
"""


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _png(path_or_fig) -> str:
    """A data: URI of a PNG file, or of a matplotlib figure rendered now (then closed)."""
    if isinstance(path_or_fig, (str, Path)):
        data = Path(path_or_fig).read_bytes()
    else:
        import matplotlib.pyplot as plt

        buf = io.BytesIO()
        path_or_fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        plt.close(path_or_fig)
        data = buf.getvalue()
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _shown(path) -> str:
    """A scene's path as the reader typed it: relative to the working folder when inside it."""
    if path is None:
        return ""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _word(stability: str | None) -> str:
    return "-" if not stability else f'<span class="{_e(stability)}">{_e(stability)}</span>'


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:+.3g}\u00a0%"  # no break between number and %


def _verification_for(cycle, verifications):
    for v in verifications:
        if v.amplitude == cycle.amplitude and v.frequency == cycle.frequency:
            return v
    return None


def _settled(run, name: str = "A") -> str:
    return f"settles at {name}={run.amplitude:.4g}, ω={run.frequency:.4g}" if run.oscillating else "comes to rest"


def cycle_table(cycles, verifications=(), unit: str = "", name: str = "A") -> str:
    """The HTML table: one row per cycle, predicted | confidence | exact orbit | closed-loop verification.
    Amplitudes are named and measured as the element's input (``name`` [``unit``], e.g. X [m])."""
    u = f" [{_e(unit)}]" if unit else ""
    a = _e(name)
    head = ('<tr class="group"><th rowspan="2">#</th><th colspan="3">predicted (describing function)</th>'
            '<th colspan="3">confidence</th><th colspan="4">exact periodic orbit</th>'
            '<th colspan="3">closed-loop verification</th></tr>'
            f'<tr><th>{a}{u}</th><th>ω [rad/s]</th><th>Loeb stability</th>'
            f'<th>distortion</th><th>est. error {a}</th><th>est. error ω</th>'
            f'<th>{a}{u}</th><th>ω [rad/s]</th><th>Floquet stability (max |μ|)</th><th>DF error {a}, ω</th>'
            '<th>verdict</th><th>from inside</th><th>from outside</th></tr>')
    rows, footnotes = [], []
    for i, c in enumerate(cycles):
        conf = getattr(c, "confidence", None)
        if conf is not None and getattr(conf, "available", False):
            confidence = [f"{100 * conf.distortion:.3g}\u00a0%", _pct(conf.amplitude_error), _pct(conf.frequency_error)]
        else:
            confidence = ["unavailable", "-", "-"]
        ex = getattr(c, "exact", None)
        if ex is None:
            exact = ["-", "-", "not computed", "-"]
        elif not ex.success:
            verdict = c.verdict   # confirmed / artefact / not checked (dfloop.solve.verdict)
            footnotes.append(f"<li>cycle {i}: {_e(verdict.kind)}: {_e(verdict.detail)}</li>")
            exact = ["-", "-", f'<td class="text" title="{_e(ex.message)}">{_e(verdict.kind)} (note {len(footnotes)})'
                               '</td>', "-"]
        else:
            exact = [f"{ex.amplitude:.6g}", f"{ex.frequency:.6g}",
                     f"{_word('stable' if ex.stable else 'unstable')} ({ex.largest_multiplier:.3g})",
                     f"{_pct(ex.amplitude_error)}, {_pct(ex.frequency_error)}"]
        v = _verification_for(c, verifications)
        verified = ["not run", "-", "-"] if v is None else [_word(v.verdict), _settled(v.inside, a),
                                                                  _settled(v.outside, a)]
        cells = [str(i), f"{c.amplitude:.6g}", f"{c.frequency:.6g}", _word(c.stability), *confidence, *exact,
                 *verified]
        rows.append("<tr>" + "".join(x if x.startswith("<td") else f"<td>{x}</td>" for x in cells) + "</tr>")
    notes = f'<ol class="source">{"".join(footnotes)}</ol>' if footnotes else ""
    return f'<div class="scroll"><table id="cycles">{head}{"".join(rows)}</table></div>{notes}'


def _settings(report) -> str:
    scene, cycles = report.scene, report.cycles
    items = [("scene file", _shown(scene.source)), ("element", repr(scene.element)), ("plant", repr(scene.plant))]
    if cycles is not None:
        src = getattr(cycles, "window_source", {}) or {}
        items += [("amplitude window", f"[{cycles.amplitude_window[0]:.4g}, {cycles.amplitude_window[1]:.4g}] "
                                       f"({src.get('amplitude', '')})"),
                  ("frequency window", f"[{cycles.omega_window[0]:.4g}, {cycles.omega_window[1]:.4g}] rad/s "
                                       f"({src.get('omega', '')})"),
                  ("grid (amplitudes x frequencies)", " x ".join(str(n) for n in cycles.grid_shape)),
                  ("evaluations of 1 + G N", cycles.n_evaluations)]
    items += [("exact orbits", "yes" if scene.exact else "no"),
              ("closed-loop verification", f"yes, starts at (1 ∓ {scene.verify_perturbation:g}) A"
               if scene.verify else "no")]
    for key, value in (scene.data.get("analysis", {}) or {}).items():
        items.append((f"[analysis] {key}", value))
    rows = "".join(f'<tr><th>{_e(k)}</th><td class="text">{_e(v)}</td></tr>' for k, v in items)
    return f'<div class="scroll"><table id="settings">{rows}</table></div>'


def _timings(report) -> str:
    rows = "".join(f"<tr><td class=\"text\">{_e(name)}</td><td>{seconds:.3f}</td></tr>"
                   for name, seconds in report.stages)
    total = sum(s for _, s in report.stages)
    return (f'<div class="scroll"><table id="timings"><tr><th>stage</th><th>time [s]</th></tr>{rows}'
            f'<tr><th>total</th><th>{total:.3f}</th></tr></table></div>')


_CAPTIONS = {"nyquist": "Nyquist plane: G(jω), the -1/N locus and the predicted cycles (filled: stable, hollow: "
                        "unstable; star: the exact orbit at its frequency; red +: -1).",
             "residual": "Residual map: each cycle sits where Re(1 + GN) = 0 meets Im(1 + GN) = 0.",
             "sweep": "The cycles followed over the swept parameter.",
             "figure": "The scene's figure.",
             "forced": "Forced response: amplitude against the forcing frequency (solid: stable, dashed: unstable, "
                       "arrows: jumps; circles: exact orbits at the forcing period, filled when stable; crosses: no "
                       "orbit at the forcing period).",
             "region": "Jump-resonance region: the multi-valued band of the forced response against the forcing "
                       "amplitude.",
             "fit": "The recorded relay experiment against the fitted model's exact relay orbit."}


def report_html(report) -> str:
    """The page of a :class:`~dfloop.scene.run.SceneReport` (after :func:`~dfloop.scene.run.run_scene`)."""
    scene = report.scene
    unit = getattr(scene.element, "input_unit", "")
    parts = [f"<h1>{_e(scene.title)}</h1>",
             f'<p class="source">dfloop scene <code>{_e(scene.name)}</code> ({_e(_shown(scene.source))})</p>']
    if report.cycles is not None:
        n = len(report.cycles)
        parts += ["<h2>Limit cycles</h2>",
                  f"<p>{n} cycle{'s' if n != 1 else ''} predicted"
                  + (f"; {len(report.cycles.jump_crossings)} jump crossing(s) of N (not cycles)"
                     if getattr(report.cycles, "jump_crossings", None) else "") + ".</p>"]
        if n:
            parts.append(cycle_table(report.cycles, report.verifications, unit,
                                     getattr(scene.element, "input_name", "A") or "A"))
    figures = []
    for path in report.files:
        if path.suffix == ".png":
            kind = path.stem.rsplit("_", 1)[-1]
            figures.append((_png(path), _CAPTIONS.get(kind, path.name), path.name))
    for i, v in enumerate(report.verifications):
        cplt = v.plot(unit=unit, name=getattr(scene.element, "input_name", "A") or "A")
        figures.append((_png(cplt.figure), f"Closed-loop verification of the cycle at ω = {v.frequency:.4g} rad/s: "
                        f"x(t) from inside and outside, predicted (and exact) ±A as bands; {v.verdict}.",
                        f"verification {i}"))
    if figures:
        parts.append("<h2>Figures</h2>")
        parts += [f'<figure><img src="{src}" alt="{_e(alt)}"><figcaption>{_e(cap)}</figcaption></figure>'
                  for src, cap, alt in figures]
    if report.verifications:
        parts += ["<h2>Verification, in words</h2>",
                  "<pre>" + "\n".join(_e(f"ω = {v.frequency:.4g} rad/s: {v.verdict}; {v.message}; {v.method}")
                                      for v in report.verifications) + "</pre>"]
    if report.sweep is not None:
        parts += ["<h2>Sweep</h2>", f"<pre>{_e(repr(report.sweep))}</pre>"]
    if report.figure is not None:
        parts += ["<h2>Figure data</h2>", f"<pre>{_e(repr(report.figure))}</pre>"]
    if getattr(report, "biased", None) is not None:
        parts += ["<h2>Biased limit cycles</h2>", f"<pre>{_e(repr(report.biased))}</pre>"]
    if getattr(report, "forced", None) is not None:
        parts += ["<h2>Forced response</h2>",
                  f"<pre>{_e(chr(10).join(repr(x) for x in report.forced if x is not None))}</pre>"]
    if getattr(report, "autotune", None) is not None:
        parts += ["<h2>Relay experiment and tuning</h2>", f"<pre>{_e(repr(report.autotune))}</pre>"]
    parts += ["<h2>Settings</h2>", _settings(report), "<h2>Timings</h2>", _timings(report)]
    if report.notes:
        parts += ["<h2>Notes</h2>", "<ul>" + "".join(f"<li>{_e(n)}</li>" for n in report.notes) + "</ul>"]
    body = "\n".join(parts)
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{_e(scene.title)} - dfloop report</title><style>{_STYLE}</style></head>\n"
            f"<body>\n{body}\n</body></html>\n")


def write_report_html(report, path: str | Path) -> Path:
    """Write :func:`report_html` to ``path`` (UTF-8) and return the path."""
    path = Path(path)
    path.write_text(report_html(report), encoding="utf-8")
    return path
