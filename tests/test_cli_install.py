"""Packaging: the shipped scenes install with the package, and every package of dfloop is listed.

A full non-editable ``pip install .`` needs the ``wheel`` package and takes ~15 s, so it is checked by hand (the
commands are in docs/scenes.md). Here setuptools' ``build_py`` builds the same tree a wheel holds, from the
same pyproject.toml, and a fresh interpreter loads a shipped scene by name from it, away from the checkout.
"""
import os
import shutil
import subprocess
import sys
from dfloop.scene.load import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_under_dfloop_is_listed_for_setuptools():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    on_disk = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "dfloop").rglob("__init__.py")}
    assert set(config["packages"]) == on_disk | {"dfloop.models"}
    assert config["package-dir"] == {"dfloop.models": "models"}
    assert config["package-data"]["dfloop.models"] == ["*.toml"]


def test_built_package_ships_the_scenes_and_finds_them_by_name(tmp_path):
    source = tmp_path / "src"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    for folder in ("dfloop", "models"):
        shutil.copytree(ROOT / folder, source / folder, ignore=shutil.ignore_patterns("__pycache__"))
    build = tmp_path / "build"
    subprocess.run([sys.executable, "-c", "import setuptools; setuptools.setup()", "-q", "build_py",
                    "--build-lib", str(build)], cwd=source, check=True, capture_output=True)
    shipped = sorted(p.name for p in (build / "dfloop" / "models").glob("*.toml"))
    assert shipped == sorted(p.name for p in (ROOT / "models").glob("*.toml"))
    assert not (build / "models").exists()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    code = ("from dfloop.scene import load_scene; s = load_scene('backlash_servo'); "
            "print(s.source); print(type(s.element).__name__, s.element.h)")
    env = {**os.environ, "PYTHONPATH": str(build)}
    out = subprocess.run([sys.executable, "-c", code], cwd=elsewhere, env=env, check=True, capture_output=True,
                         text=True).stdout.splitlines()
    assert out == [str(build / "dfloop" / "models" / "backlash_servo.toml"), "Backlash 1.0"]
