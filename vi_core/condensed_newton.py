"""The condensed Newton matrix of the iterative path, applied without being stored.

`ssn` condenses the dual-mortar multipliers out of every Newton system; what remains is the
non-symmetric n × n system K u⁺ = b in the primal unknowns, with rows R fixed over the Newton
steps (A_R − B_Rᵀ D^{-T} A_S) and rows S (the slave dofs) replaced by the active-set conditions
Dᵀ(W D^{-T} A_S + J B), which change from step to step (D = B[:, S], block diagonal).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp


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
