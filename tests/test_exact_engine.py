"""predict_limit_cycles(..., exact=True) reaches the exact layer without the solver importing it
(dfloop.solve.engines): in a fresh process that imports only the solver, the exact orbit is still attached."""
import subprocess
import sys

CODE = """
import sys
import control as ct
from dfloop.solve.predict import predict_limit_cycles
from dfloop.describing.static import Relay
assert "dfloop.exact" not in sys.modules
c = predict_limit_cycles(ct.tf([1.0], [1.0, 3.0, 2.0, 0.0]), Relay(1.0), exact=True)
print(c[0].exact.success, abs(c[0].exact.frequency - 1.38) < 0.01)
"""


def test_exact_orbits_attach_in_a_process_that_imported_only_the_solver():
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "True"]
