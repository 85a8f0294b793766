"""Dirichlet conditions by elimination of the prescribed dofs."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def reduce_dirichlet(
    A: sp.spmatrix, f: np.ndarray, fixed: np.ndarray, values: np.ndarray
) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """Eliminate prescribed dofs from A x = f.

    fixed : boolean mask (n,) of prescribed dofs; values : (n,) vector whose fixed entries are
    the prescribed values (other entries ignored). Returns (A_ff, f_f − A_fD u_D, free), with
    free the index array of the free dofs.
    """
    A = sp.csr_matrix(A)
    n = A.shape[0]
    f = np.asarray(f, dtype=float)
    fixed = np.asarray(fixed)
    values = np.asarray(values, dtype=float)
    if A.shape != (n, n):
        raise ValueError(f"A must be square, got shape {A.shape}")
    if fixed.dtype != bool:
        raise ValueError(f"fixed must be a boolean mask, got dtype {fixed.dtype}")
    for label, v in (("f", f), ("fixed", fixed), ("values", values)):
        if v.shape != (n,):
            raise ValueError(f"{label} must have shape ({n},), got {v.shape}")
    free = np.flatnonzero(~fixed)
    uD = np.where(fixed, values, 0.0)  # (n,)
    rhs = f[free] - (A @ uD)[free]
    return A[free][:, free].tocsr(), rhs, free


def expand(x_free: np.ndarray, free: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The full vector: `x_free` on the free dofs, `values` on the prescribed ones."""
    x = np.array(values, dtype=float)
    x[free] = x_free
    return x
