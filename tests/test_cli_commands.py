"""The CLI's commands: list, scene-keys (and the reference page), cache info|clear, runs of several scenes."""
import ast
import sys
from pathlib import Path

import numpy as np
import pytest

from dfloop.cli import main
from dfloop.scene import find_scene, scene_reference, shipped_scenes
from dfloop.scene.elements import registry
from dfloop.scene.load import TableProgress, read_toml
from dfloop.scene.schema import PLANT_TYPES, SceneFile, Sweep, SweepRange

ROOT = Path(__file__).resolve().parents[1]
QUICK = "[plant]\nnum = [10.0]\nden = [1.0, 3.0, 2.0, 0.0]\n[element]\ntype = 'Saturation'\nlimit = 1.0\n" \
        "[analysis]\nomega = [0.5, 5.0]\nplots = []\n"


def test_list_shows_every_shipped_scene_with_its_title(capsys):
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    files = sorted((ROOT / "models").glob("*.toml"))
    assert [line.split()[0] for line in lines] == [p.stem for p in files]
    for line, path in zip(lines, files):
        assert line.endswith(read_toml(path)["scene"]["title"])


def test_shipped_scenes_are_found_by_name_and_by_file_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no models/ here
    assert find_scene("backlash_servo") == ROOT / "models" / "backlash_servo.toml"
    assert find_scene("backlash_servo.toml") == ROOT / "models" / "backlash_servo.toml"
    (tmp_path / "backlash_servo.toml").write_text(QUICK)  # a file of the user's own wins over the shipped one
    assert find_scene("backlash_servo.toml") == Path("backlash_servo.toml")
    with pytest.raises(ValueError, match="not found") as info:
        find_scene("backlash_sevro")
    assert info.value.problems[0].suggestion == "backlash_servo"


def test_scene_keys_prints_the_committed_reference_page(capsys):
    assert main(["scene-keys"]) == 0
    printed = capsys.readouterr().out
    committed = (ROOT / "docs" / "scenes.md").read_text()
    assert printed == scene_reference() == committed, \
        "docs/scenes.md is out of date: python -m dfloop.scene --reference > docs/scenes.md"


def test_reference_lists_every_section_key_and_type():
    page = scene_reference()
    models = [Sweep, SweepRange, *PLANT_TYPES.values()]
    models += [f.annotation for f in SceneFile.model_fields.values() if hasattr(f.annotation, "model_fields")]
    for model in models:
        for key in model.model_fields:
            if key != "type":  # a plant's type heads its table
                assert f"| `{key}` |" in page, (model.__name__, key)
    for tag in PLANT_TYPES:
        assert f'`type = "{tag}"`' in page
    for section in SceneFile.model_fields:
        assert f"## `[{section}]`" in page
    for name in registry():
        assert f"### `{name}`" in page
    for name in shipped_scenes():
        assert f"| `{name}` |" in page


def test_run_reports_every_bad_file_and_runs_the_good_ones(tmp_path, capsys):
    good = tmp_path / "good.toml"
    good.write_text(QUICK)
    typo = tmp_path / "typo.toml"
    typo.write_text(QUICK.replace("[analysis]", "[analysys]"))
    broken = tmp_path / "broken.toml"
    broken.write_text(QUICK.replace("den = [1.0, 3.0, 2.0, 0.0]", "den = [1.0, 3.0, 2.0, 0.0"))
    code = main(["run", str(typo), str(good), str(broken), "nonexistent", "--out", str(tmp_path / "out"),
                 "--quiet"])
    captured = capsys.readouterr()
    assert code == 1
    assert captured.out == ""
    err = captured.err
    assert f"{typo}: analysys: unknown section (did you mean 'analysis'?" in err
    assert f"{broken}: invalid TOML" in err and "line 4" in err
    assert "nonexistent" in err and "3 of 4 scenes failed" in err
    report = (tmp_path / "out" / "good_report.md").read_text()
    # the good scene ran: saturation (N real) around 10/(s(s+1)(s+2)) cycles at the phase crossover w = sqrt(2)
    assert "1 limit cycle(s)" in report and f"{np.sqrt(2):.6g}" in report


def test_run_turns_progress_on_and_quiet_turns_it_off(tmp_path, monkeypatch, capsys):
    import dfloop.progress

    calls = []
    real = dfloop.progress.progress_bar

    def spy(label, total=None, **kwargs):
        calls.append((label, kwargs.get("enabled")))
        return real(label, total, **kwargs)

    monkeypatch.setattr(dfloop.progress, "progress_bar", spy)
    scene = tmp_path / "quick.toml"
    scene.write_text(QUICK)
    assert main(["run", str(scene), "--out", str(tmp_path)]) == 0
    assert calls == [("quick", True)] and "[quick] predict limit cycles" in capsys.readouterr().out
    calls.clear()
    assert main(["run", str(scene), "--out", str(tmp_path), "--quiet"]) == 0
    assert calls == [("quick", False)] and capsys.readouterr().out == ""


def test_table_progress_feeds_plain_lines_without_carriage_returns(monkeypatch, capsys):
    monkeypatch.setenv("DFLOOP_PROGRESS", "1")
    import dfloop.progress

    real = dfloop.progress.progress_bar
    monkeypatch.setattr(dfloop.progress, "progress_bar",
                        lambda label, total=None, **kw: real(label, total, **{**kw, "delay": 0.0}))
    progress = TableProgress("DynamicBacklash table")
    for n, stage in [(10, "base grid"), (25, "refine 1"), (31, "done")]:
        progress(n, stage)
    err = capsys.readouterr().err
    assert "\r" not in err
    assert err.splitlines()[0].startswith("DynamicBacklash table: 10 (base grid)")
    assert err.splitlines()[-1].startswith("DynamicBacklash table: 31 (done)") and err.endswith("done\n")


