"""One smoothed-aggregation multigrid hierarchy (pyamg's, to rounding) built with less memory,
its aggregates kept within the bodies of a contact problem (`bodies`).

`smoothed_aggregation` is the hierarchy of one field block of the iterative path
(`vi_core.block_amg`): the finest level's strength graph from A's structure cut between the
bodies (`strength_within_parts`), its prolongation smoothed by energy minimisation on one shared
sparsity pattern (`energy_smoothing`), the coarser levels' strength cut between the parts of
their aggregates (`coarse_parts`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .marks import mark
from .sparse_blocks import row_chunks

# prolongation smoothing: energy minimisation (two CG steps) instead of one Jacobi step; CG on
# the displacement block of the paper scene to 1e-8, levels 3, 4, 5: 14, 15, 17 iterations with
# Jacobi, 11, 12, 12 with energy minimisation (set-up about twice as long)
SMOOTH = ("energy", {"krylov": "cg", "maxiter": 2, "degree": 1, "weighting": "local"})
MAX_LEVELS = 10  # levels of a hierarchy at most (pyamg's default)


def bodies(A: sp.spmatrix) -> np.ndarray:
    """(n,) the connected component of each unknown in the graph of A: the bodies of a contact
    problem, which only the multipliers couple."""
    from scipy.sparse.csgraph import connected_components

    return connected_components(A, directed=False)[1]


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
    scalar (csr) A — the same prolongation to rounding (`test_amg`) — computed on one
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
    for r, sl in row_chunks(A):
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
    hierarchy to rounding (`test_amg`), built with less memory — the finest level's
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
