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


def evaluate(mesh: Mesh, nodal: np.ndarray, pts: np.ndarray, candidates: int = 8) -> np.ndarray:
    """The P1/Q1 function with nodal values `nodal` (N, k) at points `pts` (M, 2): (M, k).

    Each point is located among the `candidates` cells with the nearest centroids by inverting
    the cell maps (Newton; exact after one step for P1); a point outside every candidate (a
    refined curved boundary) is extrapolated from the candidate it is least outside of.
    """
    ref = reference_element(mesh.cell_type)
    X = mesh.points[mesh.cells]  # (n_cells, n_loc, 2)
    k = min(candidates, mesh.n_cells)
    _, cand = cKDTree(X.mean(axis=1)).query(pts, k=k)  # (M, k)
    cand = cand.reshape(len(pts), k)
    Xc = X[cand]  # (M, k, n_loc, 2)
    xi = np.broadcast_to(ref.centroid, cand.shape + (2,)).copy()  # (M, k, 2)
    for _ in range(6):
        flat = xi.reshape(-1, 2)
        phi = ref.values(flat).reshape(xi.shape[:2] + (-1,))  # (M, k, n_loc)
        dphi = ref.gradients(flat).reshape(xi.shape[:2] + (-1, 2))  # (M, k, n_loc, 2)
        r = np.einsum("mka,mkai->mki", phi, Xc) - pts[:, None, :]  # (M, k, 2)
        J = np.einsum("mkai,mkaj->mkij", Xc, dphi)  # (M, k, 2, 2) ∂x_i/∂ξ_j
        xi = xi - np.linalg.solve(J, r[..., None])[..., 0]
    best = np.argmin(_outside(mesh.cell_type, xi), axis=1)  # (M,)
    rows = np.arange(len(pts))
    phi = ref.values(xi[rows, best])  # (M, n_loc)
    vals = np.asarray(nodal, dtype=float).reshape(mesh.n_nodes, -1)[mesh.cells[cand[rows, best]]]
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
