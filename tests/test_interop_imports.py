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


def test_export_table_names_are_public_names_of_their_modules():
    for module, names in dfloop._EXPORTS.items():
        public = importlib.import_module(module).__all__
        assert set(names) <= set(public), (module, sorted(set(names) - set(public)))
    everything = [n for names in dfloop._EXPORTS.values() for n in names]
    assert len(everything) == len(set(everything)), "a name is exported from two modules"


def test_top_level_is_the_curated_api():
    """About 30-45 names a control engineer uses; internals live in their subpackages only."""
    names = set(dfloop.__all__) - {"__version__"}
    assert 30 <= len(names) <= 45, len(names)
    for internal in ("Table1D", "Samples", "build", "Problem", "curve_with_gaps", "simulate_impacts", "Plant",
                     "static_limit_frequency", "impact_describing_function", "cache_dir"):
        assert internal not in names
        with pytest.raises(AttributeError):
            getattr(dfloop, internal)
    # every public class or function of a subpackage stays importable from where it is defined
    from dfloop.impact import impact_describing_function  # noqa: F401
    from dfloop.plot import plot_loci  # noqa: F401
    from dfloop.tables import Table1D  # noqa: F401


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
