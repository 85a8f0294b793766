"""Checks of a built 3D contact model that do not trust the code that built it.

- `rigid_body_defect`: the six rigid-body modes r of each body are in the kernel of its
  assembled elasticity block (before Dirichlet reduction): max ‖K r‖ / (‖K‖_∞ ‖r‖_∞).
- `contact_row_defects`: each contact node's rows, read back from the assembled B as a 3×3 block
  R_k (rows of the node × its displacement dofs), must be W_k times an orthonormal right-handed
  frame whose normal row is the surface normal: W_k and n_k are recomputed from
  `fem.assembly3d` (its own face quadrature: W_k = ∫φ_k dA, n_k ∝ ∫φ_k n dA), not from
  `fem.surface3d`. Reported: the relative defects of the weights, of the normal rows, of
  orthonormality (R_k R_kᵀ = W_k² I on the rows a node carries) and the handedness
  (det R_k = W_k³ where all three rows are present).

A transposed frame block, a dropped entry of B or a wrong sign in a tangent frame each make
one of them O(1) (tests/problems/plugins/test_contact3d.py injects each).
"""

from __future__ import annotations

import numpy as np

from fem import assembly3d

from .contact3d_bodies import SURFACE_ORDER


def rigid_body_defect(body) -> float:
    """max over the six modes of ‖K r‖_∞ / (‖K‖_∞ ‖r‖_∞) of the body's elasticity block."""
    N = body.n_nodes
    K = body.A[: 3 * N, : 3 * N]
    P = body.mesh.points  # (N, 3)
    modes = np.zeros((3 * N, 6))
    for k in range(3):
        modes[k::3, k] = 1.0
    for r, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        modes[i::3, 3 + r] = -P[:, j]
        modes[j::3, 3 + r] = P[:, i]
    knorm = float(abs(K).sum(axis=1).max())
    return float(np.max(np.abs(K @ modes).max(axis=0) / (knorm * np.abs(modes).max(axis=0))))


def _independent_weights(mesh, part: str) -> tuple[np.ndarray, np.ndarray]:
    """(N,) ∫φ_i dA and (N, 3) ∫φ_i n dA over boundary `part`, by fem.assembly3d's quadrature."""
    order = SURFACE_ORDER[mesh.cell_type]  # the plug-in's order (its own rule, not its code)
    _, w, phi, n = assembly3d.face_geometry(mesh, part, order)  # (n_f, q), (q, k), (n_f, q, 3)
    faces = mesh.boundaries[part]  # (n_f, k)
    W = np.zeros(mesh.n_nodes)
    np.add.at(W, faces.ravel(), (w @ phi).ravel())
    Nn = np.zeros((mesh.n_nodes, 3))
    np.add.at(Nn, faces.ravel(), np.einsum("fq,qa,fqi->fai", w, phi, n).reshape(-1, 3))
    return W, Nn


def contact_row_defects(model) -> dict[str, float]:
    """The relative defects of the contact rows (module docstring)."""
    c = model.contact
    body, surf = c.slave, c.surf
    W_ind, N_ind = _independent_weights(body.mesh, c.slave_part)
    W, nrm = W_ind[surf.nodes], N_ind[surf.nodes]
    nrm = nrm / np.linalg.norm(nrm, axis=1)[:, None]
    dofs = body.u_dofs(surf.nodes)  # (k, 3)
    Bc = c.B_full.tocsc()
    k = surf.size
    R = np.zeros((k, 3, 3))  # rows: normal, t1, t2 (zero where not carried)
    N_n, N_b, _ = c.sizes
    slots = [(c.rows_n, np.arange(N_n), 0)]
    slots.append((c.disc, N_n + 2 * np.arange(N_b), 1))
    slots.append((c.disc, N_n + 2 * np.arange(N_b) + 1, 2))
    for slot in (0, 1):
        sel = np.flatnonzero(c.line_slot == slot)
        slots.append((c.line[sel], N_n + 2 * N_b + sel, 1 + slot))
    has = np.zeros((k, 3), dtype=bool)  # the rows each node is declared to carry
    for nodes, rows, s in slots:
        has[nodes, s] = True
        for comp in range(3):
            col = Bc[:, dofs[nodes, comp]]  # (m, len(nodes))
            R[nodes, s, comp] = np.asarray(col[rows, np.arange(nodes.size)]).ravel()
    weight_defect = float(
        np.max(
            np.abs(np.linalg.norm(R, axis=2)[has] - np.broadcast_to(W[:, None], has.shape)[has])
            / W.max()
        )
    )
    normal_defect = float(
        np.max(np.abs(R[c.rows_n, 0] - W[c.rows_n, None] * nrm[c.rows_n]), initial=0.0) / W.max()
    )
    G = np.einsum("kij,klj->kil", R, R)  # (k, 3, 3) R Rᵀ
    target = W[:, None, None] ** 2 * np.eye(3)[None] * (has[:, :, None] & has[:, None, :])
    ortho = float(np.max(np.abs(G - target)) / W.max() ** 2)
    full = has.all(axis=1)
    det = np.linalg.det(R[full])
    hand = float(np.max(np.abs(det - W[full] ** 3), initial=0.0) / W.max() ** 3)
    return {
        "weights": weight_defect,
        "normals": normal_defect,
        "orthonormality": ortho,
        "handedness": hand,
    }


def checks(model) -> dict:
    """The summary entry "checks" of a 3D contact model."""
    out = {"rigid_body_defect": max(rigid_body_defect(b) for b in model.bodies)}
    if model.contact is not None and model.contact.master is None:
        out["contact_rows"] = contact_row_defects(model)
    return out
