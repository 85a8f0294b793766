"""Jacobians of the cell maps of a `fem.mesh.Mesh` (2D or 3D) and the check that every cell
is positively oriented and not degenerate."""

from __future__ import annotations

import numpy as np

from .elements import reference_element
from .elements3d import reference_element3d
from .mesh import Mesh


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


def reference(cell_type: str):
    """The reference element (`fem.elements` or `fem.elements3d`) of a mesh's cell type."""
    return (
        reference_element3d(cell_type)
        if cell_type in ("tetra", "hexahedron")
        else (reference_element(cell_type))
    )


def jacobian_determinants(mesh: Mesh, pts: np.ndarray) -> np.ndarray:
    """det ∂x/∂ξ of every cell at reference points `pts` (n_pts, d): (n_cells, n_pts)."""
    ref = reference(mesh.cell_type)
    X = mesh.points[mesh.cells]  # (n_cells, n_loc, d)
    J = np.einsum("cai,qaj->cqij", X, ref.gradients(pts), optimize=True)  # (n_c, n_pts, d, d)
    if mesh.dim == 2:
        return J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    cof0 = np.cross(J[..., 1, :], J[..., 2, :])  # (n_c, n_pts, 3) row 0 of `cofactors`
    return np.einsum("...j,...j->...", J[..., 0, :], cof0)  # along row 0


def check_cells(mesh: Mesh) -> None:
    """Refuse inverted or degenerate cells: ValueError naming the first cell with det J ≤ 0.

    det J is constant on a simplex and affine on a bilinear quadrilateral (checked at the
    corners, where it is extreme); on a hexahedron it is checked at the 8 corners (positivity
    there is necessary: they are 6 × the volumes of the corner tetrahedra) and at the 27 points
    of the 3×3×3 Gauss rule, where the integrals use it.
    """
    ctype = mesh.cell_type  # ValueError for points and cells of no cell type
    ref = reference(ctype)
    if ctype in ("triangle", "tetra"):
        pts = ref.centroid[None, :]  # (1, d)
    elif ctype == "quad":
        pts = ref.vertices  # (4, 2)
    else:
        pts = np.concatenate([ref.vertices, ref.quadrature(4)[0]])  # (35, 3)
    det = jacobian_determinants(mesh, pts)  # (n_cells, n_pts)
    scale = np.ptp(mesh.points, axis=0).max() ** mesh.dim if mesh.n_nodes else 1.0
    bad = np.flatnonzero((det <= 1e-14 * scale).any(axis=1))  # (n_bad,)
    if bad.size:
        raise ValueError(
            f"inverted or degenerate cell {bad[0]} (nodes {mesh.cells[bad[0]].tolist()}): "
            f"det J <= 0; {bad.size} bad cell(s) in total"
        )