def test_cli_module_imports_only_the_standard_library():
    """`dfloop --help` must not pay for numpy, control, matplotlib, pydantic: cli.py imports them lazily."""
    tree = ast.parse((ROOT / "dfloop" / "cli.py").read_text())
    top = {alias.name.split(".")[0] for node in tree.body if isinstance(node, ast.Import) for alias in node.names}
    top |= {node.module.split(".")[0] for node in tree.body if isinstance(node, ast.ImportFrom) and node.level == 0}
    assert top <= set(sys.stdlib_module_names) | {"__future__"}, top


# ------------------------------------------------------------------------------------------------- cache
@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A cache with 2 files of the current code version, 3 of an old one, a truncated file and a stray .tmp."""
    import dfloop.tables.cache as c

    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "cache"))
    arrays = {"x": np.arange(50.0)}
    current = [c.save_table(c.cache_dir() / f"cur{i}.npz", arrays, f"k{i}", {"i": i}, {}) for i in range(2)]
    with monkeypatch.context() as m:
        m.setattr(c, "code_version", lambda: "0.0.1+old")
        old = [c.save_table(c.cache_dir() / f"old{i}.npz", {"x": np.arange(100.0 * (i + 1))}, f"o{i}", {}, {})
               for i in range(3)]
    truncated = c.cache_dir() / "truncated.npz"
    truncated.write_bytes(current[0].read_bytes()[:200])
    stray = c.cache_dir() / "abc.tmp"
    stray.write_bytes(b"partial")
    (c.cache_dir() / "notes.txt").write_text("not dfloop's")
    return c, current, old, [truncated, stray]


def test_cache_info_counts_files_and_bytes_per_code_version(cache, capsys):
    from dfloop.cache_admin import cache_info

    c, current, old, unreadable = cache
    info = cache_info()
    size = lambda paths: sum(p.stat().st_size for p in paths)  # noqa: E731
    assert info.by_version() == {c.code_version(): (2, size(current)), "0.0.1+old": (3, size(old)),
                                 "unreadable": (2, size(unreadable))}
    assert main(["cache", "info"]) == 0
    out = capsys.readouterr().out
    assert f"{c.code_version()} (current): 2 files" in out and "0.0.1+old (stale): 3 files" in out


def test_cache_clear_stale_keeps_current_tables_readable(cache, capsys, monkeypatch):
    import dfloop.cache_admin as admin

    c, current, old, unreadable = cache
    monkeypatch.setattr(admin, "WRITE_GRACE", -1.0)  # the stray .tmp counts as abandoned
    assert main(["cache", "clear", "--stale", "--yes"]) == 0
    assert "removed 5 stale files" in capsys.readouterr().out
    assert all(p.exists() for p in current) and not any(p.exists() for p in old + unreadable)
    assert c.load_table(current[1], "k1").arrays["x"].tolist() == list(range(50))
    assert (c.cache_dir() / "notes.txt").exists()
    assert main(["cache", "clear", "--yes"]) == 0
    assert not any(p.exists() for p in current) and (c.cache_dir() / "notes.txt").exists()
    assert admin.cache_info().files == []


def test_cache_clear_stale_spares_a_write_in_progress(cache):
    from dfloop.cache_admin import clear_cache

    c, current, old, (truncated, stray) = cache
    removed = {f.path for f in clear_cache(stale=True)}
    assert removed == set(old) | {truncated} and stray.exists()


def test_cli_loading_gives_table_builds_a_progress_bar_unless_the_scene_sets_one(tmp_path):
    from dfloop.scene import load_scene

    assert isinstance(load_scene("dynamic_backlash_pd", progress=True).element.store.progress, TableProgress)
    assert load_scene("dynamic_backlash_pd").element.store.progress is False  # quiet unless asked (--quiet)
    own = tmp_path / "own.toml"
    own.write_text((ROOT / "models" / "dynamic_backlash_pd.toml").read_text().replace(
        "restitution = 0.5", "restitution = 0.5\nprogress = false"))
    assert load_scene(own, progress=True).element.store.progress is False
    assert load_scene("backlash_servo", progress=True).element.h == 1.0  # no progress parameter: nothing added


def test_warmup_leaves_every_compiled_kernel_ready(capsys, monkeypatch):
    """`dfloop warmup` runs each compiling entry point once and says so; afterwards a prediction announces no
    compile (its kernels are compiled in this process or cached on disk). Run as a user runs it: the default
    DFLOOP_COMPILED, not the suite's "driver"."""
    import control as ct

    import dfloop as df

    monkeypatch.setenv("DFLOOP_COMPILED", "1")
    assert main(["warmup"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in out] == ["solver kernels (predict_limit_cycles)",
                                                   "exact engines (exact_cycle)", "simulation (verify_cycle)",
                                                   "impact kernels (DynamicBacklash tables)"]
    assert all(line.endswith(" s") and "ready in" in line for line in out)
    # every kernel of the compiled path is loaded in this process, the driver's helpers for the Python driver
    # too (they are used only once the driver is ready: warmup must compile them itself, or a single call on a
    # fresh installation would keep taking the Python driver)
    from dfloop.solve.compiled.residual import _kernels

    assert all(d.signatures for d in _kernels())
    assert len(df.predict_limit_cycles(ct.tf([5], [1, 1, 0]), df.Saturation(1.0))) >= 0
    err = capsys.readouterr().err
    assert "compiling" not in err and "not compiled" not in err
