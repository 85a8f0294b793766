"""Sparse LU factorisations behind one interface.

Backends: "splu" (SciPy SuperLU) and "pardiso" (MKL PARDISO through the optional `pypardiso`,
``pip install mixvi[fast]``, METIS nested dissection). "auto" takes PARDISO where it imports
and the system is large enough to pay for it, else SuperLU.

SuperLU options (SUPERLU_OPTIONS): column ordering minimum degree on the graph of Aᵀ + A
(ORDERING) *with* SymmetricMode (the elimination tree of Aᵀ + A, diagonal pivots preferred)
and a relaxed pivot threshold (PIVOT_THRESHOLD, a diagonal pivot is kept while it is at least
that fraction of its column's largest entry). Minimum degree on Aᵀ + A assumes diagonal pivots:
without SymmetricMode and with SciPy's default threshold 1.0 SuperLU pivots off the diagonal
and the fill the ordering was chosen for is lost. On the first fine Newton matrix of
`rigid_foundation` level 5 (98,688 unknowns) that factorisation did not end within 200 s where
COLAMD took 10 s CPU (fill 19.0) and minimum degree with SymmetricMode 4.5 s (fill 10.3); a
user's two-body gmsh scene at 75k unknowns ran 28 min. Measurements on the shipped scenes and
on unstructured meshes: docs/benchmarks.md, "Direct solver defaults"
(`python benchmarks/linear_solvers.py`). Every solve is followed by iterative refinement
(`_refine`), so a relaxed threshold costs no accuracy where it would matter.

Budget and fallback. A SuperLU factorisation runs in compiled code that cannot be stopped
from Python, so it is bounded before it starts: its address space may grow by at most
`factor_budget(A)` bytes (RLIMIT_AS lifted by that much for the call; SuperLU's allocation then
fails cleanly with a MemoryError instead of running on). A factorisation over budget is retried
once with FALLBACK_ORDERING; over budget again it raises `FactorizationTooLarge`, which
`vi_core.ssn` answers by solving with the iterative path. Every fallback is recorded
(`Factorization.fallback`, `Refactorizer.fallbacks`).

Memory: a factorisation's factors are released by `Factorization.free` (SuperLU: the SuperLU
object is dropped); a `Refactorizer` frees the previous factorisation before it builds the
next, so at most one factor per Refactorizer is alive.

`Refactorizer` factorises a sequence of matrices (the Newton steps of ssn). With PARDISO, a
matrix with the same sparsity pattern (indptr and indices) as the previous one reuses the
previous symbolic analysis (ordering and symbolic factorisation: PARDISO phase 22, numerical
factorisation only, instead of phase 12); `python benchmarks/bench_reuse.py` measures the
gain. SuperLU (SciPy) offers no such reuse: every factorisation is a full one.
"""

from __future__ import annotations

import glob
import os
import resource
import sys
from functools import cache

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .marks import mark

BACKENDS = ("auto", "splu", "pardiso")
ORDERING = "MMD_AT_PLUS_A"  # SuperLU's column ordering (module docstring)
PIVOT_THRESHOLD = 0.1  # SuperLU's diag_pivot_thresh (module docstring)
SUPERLU_OPTIONS = {"SymmetricMode": True}  # with ORDERING: diagonal pivots, etree of Aᵀ + A
FALLBACK_ORDERING = "COLAMD"  # tried when a factorisation with ORDERING is over budget
# the factor's budget: FILL_BUDGET entries of L + U per stored entry of A (BYTES_PER_ENTRY
# each: value, row index and SuperLU's supernode bookkeeping), at least BUDGET_FLOOR bytes
FILL_BUDGET = 100.0
BYTES_PER_ENTRY = 16.0
BUDGET_FLOOR = 256e6
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


class FactorizationTooLarge(MemoryError):
    """A SuperLU factorisation went over its budget with every ordering tried."""


def factor_budget(A: sp.spmatrix) -> float:
    """The bytes a factorisation of A may add to the address space (module docstring)."""
    return max(BUDGET_FLOOR, FILL_BUDGET * BYTES_PER_ENTRY * A.nnz)


