"""Physical checks of a contact solution computed by code independent of the contact
assembly: the global force balance of every body and Lemma 4.2.

Neither check reads the row weights ∫φ̃_k, the dual mass, the mortar matrices or the friction
weights of the build, nor the constraint rows B on the unknowns. From the solution (u, φ, λ),
the meshes, the bodies' assembled stiffness A_b and loads f_b, and the scene's friction bound g
they compute:

- the contact force on the slave body −∫_Γ3 λ_h ds (on the master +∫_Γ3 λ_h ds) by 6-point Gauss
  quadrature of λ_h = Σ_k (γ_k n_k + α_k τ_k) ψ̃_k on the slave segments, with the local dual
  functions ψ_1 = 2 − 3t, ψ_2 = 3t − 1 (ψ̃_k: the local functions node k's multiplier owns,
  `Contact.Q_n`, `Q_t`) and nodal frames n_k, τ_k recomputed from the node coordinates;
- per body the external load Σ f_b, the support reaction Σ (A_b x_b − f_b + Bᵀλ) over its
  Dirichlet dofs (the assembled rows enter only there: where Γ3 meets a Dirichlet boundary the
  support also takes the contact force of the clamped nodes), and
  `imbalance` = |external + contact + support| / max of their sizes, per component
  (zero up to rounding: the rigid translations lie in the kernel of the elastic and coupling
  blocks, so the sum of the nodal equations is the balance of the forces on the body);
- for a rigid foundation, Lemma 4.2: b(u_h, λ_h) = ∫_Γ3 λ_h·u_h ds by quadrature against
  ∫g|u_h·τ|_h (`lemma_4_2`) with g from the scene (6-point Gauss; the build uses 3-point
  Gauss, so a g that is not a polynomial of degree ≤ 4 on each segment leaves a quadrature
  difference; the shipped scenes' constant g gives rounding only).

A wrong dual weight, a dropped mortar entry or wrong normals break the balance; a wrong
friction bound breaks Lemma 4.2 (README "What catches which fault").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from problems.scene.fields import Expression

_T, _W = np.polynomial.legendre.leggauss(6)
_T, _W = 0.5 * (_T + 1.0), 0.5 * _W  # (6,) on [0, 1], weights sum 1


def _frames(P: np.ndarray, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segment lengths (n_seg,), nodal outward normals and tangents (k, 2) of a chain."""
    d = P[seg[:, 1]] - P[seg[:, 0]]  # (n_seg, 2)
    L = np.sqrt((d * d).sum(axis=1))  # (n_seg,)
    nseg = np.stack([d[:, 1], -d[:, 0]], axis=1)  # (n_seg, 2) outward × length
    acc = np.zeros_like(P)
    np.add.at(acc, seg[:, 0], nseg)
    np.add.at(acc, seg[:, 1], nseg)
    n = acc / np.sqrt((acc * acc).sum(axis=1))[:, None]  # (k, 2)
    return L, n, np.stack([-n[:, 1], n[:, 0]], axis=1)


def _psi_phi() -> tuple[np.ndarray, np.ndarray]:
    """Dual functions ψ_a and hats φ_a of a segment at the Gauss points: (6, 2) each."""
    psi = np.stack([2.0 - 3.0 * _T, 3.0 * _T - 1.0], axis=1)
    return psi, np.stack([1.0 - _T, _T], axis=1)


def _multiplier_at_gauss(model: Any, lam: np.ndarray):
    """(x (n_seg, 6, 2), λ_h (n_seg, 6, 2), weights |E|·w (n_seg, 6), seg, frames).

    λ_h = Σ_k γ_k ψ̃_k n_k + Σ_k α_k ψ̃_k τ_k, ψ̃_k = Σ_(e,a) Q[k, 2e+a] ψ_{e,a} (the multiplier
    basis: which local dual functions node k's multiplier owns), n_k, τ_k from the geometry.
    """
    c = model.contact
    P = c.slave.mesh.points[c.tr.nodes]  # (k, 2)
    seg = c.tr.facets  # (n_seg, 2)
    L, n, tau = _frames(P, seg)
    lam_n, lam_t = c.normal(lam)[:, None], c.tangential(lam)[:, None]  # (N_n, 1), (N_t, 1)
    vec = c.Q_n.T @ (lam_n * n[c.rows_n]) + c.Q_t.T @ (lam_t * tau[c.rows_t])
    vec = np.asarray(vec).reshape(seg.shape[0], 2, 2)  # (n_seg, end a, component)
    psi, phi = _psi_phi()
    lam_q = np.einsum("qa,eai->eqi", psi, vec)  # (n_seg, 6, 2)
    x_q = np.einsum("qa,eai->eqi", phi, P[seg])  # (n_seg, 6, 2)
    w_q = L[:, None] * _W[None, :]  # (n_seg, 6)
    return x_q, lam_q, w_q, seg, (n, tau)


