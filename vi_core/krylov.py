"""An iterative linear path for the semismooth Newton steps: GMRES with algebraic multigrid.

`ssn` condenses the dual-mortar multipliers out of every Newton system; what remains is the
non-symmetric n × n system K u⁺ = b in the primal unknowns, with rows R fixed over the Newton
steps (A_R − B_Rᵀ D^{-T} A_S) and rows S (the slave dofs) replaced by the active-set conditions
Dᵀ(W D^{-T} A_S + J B), which change from step to step (D = B[:, S], block diagonal).

**Preconditioner** (right, for restarted GMRES): the tied rows eliminated exactly, one
multigrid cycle per field for the rest. Premultiplied by D^{-T}, row i of S reads
(W D^{-T} A_S u + J B u)_i. Where row i of W is zero (a stick or bilateral-normal row: "tied")
it is the tying condition (B u)_i = …; elsewhere (J = 0: slip, inactive) it is the stiffness
row (D^{-T} A_S u)_i. In the coordinates y = (u_R, s_F), s = C^{-1} D u_S the slave dofs in
their node's frame (C the row norms of D) with F the free rows, the slave dofs of the tied
rows follow the others: u = T0 y + u_p, u_S = D^{-1}(C E_F s_F − E_T (B_R u_R)_T) + u_p,S. With
0/1 rows of J this turns K u = r into Â y = T0ᵀ(…) with the symmetric Â = T0ᵀ A T0 — the
stiffness of the bodies glued where they stick and free to slide where they slip — so a
hierarchy of Â and an exact tied part make the preconditioner exact (`test_krylov`).
Rows with fractional J (a slip disc in 3D: J = γ(I − ŷŷᵀ), γ = g/|y_t| < 1, W = I − J) are
free rows with a spring: on the free rows F, W_FF λ_F = J_F·(B u) − q_F (W_FT = 0 but for
Coulomb's dρ/dλ_n), so λ_F = M (B u)_F − W_FF^{-1}(q_F − J_FT q_T) with M = W_FF^{-1} J_FF,
symmetric and ≥ 0, and the glued stiffness gains the spring: Â = T0ᵀ (A + B_Fᵀ M B_F) T0 — exact
(`test_krylov`, a Ball with fractional rows). The spring κ = γ/(1 − γ) is unbounded where a
disc has only just started to slip (γ → 1; γ = 1 to rounding occurs, W_FF singular), and a
multigrid hierarchy of a matrix with springs of 1e16 fails (bracket3d level 2, first fine
step, GMRES iterations to 1e-8: 12 counting the slip rows free, 192 with the exact springs),
so κ is capped smoothly at SPRING_CAP: exact where κ ≪ SPRING_CAP, a stiff spring between
free and tied above. Measured on the same step and two later ones (hierarchy rebuilt, caps
0.1, 1, 10, 1e3, none): 12, 11, 10, 19, 192 / 18, 13, 11, 14, 14 / 16, 12, 10, 11, 11, against
12 / 21 / 19 with the slip rows free. Coulomb's coupling W_FT of a slip row to its (tied)
normal multiplier is left out (GMRES makes up that difference). Â is
block lower triangular over the fields of the problem (`MixedVI.fields`, e.g. displacement
then potential): one pyamg smoothed-aggregation hierarchy per field, built on the symmetric
part of its diagonal block, with the field's near-null space (`MixedVI.near_null`, the
rigid-body modes for displacement, carried to s by C^{-1}D) or the constant vector, aggregates
within one body on every level, energy-minimising prolongation; the coupling blocks below the
diagonal (the piezoelectric coupling) are applied exactly. The hierarchies depend on which
rows are tied: they are rebuilt when more than REUSE of the rows changed type since they were
built; below that the whole preconditioner of the old tied rows is kept — the exact inverse
(with exact hierarchies) of a Newton matrix that differs from K in the changed S rows only, a
low-rank difference GMRES absorbs in a few iterations (passing the old hierarchy on with the
changed rows merely left out made GMRES stagnate).
After GMRES the S rows are solved exactly once more (K_SS by SuperLU): a slip row's
multiplier is then on its bound to rounding, as after a direct solve — nested iteration reads
the stick/slip partition of the coarse answer, and without it the paper scene's level 5 took 8
Newton steps instead of 2.

Measured on the paper scene (`mixvi bench --scenes paper_two_body --levels 2..5 --linear-solvers
amg`; the tied linear system to 1e-11 from zero): 14, 15, 16, 16 GMRES iterations at levels 2–5
(16 at level 6, 1.5M unknowns) with this preconditioner and W-cycles; 19, 23, 28, 35 with the
previous one (the R rows' operator A_R − B_Rᵀ D^{-T} A_S with a direct solve of K_SS, which
misses the coupling of the slave dofs to the rest: its Schur complement differs from it by a
term of the rank of the interface). On the Newton systems of the first nested fine step (an
experiment on those matrices saved, GMRES to 1e-8 from zero), V-cycles: 14, 16, 20, 24 (levels
2–5), W-cycles 14, 14, 17, 18, and W costs less time at level 5 (6.6 s against 9.3 s).

**Inexact Newton.** Each step starts from the current iterate and stops when the linear residual
is ≤ η_k times its initial value (Eisenstat–Walker, choice 2: η_k = 0.9 (F_k/F_{k−1})², at most
ETA_MAX from a cold start; from a warm start ETA_MAX_WARM = 0: nested iteration's prediction of
the active set usually holds, and then one step solved to tol is the answer; it applies to every
warm start — load-path steps, homotopy steps, the Coulomb fixed point's inner solves, conic's
polish — and on `mixvi solve shear_strip_path --level 3 --linear-solver amg` it takes mostly 1
Newton step per load step where 1e-8 took 2 and 0.1 took 3, at the same wall time), but never
asks for more than 0.1·tol relative to ‖b‖: the step that brings the natural residual below tol
is solved to about the requested tolerance, and convergence is judged from the natural residual
of the iterate itself, as with a direct solve.

**Fallback.** A solve whose true residual falls by less than a factor 0.9 over a restart cycle,
or does not reach its tolerance within `max_cycles` cycles, is redone by the direct solver; the
step and the reason are recorded in `info["fallback"]`.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .gmres import gmres_cycle
from .linalg import BACKENDS
from .marks import mark

LINEAR_SOLVERS = (*BACKENDS, "amg")  # the direct backends and the iterative path
# linear_solver="auto": the iterative path once A has more stored entries than this, for the
# mesh's kind told by A's mean row length (entries per row of A at least ROW_3D: a 3D mesh,
# whose factors fill far faster). Measured in docs/benchmarks.md, "Direct solver defaults"
AUTO_AMG_NNZ = {2: 1_000_000, 3: 300_000}
ROW_3D = 40.0  # 2D: ≤ 27 entries per row (Q1 piezo), 3D: 45 (P1 tetrahedra, elastic) … 108 (Q1
# hexahedra, piezo)
# the loosest relative linear tolerance of a Newton step, from a cold start and from a warm
# start (u0/λ0 given: nested iteration, where the active set is nearly right and Newton needs
# one exact step, so an inexact step only adds steps: 0 = every warm step is solved to the
# requested tolerance, 0.1·tol·‖b‖). Measured with the fine level of the paper scene (GMRES
# iterations / Newton steps): level 3 cold, 0.1 → 78 / 9, 1e-3 → 97 / 7; level 4 nested,
# 1e-4 → 98 / 4, 1e-8 → 71 / 2; with the warm start's stick/slip prediction at the transitions
# (piezo_contact.warm_start) level 4 nested, 1e-8 → 13 + 6 its in 2 steps, 0 → 18 in 1 step,
# 3.13 s → 3.04 s (each step also costs a K_SS factorisation, residuals and the line search)
ETA_MAX = 0.1
ETA_MAX_WARM = 0.0
# prolongation smoothing: energy minimisation (two CG steps) instead of one Jacobi step; CG on
# the displacement block of the paper scene to 1e-8, levels 3, 4, 5: 14, 15, 17 iterations with
# Jacobi, 11, 12, 12 with energy minimisation (set-up about twice as long)
SMOOTH = ("energy", {"krylov": "cg", "maxiter": 2, "degree": 1, "weighting": "local"})
CYCLE = "W"  # see the module docstring for the measurements
# the hierarchy is rebuilt only when more than this fraction of the rows changed between tied
# and free since it was built; otherwise the preconditioner of the old tied rows is used as it
# is (module docstring). Paper scene, level 4 from a cold start: 10.5 s with 8 set-ups at 0,
# 6.2 s with 2 at 0.1, 6.5 s with 1 at 1.0 (more GMRES iterations); nested to level 5: one
# set-up on the fine level instead of two, 13 and 12 iterations either way
REUSE = 0.1
SPRING_CAP = 10.0  # the largest spring of a slip row (equilibrated units; module docstring)
MAX_LEVELS = 10  # levels of a hierarchy at most (pyamg's default)
CHUNK = 1 << 18  # entries per chunk of the one-pass gathers (`gather_rows`): its temporaries
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


def forcing_term(res: float, res_prev: float | None, tol: float, eta_max: float = ETA_MAX) -> float:
    """Eisenstat–Walker (choice 2, γ = 0.9, α = 2) forcing term for the next Newton step:
    η = 0.9 (res / res_prev)², at most eta_max (also on the first step, res_prev None), and not
    below 0.1·tol/res (no step solved more accurately than reaching tol needs, whatever
    eta_max: with eta_max = 0 every step is solved to that floor)."""
    eta = eta_max if not res_prev else 0.9 * (res / res_prev) ** 2
    floor = 0.1 * tol / res if res > 0 else eta_max
    return float(max(min(eta_max, eta), floor))


def bodies(A: sp.spmatrix) -> np.ndarray:
    """(n,) the connected component of each unknown in the graph of A: the bodies of a contact
    problem, which only the multipliers couple."""
    from scipy.sparse.csgraph import connected_components

    return connected_components(A, directed=False)[1]


def block_inverse(W: sp.spmatrix) -> sp.csr_matrix:
    """W⁻¹ of a block-diagonal W whose blocks (the connected components of its graph) are
    small: the blocks of one size inverted together."""
    from scipy.sparse.csgraph import connected_components

    W = sp.csr_matrix(W)
    k = W.shape[0]
    _, comp = connected_components(W, directed=False)  # (k,) block of each row
    order = np.argsort(comp, kind="stable")  # (k,) rows block by block
    sizes = np.bincount(comp)  # (n_blocks,)
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])  # (n_blocks,) first row of each
    rows, cols, vals = [], [], []
    for size in np.unique(sizes):
        first = start[sizes == size]  # (b,)
        idx = order[first[:, None] + np.arange(size)]  # (b, size) the rows of each block
        r = np.repeat(idx, size, axis=1).ravel()  # (b·size²,) entry (i, j) of each block
        c = np.tile(idx, (1, size)).ravel()  # (b·size²,)
        dense = np.asarray(W[r, c]).reshape(-1, size, size)  # (b, size, size)
        rows.append(r)
        cols.append(c)
        vals.append(np.linalg.inv(dense).ravel())
    if not rows:
        return sp.csr_matrix((k, k))
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(k, k)
    )


class Split(Protocol):
    """What the iterative path needs of a condensation (`ssn.Condensation` has it)."""

    R: np.ndarray  # (n − m,) the remaining columns
    S: np.ndarray  # (m,) the slave column of each row of B
    D: sp.csr_matrix  # (m, m) B[:, S], block diagonal
    Dt_inv: sp.csr_matrix  # (m, m) D^{-T}


class CondensedNewton:
    """The condensed Newton matrix K of the iterative path, applied without being stored:
    rows R are A_R − B_Rᵀ D^{-T} A_S (fixed), rows S the step's K_S (m, n), so K x is A x
    with the R rows corrected by B_Rᵀ D^{-T} (A x)_S and the S rows replaced by K_S x.

    Why: stored, K is a second copy of A (its R rows are A's but where B_R reaches, and its
    pattern is kept for the direct solvers' one analysis); GMRES only applies it, and the
    exact S-row solve needs K_SS only. paper scene level 5 (386k unknowns): K and its
    pattern were 112 MB held through the multigrid set-up. `tocsr` assembles it where a
    direct solve needs it (the fallback)."""

    def __init__(
        self,
        A: sp.csr_matrix,
        R: np.ndarray,
        S: np.ndarray,
        BR_t: sp.csr_matrix,
        Dt_inv: sp.csr_matrix,
        K_S: sp.csr_matrix,
    ):
        self.A, self.R, self.S = A, R, S  # (n, n), (n − m,), (m,)
        self.BR_t, self.Dt_inv = BR_t, Dt_inv  # (n − m, m) B_Rᵀ, (m, m) D^{-T}
        self.K_S = K_S  # (m, n) the S rows, in the order of S
        self.shape = A.shape
        self.nnz = A.nnz + K_S.nnz  # stored entries (A is shared, not copied)

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        y = self.A @ x  # (n,)
        y[self.R] -= self.BR_t @ (self.Dt_inv @ y[self.S])
        y[self.S] = self.K_S @ x
        return y

    def tocsr(self) -> sp.csr_matrix:
        """K assembled (n, n)."""
        R, S, n = self.R, self.S, self.shape[0]
        K_R = self.A[R] - self.BR_t @ (self.Dt_inv @ self.A[S])  # (n − m, n)
        rows = np.concatenate([R, S])  # stacked row i is row rows[i] of K
        P = sp.csr_matrix((np.ones(n), (rows, np.arange(n))), shape=(n, n))
        return (P @ sp.vstack([K_R, self.K_S], format="csr")).tocsr()


@dataclass
class Spring:
    """The free rows F with fractional J (3D slip discs) of one Newton matrix: on them
    λ_F = M (B u)_F − Wi (q_F − J_FT q_T) (module docstring)."""

    M: sp.csr_matrix  # (k_F, k_F) W_FF^{-1} J_FF, symmetric ≥ 0 (block diagonal)
    Wi: sp.csr_matrix  # (k_F, k_F) W_FF^{-1}
    J_FT: sp.csr_matrix  # (k_F, k_T) J[F, T]
    rows: np.ndarray  # (m,) bool: the free rows with J ≠ 0 (the springs)

    @staticmethod
    def of(tied: np.ndarray, W: sp.spmatrix | None, J: sp.spmatrix | None) -> Spring | None:
        """The springs of the free rows, None where there are none (J = 0 on the free rows:
        every 2D step, and 3D steps without a slip disc)."""
        if W is None or J is None:
            return None
        F, T = np.flatnonzero(~tied), np.flatnonzero(tied)
        J_F = sp.csr_matrix(J)[F]  # (k_F, m)
        J_F.eliminate_zeros()
        if J_F.nnz == 0:
            return None
        rows = np.zeros(tied.size, dtype=bool)
        rows[F[np.diff(J_F.indptr) > 0]] = True
        J_FF = J_F[:, F]
        # M = W_FF^{-1} J_FF with its stiffness κ = γ/(1 − γ) capped smoothly at SPRING_CAP:
        # (W_FF + J_FF/c)^{-1} J_FF = κ/(1 + κ/c) (never singular, also where γ = 1 exactly)
        M = (block_inverse(sp.csr_matrix(W)[F][:, F] + J_FF / SPRING_CAP) @ J_FF).tocsr()
        return Spring(M, (sp.identity(F.size) + M).tocsr(), J_F[:, T].tocsr(), rows)


def _springs(spring: Spring | None, tied: np.ndarray) -> np.ndarray:
    """(m,) bool: the rows that are springs (none without a Spring)."""
    return np.zeros(tied.size, dtype=bool) if spring is None else spring.rows


@dataclass
class FieldBlock:
    """One field of the operator: its positions and its multigrid hierarchy."""

    name: str
    index: np.ndarray  # (k,) positions within the operator
    ml: object  # pyamg MultilevelSolver
    lower: list = field(default_factory=list)  # [(j, K[self, field j])] for earlier fields j


def _fields(n: int, fields: dict | None, near_null: dict | None) -> list[tuple]:
    """[(name, mask (n,), near-null rows or None)], covering every unknown exactly once."""
    out, covered = [], np.zeros(n, dtype=bool)
    for name, sel in (fields or {}).items():
        mask = np.zeros(n, dtype=bool)
        mask[sel] = True
        if (mask & covered).any():
            raise ValueError(f"field {name!r} overlaps an earlier field")
        covered |= mask
        if mask.any():
            out.append((name, mask, None if near_null is None else near_null.get(name)))
    if not covered.all():
        out.append(("rest", ~covered, None))
    return out


def strength_within_parts(A: sp.csr_matrix, part: np.ndarray | None) -> sp.csr_array:
    """The strength of connection of the finest level, structure only (data float32 ones):
    pyamg's symmetric strength with θ = 0 keeps every stored entry of A, and its values are
    read by nothing downstream (standard aggregation and the pattern of the smoothed
    prolongation use the structure), so it is A's structure with every connection between two
    parts (bodies) dropped: no aggregate spans two bodies (without two parts, A's structure).
    Built from A's index arrays (pyamg's strength and a COO filter made four full-size
    temporaries: paper scene level 5, 241 MB above the set-up's start). On the coarser levels
    `smoothed_aggregation` cuts pyamg's strength of the blocks the same way, with the parts
    of the aggregates (`coarse_parts`).

    Why within parts: where bodies slide along each other (slip rows), an aggregate across the
    interface ties their tangential motions together, and the coarse spaces cannot represent
    the slip; the GMRES iterations then grow with the level (paper scene, CG on the glued
    displacement block to 1e-8: 25, 26, 38 at levels 3–5 aggregating across, 19, 22, 31
    within the bodies; with energy-minimising prolongation 19, 20, 28 against 13, 17, 20).
    On every level, not the finest alone: with the coarser levels aggregating across the
    bodies, the fine nested step of the 10M row's scene (README, "Scale") took 18 GMRES
    iterations at level 5 and 21 at level 6 (27 at level 7, 10.7M unknowns) against 19 and 18
    for the tied solve, its residual stalling for 3–4 iterations at a time; an exact solve of
    the disc within 0.3 of the ends of Γ3 removed the stalls — the disc sliding along the
    cradle, which aggregates spanning the interface cannot represent at their scale. Cut on
    every level: 14 at level 5, 13 at level 6, no stalls."""
    A = sp.csr_array(A)
    A.sort_indices()
    n = A.shape[0]
    if part is None or np.unique(part).size < 2:
        indptr, indices = A.indptr.copy(), A.indices.copy()
    else:
        rows = np.repeat(np.arange(n, dtype=A.indices.dtype), np.diff(A.indptr))  # (nnz,)
        keep = part[rows] == part[A.indices]  # (nnz,) within one part
        indptr = np.zeros(n + 1, dtype=A.indptr.dtype)
        np.cumsum(np.bincount(rows[keep], minlength=n), out=indptr[1:])
        del rows
        indices = A.indices[keep]
    return sp.csr_array((np.ones(indices.size, dtype=np.float32), indices, indptr), shape=(n, n))


def _row_chunks(A: sp.csr_matrix):
    """(rows (e,), slice) per chunk of A's rows of about CHUNK entries: the row of each entry
    of the chunk and the chunk's slice of A's index and data arrays."""
    r0, n = 0, A.shape[0]
    while r0 < n:
        r1 = int(np.searchsorted(A.indptr, A.indptr[r0] + CHUNK, side="right")) - 1
        r1 = min(max(r1, r0 + 1), n)
        rows = np.repeat(np.arange(r0, r1), np.diff(A.indptr[r0 : r1 + 1]))  # (e,)
        yield rows, slice(int(A.indptr[r0]), int(A.indptr[r1]))
        r0 = r1


def gather_rows(
    A: sp.csr_matrix,
    row_of: np.ndarray,
    col_of: np.ndarray,
    shape: tuple[int, int],
    extra: sp.csr_matrix,
) -> sp.csr_matrix:
    """The (shape) csr matrix holding, in row row_of[r] ≥ 0, the stored entries (c, v) of A's
    row r with col_of[c] ≥ 0, at column col_of[c], and the rows of `extra` (shape, few stored
    rows, none of them a row row_of gives). row_of must increase over the rows it keeps,
    col_of over the columns. Built from A's index arrays in chunks of about CHUNK entries:
    the only full-size arrays are the result's (fancy indexing such as A[rows][:, cols] makes
    an intermediate of the rows, a sum a copy of both)."""
    n_rows, n_cols = shape
    extra = sp.csr_matrix(extra)
    extra.sum_duplicates()

    def kept():  # A's entries that land in the result, per chunk: (their rows (k,), slice, mask)
        for rows, sl in _row_chunks(A):
            keep = (row_of[rows] >= 0) & (col_of[A.indices[sl]] >= 0)  # (e,)
            yield rows[keep], sl, keep

    count = np.diff(extra.indptr).astype(np.int64)  # (n_rows,) entries per row of the result
    for rows, _, _ in kept():
        count += np.bincount(row_of[rows], minlength=n_rows)
    nnz = int(count.sum())
    idx = np.int32 if max(nnz, n_rows, n_cols) < np.iinfo(np.int32).max else np.int64
    indptr = np.zeros(n_rows + 1, dtype=idx)
    np.cumsum(count, out=indptr[1:])
    del count
    indices = np.empty(nnz, dtype=idx)
    data = np.empty(nnz, dtype=np.result_type(A.dtype, extra.dtype))
    for rows, sl, keep in kept():
        # rank of each kept entry within its row (rows ascending: a row's entries adjoin)
        rank = np.arange(rows.size) - np.searchsorted(rows, rows)  # (k,)
        dest = indptr[row_of[rows]] + rank  # (k,)
        indices[dest] = col_of[A.indices[sl][keep]]
        data[dest] = A.data[sl][keep]
    rows = np.repeat(np.arange(n_rows), np.diff(extra.indptr))  # (extra.nnz,)
    dest = indptr[rows] + np.arange(extra.nnz) - extra.indptr[rows]  # (extra.nnz,)
    indices[dest] = extra.indices
    data[dest] = extra.data
    out = sp.csr_matrix((data, indices, indptr), shape=shape)
    out.sort_indices()
    return out


def restricted_plus(
    A: sp.csr_matrix,
    rows: np.ndarray,
    cols: np.ndarray,
    Z: sp.csr_matrix,
    lone: tuple[np.ndarray, np.ndarray] | None = None,
) -> sp.csr_matrix:
    """(k_r, k_c) A[rows][:, cols] + Z, where an entry −1 of rows/cols stands for a row/column
    of zeros (their other entries increasing) and Z has few stored rows: A's rows outside Z's
    gathered from A's index arrays (`gather_rows`), Z's rows summed with A's there (a small
    sum). Stored zeros are kept; given lone = `lone_entries(A)` (with rows = cols) the pattern
    is widened by stored zeros to a symmetric one (`symmetric_part` then needs no transpose):
    the transposes of Z's entries and of the lone entries in the block."""
    row_of = np.full(A.shape[0], -1, dtype=np.int64)  # (n,) the result's row of A's rows
    row_of[rows[rows >= 0]] = np.flatnonzero(rows >= 0)
    col_of = np.full(A.shape[1], -1, dtype=np.int64)  # (n,) the result's column of A's
    col_of[cols[cols >= 0]] = np.flatnonzero(cols >= 0)
    Z = sp.coo_matrix(Z)
    if lone is not None:  # Zᵀ's pattern and that of the lone entries' transposes, as zeros
        r, c = lone
        inside = (row_of[r] >= 0) & (col_of[c] >= 0)  # (k,) the lone entries in the block
        add_r = np.concatenate([Z.col, col_of[c[inside]]])
        add_c = np.concatenate([Z.row, row_of[r[inside]]])
        Z = sp.coo_matrix(
            (np.concatenate([Z.data, np.zeros(add_r.size)]),
             (np.concatenate([Z.row, add_r]), np.concatenate([Z.col, add_c]))),
            shape=Z.shape,
        )  # fmt: skip
    t = np.unique(Z.row[rows[Z.row] >= 0])  # (k,) Z's rows that have a row of A
    row_of[rows[t]] = -1  # those rows come from the sum below
    A_t = A[rows[t]]  # (k, n) A's rows there
    r = np.repeat(t, np.diff(A_t.indptr))  # (nnz_t,) their rows in the result
    c = col_of[A_t.indices]  # (nnz_t,) their columns in the result, −1 dropped
    Z = sp.coo_matrix(  # (k_r, k_c) the sum on Z's rows, stored zeros kept (tocsr)
        (np.concatenate([Z.data, A_t.data[c >= 0]]),
         (np.concatenate([Z.row, r[c >= 0]]), np.concatenate([Z.col, c[c >= 0]]))),
        shape=Z.shape,
    ).tocsr()  # fmt: skip
    return gather_rows(A, row_of, col_of, Z.shape, extra=Z)


