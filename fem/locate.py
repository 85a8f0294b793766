"""Point location in a 2D or 3D P1/Q1 mesh: the cell that holds a point and the point's
reference coordinates in it, and a nodal P1/Q1 field evaluated at arbitrary points (the
transfer between the levels of a scene: the multigrid prolongation wherever the meshes are
nested, interpolation elsewhere).

A point is looked for in the cell with the nearest centroid, then, if it lies outside that
one by more than OUTSIDE_TOL, among the cells with the nearest centroids, by inverting the
cell maps (Newton; exact after one step for P1). A point outside every candidate (a refined
curved boundary's new node, which lies outside the coarse mesh) gets the candidate it is
least outside of, and the field there is extrapolated from that cell. So is a point inside
the mesh whose cell is not among the candidates (possible on strongly graded meshes, whose
nearest centroids need not be those of the cells around a point); `locate`'s third output
tells both apart from points found inside.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from fem.elements import ReferenceElement, reference_element
from fem.elements3d import CELL_TYPES as CELL_TYPES_3D
from fem.elements3d import ReferenceElement3D, reference_element3d
from fem.mesh import Mesh
from fem.mesh3d import Mesh3D

CHUNK = 32_768  # point-cell pairs inverted at once (memory: arrays of (CHUNK, n_loc, d) floats)
OUTSIDE_TOL = 1e-9  # reference coordinates: a point farther out of a cell is outside it
# cells with the nearest centroids tried for a point outside the nearest one, per dimension
CANDIDATES = {2: 8, 3: 12}
NEWTON_STEPS = 8  # at most, inverting a cell map (an affine cell: one step)
NEWTON_TOL = 1e-13  # reference coordinates: a Newton step this small has converged


def _reference(cell_type: str) -> ReferenceElement | ReferenceElement3D:
    """The reference element of a 2D or 3D cell type."""
    if cell_type in CELL_TYPES_3D:
        return reference_element3d(cell_type)
    return reference_element(cell_type)


def outside(cell_type: str, xi: np.ndarray) -> np.ndarray:
    """How far reference points xi (..., d) lie outside the reference cell (...,) (≤ 0
    inside): the simplex {ξ ≥ 0, Σξ ≤ 1} (triangle, tetra) or the box [−1, 1]^d (quad,
    hexahedron)."""
    if cell_type in ("triangle", "tetra"):
        return np.maximum(-xi.min(axis=-1), xi.sum(axis=-1) - 1.0)
    return np.abs(xi).max(axis=-1) - 1.0


def locate(
    mesh: Mesh | Mesh3D, pts: np.ndarray, candidates: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cell (M,) and reference coordinates (M, d) of each point of `pts` (M, d) in
    `mesh`, and how far each lies outside that cell in reference coordinates (M,) (≤ 0
    inside: `outside`).

    A point is looked for in the cell with the nearest centroid, then, if it lies outside that
    one by more than OUTSIDE_TOL, among the `candidates` (default CANDIDATES of the mesh's
    dimension) cells with the nearest centroids; a point outside every candidate gets the
    candidate it is least outside of (extrapolation)."""
    d = mesh.points.shape[1]
    tree = cKDTree(mesh.points[mesh.cells].mean(axis=1))  # (n_cells, d) centroids
    cell = tree.query(pts, k=1)[1].astype(np.int64)  # (M,)
    xi = _invert(mesh, pts, cell[:, None])[:, 0]  # (M, d)
    out = outside(mesh.cell_type, xi)  # (M,)
    retry = np.flatnonzero(out > OUTSIDE_TOL)
    k = min(CANDIDATES[d] if candidates is None else candidates, mesh.n_cells)
    if retry.size and k > 1:
        cand = tree.query(pts[retry], k=k)[1].reshape(retry.size, k)  # (M_r, k)
        xr = _invert(mesh, pts[retry], cand)  # (M_r, k, d)
        outr = outside(mesh.cell_type, xr)  # (M_r, k)
        best = np.argmin(outr, axis=1)  # (M_r,)
        rows = np.arange(retry.size)
        cell[retry], xi[retry], out[retry] = cand[rows, best], xr[rows, best], outr[rows, best]
    return cell, xi, out


def _invert(mesh: Mesh | Mesh3D, pts: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """Reference coordinates (M, k, d) of the points `pts` (M, d) in each of their candidate
    cells `cand` (M, k): Newton on the cell map, CHUNK point-cell pairs at a time."""
    ref = _reference(mesh.cell_type)
    M, k = cand.shape
    d = pts.shape[1]
    xi = np.empty((M, k, d))
    step = max(1, CHUNK // k)
    for lo in range(0, M, step):
        c = cand[lo : lo + step].reshape(-1)  # (c k,)
        p = np.repeat(pts[lo : lo + step], k, axis=0)  # (c k, d)
        X = mesh.points[mesh.cells[c]]  # (c k, n_loc, d)
        x = np.broadcast_to(ref.centroid, p.shape).copy()  # (c k, d)
        for _ in range(NEWTON_STEPS):
            phi, dphi = ref.values(x), ref.gradients(x)  # (c k, n_loc), (c k, n_loc, d)
            r = np.einsum("ca,cai->ci", phi, X) - p  # (c k, d)
            J = np.einsum("cai,caj->cij", X, dphi)  # (c k, d, d) ∂x_i/∂ξ_j
            dx = np.linalg.solve(J, r[:, :, None])[:, :, 0]  # (c k, d)
            x -= dx
            if np.abs(dx).max(initial=0.0) < NEWTON_TOL:
                break
        xi[lo : lo + step] = x.reshape(-1, k, d)
    return xi


def interpolate(
    mesh: Mesh | Mesh3D, nodal: np.ndarray, cell: np.ndarray, xi: np.ndarray
) -> np.ndarray:
    """(M, c): the P1/Q1 function with nodal values `nodal` (N, c) or (N,) at the reference
    points xi (M, d) of the cells `cell` (M,)."""
    phi = _reference(mesh.cell_type).values(xi)  # (M, n_loc)
    vals = np.asarray(nodal, dtype=float).reshape(mesh.n_nodes, -1)[mesh.cells[cell]]
    return np.einsum("ma,mac->mc", phi, vals)  # (M, c)


def evaluate(
    mesh: Mesh | Mesh3D, nodal: np.ndarray, pts: np.ndarray, candidates: int | None = None
) -> np.ndarray:
    """The P1/Q1 function with nodal values `nodal` (N, c) or (N,) at the points `pts`
    (M, d): (M, c); a point outside the mesh is extrapolated from the cell `locate` gives it."""
    cell, xi, _ = locate(mesh, pts, candidates)
    return interpolate(mesh, nodal, cell, xi)
