"""Which linear solver a semismooth Newton step uses: the names allowed, what "auto" means for a
problem of a given size and kind, and the thread settings a solve reports.

`linear_solver="auto"` takes the iterative path (GMRES with algebraic multigrid, `vi_core.krylov`)
once the stiffness A stores more than AUTO_AMG_NNZ entries for its kind (2D or 3D, told by A's
mean row length), and a direct backend (`linalg.resolve_backend`) below that.
"""

from __future__ import annotations

import os

from .linalg import BACKENDS

LINEAR_SOLVERS = (*BACKENDS, "amg")  # the direct backends and the iterative path
# linear_solver="auto": the iterative path once A has more stored entries than this, for the
# mesh's kind told by A's mean row length (entries per row of A at least ROW_3D: a 3D mesh,
# whose factors fill far faster). Measured in docs/benchmarks.md, "Direct solver defaults"
AUTO_AMG_NNZ = {2: 1_000_000, 3: 300_000}
ROW_3D = 40.0  # 2D: ≤ 27 entries per row (Q1 piezo), 3D: 45 (P1 tetrahedra, elastic) … 108 (Q1
# hexahedra, piezo)
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def auto_linear_solver(nnz: int, n: int, condensable: bool = True) -> str:
    """What linear_solver="auto" means for a problem whose stiffness A (n × n) stores nnz
    entries: "amg" when the Newton steps condense and A is larger than AUTO_AMG_NNZ of its
    kind (2D or 3D by the mean row length, ROW_3D), else "auto" (the direct backend
    `linalg.resolve_backend` picks)."""
    kind = 3 if nnz / max(n, 1) >= ROW_3D else 2
    return "amg" if condensable and nnz > AUTO_AMG_NNZ[kind] else "auto"


def thread_settings() -> dict:
    """The thread-count environment variables as set (None = library default), the cores, and
    the threads each loaded BLAS/OpenMP library uses now (threadpoolctl)."""
    from threadpoolctl import threadpool_info

    pools = {f"{p['internal_api']}:{p['user_api']}": p["num_threads"] for p in threadpool_info()}
    env = {k: os.environ.get(k) for k in THREAD_VARIABLES}
    return {**env, "cpu_count": os.cpu_count(), "thread_pools": pools}
