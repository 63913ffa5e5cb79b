"""Disk cache: round trip, key and checksum checks, atomic writes, directory selection."""
import warnings

import numpy as np
import pytest

from dfloop.errors import CacheWarning
from dfloop.tables import cache


@pytest.fixture
def arrays():
    return {"x": np.linspace(0, 1, 11), "value": np.exp(1j * np.arange(11.0)), "flag": np.arange(11) % 2 == 0}


def test_round_trip(tmp_path, arrays):
    key = cache.cache_key({"a": 1.0, "b": [1, 2]})
    p = cache.save_table(tmp_path / "sub" / "t.npz", arrays, key, {"a": 1.0}, {"tol": 1e-4})
    f = cache.load_table(p, key)
    for k, v in arrays.items():
        np.testing.assert_array_equal(f.arrays[k], v)
        assert f.arrays[k].dtype == v.dtype
    assert f.meta["params"] == {"a": 1.0} and f.meta["settings"] == {"tol": 1e-4}
    assert f.meta["code_version"] == cache.code_version()
    assert not list((tmp_path / "sub").glob("*.tmp"))


def test_key_depends_on_every_parameter_and_code(monkeypatch):
    k = cache.cache_key({"a": 1.0, "b": 2.0})
    assert k == cache.cache_key({"b": 2.0, "a": 1.0})
    assert k != cache.cache_key({"a": 1.0, "b": 2.0000000001})
    monkeypatch.setattr(cache, "code_version", lambda: "0.0+other")
    assert k != cache.cache_key({"a": 1.0, "b": 2.0})


def test_wrong_key_missing_and_corrupted_files_are_misses(tmp_path, arrays):
    key = cache.cache_key({"a": 1})
    p = cache.save_table(tmp_path / "t.npz", arrays, key, {}, {})
    with pytest.warns(CacheWarning, match="stale"):
        assert cache.load_table(p, cache.cache_key({"a": 2})) is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # a missing file is a plain miss: no warning
        assert cache.load_table(tmp_path / "missing.npz", key) is None
        assert cache.load_table(tmp_path / "no" / "dir" / "t.npz", key) is None
    good = p.read_bytes()
    for pos in (len(good) // 3, len(good) // 2, len(good) - 30):
        bad = bytearray(good)
        bad[pos] ^= 0x5A
        p.write_bytes(bytes(bad))
        with pytest.warns(CacheWarning, match="corrupted"):
            assert cache.load_table(p, key) is None
    p.write_bytes(good[: len(good) // 2])             # truncated
    with pytest.warns(CacheWarning, match="corrupted"):
        assert cache.load_table(p, key) is None
    p.write_bytes(b"not a zip file")
    with pytest.warns(CacheWarning, match="corrupted"):
        assert cache.load_table(p, key) is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert cache.load_table(p, key, on_error="ignore") is None


def test_tampered_array_with_valid_zip_is_rejected(tmp_path, arrays):
    key = cache.cache_key({"a": 1})
    p = cache.save_table(tmp_path / "t.npz", arrays, key, {}, {})
    with np.load(p) as z:
        payload = {k: z[k] for k in z.files}
    payload["a.x"] = payload["a.x"] + 1e-15         # well-formed file, wrong content
    np.savez(p, **payload)
    with pytest.warns(CacheWarning, match="checksum mismatch"):
        assert cache.load_table(p, key) is None


def test_cache_dir_from_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("DFLOOP_CACHE_DIR", str(tmp_path / "c"))
    assert cache.cache_dir() == tmp_path / "c"
    monkeypatch.delenv("DFLOOP_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "xdg" / "dfloop"


@pytest.mark.parametrize("value", ["", "  "])
def test_empty_cache_dir_is_refused_by_the_table_code_too(monkeypatch, value):
    """DFLOOP_CACHE_DIR set but blank is one rule everywhere: refused with its name (the CLI and cache admin
    refuse it too), never silently the default directory."""
    from dfloop.cache_admin import cache_info
    from dfloop.tables.store import TableStore

    monkeypatch.setenv("DFLOOP_CACHE_DIR", value)
    with pytest.raises(ValueError, match="DFLOOP_CACHE_DIR is set but empty"):
        cache.cache_dir()
    store = TableStore("probe", lambda: {"x": 1}, lambda arrays: None)
    with pytest.raises(ValueError, match="DFLOOP_CACHE_DIR is set but empty"):
        store.load_cached()
    with pytest.raises(ValueError, match="DFLOOP_CACHE_DIR is set but empty"):
        cache_info()


def test_code_version_covers_every_module_the_tables_run():
    """The cache key hashes the sources that decide a table's content: every module of dfloop.impact and
    dfloop.tables that dynamic_backlash.py imports, directly or through another one (relative imports of any
    level, inside functions too), must be among them (a change there must invalidate cached tables)."""
    import ast
    from pathlib import Path

    from dfloop.tables import cache

    root = Path(cache.__file__).parent.parent            # the dfloop package
    seen, todo = set(), ["impact/dynamic_backlash.py"]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        package = Path(name).parent
        for node in ast.walk(ast.parse((root / name).read_text())):
            if not (isinstance(node, ast.ImportFrom) and node.level >= 1):
                continue
            base = package
            for _ in range(node.level - 1):
                base = base.parent
            stems = ([base / Path(*node.module.split("."))] if node.module else []) + \
                    [base / Path(*(node.module.split(".") if node.module else [])) / a.name for a in node.names]
            for stem in stems:
                for candidate in (stem.with_suffix(".py"), stem / "__init__.py"):
                    if (root / candidate).is_file() and candidate.parts[0] in ("impact", "tables"):
                        todo.append(candidate.as_posix())
    seen = {n for n in seen if not n.endswith("__init__.py")}
    assert {"tables/table1d.py", "tables/store.py", "impact/kernel.py"} <= seen      # the walk reaches them
    assert seen <= set(cache.SOURCES), sorted(seen - set(cache.SOURCES))
