"""Jacobians of the cell maps of a `fem.mesh.Mesh` (2D or 3D) and the check that every cell
is positively oriented and not degenerate."""

from __future__ import annotations

import numpy as np

from .elements import reference_element
from .mesh import Mesh

CHUNK = 16384  # cells per block of the check and of the assembly (bounds their temporaries)


def cofactors(J: np.ndarray) -> np.ndarray:
    """Cofactor matrices of a stack of d×d matrices (..., d, d), d = 2 or 3: det(J) J⁻ᵀ."""
    if J.shape[-1] == 2:
        cof = np.empty_like(J)  # (..., 2, 2)
        cof[..., 0, 0], cof[..., 0, 1] = J[..., 1, 1], -J[..., 1, 0]
        cof[..., 1, 0], cof[..., 1, 1] = -J[..., 0, 1], J[..., 0, 0]
        return cof
    a, b = np.roll(J, -1, axis=-1), np.roll(J, -2, axis=-1)  # columns j+1, j+2 (cyclic)
    # cof_ij = J_{i+1, j+1} J_{i+2, j+2} − J_{i+1, j+2} J_{i+2, j+1} (indices cyclic)
    return np.roll(a, -1, axis=-2) * np.roll(b, -2, axis=-2) - np.roll(b, -1, axis=-2) * np.roll(
        a, -2, axis=-2
    )


def determinants(J: np.ndarray, cof: np.ndarray) -> np.ndarray:
    """det J (...) of a stack (..., d, d) from its cofactors `cof`, along row 0."""
    det = J[..., 0, 0] * cof[..., 0, 0]
    for j in range(1, J.shape[-1]):
        det += J[..., 0, j] * cof[..., 0, j]
    return det


def _dets(J: np.ndarray) -> np.ndarray:
    """det J (...) of a stack (..., d, d); in 2D directly, without the cofactors."""
    if J.shape[-1] == 2:
        return J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    # along row 0 with only that row's cofactors (as `determinants(J, cofactors(J))`, bit for bit)
    det = J[..., 0, 0] * (J[..., 1, 1] * J[..., 2, 2] - J[..., 1, 2] * J[..., 2, 1])
    det += J[..., 0, 1] * (J[..., 1, 2] * J[..., 2, 0] - J[..., 1, 0] * J[..., 2, 2])
    det += J[..., 0, 2] * (J[..., 1, 0] * J[..., 2, 1] - J[..., 1, 1] * J[..., 2, 0])
    return det


def solve2(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """J⁻¹ r for stacks of 2×2 matrices J (..., 2, 2) and vectors r (..., 2), by Cramer's rule
    (NaN or inf where J is singular)."""
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]  # (...,)
    x0 = J[..., 1, 1] * r[..., 0] - J[..., 0, 1] * r[..., 1]
    x1 = J[..., 0, 0] * r[..., 1] - J[..., 1, 0] * r[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([x0, x1], axis=-1) / det[..., None]


def jacobian_determinants(mesh: Mesh, pts: np.ndarray) -> np.ndarray:
    """det ∂x/∂ξ of every cell at reference points `pts` (n_pts, d): (n_cells, n_pts)."""
    ref = reference_element(mesh.cell_type)
    return _dets(ref.jacobians(mesh.points[mesh.cells], pts))  # (n_cells, n_pts)


# the smallest cell extent, relative to the mesh's, that `check_cells` accepts: the coordinates'
# rounding (~1e-16 of the mesh's extent) is then 1e-6 of the cell
MIN_CELL = 1e-10


def check_cells(mesh: Mesh, chunk: int = CHUNK) -> None:
    """Refuse inverted or degenerate cells: ValueError naming the first cell with det J ≤ 0
    relative to its own size, 1e-14 × h^d (h the longest column of J), or smaller than
    MIN_CELL × the mesh's extent (lost in the coordinates' rounding), at the reference
    element's `check_points` (the centroid of a simplex; the corners of a quadrilateral, where
    its affine det J is extreme; the 8 corners and the 27 Gauss points of a hexahedron),
    `chunk` cells at a time. A well-shaped cell passes however small adaptive refinement makes
    it, down to MIN_CELL."""
    ref = reference_element(mesh.cell_type)  # ValueError for points and cells of no cell type
    pts = ref.check_points  # (n_pts, d)
    extent = np.ptp(mesh.points, axis=0).max() if mesh.n_nodes else 1.0
    bad = []
    for lo in range(0, mesh.n_cells, chunk):
        J = ref.jacobians(mesh.points[mesh.cells[lo : lo + chunk]], pts)  # (k, n_pts, d, d)
        h = np.sqrt(np.einsum("cpij,cpij->cpj", J, J).max(axis=(1, 2)))  # (k,) longest ∂x/∂ξ_j
        flat = (_dets(J) <= 1e-14 * (h**ref.dim)[:, None]).any(axis=1)  # (k,)
        bad.append(np.flatnonzero(flat | (h < MIN_CELL * extent)) + lo)  # (n_bad,)
    bad = np.concatenate(bad) if bad else np.zeros(0, int)
    if bad.size:
        raise ValueError(
            f"inverted or degenerate cell {bad[0]} (nodes {mesh.cells[bad[0]].tolist()}): "
            f"det J <= 0; {bad.size} bad cell(s) in total"
        )
