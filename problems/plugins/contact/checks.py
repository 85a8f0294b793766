"""Checks of contact data and of built contact models that do not trust the code that built them.

- `finite_data` (2D and 3D, at build): every assembled number finite (SceneError otherwise).

3D models (summary.json "checks"):

- `rigid_body_defect`: the six rigid-body modes r of each body are in the kernel of its
  assembled elasticity block (before Dirichlet reduction): max ‖K r‖ / (‖K‖_∞ ‖r‖_∞).
- `contact_row_defects`: each contact node's rows, read back from the assembled B as a 3×3 block
  R_k (rows of the node × its displacement dofs), must be W_k times an orthonormal right-handed
  frame whose normal row is the surface normal: W_k and n_k are recomputed from
  `fem.assembly` (its own face quadrature: W_k = ∫φ_k dA, n_k ∝ ∫φ_k n dA), not from
  `fem.facets`. Reported: the relative defects of the weights, of the normal rows, of
  orthonormality (R_k R_kᵀ = W_k² I on the rows a node carries) and the handedness
  (det R_k = W_k³ where all three rows are present).

A transposed frame block, a dropped entry of B or a wrong sign in a tangent frame each make
one of them O(1) (tests/problems/plugins/contact/test_solid.py injects each).
- `separation` (unilateral contact on a rigid foundation): the remaining gap and λ_n of the
  solution, node by node, from the displacement (not from B): no penetration, no tension, no
  pressure where open, complementarity.
"""

from __future__ import annotations

import numpy as np

from fem import assembly
from problems.errors import SceneError
from vi_core import states as node_states

from .bodies import operator
from .interface import SURFACE_ORDER


def finite_data(A_full, f_full: np.ndarray, values: np.ndarray, contact) -> None:
    """Refuse data that overflow in assembly (each number finite, their products not): the
    stiffness, loads, prescribed values and the contact's friction bound (or Coulomb F) and
    initial gap (`model.mixed_vi`'s check, 2D and 3D)."""
    parts = {"stiffness (materials)": A_full.data, "loads": f_full, "Dirichlet values": values}
    if contact is not None:
        coulomb = contact.F is not None
        parts["friction coefficient F" if coulomb else "friction bound g"] = (
            contact.F if coulomb else contact.g
        )
        if contact.gap0 is not None:
            parts["gap"] = contact.gap0
    for what, arr in parts.items():
        if not np.isfinite(arr).all():
            raise SceneError(
                "(scene)", what, "data whose assembled system is finite (magnitudes overflow)"
            )


def rigid_body_defect(body) -> float:
    """max over the six modes of ‖K r‖_∞ / (‖K‖_∞ ‖r‖_∞) of the body's elasticity block."""
    N = body.n_nodes
    K = operator(body)[: 3 * N, : 3 * N]  # assembled again (a built model keeps A's rows
    # of the prescribed dofs only)
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
    """(N,) ∫φ_i dA and (N, 3) ∫φ_i n dA over boundary `part`, by fem.assembly's quadrature."""
    order = SURFACE_ORDER[mesh.cell_type]  # the plug-in's order (its own rule, not its code)
    _, w, phi, n = assembly.facet_geometry(mesh, part, order)  # (n_f, q), (q, k), (n_f, q, 3)
    faces = mesh.boundaries[part]  # (n_f, k)
    W = np.zeros(mesh.n_nodes)
    np.add.at(W, faces.ravel(), (w @ phi).ravel())
    Nn = np.zeros((mesh.n_nodes, 3))
    np.add.at(Nn, faces.ravel(), np.einsum("fq,qa,fqi->fai", w, phi, n).reshape(-1, 3))
    return W, Nn


