"""Shared test configuration: the hypothesis CI profile (deadline=None, derandomize=True), and
one BLAS/OpenMP thread per test process when pytest-xdist runs one worker per core (threads of
two workers fighting over the same cores slowed single tests tenfold; the solvers' own thread
settings are tested through their reports, not through the runner's)."""

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    "ci",
    deadline=None,
    derandomize=True,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("dev", deadline=None, max_examples=20)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
