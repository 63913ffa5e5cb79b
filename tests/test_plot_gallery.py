"""Every plot function, rendered on representative results, read back from the drawn figure as a person would:
no two text labels overlap, every legend entry is distinct and shows something inside its axes, and every axis
label carries its unit in brackets.

The checks use the rendered artists (renderer bounding boxes after ``canvas.draw()``), not the code's intent.
"""
import re
import warnings

import control as ct
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

import dfloop as df  # noqa: E402
from dfloop.describing.composition import MassBacklash  # noqa: E402
from dfloop.impact.kernel import simulate  # noqa: E402
from dfloop.plot.impact import plot_collision_map, plot_time_response  # noqa: E402
from dfloop.plot.loci import plot_loci  # noqa: E402
from dfloop.plot.nyquist import plot_nyquist, plot_residual_map  # noqa: E402
from dfloop.plot.study import plot_element_study  # noqa: E402
from dfloop.scene.figure import Curve, FigureData  # noqa: E402

UNIT = re.compile(r"\[[^\[\]]+\]")


def RELAY_DELAY(w):  # exp(-0.5 s) / (s + 1): a relay predicts five cycles that crowd the origin
    return np.exp(-0.5j * w) / (1j * w + 1)


@pytest.fixture(scope="module")
def servo():
    """The main study: 5/(s(s+1)) with backlash h = 1, two cycles, the stable one with its exact orbit."""
    return df.predict_limit_cycles(ct.tf([5.0], [1.0, 1.0, 0.0]), df.Backlash(1.0), exact=True)


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _texts(fig, renderer):
    """(text, box) of every drawn, non-empty text of the figure: titles, axis labels, tick labels of the ticks
    inside the view, annotations, legend entries and titles, colour-bar labels."""
    tick_texts, shown_ticks = set(), []
    for ax in fig.axes + [c for a in fig.axes for c in a.child_axes]:  # insets are child axes
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                labels = (tick.label1, tick.label2)
                tick_texts.update(id(t) for t in labels)
                inside = lo - 1e-9 * abs(hi - lo) <= tick.get_loc() <= hi + 1e-9 * abs(hi - lo)
                shown_ticks += [t for t in labels if inside and t.get_visible()]
    others = [t for t in fig.findobj(matplotlib.text.Text) if id(t) not in tick_texts and t.get_visible()]
    out = []
    for t in others + shown_ticks:
        if t.get_text().strip():
            box = matplotlib.text.Text.get_window_extent(t, renderer)
            if box.width > 0 and box.height > 0:
                out.append((t, box))
    return out


