"""Transfer between levels: a coarse P1/Q1 function evaluated on a finer mesh, and the errors
of a scalar or vector nodal field against a finer level's solution (`mixvi study`'s reference
mode for plug-ins without an exact solution)."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from fem import assembly
from fem.elements import reference_element
from fem.mesh import Mesh


def _outside(cell_type: str, xi: np.ndarray) -> np.ndarray:
    """How far reference points (..., 2) lie outside the reference cell (≤ 0 inside)."""
    s, t = xi[..., 0], xi[..., 1]
    if cell_type == "triangle":
        return np.maximum.reduce([-s, -t, s + t - 1])
    return np.maximum(np.abs(s), np.abs(t)) - 1


CHUNK = 65_536  # point-cell pairs tried at once (memory: arrays of (CHUNK, 4, 2) floats)
OUTSIDE_TOL = 1e-9  # reference coordinates: a point farther out of a cell is outside it


def locate(
    mesh: Mesh, pts: np.ndarray, candidates: int = 8
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cell (M,) and reference coordinates (M, 2) of each point of `pts` (M, 2) in
    `mesh`, and how far each lies outside that cell in reference coordinates (M,) (≤ 0
    inside: `_outside`).

    A point is looked for in the cell with the nearest centroid, then, if it lies outside that
    one by more than OUTSIDE_TOL, among the `candidates` cells with the nearest centroids, by
    inverting the cell maps (Newton; exact after one step for P1); a point outside every
    candidate (a refined curved boundary) gets the candidate it is least outside of.
    """
    tree = cKDTree(mesh.points[mesh.cells].mean(axis=1))  # cell centroids
    cell = tree.query(pts, k=1)[1]  # (M,)
    xi, out = _invert(mesh, pts, cell[:, None])
    cell, xi, out = cell.astype(np.int64), xi[:, 0], out[:, 0]
    retry = np.flatnonzero(out > OUTSIDE_TOL)
    k = min(candidates, mesh.n_cells)
    if retry.size and k > 1:
        cand = tree.query(pts[retry], k=k)[1].reshape(retry.size, k)  # (M_r, k)
        xr, outr = _invert(mesh, pts[retry], cand)  # (M_r, k, 2), (M_r, k)
        best = np.argmin(outr, axis=1)  # (M_r,)
        rows = np.arange(retry.size)
        cell[retry], xi[retry], out[retry] = cand[rows, best], xr[rows, best], outr[rows, best]
    return cell, xi, out