def contact_row_defects(model) -> dict[str, float]:
    """The relative defects of the contact rows (module docstring)."""
    c = model.contact
    body, surf = c.slave, c.tr
    W_ind, N_ind = _independent_weights(body.mesh, c.slave_part)
    W, nrm = W_ind[surf.nodes], N_ind[surf.nodes]
    nrm = nrm / np.linalg.norm(nrm, axis=1)[:, None]
    dofs = body.u_dofs(surf.nodes)  # (k, 3)
    Bc = c.B_full.tocsc()
    k = surf.size
    R = np.zeros((k, 3, 3))  # rows: normal, t1, t2 (zero where not carried)
    idx_n, idx_b, idx_l = c.rows()
    slots = [(c.rows_n, idx_n, 0), (c.disc, idx_b[:, 0], 1), (c.disc, idx_b[:, 1], 2)]
    for slot in (0, 1):
        sel = np.flatnonzero(c.line_slot == slot)
        slots.append((c.line[sel], idx_l[sel], 1 + slot))
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


def solution_checks(model, sol) -> dict:
    """The summary entries "checks" of a solved 3D contact model: `checks` and, for
    unilateral contact, `separation`."""
    out = checks(model)
    c = model.contact
    if c is not None and c.law == "unilateral":
        out["separation"] = separation(model, sol)
    return out


def _shares(faces: np.ndarray, carry: np.ndarray | None) -> np.ndarray:
    """(n_f, m, m) the part of each face's local function a (last axis) that node t (middle)
    takes: the identity, or with carry (N,) bool ("merge") a node without carry gives its share
    to the face's carrying nodes next to it along an edge (to all carrying ones if none is),
    equally. Written apart from `fem.facets.multiplier_basis`."""
    n_f, m = faces.shape
    if carry is None:
        return np.broadcast_to(np.eye(m), (n_f, m, m))
    c = carry[faces]  # (n_f, m)
    out = np.where(c[:, :, None], np.eye(m)[None], 0.0)  # (n_f, m, m)
    for a in range(m):
        tgt = np.zeros_like(c)
        tgt[:, [(a - 1) % m, (a + 1) % m]] = True
        tgt &= c
        tgt = np.where(tgt.any(axis=1, keepdims=True), tgt, c)
        out[:, :, a] += tgt * (~c[:, a] / np.maximum(tgt.sum(axis=1), 1))[:, None]
    return out


def _nodal_means(mesh, part: str, f, carry: np.ndarray | None = None) -> np.ndarray:
    """(N,) ∫f φ̃_i dA / ∫φ̃_i dA over boundary `part` by fem.assembly's face quadrature (the
    nodal value of a friction field as the plug-in defines it, computed apart from it);
    φ̃ = φ, or merged by `_shares` with carry (N,) ("merge")."""
    order = SURFACE_ORDER[mesh.cell_type]
    x, w, phi, _ = assembly.facet_geometry(mesh, part, order)  # (n_f, q, 3), (n_f, q), (q, k)
    fv = np.broadcast_to(f(x[..., 0], x[..., 1], x[..., 2]), w.shape)  # (n_f, q)
    faces = mesh.boundaries[part]  # (n_f, m)
    sh = _shares(faces, carry)  # (n_f, m, m)
    loc_f = np.einsum("fta,fa->ft", sh, (w * fv) @ phi)  # (n_f, m) ∫_e f φ̃_t
    loc_1 = np.einsum("fta,fa->ft", sh, w @ phi)  # (n_f, m) ∫_e φ̃_t
    num, den = np.zeros(mesh.n_nodes), np.zeros(mesh.n_nodes)
    np.add.at(num, faces.ravel(), loc_f.ravel())
    np.add.at(den, faces.ravel(), loc_1.ravel())
    return num / np.where(den > 0, den, 1.0)