def _find(A: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(k,) the position in A's index arrays of each entry (rows[t], cols[t]), −1 where it is
    not stored (A canonical: sorted indices, no duplicates): a binary search within each row."""
    end = A.indptr[rows + 1].astype(np.int64)  # (k,)
    lo, hi = A.indptr[rows].astype(np.int64), end.copy()  # (k,) the search interval
    last = max(A.nnz - 1, 0)
    while (active := lo < hi).any():
        mid = (lo + hi) // 2
        right = active & (A.indices[np.minimum(mid, last)] < cols)
        lo = np.where(right, mid + 1, lo)
        hi = np.where(active & ~right, mid, hi)
    found = lo < end
    found[found] = A.indices[lo[found]] == cols[found]
    return np.where(found, lo, -1)


def lone_entries(A: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """(rows (k,), cols (k,)) the stored entries of a square csr A (made canonical in place,
    the same values) whose transpose A does not store (`_find`, in chunks): A's pattern is
    symmetric but for exact zeros dropped on one side (2 entries at the paper scene's level
    5)."""
    A.sum_duplicates()
    out_r, out_c = [], []
    for r, sl in _row_chunks(A):
        c = A.indices[sl]  # (e,)
        lone = _find(A, c, r) < 0  # (e,)
        out_r.append(r[lone])
        out_c.append(c[lone])
    return np.concatenate(out_r), np.concatenate(out_c)


def symmetric_part(K: sp.csr_matrix) -> sp.csr_matrix:
    """(K + Kᵀ)/2 of a square csr K, its zeros dropped, computed in K's data in place for each
    stored (i, j) above the diagonal with a stored (j, i): the same numbers as the sum, without
    the transpose copy and the sum's arrays. Where K's pattern is not symmetric, that sum of
    the result follows (its averaged pairs are (v + v)/2 = v exactly: the same numbers)."""
    K.sum_duplicates()
    n_upper = n_lower = 0
    matched = True
    for rows, sl in _row_chunks(K):
        cols = K.indices[sl]  # (e,)
        upper = cols > rows  # (e,)
        n_upper += int(upper.sum())
        n_lower += int((cols < rows).sum())
        e = np.flatnonzero(upper) + sl.start  # (k,) the entries (i, j) above the diagonal
        p = _find(K, cols[upper], rows[upper])  # (k,) their (j, i)
        matched &= bool((p >= 0).all())
        e, p = e[p >= 0], p[p >= 0]
        v = 0.5 * (K.data[e] + K.data[p])  # (k,) as (a + b)·0.5 in the sum: the same numbers
        K.data[e] = v
        K.data[p] = v
    if not matched or n_upper != n_lower:
        K = (K + K.T).tocsr()
        K.data *= 0.5
    K.eliminate_zeros()
    return K


def smoothing_pattern(C: sp.csr_matrix, T) -> tuple[np.ndarray, np.ndarray]:
    """(indptr (n + 1,), indices (nb,)) the block pattern of the smoothed prolongation: C (n, n)
    the strength graph times T's block pattern (degree 1), structure only, sorted."""
    n, n_agg = C.shape[0], T.shape[1] // T.blocksize[1]
    T = sp.bsr_array(T)
    ones = np.ones(C.nnz, dtype=np.float32)
    Cs = sp.csr_array((ones, C.indices, C.indptr), shape=C.shape)  # C's data may be any
    ones = np.ones(T.indices.size, dtype=np.float32)
    pat = (Cs @ sp.csr_array((ones, T.indices, T.indptr), shape=(n, n_agg))).tocsr()
    del Cs, ones
    pat.sort_indices()
    return pat.indptr, pat.indices


def energy_smoothing(A: sp.csr_matrix, T, pattern: tuple, B: np.ndarray):
    """pyamg's energy_prolongation_smoother(A, T, C, B, None, (False, {}), **SMOOTH[1]) for a
    scalar (csr) A — the same prolongation to rounding (`test_krylov`) — computed on one
    shared sparsity pattern: the CG iterates are data arrays of the pattern, updated in place,
    where pyamg makes a new bsr matrix with its own index arrays for each operation of its
    loop and copies C. Memory: the finest level's smoothing was the peak of the whole solve
    (paper scene level 5, displacement block: 308 MB above its start with pyamg's, 133 MB
    with this one; then, held → peak, 528 → 659 MB: np.abs(A), a copy of A, for the row sums
    — now in chunks —, the strength graph C held through it — now freed once
    `smoothing_pattern` is made — and two temporaries per CG step — now in place —: 488 → 604
    MB). T (n, n_agg·k) tentative prolongation (bsr, blocks 1 × k),
    pattern `smoothing_pattern(C, T)`, B (n_agg·k, k) the coarse near-null vectors."""
    from pyamg import amg_core
    from pyamg.aggregation.smooth import satisfy_constraints
    from pyamg.util.utils import compute_BtBinv
    from scipy.linalg.blas import daxpy

    opts = SMOOTH[1]
    assert SMOOTH[0] == "energy" and opts["krylov"] == "cg" and opts["degree"] == 1
    assert opts["weighting"] == "local"
    n = A.shape[0]
    k = T.blocksize[1]  # columns per block: the near-null dimension
    n_agg = T.shape[1] // k
    T = sp.bsr_array(T)
    T.sort_indices()
    indptr, indices = pattern  # (n + 1,), (nb,) the blocks of the pattern
    nb = indices.size

    def bsr(data):  # (nb, 1, k) data on the pattern → (n, n_agg·k) bsr sharing its indices
        return sp.bsr_array((data, indices, indptr), shape=(n, n_agg * k))

    BtBinv = compute_BtBinv(B, bsr(np.ones((nb, 1, k))))  # (n, k, k)
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))  # (nb,) row of each block
    Td = np.zeros((nb, 1, k))  # T on the pattern (T's blocks are among them: C has A's diagonal)
    keys_T = np.repeat(np.arange(n, dtype=np.int64), np.diff(T.indptr)) * n_agg + T.indices
    Td[np.searchsorted(rows * n_agg + indices, keys_T)] = T.data
    del keys_T, T
    D = np.zeros(n)  # (n,) the local weighting: row sums of |A|, in chunks (no copy of A)
    for r, sl in _row_chunks(A):
        if r.size:
            sums = np.bincount(r - r[0], weights=np.abs(A.data[sl]))  # (rows of the chunk,)
            D[r[0] : r[0] + sums.size] = sums
    Dinv = np.zeros(n)
    Dinv[D != 0] = 1.0 / D[D != 0]
    Dinv = Dinv[rows][:, None, None]  # (nb, 1, 1)
    del rows, D

    def times_A(Xd, out):  # out ← (A X) on the pattern
        out[:] = 0.0
        amg_core.incomplete_mat_mult_bsr(
            A.indptr, A.indices, np.ravel(A.data), indptr, indices, np.ravel(Xd),
            indptr, indices, np.ravel(out), n, n_agg, 1, 1, k,
        )  # fmt: skip

    Rd = np.empty((nb, 1, k))  # the residual −A T, projected onto the constraints
    times_A(Td, Rd)
    Rd *= -1.0
    satisfy_constraints(bsr(Rd), B, BtBinv)
    APd = np.empty_like(Rd)
    Pd, oldsum = None, 1.0
    for i in range(opts["maxiter"]):
        if i == 0:  # Z = D⁻¹ R, the first direction
            Zd = Pd = Rd * Dinv
        else:  # later held in APd, free until A P overwrites it
            Zd = np.multiply(Rd, Dinv, out=APd)
        newsum = float(np.vdot(Rd, Zd))
        if newsum < 1e-8:  # pyamg's tol
            break
        if i > 0:
            Pd *= newsum / oldsum
            Pd += Zd
        del Zd
        oldsum = newsum
        times_A(Pd, APd)
        satisfy_constraints(bsr(APd), B, BtBinv)
        alpha = newsum / float(np.vdot(Pd, APd))
        daxpy(Pd.ravel(), Td.ravel(), a=alpha)  # Td += α Pd, Rd −= α A Pd in place
        daxpy(APd.ravel(), Rd.ravel(), a=-alpha)
    del Rd, APd, Pd, BtBinv
    P = bsr(Td)
    P.eliminate_zeros()
    return P