def check_figure(fig, name):
    """The three facts a reader checks, asserted on the rendered figure."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = _texts(fig, renderer)
    for i, (ti, bi) in enumerate(texts):
        for tj, bj in texts[:i]:
            ov_w = min(bi.x1, bj.x1) - max(bi.x0, bj.x0)
            ov_h = min(bi.y1, bj.y1) - max(bi.y0, bj.y0)
            assert not (ov_w > 0.5 and ov_h > 0.5), \
                f"{name}: {ti.get_text()!r} overlaps {tj.get_text()!r} ({ov_w:.1f} x {ov_h:.1f} px)"
    every = fig.axes + [c for a in fig.axes for c in a.child_axes]
    legends = [a.get_legend() for a in every if a.get_legend() is not None]
    for leg in legends:
        ax = leg.axes
        labels = [t.get_text() for t in leg.get_texts()]
        assert len(labels) == len(set(labels)), f"{name}: repeated legend entries {labels}"
        (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
        handles = dict(zip(*ax.get_legend_handles_labels()[::-1]))
        for label in labels:
            h = handles.get(label)
            if isinstance(h, Line2D):
                x, y = (np.asarray(v, dtype=float) for v in h.get_data())
                x, y = np.broadcast_arrays(x, y)
                shown = np.isfinite(x) & np.isfinite(y) & (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
                assert shown.any(), f"{name}: legend entry {label!r} has nothing inside the axes"
    for ax in fig.axes:
        if ax in [c for a in fig.axes for c in a.child_axes]:
            continue  # a zoomed inset repeats its parent's axes
        for lab in (ax.get_xlabel(), ax.get_ylabel()):
            if lab:
                assert UNIT.search(lab), f"{name}: axis label {lab!r} has no [unit]"
        if ax.lines:  # a data axis whose numbers are shown says what they are
            for axis, lab in ((ax.xaxis, ax.get_xlabel()), (ax.yaxis, ax.get_ylabel())):
                numbered = any(t.get_visible() and t.get_text() for t in axis.get_ticklabels())
                assert lab or not numbered, f"{name}: an axis with numbers and no label"
    return texts


def test_nyquist_pictures(servo):
    figs = {"backlash servo": plot_nyquist(servo).figure}
    relay = df.predict_limit_cycles(RELAY_DELAY, df.Relay(1.0), omega=(0.1, 60.0))
    cplt = plot_nyquist(relay)
    figs["relay with delay"] = cplt.figure
    for name, fig in figs.items():
        check_figure(fig, name)
    # crowded cycles get a zoomed inset, and every cycle is named once somewhere
    ax = cplt.axes[0, 0]
    assert len(ax.child_axes) == 1
    text = "\n".join(t.get_text() for a in [ax, *ax.child_axes] for t in a.texts)
    for c in relay:
        assert text.count(f"A={c.amplitude:.3g}, ω={c.frequency:.3g} rad/s") == 1
    # a cycle listed beside the plot (crowded) is marked on it by its number, at its own marker
    listed = re.findall(r"^#(\d+): ", text, re.M)
    tags = {t.get_text(): t for a in [ax, *ax.child_axes] for t in a.texts if re.fullmatch(r"#\d+", t.get_text())}
    assert set(tags) == {f"#{k}" for k in listed}
    for k in listed:
        c = relay[int(k)]
        assert complex(*tags[f"#{k}"].xy) == pytest.approx(c.G)
    # the backlash servo's legend explains filled, hollow, the star and -1
    labels = [t.get_text() for t in figs["backlash servo"].axes[0].get_legend().get_texts()]
    assert {"stable cycle (filled)", "unstable cycle (hollow)", "-1 (critical point)"} <= set(labels)
    assert any("exact orbit" in lab for lab in labels)


def test_frequency_dependent_family_and_residual_map(servo):
    G = ct.tf([2.0], [1.0, 2.0, 2.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = df.predict_limit_cycles(G, MassBacklash(1.0, 1.0, 0.1), omega=(0.5, 6.0), amplitude=(0.5, 20.0))
    cplt = plot_nyquist(cycles, n_loci=5)
    check_figure(cplt.figure, "mass backlash family")
    colors = {matplotlib.colors.to_hex(line.get_color()) for line in cplt.lines[1]}
    assert len(colors) == len(cplt.lines[1])  # one colour per locus of the family
    check_figure(plot_residual_map(servo, shape=(30, 30)).figure, "residual map")
    check_figure(plot_loci(df.Backlash(0.2)).figure, "loci")
    check_figure(plot_loci(MassBacklash(1.0, 1.0, 0.1), amplitudes=[10, 30, 50], omega=np.linspace(0.5, 20, 200))
                 .figure, "loci family")


def test_time_domain_pictures(servo):
    stable = next(c for c in servo if c.stable)
    check_figure(stable.exact.plot(unit="m").figure, "exact orbit")
    v = df.verify_cycle(ct.tf([5.0], [1.0, 1.0, 0.0]), df.Backlash(1.0), stable, periods=25, steps_per_period=80,
                        measure_periods=5)
    check_figure(v.plot(unit="m").figure, "verification")
    traj = simulate(1.0, 1.0, 0.1, 0.5, 50.0, 25.0, 1.0)
    check_figure(plot_time_response(traj, "v1").figure, "time response")


def test_sweep_and_collision_map():
    G0 = ct.tf([1.0], [1.0, 3.0, 2.0, 0.0])
    res = df.sweep(lambda K: (K * G0, df.Backlash(0.2)), np.linspace(4.0, 6.0, 3), parameter="K", unit="-",
                   progress=False)
    check_figure(res.plot().figure, "sweep")
    w = np.geomspace(5.0, 45.0, 40)
    rng = np.random.default_rng(0)
    runs = rng.integers(1, 40, size=(9, w.size))
    regular = rng.random((9, w.size)) > 0.2
    cplt = plot_collision_map(w, runs, regular, [f"{e:.1f}" for e in np.linspace(0.1, 0.9, 9)],
                              legend_title="eps")
    check_figure(cplt.figure, "collision map")
    ax = cplt.axes[0, 0]
    styles = {(matplotlib.colors.to_hex(line.get_color()), line.get_marker()) for line in cplt.lines[0]}
    assert len(styles) == 9  # nine cases, nine distinguishable styles
    ax.figure.canvas.draw()
    ticks = [t.get_text() for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
    assert ticks and all(re.fullmatch(r"[0-9.]+", t.replace("\u2212", "-")) for t in ticks), ticks  # plain numbers


def test_forced_response():
    from dfloop.solve.forced import forced_response

    res = forced_response(ct.tf([1.0], [1.0, 0.2, 1.0]), df.CubicStiffness(1.0, 0.5), 0.3, np.linspace(0.5, 3.0, 61),
                          amplitude=(1e-3, 20.0))
    cplt = res.plot()
    check_figure(cplt.figure, "forced response")
    assert len(cplt.lines[1]) == 2  # one arrow per jump
    styles = {line.get_linestyle() for line in cplt.lines[0] if line.get_label() in ("stable", "unstable")}
    assert styles == {"-", "--"}


def test_jump_region_and_exact_forced_points():
    from dfloop.hybrid.forced import exact_forced_response
    from dfloop.solve.forced import forced_response, jump_region

    G, N = ct.tf([1.0], [1.0, 0.2, 1.0]), df.CubicStiffness(1.0, 0.5)
    res = forced_response(G, N, 0.3, [1.5, 1.8, 2.1], amplitude=(1e-3, 20.0))
    cplt = exact_forced_response(G, N, res, observe=False).plot()
    check_figure(cplt.figure, "forced response with exact points")
    labels = {line.get_label() for line in cplt.lines[2]}
    assert labels == {"exact, stable", "exact, unstable"}
    region = jump_region(G, N, [0.05, 0.1, 0.2, 0.3], np.linspace(0.5, 3.0, 26), amplitude=(1e-3, 20.0))
    cplt = region.plot()
    check_figure(cplt.figure, "jump region")
    assert len(cplt.lines[1]) == 1 and {line.get_label() for line in cplt.lines[0]} == {"jump sweeping up",
                                                                                         "jump sweeping down"}


def _chart_loop(K, h):
    return K * ct.tf([1.0], [1.0, 3.0, 2.0, 0.0]), df.Backlash(h)


def test_design_chart():
    from dfloop.chart import ChartAxis, design_chart

    res = design_chart(_chart_loop, ChartAxis(2.5, 5.5, "gain K"), ChartAxis(0.1, 0.5, "clearance h", "m"),
                       nominal=(3.0, 0.3), samples=3, resolution=12, omega=(0.01, 100.0), progress=False)
    check_figure(res.plot().figure, "design chart")


def _study(kind):
    """A FigureData of every kind with the shape of the paper's figures (nine restitutions, F = 50 N)."""
    w = np.geomspace(5.0, 45.0, 60)
    curves = []
    for k, eps in enumerate(np.linspace(0.1, 0.9, 9)):
        if kind == "collisions":
            y, x = np.full(w.size, 10.0 + k), w
        elif kind == "time_response":  # the motion itself, as the scene keeps it
            traj = simulate(1.0, 1.0, 0.1, float(eps), 50.0, 25.0, 1.0) if k < 3 else None
            x = np.linspace(0.5, 1.0, 200)
            y = traj.evaluate(x)["v1"] if traj is not None else x
        else:
            x = w
            y = -(50.0 / (0.1 * (1 + eps))) * np.exp(-1j * (w / 45.0 + 0.1 * k))
        curves.append(Curve(50.0, float(eps), x, y, np.arange(x.size) % 7 != 0,
                            omega=25.0 if kind == "time_response" else None,
                            note="period 1" if kind == "time_response" else "",
                            trajectory=traj if kind == "time_response" else None))
    if kind == "time_response":
        curves = curves[:3]
    return FigureData(kind, "Paper Fig. N: dynamic backlash, F = 50 N", "element.restitution", curves, "F", "N")


