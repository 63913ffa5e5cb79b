"""The package's layers run one way (docs/design.md, section 4): read from the source, imports inside functions too.

Every module belongs to one layer; an import may reach its own layer or a lower one, never a higher one, and no
module imports another module's private name (``_x`` from a module whose own name is not private). One exception,
by design: a result's ``.plot()`` delegates to :mod:`dfloop.plot` through an import inside the method (it defers
matplotlib, and the plotting layer stays the only one that draws).
"""
import ast
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "dfloop"

# lowest first; a module belongs to the layer of its longest matching prefix (docs/design.md has the picture)
LAYERS = (
    ("foundation", ("dfloop", "dfloop.errors", "dfloop._checks", "dfloop._blas", "dfloop.progress",
                    "dfloop.harmonics")),
    ("elements", ("dfloop.describing",)),
    ("tables", ("dfloop.tables",)),
    ("impact", ("dfloop.impact",)),
    ("solve", ("dfloop.solve",)),
    ("exact", ("dfloop.hybrid", "dfloop.exact", "dfloop.verify", "dfloop.biased")),
    ("many", ("dfloop.continuation", "dfloop.batch", "dfloop.chart", "dfloop.autotune")),
    ("plot", ("dfloop.plot",)),
    ("application", ("dfloop.scene", "dfloop.cli", "dfloop.cache_admin")),
)

# the one upward import left, by design: predict_limit_cycles(..., exact=True) attaches each cycle's exact orbit,
# imported inside that branch (the solver itself never needs the engine)
KNOWN_UPWARD = {("dfloop.solve.predict", "dfloop.exact")}
KNOWN_PRIVATE: set = set()


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports():
    """(importer, imported module, imported name) for every import of the package's own modules."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    out = []
    for mod, path in modules.items():
        package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        tree = ast.parse(path.read_text(encoding="utf-8"))
        nested = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                  for n in ast.walk(f)}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                for alias in node.names:
                    target = f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                    if target in modules and target != mod:
                        out.append((mod, target, alias.name, id(node) in nested))
            elif isinstance(node, ast.Import):
                out += [(mod, a.name, "", id(node) in nested) for a in node.names if a.name in modules and a.name != mod]
    return modules, out


def _layer(module: str) -> int:
    best = max(((len(p), i) for i, (_, prefixes) in enumerate(LAYERS) for p in prefixes
                if module == p or module.startswith(p + ".")), default=None)
    if best is None:
        pytest.fail(f"{module} is in no layer: add it to LAYERS (and to the picture in docs/design.md)")
    return best[1]


def test_every_module_has_a_layer_and_imports_run_downward():
    modules, edges = _imports()
    for m in modules:
        _layer(m)
    plot = next(i for i, (name, _) in enumerate(LAYERS) if name == "plot")
    upward = {(a, b) for a, b, _, deferred in edges if b != "dfloop" and _layer(b) > _layer(a)
              and not (deferred and _layer(b) == plot)}
    new = sorted(upward - KNOWN_UPWARD)
    assert not new, "imports from a lower layer to a higher one: " + ", ".join(
        f"{a} ({LAYERS[_layer(a)][0]}) -> {b} ({LAYERS[_layer(b)][0]})" for a, b in new)


def test_no_module_imports_another_modules_private_name():
    _, edges = _imports()
    private = {(a, b, n) for a, b, n, _ in edges
               if n.startswith("_") and not n.startswith("__") and not b.rsplit(".", 1)[-1].startswith("_")}
    assert not private - KNOWN_PRIVATE, sorted(private - KNOWN_PRIVATE)


def test_the_checks_catch_an_upward_and_a_private_import(tmp_path, monkeypatch):
    # the same walk over a two-module package that breaks both rules must report both
    pkg = tmp_path / "dfloop"
    (pkg / "describing").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "describing" / "__init__.py").write_text("def f():\n    from ..scene import _hidden\n")
    (pkg / "scene").mkdir()
    (pkg / "scene" / "__init__.py").write_text("_hidden = 1\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", pkg)
    _, edges = _imports()
    assert ("dfloop.describing", "dfloop.scene", "_hidden", True) in edges
    assert _layer("dfloop.scene") > _layer("dfloop.describing")
