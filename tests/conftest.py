"""Test-session settings.

The loops under test use small matrices (a few states): a multi-threaded BLAS only adds thread hand-off cost
to each ``expm`` / ``dot`` on a shared machine (measured 20 ms instead of 0.05 ms for a 4 x 4 ``expm`` under
load), so the suite runs BLAS single-threaded unless the caller chose otherwise. This must run before numpy is
imported by any test module.
"""
import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# the compiled driver on every call, whatever the state of numba's cache: results must not depend on which
# test ran first (the default mode runs it only once it is compiled; dfloop.solve.compiled.driver_wanted)
os.environ.setdefault("DFLOOP_COMPILED", "driver")