def force_balance(model: Any, sol: Any) -> dict:
    """Per body: external load, contact force, support reaction (N/m, x and y) and the relative
    imbalance; `imbalance` is the largest over bodies (module docstring)."""
    x_full = model.full(sol.u)
    contact = np.zeros(2)
    on_fixed = np.zeros(x_full.size)  # contact forces acting on Dirichlet dofs: part of support
    if model.contact is not None:
        on_fixed = model.contact.B_full.T @ sol.lam  # (n_full,), read at fixed dofs only
        _, lam_q, w_q, *_ = _multiplier_at_gauss(model, sol.lam)
        contact = np.einsum("eq,eqi->i", w_q, lam_q)  # ∫ λ_h ds, (2,)
    out: dict = {"bodies": {}}
    worst = 0.0
    for b in model.bodies:
        xb = x_full[b.offset : b.offset + b.size]
        dof = np.flatnonzero(b.fixed)  # (n_fixed_b,) the prescribed dofs
        r = b.A_fixed @ xb - b.f[dof] + on_fixed[b.offset + dof]  # (n_fixed_b,) their reactions
        N2 = 2 * b.n_nodes
        support = np.array([r[(dof < N2) & (dof % 2 == c)].sum() for c in range(2)])
        external = np.array([b.f[c:N2:2].sum() for c in range(2)])
        on_body = np.zeros(2)
        if model.contact is not None and b is model.contact.slave:
            on_body = -contact
        elif model.contact is not None and b is model.contact.master:
            on_body = contact
        total = external + on_body + support
        size = max(np.abs(external).max(), np.abs(on_body).max(), np.abs(support).max(), 1e-300)
        rel = float(np.abs(total).max() / size)
        worst = max(worst, rel)
        out["bodies"][b.name] = {
            "external": external.tolist(),
            "contact": on_body.tolist(),
            "support": support.tolist(),
            "imbalance": rel,
        }
    out["imbalance"] = worst
    return out


def _friction_bound(model: Any):
    """The scene's friction bound g(x, y) (compiled again from the scene's text, not taken
    from the build)."""
    return Expression.parse(model.scene.data["contact"]["g"])


def lemma_4_2(model: Any, sol: Any) -> dict | None:
    """Lemma 4.2 by quadrature for a rigid foundation: {"b_uh_lam", "int_g_abs_u", "gap"}
    with gap = |b − ∫g|u_τ|_h| / ∫g|u_τ|_h (None for two bodies, unilateral contact or
    without contact).

    b(u_h, λ_h) = ∫_Γ3 λ_h·u_h ds; ∫g|u_τ|_h = Σ_k ∫gφ̃_k |τ_k·ū_k| over the tangential
    multipliers, ū_k = ∫ψ̃_k u_h ds / ∫ψ̃_k ds the dual-weighted mean of u_h on the support of
    node k's multiplier (the nodal value when its support is its own two segments) and
    φ̃_k = Σ_(e,a) Q_t[k, 2e+a] φ_{e,a}; every integral by 6-point Gauss.
    """
    c = model.contact
    if c is None or c.master is not None or c.law != "bilateral":
        return None
    x_q, lam_q, w_q, seg, (_, tau) = _multiplier_at_gauss(model, sol.lam)
    psi, phi = _psi_phi()
    u = model.full(sol.u)[c.slave.u_dofs(c.tr.nodes)]  # (k, 2) slave trace displacement
    u_q = np.einsum("qa,eai->eqi", phi, u[seg])  # (n_seg, 6, 2)
    b_val = float(np.einsum("eq,eqi,eqi->", w_q, lam_q, u_q))
    g = np.broadcast_to(
        np.asarray(_friction_bound(model)(x_q[..., 0], x_q[..., 1]), float), w_q.shape
    )  # (n_seg, 6)
    num = c.Q_t @ np.einsum("eq,qa,eqi->eai", w_q, psi, u_q).reshape(-1, 2)  # (N_t, 2) ∫ψ̃u
    den = c.Q_t @ np.einsum("eq,qa->ea", w_q, psi).ravel()  # (N_t,) ∫ψ̃
    gphi = c.Q_t @ np.einsum("eq,eq,qa->ea", w_q, g, phi).ravel()  # (N_t,) ∫gφ̃
    mean_t = np.abs((num * tau[c.rows_t]).sum(axis=1)) / den  # (N_t,)
    g_abs = float(gphi @ mean_t)
    scale = max(g_abs, np.finfo(float).eps * float(gphi.sum()) * float(np.abs(u).max()), 1e-300)
    return {"b_uh_lam": b_val, "int_g_abs_u": g_abs, "gap": abs(b_val - g_abs) / scale}