def _vm_size() -> float | None:
    """This process's address-space size in bytes (VmSize), None where /proc is absent."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmSize:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return None


def superlu(At: sp.csc_matrix, ordering: str, budget: float | None):
    """SuperLU of At with SUPERLU_OPTIONS, its address space grown by at most `budget` bytes
    (None: unbounded). MemoryError when SuperLU could not allocate within it."""
    size = _vm_size() if budget is not None else None
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if size is not None:
        cap = int(size + budget)
        if soft != resource.RLIM_INFINITY:
            cap = min(cap, soft)
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        return spla.splu(
            At,
            permc_spec=ordering,
            diag_pivot_thresh=PIVOT_THRESHOLD,
            options=SUPERLU_OPTIONS if ordering == ORDERING else {},
        )
    except RuntimeError as err:  # an allocation outside the factors' expansion ("MALLOC fails")
        if "MALLOC" in str(err):
            raise MemoryError(str(err)) from None
        raise
    finally:
        if size is not None:
            resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


class Factorization:
    """x = F(b) solves A x = b with a stored LU factorisation (plus iterative refinement).

    pardiso_solver : (PARDISO only) a solver object whose symbolic analysis of a matrix with
        A's sparsity pattern is reused: only the numerical factorisation is computed, and the
        object stays owned by the caller (`Refactorizer`).
    budget : (SuperLU) the bytes the factorisation may take (module docstring); "default" is
        `factor_budget(A)`, None unbounded. Over it: FALLBACK_ORDERING, then
        FactorizationTooLarge. `fallback` says what happened ('' when nothing did), `fill` is
        the factors' stored entries (SuperLU's supernodes, padding included) / nnz(A).
    After `free()` (or `stale`) the factorisation cannot solve any more.
    """

    def __init__(
        self,
        A: sp.spmatrix,
        backend: str = "auto",
        pardiso_solver=None,
        budget: float | str | None = "default",
    ):
        self.A = sp.csr_matrix(A)
        self.A.sort_indices()
        self.backend = resolve_backend(backend, self.A.shape[0])
        self.stale = False  # set by a Refactorizer when its next factorisation replaces this
        self.fallback = ""
        self.fill = float("nan")
        self.ordering = ""
        if self.backend == "pardiso":
            import pypardiso

            self._owner = pardiso_solver is None
            if self._owner:
                self._pardiso = pypardiso.PyPardisoSolver()  # real non-symmetric, METIS
                self._pardiso.factorize(self.A)  # phase 12: analysis + numerical
            else:
                self._pardiso = pardiso_solver
                self._pardiso._check_A(self.A)
                self._pardiso.factorized_A = self.A  # not modified: no copy needed
                self._pardiso.set_phase(22)  # numerical factorisation, symbolic reused
                self._pardiso._call_pardiso(self.A, np.zeros((self.A.shape[0], 1)))
            self._lu = None
        else:
            self._pardiso = None
            # A's csr arrays are Aᵀ in csc: factorise Aᵀ without a copy of A, solve transposed
            At = sp.csc_matrix((self.A.data, self.A.indices, self.A.indptr), self.A.shape[::-1])
            mark("splu", At.shape[0])  # a test hook (vi_core.marks); nothing when unset
            limit = factor_budget(self.A) if budget == "default" else budget
            self._lu = None
            for ordering in (ORDERING, FALLBACK_ORDERING):
                try:
                    self._lu = superlu(At, ordering, limit)
                except MemoryError:
                    self.fallback += (
                        f"SuperLU with {ordering} over its budget of {limit / 1e6:.0f} MB; "
                    )
                    continue
                self.ordering = ordering
                break
            if self._lu is None:
                raise FactorizationTooLarge(
                    f"{self.fallback}n = {self.A.shape[0]}, nnz(A) = {self.A.nnz}"
                )
            self.fill = self._lu.nnz / max(self.A.nnz, 1)  # nnz(L + U) (no copy of them)
        self._transposed: Factorization | None = None  # PARDISO: a factorisation of Aᵀ

    def _solve(self, b: np.ndarray, trans: str = "N") -> np.ndarray:
        if self.stale or (self._lu is None and self._pardiso is None):
            raise RuntimeError("this factorisation was freed or replaced by a later one")
        b = np.ascontiguousarray(b, dtype=float)
        if self._lu is not None:  # the factors are those of Aᵀ
            return self._lu.solve(b, trans="N" if trans == "T" else "T")
        return self._pardiso.solve(self.A, b)

    def __call__(self, b: np.ndarray) -> np.ndarray:
        x = self._solve(b)
        return _refine(self.A, b, x, self._solve)

    def solve_transposed(self, b: np.ndarray) -> np.ndarray:
        """x with Aᵀx = b (PARDISO: factorises Aᵀ on first use)."""
        if self._pardiso is None:
            return self._solve(np.ravel(b), trans="T")
        if self._transposed is None:
            self._transposed = Factorization(self.A.T, self.backend)
        return self._transposed(np.ravel(b))

    def free(self) -> None:
        """Release the factor's memory now (PARDISO keeps it outside Python's heap; a shared
        solver object is released by its Refactorizer)."""
        if getattr(self, "_pardiso", None) is not None and getattr(self, "_owner", True):
            self._pardiso.free_memory(everything=True)
        self._pardiso = None
        self._lu = None
        if getattr(self, "_transposed", None) is not None:
            self._transposed.free()
            self._transposed = None

    def __del__(self):
        self.free()


class Refactorizer:
    """Factorise a sequence of matrices, reusing PARDISO's symbolic analysis while the sparsity
    pattern does not change (module docstring). Each returned Factorization is valid until the
    next call (then `stale`). `analyses` and `factorizations` count what was done,
    `fallbacks` lists each factorisation that went over its budget (`Factorization.fallback`),
    `fills` the fill nnz(L + U) / nnz(A) of each SuperLU factorisation. `budget` as for
    `Factorization`."""

    def __init__(self, backend: str = "auto", budget: float | str | None = "default"):
        self.backend = backend
        self.budget = budget
        self.fallbacks: list[str] = []
        self.fills: list[float] = []
        self.analyses = 0  # symbolic analyses (PARDISO phase 12, or every SuperLU factorisation)
        self.factorizations = 0
        self._solver = None  # the PARDISO object holding the current analysis
        self._pattern: tuple[np.ndarray, np.ndarray] | None = None
        self._last: Factorization | None = None

    def __call__(self, A: sp.spmatrix) -> Factorization:
        """Factorise A (a new analysis only if the pattern changed or the backend is SuperLU)."""
        A = sp.csr_matrix(A)
        A.sort_indices()
        backend = resolve_backend(self.backend, A.shape[0])
        self.release()  # never two factors at once: the old one goes first
        self.factorizations += 1
        if backend != "pardiso":
            self.analyses += 1
            try:
                self._last = Factorization(A, backend, budget=self.budget)
            except FactorizationTooLarge as err:
                self.fallbacks.append(str(err))
                raise
            if self._last.fallback:
                self.fallbacks.append(self._last.fallback + f"factorised with {FALLBACK_ORDERING}")
            self.fills.append(self._last.fill)
            return self._last
        same = self._pattern is not None and (
            np.array_equal(self._pattern[0], A.indptr)
            and np.array_equal(self._pattern[1], A.indices)
        )
        if not same:
            self.free()
            import pypardiso

            self._solver = pypardiso.PyPardisoSolver()
            self._solver.set_phase(11)  # analysis only
            self._solver._check_A(A)
            self._solver._call_pardiso(A, np.zeros((A.shape[0], 1)))
            self._pattern = (A.indptr.copy(), A.indices.copy())
            self.analyses += 1
        self._last = Factorization(A, "pardiso", pardiso_solver=self._solver)
        return self._last

    def release(self) -> None:
        """Free the last factorisation now (it goes `stale`); a PARDISO analysis is kept (its
        numerical factor is overwritten in place by the next call)."""
        if self._last is not None:
            self._last.stale = True
            if self._last.backend != "pardiso":
                self._last.free()
            self._last = None

    def free(self) -> None:
        """Release the PARDISO analysis and factors."""
        if self._solver is not None:
            self._solver.free_memory(everything=True)
            self._solver = None
            self._pattern = None

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