def coarse_parts(AggOp, part: np.ndarray | None) -> np.ndarray | None:
    """(n_agg,) the part of each aggregate of AggOp (n, n_agg): that of its members (one part:
    the strength it was aggregated on is cut between the parts); None without parts."""
    if part is None:
        return None
    agg = sp.coo_array(AggOp)
    out = np.empty(agg.shape[1], dtype=np.asarray(part).dtype)
    out[agg.col] = np.asarray(part)[agg.row]
    return out


def smoothed_aggregation(A: sp.csr_matrix, B: np.ndarray | None, part: np.ndarray | None):
    """pyamg.smoothed_aggregation_solver(A, B, max_coarse=500, coarse_solver="splu",
    smooth=SMOOTH, strength=[("predefined", {"C": strength_within_parts(A, part)})] + [the
    symmetric strength of each coarser level cut between the parts of its aggregates] …) with
    its other defaults (MAX_LEVELS, standard aggregation, the
    near-null vectors improved by 4 symmetric block Gauss–Seidel sweeps on the finest level,
    R = Pᵀ, Galerkin coarse operators, symmetric block Gauss–Seidel smoothers): the same
    hierarchy to rounding (`test_krylov`), built with less memory — the finest level's
    prolongation by `energy_smoothing`, its strength graph freed once used."""
    from pyamg.aggregation.aggregate import standard_aggregation
    from pyamg.aggregation.smooth import energy_prolongation_smoother
    from pyamg.aggregation.tentative import fit_candidates
    from pyamg.multilevel import MultilevelSolver
    from pyamg.relaxation.smoothing import change_smoothers
    from pyamg.relaxation.utils import relaxation_as_linear_operator
    from pyamg.strength import symmetric_strength_of_connection
    from pyamg.util.utils import get_blocksize

    A = sp.csr_array(A)
    A.symmetry = "hermitian"
    n = A.shape[0]
    mark("amg", n)  # a test hook (vi_core.marks); nothing when unset
    B = np.ones((n, 1)) if B is None else np.asarray(B, dtype=float).reshape(n, -1)
    levels = [MultilevelSolver.Level()]
    levels[0].A, levels[0].B = A, B
    C = strength_within_parts(A, part)
    while len(levels) < MAX_LEVELS and A.shape[0] // get_blocksize(A) > 500:
        if C is None:  # a coarser level: pyamg's strength of its blocks, cut between the parts
            C = symmetric_strength_of_connection(A, 0.0)
            if part is not None and np.unique(part).size > 1:
                C = strength_within_parts(C, part)
        AggOp = standard_aggregation(sp.csr_array(C))[0]
        part = coarse_parts(AggOp, part)
        if len(levels) == 1:
            relax = ("block_gauss_seidel", {"sweep": "symmetric", "iterations": 4})
            B = relaxation_as_linear_operator(relax, A, np.zeros((n, 1))) @ B
            levels[0].B = B
        T, B = fit_candidates(AggOp, B)
        del AggOp
        if len(levels) == 1:  # C freed before the smoothing, once its pattern is made
            pattern = smoothing_pattern(C, T)
            C = None
            P = energy_smoothing(A, T, pattern, B)
            del pattern
        else:  # coarser levels (bsr, blocks of the near-null dimension) are small
            P = energy_prolongation_smoother(A, T, C, B, None, (False, {}), **SMOOTH[1])
        del T
        C = None
        levels[-1].P, levels[-1].R = P, P.T.conjugate()
        A = levels[-1].R @ A @ P
        A.symmetry = "hermitian"
        levels.append(MultilevelSolver.Level())
        levels[-1].A, levels[-1].B = A, B
    ml = MultilevelSolver(levels, coarse_solver="splu")
    smoother = ("block_gauss_seidel", {"sweep": "symmetric"})
    change_smoothers(ml, smoother, smoother)
    return ml