def _row_means(mesh, part: str, carry: np.ndarray | None, v: np.ndarray) -> np.ndarray:
    """(N, ...) Σ_j w_kj v_j / Σ_j w_kj, w_kj = ∫φ̃_k φ_j dA (= δ_kj ∫φ_k under "keep": the
    nodal values): what a contact row of node k reads of a nodal field v (N, ...), by
    fem.assembly's face quadrature and `_shares` (biorthogonality: ∫ψ_{e,a} φ_{e,b} =
    δ_ab ∫_e φ_a)."""
    order = SURFACE_ORDER[mesh.cell_type]
    _, w, phi, _ = assembly.facet_geometry(mesh, part, order)  # (n_f, q), (q, m)
    faces = mesh.boundaries[part]  # (n_f, m)
    sh = _shares(faces, carry) * (w @ phi)[:, None, :]  # (n_f, m, m) w of (target, source)
    tgt = np.broadcast_to(faces[:, :, None], sh.shape).ravel()
    src = np.broadcast_to(faces[:, None, :], sh.shape).ravel()
    num = np.zeros((mesh.n_nodes, *v.shape[1:]))
    np.add.at(num, tgt, sh.ravel().reshape(-1, *([1] * (v.ndim - 1))) * v[src])
    den = np.bincount(tgt, sh.ravel(), mesh.n_nodes)
    return num / np.where(den > 0, den, 1.0).reshape(-1, *([1] * (v.ndim - 1)))