def _invert(mesh: Mesh, pts: np.ndarray, cand: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference coordinates (M, k, 2) of the points `pts` (M, 2) in each of their candidate
    cells `cand` (M, k), and how far outside each cell they lie (M, k), CHUNK pairs at a time."""
    ref = reference_element(mesh.cell_type)
    M, k = cand.shape
    xi = np.empty((M, k, 2))
    step = max(1, CHUNK // k)
    for lo in range(0, M, step):
        c = cand[lo : lo + step].reshape(-1)  # (c k,)
        p = np.repeat(pts[lo : lo + step], k, axis=0)  # (c k, 2)
        X = mesh.points[mesh.cells[c]]  # (c k, n_loc, 2)
        x = np.broadcast_to(ref.centroid, p.shape).copy()  # (c k, 2)
        for _ in range(6):
            phi, dphi = ref.values(x), ref.gradients(x)  # (c k, n_loc), (c k, n_loc, 2)
            r = (phi[:, :, None] * X).sum(axis=1) - p  # (c k, 2)
            J = (X[:, :, :, None] * dphi[:, :, None, :]).sum(axis=1)  # (c k, 2, 2) ∂x_i/∂ξ_j
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]  # (c k,)
            dx = (
                np.stack(
                    [
                        J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1],
                        J[:, 0, 0] * r[:, 1] - J[:, 1, 0] * r[:, 0],
                    ],
                    axis=1,
                )
                / det[:, None]
            )  # (c k, 2)
            x -= dx
            if np.abs(dx).max(initial=0.0) < 1e-14:  # converged (an affine cell: one step)
                break
        xi[lo : lo + step] = x.reshape(-1, k, 2)
    return xi, _outside(mesh.cell_type, xi)


def evaluate(mesh: Mesh, nodal: np.ndarray, pts: np.ndarray, candidates: int = 8) -> np.ndarray:
    """The P1/Q1 function with nodal values `nodal` (N, k) at points `pts` (M, 2): (M, k);
    a point outside the mesh is extrapolated from the cell `locate` gives it."""
    cell, xi, _ = locate(mesh, pts, candidates)
    return _values(mesh, nodal, cell, xi)


def _values(mesh: Mesh, nodal: np.ndarray, cell: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """(M, k): the P1/Q1 function with nodal values `nodal` (N, k) at reference points xi
    (M, 2) of the cells `cell` (M,)."""
    phi = reference_element(mesh.cell_type).values(xi)  # (M, n_loc)
    vals = np.asarray(nodal, dtype=float).reshape(mesh.n_nodes, -1)[mesh.cells[cell]]
    return np.einsum("ma,mak->mk", phi, vals)  # (M, k)


def nodal_reference_errors(
    mesh: Mesh, nodal: np.ndarray, ref_mesh: Mesh, ref_nodal: np.ndarray
) -> dict[str, float]:
    """‖·‖_{H¹} and ‖·‖_{L²} of the difference of the coarse field `nodal` (N, k) or (N,) on
    `mesh` and the finer `ref_nodal` (N_ref, k) or (N_ref,) on `ref_mesh`, measured with the
    finer mesh's mass and stiffness matrices (exact for nested meshes)."""
    d = np.asarray(ref_nodal, float).reshape(ref_mesh.n_nodes, -1)  # (N_ref, k)
    d = d - evaluate(mesh, nodal, ref_mesh.points)  # (N_ref, k)
    M = assembly.mass_matrix(ref_mesh).tocsr()
    K = assembly.stiffness_matrix(ref_mesh).tocsr()
    l2 = float(sum(d[:, c] @ (M @ d[:, c]) for c in range(d.shape[1])))
    h1 = l2 + float(sum(d[:, c] @ (K @ d[:, c]) for c in range(d.shape[1])))
    return {"h1": float(np.sqrt(h1)), "l2": float(np.sqrt(l2))}


# ------------------------------------------------------- the scalar plug-ins' study hooks
def scalar_mesh_size(model: Any) -> float:
    """h of the built level (contract: `mesh_size`) of a plug-in with one `model.mesh`."""
    return model.mesh.h


def scalar_exact_errors(model: Any, sol: Any) -> dict[str, float] | None:
    """H¹ and L² errors (keys "h1", "l2") against the scene's [exact] table (contract:
    `exact_errors`); None without one."""
    if model.exact is None:
        return None
    err = model.errors(sol)
    return {k: err[k] for k in ("h1", "l2")}


def scalar_reference_errors(model: Any, sol: Any, ref: Any, ref_sol: Any) -> dict:
    """‖u_h − u_ref‖ in H¹ and L² against the finer level `ref` (contract: `reference_errors`)
    for a plug-in whose model maps its unknowns to nodal values with `model.full`."""
    return nodal_reference_errors(model.mesh, model.full(sol.u), ref.mesh, ref.full(ref_sol.u))


def prolongate(coarse: Any, x: np.ndarray, fine: Any) -> tuple[np.ndarray, int]:
    """The full vector x (n_full,) of a coarse level of a bodies model (`BodiesModel`) carried
    to the finer level `fine` (the same scene): each body's displacement and potential, P1/Q1
    nodal fields, evaluated at the fine body's nodes (`evaluate`). For nested meshes this is
    the multigrid prolongation; where the fine mesh is not nested in the coarse one (new nodes
    of a refined curved boundary, meshes generated per level) it is interpolation, and a fine
    node outside the coarse mesh is extrapolated from the nearest cell. Returns the fine full
    vector (n_full_fine,) and the number of fine nodes outside the coarse mesh (by more than
    OUTSIDE_TOL in reference coordinates)."""
    out = np.zeros(fine.values.size)
    outside = 0
    for bc, bf in zip(coarse.bodies, fine.bodies, strict=True):
        u, phi = bc.split(x[bc.offset : bc.offset + bc.size])  # (N, d), (N,) or None
        nodal = u if phi is None else np.column_stack([u, phi])  # (N, d [+ 1])
        cell, xi, dist = locate(bc.mesh, bf.mesh.points)
        vals = _values(bc.mesh, nodal, cell, xi)  # (N_f, d [+ 1])
        d = bf.dim
        out[bf.offset : bf.offset + d * bf.n_nodes] = vals[:, :d].ravel()  # node-major
        if bf.has_potential:
            out[bf.offset + d * bf.n_nodes : bf.offset + bf.size] = vals[:, d]
        outside += int((dist > OUTSIDE_TOL).sum())
    return out, outside
