"""Shared checks of the fem tests."""

import numpy as np
import scipy.sparse as sp

from fem.tensors import VOIGT_PAIRS, Material3D


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


def shifted_geometry(real):
    """A fault for the chunked assemblies' mutation tests: `real` (a module's `_geometry`)
    computing every chunk after the first from the cells one before its own."""

    def shifted(mesh, pts, wts, cells=slice(None)):
        if cells.start:
            cells = slice(cells.start - 1, min(cells.stop, mesh.n_cells) - 1)
        return real(mesh, pts, wts, cells)

    return shifted


def full_tensors(m: Material3D) -> tuple[np.ndarray, np.ndarray]:
    """c_ijkl (3, 3, 3, 3) and e_kij (3, 3, 3) from the Voigt matrices (engineering shear): the
    definitions, independent of the kernels that use the Voigt forms."""
    c = np.zeros((3, 3, 3, 3))
    e = np.zeros((3, 3, 3))
    for I, (i, j) in enumerate(VOIGT_PAIRS):
        for J, (k, l) in enumerate(VOIGT_PAIRS):
            for a, b in {(i, j), (j, i)}:
                for p, q in {(k, l), (l, k)}:
                    c[a, b, p, q] = m.C[I, J]
        for a, b in {(i, j), (j, i)}:
            e[:, a, b] = m.e[:, I]
    return c, e
