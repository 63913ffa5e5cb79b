"""The lazy package namespace: the export table equals the modules' __all__, and start-up stays light."""
import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

import dfloop

ROOT = Path(__file__).resolve().parent.parent
HEAVY = ("control", "scipy.signal", "matplotlib.pyplot", "numba")


def _modules_after(code: str) -> set[str]:
    """The heavy modules loaded by ``code`` in a fresh interpreter."""
    probe = f"{code}\nimport sys\nprint(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", probe], env=env, cwd=ROOT, capture_output=True, text=True,
                         check=True, timeout=120)
    return set(out.stdout.split())


def test_export_table_is_each_modules_all():
    for module, names in dfloop._EXPORTS.items():
        assert list(names) == list(importlib.import_module(module).__all__), module
    everything = [n for names in dfloop._EXPORTS.values() for n in names]
    assert len(everything) == len(set(everything)), "a name is exported from two modules"


def test_every_export_resolves_to_its_module_object():
    for name in dfloop.__all__:
        if name == "__version__":
            continue
        module = importlib.import_module(dfloop._WHERE[name])
        assert getattr(dfloop, name) is getattr(module, name)
    assert set(dfloop.__all__) <= set(dir(dfloop))
    assert {"plot", "solve", "describing"} <= set(dir(dfloop))


def test_from_import_and_unknown_name():
    from dfloop import Backlash, plot_nyquist, predict_limit_cycles  # noqa: F401

    assert dfloop.plot.plot_nyquist is plot_nyquist
    with pytest.raises(AttributeError, match="no attribute 'Backlash2'"):
        dfloop.Backlash2  # noqa: B018


def test_import_and_help_load_no_heavy_dependency():
    assert _modules_after("import dfloop") == set()
    assert _modules_after("import contextlib, io\nfrom dfloop.cli import main\n"
                          "with contextlib.redirect_stdout(io.StringIO()):\n"
                          "    try:\n        main(['--help'])\n    except SystemExit:\n        pass") == set()


def test_elements_and_solver_do_not_load_control_pyplot_or_numba():
    # the solver's grid kernels are numpy (nothing to JIT-compile on a first call); python-control is loaded
    # only by the user (or by a plant that is an LTI)
    loaded = _modules_after("import numpy as np\n"
                            "from dfloop import MassBacklash, Relay, predict_limit_cycles\n"
                            "MassBacklash(1.0, 1.0, 0.1)(1.0, 2.0)\n"
                            "predict_limit_cycles(lambda w: np.exp(-0.5j * w) / (1j * w + 1), Relay(1.0), "
                            "omega=(0.1, 10.0))")
    assert loaded == set()