def field_blocks(
    K: sp.csr_matrix,
    fields: list[tuple],
    couple: bool = True,
    R: np.ndarray | None = None,
    Z: sp.csr_matrix | None = None,
    lone: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[dict]:
    """The blocks of Â = K[R][:, R] in the leading block of y plus Z (n_y, n_y, few stored
    rows) — by default R all of K's rows and Z none: Â = K — for the fields over y (masks
    (n_y,)): per field (in order) its positions `index` (k,), the symmetric part `sym` (k, k)
    of its diagonal block, its near-null rows `nn`, and `lower` = [(j, Â[field, field j])] for
    the earlier fields j (empty with couple=False). Each block is gathered from K's index
    arrays (`restricted_plus`) and Â is never formed: the only full-size arrays are the
    blocks' (forming Â and taking its blocks by fancy indexing peaked at 685 MB from 365 held,
    paper scene level 5). lone: `lone_entries(K)` where known (computed otherwise). Nothing
    refers to K afterwards."""
    n_y = fields[0][1].size if fields else K.shape[0]
    R = np.arange(K.shape[0]) if R is None else np.asarray(R)
    R_y = np.full(n_y, -1, dtype=np.int64)  # (n_y,) K's row of each position, −1 beyond R
    R_y[: R.size] = R
    Z = sp.csr_matrix((n_y, n_y)) if Z is None else sp.csr_matrix(Z)
    lone = lone_entries(K) if lone is None else lone
    out: list[dict] = []
    for name, mask, nn in fields:
        index = np.flatnonzero(mask)
        if index.size == 0:
            continue
        Z_f = Z[index]  # (k, n_y) Z's rows of the field (few stored)
        lower = []
        for j, prev in enumerate(out if couple else []):
            C = restricted_plus(K, R_y[index], R_y[prev["index"]], Z_f[:, prev["index"]])
            C.eliminate_zeros()
            if C.nnz:
                lower.append((j, C))
        sym = symmetric_part(restricted_plus(K, R_y[index], R_y[index], Z_f[:, index], lone))
        out.append({"name": name, "index": index, "sym": sym, "nn": nn, "lower": lower})
    return out


class BlockAMG:
    """x ≈ K⁻¹ r: one multigrid cycle per field, block lower triangular over the fields.

    parts : optional (n_R,) label of each unknown's body (aggregates stay within one body)."""

    def __init__(
        self,
        K: sp.csr_matrix,
        fields: list[tuple],
        couple: bool = True,
        parts: np.ndarray | None = None,
        cycle: str = "V",
    ):
        self._setup(field_blocks(K, fields, couple), parts, cycle)

    @classmethod
    def from_blocks(
        cls, blocks: list[dict], parts: np.ndarray | None = None, cycle: str = "V"
    ) -> BlockAMG:
        """The preconditioner of `field_blocks`' output; each field's symmetric block is
        dropped from `blocks` once its hierarchy is built."""
        self = cls.__new__(cls)
        self._setup(blocks, parts, cycle)
        return self

    def _setup(self, blocks: list[dict], parts: np.ndarray | None, cycle: str) -> None:
        self.cycle = cycle
        t = time.perf_counter()
        self.blocks: list[FieldBlock] = []
        for blk in blocks:
            index, nn = blk["index"], blk["nn"]
            sym = blk.pop("sym")
            ml = smoothed_aggregation(sym, nn, None if parts is None else parts[index])
            del sym
            self.blocks.append(FieldBlock(blk["name"], index, ml, blk["lower"]))
        self.setup_time = time.perf_counter() - t

    def __call__(self, r: np.ndarray) -> np.ndarray:
        x = np.zeros_like(r)
        parts = []
        for blk in self.blocks:
            rhs = r[blk.index]
            for j, C in blk.lower:
                rhs = rhs - C @ parts[j]
            xb = blk.ml.solve(rhs, x0=np.zeros_like(rhs), tol=0.0, maxiter=1, cycle=self.cycle)
            parts.append(xb)
            x[blk.index] = xb
        return x

    def describe(self) -> dict:
        return {
            b.name: {
                "size": int(b.index.size),
                "levels": len(b.ml.levels),
                "operator_complexity": float(b.ml.operator_complexity()),
                "near_null_dim": int(b.ml.levels[0].B.shape[1]),
            }
            for b in self.blocks
        }


class KrylovSolver:
    """Solves the condensed Newton systems K u = b of one ssn run (module docstring).

    A, B : the equilibrated operator (n, n) and constraint rows (m, n).
    cond : the condensation of B (`ssn.Condensation`: R, S, D, Dt_inv).
    fields, near_null : `MixedVI.fields` / `MixedVI.near_null` of the equilibrated problem.
    parts : optional (n,) body of each unknown (`bodies`): no aggregate spans two bodies.
    cycle : the multigrid cycle of each preconditioner application ("V" or "W").
    """

    def __init__(
        self,
        A: sp.csr_matrix,
        B: sp.csr_matrix,
        cond: Split,
        fields: dict | None = None,
        near_null: dict | None = None,
        restart: int = 50,
        max_cycles: int = 8,
        couple: bool = True,
        parts: np.ndarray | None = None,
        cycle: str = CYCLE,
    ):
        self.A = A
        self.R, self.S = np.asarray(cond.R), np.asarray(cond.S)
        self.Dt_inv = cond.Dt_inv  # (m, m) D^{-T}
        self.D_inv = sp.csr_matrix(cond.Dt_inv.T)  # (m, m) D^{-1}
        self.B = sp.csr_matrix(B)  # (m, n)
        self.B_R = sp.csr_matrix(B[:, self.R])  # (m, n_R)
        D = sp.csr_matrix(cond.D)
        self.scale = np.sqrt(np.asarray(D.multiply(D).sum(axis=1)).ravel())  # (m,) row norms
        self.D = D
        self.parts = None if parts is None else np.asarray(parts)
        self.n = self.R.size + self.S.size
        self.fields, self.near_null = fields, near_null
        self.restart, self.max_cycles, self.couple = restart, max_cycles, couple
        self.cycle = cycle
        self.amg: BlockAMG | None = None
        self.lone: tuple | None = None  # `lone_entries(A)`, found at the first set-up
        self.tied: np.ndarray | None = None  # (m,) the tied rows the hierarchy was built for
        self.spring: Spring | None = None  # the free rows' springs it was built with
        self.setups: list[float] = []  # seconds of each hierarchy set-up
        self.steps: list[dict] = []  # per Newton step: iterations, tolerance, residual, …
        self.time = 0.0
        self.on_iteration: Callable[[int], None] | None = None  # after each GMRES iteration,
        # with the iterations of the current solve so far (`ssn.solve_ssn`'s on_step)

    def _U_S(self, tied: np.ndarray) -> sp.csr_matrix:
        """(m, n_R + n_F) y = (u_R, s_F) ↦ u_S = D^{-1}(C E_F s_F − E_T (B_R u_R)_T)."""
        F = np.flatnonzero(~tied)
        keep_T = sp.diags(tied.astype(float))
        E_F = sp.csr_matrix((self.scale[F], (F, np.arange(F.size))), shape=(tied.size, F.size))
        return sp.hstack([-(self.D_inv @ (keep_T @ self.B_R)), self.D_inv @ E_F]).tocsr()

    def _P_R(self, n_y: int) -> sp.csr_matrix:
        """(n, n_y) y ↦ u_R at the positions R (zero on S)."""
        R = self.R
        return sp.csr_matrix((np.ones(R.size), (R, np.arange(R.size))), shape=(self.n, n_y))

    def _blocks(self, tied: np.ndarray, spring: Spring | None = None) -> list[dict]:
        """The field blocks (`field_blocks`) of Â = T0ᵀ (A + B_Fᵀ M B_F) T0 (n_y, n_y), never
        formed: with T0 = P_R + P_S U_S and U_S (m, n_y) of the few contact rows,
        Â = P_Rᵀ A P_R + P_Rᵀ (A P_S) U_S + U_Sᵀ (P_Sᵀ A P_R + A_SS U_S) + (B T0)_Fᵀ M (B T0)_F:
        A restricted to R × R plus corrections of rank ≤ m (`_corrections`), each block
        gathered from A's index arrays. Forming T0ᵀ (A T0) made three full-size products
        (paper scene level 5: 365 → 685 MB)."""
        if self.lone is None:  # A is fixed: its lone entries are found once
            self.lone = lone_entries(self.A)
        Z = sum(self._corrections(tied, spring))
        return field_blocks(self.A, self._fields_y(tied), self.couple, self.R, Z, self.lone)

    def _corrections(self, tied: np.ndarray, spring: Spring | None) -> list[sp.csr_matrix]:
        """The terms of Â beyond A's R × R block (`_blocks`), each (n_y, n_y) with few rows."""
        U_S = self._U_S(tied)  # (m, n_y)
        P_R = self._P_R(U_S.shape[1])  # (n, n_y)
        AU = self.A[:, self.S] @ U_S  # (n, n_y) A P_S U_S: the rows near the contact
        out = [P_R.T @ AU, U_S.T @ (self.A[self.S] @ P_R), U_S.T @ AU[self.S]]
        if spring is not None:
            F = np.flatnonzero(~tied)
            BT = self.B[F] @ P_R + self.D[F] @ U_S  # (k_F, n_y) (B T0)_F = (B u)_F in y
            out.append(BT.T @ (spring.M @ BT))
        return out

    def _fields_y(self, tied: np.ndarray) -> list[tuple]:
        """The fields over y = (u_R, s_F) (masks, near-null rows): s_i = (C^{-1} D u_S)_i is the
        field of its slave column S[i], its near-null rows C^{-1} D N_S."""
        free = ~tied
        S_F = self.S[free]
        out = []
        for name, mask, nn in _fields(self.n, self.fields, self.near_null):
            my = np.concatenate([mask[self.R], mask[S_F]])
            if nn is None:
                out.append((name, my, None))
                continue
            nn = np.asarray(nn, float).reshape(int(mask.sum()), -1)
            N = np.zeros((self.n, nn.shape[1]))  # (n, d) the field's vectors, zero elsewhere
            N[mask] = nn
            N_s = (self.D @ N[self.S]) / self.scale[:, None]  # (m, d)
            out.append((name, my, np.vstack([N[self.R][mask[self.R]], N_s[free][mask[S_F]]])))
        return out

    def _hierarchy(self, tied: np.ndarray, spring: Spring | None = None) -> None:
        """(Re)build the hierarchies of Â = T0ᵀ (A + B_Fᵀ M B_F) T0 for these tied rows and the
        free rows' springs M (kept while the tied rows stay)."""
        self.amg = None  # the old hierarchy is freed before the new one is built
        blocks = self._blocks(tied, spring)
        parts = None
        if self.parts is not None:
            parts = np.concatenate([self.parts[self.R], self.parts[self.S][~tied]])
        self.amg = BlockAMG.from_blocks(blocks, parts=parts, cycle=self.cycle)
        self.tied, self.spring = tied.copy(), spring
        self.setups.append(self.amg.setup_time)

    def __call__(
        self,
        K: sp.csr_matrix | CondensedNewton,
        b: np.ndarray,
        x0: np.ndarray | None,
        eta: float,
        tol: float,
        tied: np.ndarray,
        W: sp.spmatrix | None = None,
        J: sp.spmatrix | None = None,
    ) -> tuple[np.ndarray | None, dict]:
        """Solve K x = b to ‖b − Kx‖ ≤ max(η‖b − K x0‖, 0.1·tol·‖b‖); tied (m,) the rows whose
        W row is zero (a tying condition (B u)_i = …; the others are stiffness rows); W, J (m, m)
        the step's matrices, where given the free rows with J ≠ 0 (3D slip discs) are springs
        in the preconditioner (module docstring); without them such rows count as J = 0.

        Returns (x, record); x is None where the solve stagnated (record["fallback"] says why).
        """
        from threadpoolctl import threadpool_limits

        # the BLAS calls of set-up and Krylov vectors are far too small to gain from threads: on
        # the shared 2-core machine OpenBLAS's threads made the paper scene's level 3 solve 8×
        # slower (set-up 8.1 s → 0.3 s, GMRES 5.9 s → 1.2 s with one thread)
        with threadpool_limits(limits=1, user_api="blas"):
            tied = np.asarray(tied, dtype=bool)
            return self._solve(K, b, x0, eta, tol, tied, Spring.of(tied, W, J))

    def preconditioner(self, tied: np.ndarray, spring: Spring | None = None):
        """x ≈ K⁻¹ r for the Newton matrix K with these tied rows and free rows' springs
        (`Spring.of(tied, W, J)`; None: J = 0 on the free rows) (module docstring)."""
        if (
            self.tied is None
            or ((tied != self.tied) | (_springs(spring, tied) != _springs(self.spring, tied))).sum()
            > REUSE * tied.size
        ):
            self._hierarchy(tied, spring)
        tied, spring = self.tied, self.spring  # the exact inverse of a Newton matrix differing
        A, R, S, amg = self.A, self.R, self.S, self.amg  # in a few S rows (and springs)
        free = ~tied
        scale_F = self.scale[free]
        n_R = R.size

        def T0(y):  # (n_R + n_F,) → (n,)
            z = np.zeros(S.size)
            z[free] = scale_F * y[n_R:]
            z[tied] = -(self.B_R @ y[:n_R])[tied]
            u = np.empty(self.n)
            u[R] = y[:n_R]
            u[S] = self.D_inv @ z
            return u

        def T0t(v):  # (n,) → (n_R + n_F,)
            w = self.Dt_inv @ v[S]
            return np.concatenate([v[R] - self.B_R.T @ np.where(tied, w, 0.0), scale_F * w[free]])

        def precondition(r):
            q = self.Dt_inv @ r[S]  # the S rows in multiplier coordinates
            u_p = self._lift(q, tied)
            q_F = q[free] if spring is None else spring.Wi @ (q[free] - spring.J_FT @ q[tied])
            z = np.zeros(S.size)
            z[free] = q_F
            rhs = np.concatenate([r[R] + self.B_R.T @ z, scale_F * q_F])
            return T0(amg(rhs - T0t(A @ u_p))) + u_p

        return precondition

    def _lift(self, q: np.ndarray, tied: np.ndarray) -> np.ndarray:
        """(n,) u_p: zero but on S, where D u_p,S = q on the tied rows and 0 on the others."""
        u_p = np.zeros(self.n)
        u_p[self.S] = self.D_inv @ np.where(tied, q, 0.0)
        return u_p

    def _exact_S_rows(self, K: sp.csr_matrix, b: np.ndarray, x: np.ndarray) -> None:
        """x_S += K_SS⁻¹ (b − K x)_S in place: the S rows solved exactly (one block Gauss–Seidel
        step; a slip row's multiplier is then on its bound to rounding, module docstring)."""
        S = self.S
        K_S = K.K_S if isinstance(K, CondensedNewton) else K[S]  # (m, n)
        x[S] += spla.splu(sp.csc_matrix(K_S[:, S])).solve((b - K @ x)[S])

    def _solve(self, K, b, x0, eta, tol, tied, spring=None):
        t0 = time.perf_counter()
        M = self.preconditioner(tied, spring)
        x = np.zeros(self.n) if x0 is None else np.array(x0, dtype=float)
        nb = float(np.linalg.norm(b))
        r0 = float(np.linalg.norm(b - K @ x))
        target = max(eta * r0, 0.1 * tol * nb)
        its = [0]

        def count(_):
            its[0] += 1
            if self.on_iteration is not None:
                self.on_iteration(its[0])

        record = {"eta": eta, "target": target / nb if nb else 0.0, "fallback": None}
        res, cycles = r0, 0
        while res > target:
            if cycles == self.max_cycles:
                record["fallback"] = f"no convergence in {cycles} GMRES({self.restart}) cycles"
                break
            with warnings.catch_warnings():  # a (near) breakdown is judged by the residual below
                warnings.simplefilter("ignore", sla.LinAlgWarning)
                x, _ = gmres_cycle(K, b, x, M, target, min(self.restart, self.n), count)
            cycles += 1
            new = float(np.linalg.norm(b - K @ x))
            if new > 0.9 * res and new > target:
                record["fallback"] = f"stagnation: residual {res:.2e} → {new:.2e} in a cycle"
                res = new
                break
            res = new
        if record["fallback"] is None and res > 0:
            self._exact_S_rows(K, b, x)
            res = float(np.linalg.norm(b - K @ x))
        record.update(iterations=its[0], residual=res / nb if nb else 0.0)
        self.time += time.perf_counter() - t0
        self.steps.append(record)
        return (None if record["fallback"] else x), record

    def info(self) -> dict:
        """What the Newton solve's `info` reports about the iterative path."""
        return {
            "krylov": "gmres (vi_core.gmres, right preconditioned)",
            "restart": self.restart,
            "preconditioner": (
                f"tied rows eliminated, smoothed aggregation per field ({self.cycle}-cycle)"
            ),
            "krylov_iterations": [s["iterations"] for s in self.steps],
            "krylov_residuals": [s["residual"] for s in self.steps],
            "forcing_terms": [s["eta"] for s in self.steps],
            "fallback": [
                {"step": i + 1, "reason": s["fallback"]}
                for i, s in enumerate(self.steps)
                if s["fallback"]
            ],
            "amg_setups": len(self.setups),
            "amg_setup_s": float(sum(self.setups)),
            "amg_fields": self.amg.describe() if self.amg else {},
            "linear_time_s": self.time,
        }
