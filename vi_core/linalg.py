"""Sparse LU factorisations behind one interface.

Backends: "splu" (SciPy SuperLU, COLAMD ordering: 5.5 s on a 99k-unknown piezo system, where
the MMD(AᵀA+A) ordering took far longer) and "pardiso" (MKL PARDISO through the optional
`pypardiso`, ``pip install mixvi[fast]``: 1.05 s on the same system). "auto" takes PARDISO
where it imports and the system is large enough to pay for it, else SuperLU.
"""

from __future__ import annotations

import glob
import os
import sys
from functools import cache

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

BACKENDS = ("auto", "splu", "pardiso")
AUTO_PARDISO_MIN = 2000  # below this SuperLU is as fast and has no library overhead


@cache
def pardiso_available() -> bool:
    """Whether the optional PARDISO backend imports (and locate MKL once, not per solver)."""
    try:
        import pypardiso  # noqa: F401
    except Exception:
        return False
    if "PYPARDISO_MKL_RT" not in os.environ:
        # pypardiso searches the file system for mkl_rt in every constructor (~0.5 s): do it once
        libs = sorted(glob.glob(f"{sys.prefix}/[Ll]ib*/**/*mkl_rt*", recursive=True), key=len)
        if libs:
            os.environ["PYPARDISO_MKL_RT"] = libs[0]
    return True


def resolve_backend(backend: str = "auto", n: int | None = None) -> str:
    """The concrete backend for `backend` and system size n ('auto' → PARDISO when useful)."""
    if backend not in BACKENDS:
        raise ValueError(f"linear solver {backend!r} unknown; allowed: {', '.join(BACKENDS)}")
    if backend == "auto":
        big = n is None or n >= AUTO_PARDISO_MIN
        return "pardiso" if big and pardiso_available() else "splu"
    if backend == "pardiso" and not pardiso_available():
        raise ValueError(
            "linear solver 'pardiso' needs the optional package: pip install mixvi[fast]"
        )
    return backend


class Factorization:
    """x = F(b) solves A x = b with a stored LU factorisation (plus iterative refinement)."""

    def __init__(self, A: sp.spmatrix, backend: str = "auto"):
        self.A = sp.csr_matrix(A)
        self.backend = resolve_backend(backend, self.A.shape[0])
        if self.backend == "pardiso":
            import pypardiso

            self._pardiso = pypardiso.PyPardisoSolver()  # real non-symmetric, METIS ordering
            self._pardiso.factorize(self.A)
            self._solve = lambda b: self._pardiso.solve(self.A, np.ascontiguousarray(b, float))
            self._solve_t = None  # a factorisation of Aᵀ, made on first use
        else:
            lu = spla.splu(sp.csc_matrix(self.A), permc_spec="COLAMD")
            self._solve = lambda b: lu.solve(np.asarray(b, dtype=float))
            self._solve_t = lambda b: lu.solve(np.asarray(b, dtype=float), trans="T")

    def __call__(self, b: np.ndarray) -> np.ndarray:
        x = self._solve(b)
        return _refine(self.A, b, x, self._solve)

    def solve_transposed(self, b: np.ndarray) -> np.ndarray:
        """x with Aᵀx = b (PARDISO: factorises Aᵀ on first use)."""
        if self._solve_t is None:
            self._transposed = Factorization(self.A.T, self.backend)
            self._solve_t = self._transposed
        return self._solve_t(np.ravel(b))

    def free(self) -> None:
        """Release the factor's memory now (PARDISO keeps it outside Python's heap)."""
        if getattr(self, "_pardiso", None) is not None:
            self._pardiso.free_memory(everything=True)
            self._pardiso = None

    def __del__(self):
        self.free()


def condition_estimate(F: Factorization) -> float:
    """‖A‖₁ · est‖A⁻¹‖₁ (Hager–Higham block 1-norm estimator, `scipy...onenormest`).

    Uses solves with A and Aᵀ; with SuperLU both come from one factorisation, with PARDISO the
    transposed solves factorise Aᵀ once more (about the cost of one more linear solve).
    """
    n = F.A.shape[0]
    if n == 0:
        return 0.0
    op = spla.LinearOperator((n, n), matvec=F, rmatvec=F.solve_transposed, dtype=float)
    return float(abs(F.A).sum(axis=0).max()) * float(spla.onenormest(op))


def factorize(A: sp.spmatrix, backend: str = "auto") -> Factorization:
    """Factorise the square sparse matrix A once; return x = solve(b)."""
    return Factorization(A, backend)


def _refine(A, b, x, solve, steps: int = 2) -> np.ndarray:
    """A few steps of iterative refinement (cheap: one solve each) while they help."""
    b = np.asarray(b, dtype=float)
    r = b - A @ x
    nr = np.linalg.norm(r)
    for _ in range(steps):
        if nr <= 1e-15 * max(np.linalg.norm(b), 1e-300):
            break
        x_new = x + solve(r)
        r_new = b - A @ x_new
        n_new = np.linalg.norm(r_new)
        if n_new >= nr:
            break
        x, r, nr = x_new, r_new, n_new
    return x