def separation(model, sol) -> dict[str, float]:
    """A posteriori unilateral conditions of a solution, per normal node k: the remaining
    gap d_k, λ_n,k, |λ_t,k| and the slip. A rigid foundation: from the displacement itself, not
    from the assembled rows — d_k = gap(x_k) − n_k·u_k (n_k recomputed from `fem.assembly`'s
    face quadrature, gap from the scene's field), the slip |u_k − (n_k·u_k) n_k|; under
    "merge" the gap and u are the means the rows read (`_row_means`: ψ̃_k reaches the dropped
    neighbours), by a quadrature and a merge rule of this module. Two bodies, and a step of a
    load path (its slip since the previous step): from the rows,
    d_k = (gap_k − (B u)_n,k)/W_k and the slip |(B u − origin)_t,k|/W_k (the discrete
    conditions as assembled; tests/problems/plugins/contact/test_solid_unilateral.py checks
    the geometry apart).

    Reported, relative to the length scale max(|gap|, |u|) and the pressure scale max(λ_n):
    `penetration` max(−d_k, 0), `tension` max(−λ_n,k, 0), `open_pressure` max λ_n,k over the
    nodes open by more than 1e-6 of the length scale, `complementarity` max |λ_n,k d_k|, and
    `friction`: the excess of |λ_t,k| over the friction radius ρ_k (Coulomb F_k λ_n,k; Tresca
    g_k where the node is not open by `vi_core.states`, 0 elsewhere; F_k, g_k the nodal means of the
    scene's field by the same quadrature) and, where the node slips (by more than 1e-6 of the
    length scale), the shortfall. Each is rounding at a solution; a wrong sign of the gap, a
    dropped complementarity row or a wrong scaling of F makes one O(1)
    (tests/problems/plugins/contact/test_solid_unilateral.py injects each)."""
    c = model.contact
    body, surf = c.slave, c.tr
    nodes = surf.nodes[c.rows_n]  # (N_n,) mesh nodes carrying λ_n
    x_full = model.full(sol.u)
    u_all = x_full[body.u_dofs(np.arange(body.n_nodes))]  # (N, 3) the slave's displacement
    if c.master is None and model.slip_origin is None:
        _, N_ind = _independent_weights(body.mesh, c.slave_part)
        nrm = N_ind[nodes] / np.linalg.norm(N_ind[nodes], axis=1)[:, None]  # (N_n, 3)
        x, y, z = body.mesh.points.T  # (N,) each
        gap = np.zeros(x.size)
        if c.gap_field is not None:
            gap = np.broadcast_to(c.gap_field(x, y, z), x.shape)
        carry_n = carry_t = None  # "keep": the nodal values themselves
        if c.ends == "merge":
            carry_n = np.isin(np.arange(body.mesh.n_nodes), nodes)
            carry_t = np.isin(np.arange(body.mesh.n_nodes), surf.nodes[np.r_[c.disc, c.line]])
        mean_n = _row_means(body.mesh, c.slave_part, carry_n, np.c_[gap, u_all])[nodes]
        un = np.einsum("ij,ij->i", nrm, mean_n[:, 1:])  # (N_n,) the normal rows' mean n_k·u
        d = mean_n[:, 0] - un  # (N_n,) remaining gap
        u = _row_means(body.mesh, c.slave_part, carry_t, u_all)[nodes]  # (N_n, 3)
        ut = np.linalg.norm(u - np.einsum("ij,ij->i", nrm, u)[:, None] * nrm, axis=1)  # slip
        length = max(float(np.abs(gap).max(initial=0.0)), float(np.abs(u_all).max()), 1e-300)
    else:  # two bodies or a load step: the weighted gap and jump of the rows themselves
        W = c.W_n[c.rows_n]  # (N_n,) the normal rows' ∫ψ̃_k
        Bu = c.B_full @ x_full  # (m,)
        d = (c.gap0 - Bu[c.rows()[0]]) / W
        if model.slip_origin is not None:
            Bu = Bu - model.slip_origin  # the slip of this load step
        jump = np.zeros((surf.size, 2))
        jump[c.disc] = Bu[c.rows()[1]] / c.W_t[c.disc, None]
        jump[c.line, 0] = Bu[c.rows()[2]] / c.W_t[c.line]
        ut = np.linalg.norm(jump, axis=1)[c.rows_n]  # (N_n,) tangential mortar jump
        scale = float(np.abs(u_all).max())
        if c.master is not None:
            u_m = x_full[c.master.u_dofs(np.arange(c.master.n_nodes))]
            scale = max(scale, float(np.abs(u_m).max()))
        length = max(float(np.abs(c.gap0 / W).max(initial=0.0)), scale, 1e-300)
    idx_n, idx_b, idx_l = c.rows()
    lam_n = sol.lam[idx_n]  # (N_n,)
    lam_t = np.zeros(surf.size)  # |λ_t| per surface node
    lam_t[c.disc] = np.linalg.norm(sol.lam[idx_b], axis=1)
    lam_t[c.line] = np.abs(sol.lam[idx_l])
    lam_t = lam_t[c.rows_n]
    p = max(float(lam_n.max(initial=0.0)), 1e-300)
    open_ = d > 1e-6 * length
    carry = None
    if c.ends == "merge":  # the tangential class's carriers (an uncovered node keeps its own)
        tan = np.zeros(surf.size, dtype=bool)
        tan[c.disc] = tan[c.line] = True
        if c.master is not None:
            tan |= ~c.covered
        carry = np.isin(np.arange(body.mesh.n_nodes), surf.nodes[tan])
    bound = _nodal_means(body.mesh, c.slave_part, c.bound_field, carry)[nodes]  # (N_n,)
    # Tresca acts where the node is not open by the contact states (vi_core.states: λ_n and
    # the gap d against thresholds scaled by the achieved residual)
    th = node_states.solution_thresholds(sol, p, length)
    touch = node_states.normal_states(lam_n, d, th) != "open"
    rho = bound * np.maximum(lam_n, 0.0) if c.friction == "coulomb" else bound * touch
    slips = ut > 1e-6 * length
    excess = np.maximum(lam_t - rho, 0.0)
    excess[slips & ~open_] = np.abs(lam_t - rho)[slips & ~open_]
    return {
        "penetration": float(np.maximum(-d, 0.0).max(initial=0.0)) / length,
        "tension": float(np.maximum(-lam_n, 0.0).max(initial=0.0)) / p,
        "open_pressure": float(np.max(lam_n[open_], initial=0.0)) / p,
        "complementarity": float(np.max(np.abs(lam_n * d), initial=0.0)) / (p * length),
        "friction": float(excess.max(initial=0.0)) / p,
    }
