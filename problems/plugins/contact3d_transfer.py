"""Transfer between the levels of a 3D contact scene: a coarse P1/Q1 solution evaluated at the
nodes of a finer mesh (nested iteration's displacement and potential warm start,
`contact3d.warm_start`).

The fine mesh of a level need not number its nodes after the coarse one (`fem.mesh3d.box` builds
every level at once, curved bottoms move the new nodes, extruded sections renumber), so the fine
nodes are located in the coarse cells (centroid search, the cell maps inverted), which is the
multigrid prolongation wherever the meshes are nested and interpolation elsewhere.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from fem.elements3d import reference_element3d
from fem.mesh3d import Mesh3D

CHUNK = 32_768  # point-cell pairs inverted at once (memory: arrays of (CHUNK, 8, 3) floats)
OUTSIDE_TOL = 1e-9  # reference coordinates: a point farther out of a cell is outside it
CANDIDATES = 12  # cells with the nearest centroids tried for a point outside the nearest one


def _outside(cell_type: str, xi: np.ndarray) -> np.ndarray:
    """How far reference points (..., 3) lie outside the reference cell (≤ 0 inside)."""
    if cell_type == "tetra":
        return np.maximum(-xi.min(axis=-1), xi.sum(axis=-1) - 1.0)
    return np.abs(xi).max(axis=-1) - 1.0


def _invert(mesh: Mesh3D, pts: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """Reference coordinates (M, k, 3) of the points `pts` (M, 3) in each of their candidate
    cells `cand` (M, k): Newton on the cell map (one step for an affine tetrahedron)."""
    ref = reference_element3d(mesh.cell_type)
    M, k = cand.shape
    xi = np.empty((M, k, 3))
    step = max(1, CHUNK // k)
    for lo in range(0, M, step):
        c = cand[lo : lo + step].reshape(-1)  # (c k,)
        p = np.repeat(pts[lo : lo + step], k, axis=0)  # (c k, 3)
        X = mesh.points[mesh.cells[c]]  # (c k, n_loc, 3)
        x = np.broadcast_to(ref.centroid, p.shape).copy()  # (c k, 3)
        for _ in range(8):
            phi, dphi = ref.values(x), ref.gradients(x)  # (c k, n_loc), (c k, n_loc, 3)
            r = np.einsum("ca,cai->ci", phi, X) - p  # (c k, 3)
            J = np.einsum("cai,caj->cij", X, dphi)  # (c k, 3, 3) ∂x_i/∂ξ_j
            dx = np.linalg.solve(J, r[:, :, None])[:, :, 0]  # (c k, 3)
            x -= dx
            if np.abs(dx).max(initial=0.0) < 1e-13:
                break
        xi[lo : lo + step] = x.reshape(-1, k, 3)
    return xi


def locate(mesh: Mesh3D, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cell (M,) and reference coordinates (M, 3) of each point of `pts` (M, 3) in `mesh`,
    and how far it lies outside that cell in reference coordinates (M,) (≤ 0 inside).

    Each point is looked for in the cell with the nearest centroid, then, if it lies outside
    that one by more than OUTSIDE_TOL, among the CANDIDATES cells with the nearest centroids; a
    point outside all of them (a curved boundary's new node) gets the one it is least outside
    of (extrapolation)."""
    tree = cKDTree(mesh.points[mesh.cells].mean(axis=1))  # (n_cells, 3) centroids
    cell = tree.query(pts, k=1)[1].astype(np.int64)  # (M,)
    xi = _invert(mesh, pts, cell[:, None])[:, 0]  # (M, 3)
    out = _outside(mesh.cell_type, xi)  # (M,)
    retry = np.flatnonzero(out > OUTSIDE_TOL)
    k = min(CANDIDATES, mesh.n_cells)
    if retry.size and k > 1:
        cand = tree.query(pts[retry], k=k)[1].reshape(retry.size, k)  # (M_r, k)
        xr = _invert(mesh, pts[retry], cand)  # (M_r, k, 3)
        outr = _outside(mesh.cell_type, xr)  # (M_r, k)
        best = np.argmin(outr, axis=1)  # (M_r,)
        rows = np.arange(retry.size)
        cell[retry], xi[retry], out[retry] = cand[rows, best], xr[rows, best], outr[rows, best]
    return cell, xi, out


def evaluate(mesh: Mesh3D, nodal: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, int]:
    """The P1/Q1 function with nodal values `nodal` (N, c) at the points `pts` (M, 3): (M, c),
    and how many points lie outside the mesh (by more than OUTSIDE_TOL; extrapolated)."""
    cell, xi, out = locate(mesh, pts)
    phi = reference_element3d(mesh.cell_type).values(xi)  # (M, n_loc)
    vals = np.einsum("ma,mac->mc", phi, nodal[mesh.cells[cell]])  # (M, c)
    return vals, int((out > OUTSIDE_TOL).sum())


def prolongate(coarse: Any, x: np.ndarray, fine: Any) -> tuple[np.ndarray, int]:
    """The full vector x (n_full,) of a coarse level of a 3D bodies model carried to the finer
    level `fine` of the same scene: each body's displacement (and potential) evaluated at the
    fine body's nodes, the fine prescribed values kept on the fixed entries. Returns the fine
    full vector (n_full_fine,) and the number of fine nodes outside the coarse meshes."""
    out = fine.values.copy()  # (n_full_fine,)
    fixed = np.ones(out.size, dtype=bool)
    fixed[fine.free] = False
    outside = 0
    for bc, bf in zip(coarse.bodies, fine.bodies, strict=True):
        u, phi = bc.split(x[bc.offset : bc.offset + bc.size])  # (N, 3), (N,) or None
        nodal = u if phi is None else np.column_stack([u, phi])  # (N, 3 [+ 1])
        vals, n_out = evaluate(bc.mesh, nodal, bf.mesh.points)  # (N_f, 3 [+ 1])
        outside += n_out
        body = np.empty(bf.size)
        body[: 3 * bf.n_nodes] = vals[:, :3].ravel()  # node-major
        if bf.has_potential:
            body[3 * bf.n_nodes :] = vals[:, 3]
        sl = slice(bf.offset, bf.offset + bf.size)
        out[sl] = np.where(fixed[sl], out[sl], body)
    return out, outside
