"""Shared checks of the fem tests."""

import numpy as np
import scipy.sparse as sp


def same_matrix(M: sp.spmatrix, R: sp.spmatrix) -> bool:
    """M and the reference R have the same stored pattern and values to 1e-13 of R's largest
    entry (chunked against one-shot assembly: the same sums in another order)."""
    M, R = sp.csr_matrix(M), sp.csr_matrix(R)
    M.sort_indices()
    R.sort_indices()
    return (
        np.array_equal(M.indptr, R.indptr)
        and np.array_equal(M.indices, R.indices)
        and np.allclose(M.data, R.data, rtol=0, atol=1e-13 * np.abs(R.data).max())
    )