@pytest.mark.parametrize("kind", ["nyquist", "loglog", "time_response", "collisions"])
def test_scene_figure_study(kind):
    data = _study(kind)
    cplt = plot_element_study(data)
    check_figure(cplt.figure, kind)
    legend = next((a.get_legend() for a in cplt.figure.axes if a.get_legend() is not None), None)
    if kind == "time_response":  # drawn from the trajectory: the velocity's jumps at impacts are gaps, not lines
        for line, curve in zip(cplt.lines[0], data.curves):
            t = line.get_xdata()
            assert np.count_nonzero(np.isnan(t)) == np.count_nonzero((curve.trajectory.t0 > t[0]) &
                                                                     (curve.trajectory.t0 < np.nanmax(t)))
    if legend is not None:  # what every curve shares is said once, not on every entry: the varying quantity
        entries = [t.get_text() for t in legend.get_texts()]  # names the legend, its values are the entries
        assert not any("50 N" in t for t in entries)
        assert legend.get_title().get_text() == "restitution"
        assert entries == [f"{e:g}" for e in np.linspace(0.1, 0.9, 9)]


def test_relay_fit():
    from dfloop.autotune.fit import fit_relay_record
    from dfloop.autotune.models import ProcessModel
    from dfloop.autotune.synthetic import synthetic_record

    rec = synthetic_record(ProcessModel(2.0, (3.0,), 1.0), high=1.2, low=-0.8, hysteresis=0.05, cycles=5, noise=0.02)
    cplt = fit_relay_record(rec).plot()
    check_figure(cplt.figure, "relay fit")
    assert [len(g) for g in cplt.lines] == [1, 1, 2]


# every public plot function of dfloop.plot and where the gallery renders it (a new one must be added here)
GALLERY = {"plot_nyquist": test_nyquist_pictures, "plot_residual_map": test_frequency_dependent_family_and_residual_map,
           "plot_loci": test_frequency_dependent_family_and_residual_map, "plot_exact_cycle": test_time_domain_pictures,
           "plot_verification": test_time_domain_pictures, "plot_time_response": test_time_domain_pictures,
           "plot_sweep": test_sweep_and_collision_map, "plot_collision_map": test_sweep_and_collision_map,
           "plot_element_study": test_scene_figure_study, "plot_chart": test_design_chart,
           "plot_forced_response": test_forced_response, "plot_jump_region": test_jump_region_and_exact_forced_points,
           "plot_relay_fit": test_relay_fit}


def test_the_gallery_covers_every_plot_function():
    import importlib
    import pkgutil

    import dfloop.plot

    found = set()
    for info in pkgutil.iter_modules(dfloop.plot.__path__):
        module = importlib.import_module(f"dfloop.plot.{info.name}")
        found |= {n for n in getattr(module, "__all__", ()) if n.startswith("plot_")}
    assert found == set(GALLERY), f"not in the gallery: {found - set(GALLERY)}"
