"""Transfer between levels: a coarse level's solution carried to a finer level of a 2D or 3D
bodies model (nested iteration's warm start: `prolongate`, `carried_start`), and the errors of
a scalar or vector nodal field against a finer level's solution (`mixvi study`'s reference
mode for plug-ins without an exact solution). Point location and evaluation: `fem.locate`."""

from __future__ import annotations

from typing import Any

import numpy as np

from fem import assembly
from fem.locate import OUTSIDE_TOL, evaluate, interpolate, locate
from fem.mesh import Mesh
from vi_core.ssn import tied_start

# Nested iteration's start guess (the contact plug-in's warm starts, 2D and 3D): a coarse
# node whose interpolated ratio |λ_t|/ρ reaches 1 − ON_BOUND starts on the friction bound. An
# internal active-set guess, never a reported state (those follow from the answer by
# vi_core.states): a wrong guess costs the fine level a Newton step, never a wrong answer.
ON_BOUND = 1e-9


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


def prolongate(coarse: Any, x: np.ndarray, fine: Any) -> tuple[np.ndarray, int]:
    """The full vector x (n_full,) of a coarse level of a 2D or 3D bodies model carried to the
    finer level `fine` of the same scene: each body's displacement and potential, P1/Q1 nodal
    fields, evaluated at the fine body's nodes (`fem.locate`), the fine prescribed values kept
    on the fixed entries. For nested meshes this is the multigrid prolongation; where the fine
    mesh is not nested in the coarse one (new nodes of a refined curved boundary, meshes
    generated per level) it is interpolation, and a fine node outside the coarse mesh is
    extrapolated from the nearest cell. Returns the fine full vector (n_full_fine,) and the
    number of fine nodes outside the coarse meshes (by more than OUTSIDE_TOL in reference
    coordinates)."""
    out = fine.values.copy()  # (n_full_fine,)
    fixed = np.ones(out.size, dtype=bool)
    fixed[fine.free] = False
    outside = 0
    for bc, bf in zip(coarse.bodies, fine.bodies, strict=True):
        u, phi = bc.split(x[bc.offset : bc.offset + bc.size])  # (N, d), (N,) or None
        nodal = u if phi is None else np.column_stack([u, phi])  # (N, d [+ 1])
        cell, xi, dist = locate(bc.mesh, bf.mesh.points)
        vals = interpolate(bc.mesh, nodal, cell, xi)  # (N_f, d [+ 1])
        outside += int((dist > OUTSIDE_TOL).sum())
        d = bf.dim
        body = np.empty(bf.size)
        body[: d * bf.n_nodes] = vals[:, :d].ravel()  # node-major
        if bf.has_potential:
            body[d * bf.n_nodes :] = vals[:, d]
        sl = slice(bf.offset, bf.offset + bf.size)
        out[sl] = np.where(fixed[sl], out[sl], body)
    return out, outside


def carried_start(
    coarse: Any, coarse_sol: Any, fine: Any, lam0: np.ndarray, tied: np.ndarray | None = None
) -> dict:
    """The nested warm start of a bodies model with contact multipliers λ0 (m,) already
    predicted on `fine`: u0, the coarse solution carried to the fine nodes (`prolongate`), tied
    where λ0 predicts a tied row, or on the rows `tied` (m,) bool (`vi_core.ssn.tied_start`).
    Returns the keyword arguments of the fine solve ("lam0", "u0") and what was carried
    ("start": how u0 was made, the fine nodes outside the coarse mesh); without a condensation
    of B to tie u0 with, λ0 only."""
    x, outside = prolongate(coarse, coarse.full(coarse_sol.u), fine)
    u0 = tied_start(fine.vi, x[fine.free], lam0, tied)
    if u0 is None:
        return {"lam0": lam0, "start": {"u0": "not carried: B has no condensation to tie it"}}
    potential = any(b.has_potential for b in fine.bodies)
    how = f"the coarse displacement{' and potential' * potential} interpolated (P1/Q1)"
    return {
        "lam0": lam0,
        "u0": u0,
        "start": {
            "u0": f"{how} at the fine nodes, tied on the rows λ0 predicts tied",
            "outside_nodes": outside,
        },
    }
