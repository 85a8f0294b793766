"""Error norms of the study (Theorem 4.1): against an exact solution, or against a finer level.

Norms (all absolute, SI units, lengths in m):

- ``u_H1``  = ‖u − u_h‖_{H¹(Ω)} = (‖·‖²_{L²} + |·|²_{H¹})^{1/2}, summed over bodies;
- ``phi_H1``, ``phi_L2`` the same for φ (piezoelectric bodies only; 0 if there are none);
- ``lam``   = (Σ_E h_E ‖λ − λ_h‖²_{L²(E)})^{1/2} over the segments E of Γ3 (slave side): the
  mesh-weighted h^{1/2}‖·‖_{L²(Γ3)} stand-in for H^{-1/2}(Γ3). λ_h is compared as a *function*,
  λ_h = Σ_k (γ_k n_k + α_k τ_k) ψ̃_k with the multiplier basis ψ̃_k (the dual basis, modified at
  crosspoints by the end treatment), component-wise in the nodal frame:
  (Σγ_kψ̃_k − λ·n)² + (Σα_kψ̃_k − λ·τ)².

Against an exact solution the integrals use 4th-order cell quadrature (`fem.assembly`) and 4-point
Gauss on segments. Against a finer reference level the coarse discrete solution is evaluated
exactly (as a P1/Q1 finite element function) at the nodes of the reference mesh and the
difference is measured with the reference mesh's mass and stiffness matrices; this is exact for
nested meshes (structured rectangles) and an O(h²)-accurate transfer for mapped curved blocks,
whose refined boundary nodes move onto the true arc. λ_h of the coarse level is evaluated at
Gauss points of the reference Γ3 located by normalised arc length, weighted by the coarse h_E.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fem import assembly
from fem.facets import SEGMENT_DUAL, facet_values
from fem.locate import evaluate
from problems.scene.exact import Exact

GAUSS_T, GAUSS_W = np.polynomial.legendre.leggauss(4)
GAUSS_T, GAUSS_W = 0.5 * (GAUSS_T + 1), 0.5 * GAUSS_W  # (4,) on [0, 1], weights sum 1
NORMS = ("u_H1", "phi_H1", "phi_L2", "lam")


def _fields(model: Any, u: np.ndarray):
    """Per body: (body, displacement (N, 2), potential (N,) or None) of the full solution."""
    x = model.full(u)
    return [(b, *b.split(x[b.offset : b.offset + b.size])) for b in model.bodies]


def _multiplier(model: Any, lam: np.ndarray):
    """(trace, γ, α) of the contact multiplier as segment-local dual coefficients (n_seg, 2):
    λ·n = Σ_(e,a) γ[e, a] ψ_{e,a} (the multiplier basis, end treatment included)."""
    c = model.contact
    gam = (c.Q_n.T @ c.normal(lam)).reshape(-1, 2)  # (n_seg, 2)
    alp = (c.Q_t.T @ c.tangential(lam)).reshape(-1, 2)  # (n_seg, 2)
    return c.tr, gam, alp


def _dual_values(coef: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Σ_a coef[e, a] ψ_{e,a} at points t ∈ [0, 1] of segments e = `seg` (both (k,)): (k,)."""
    psi = facet_values("line", t[:, None]) @ SEGMENT_DUAL.T  # (k, 2) ψ_a = Σ_b A_ab φ_b
    return np.einsum("ka,ka->k", psi, coef[seg])


def exact_errors(model: Any, u: np.ndarray, lam: np.ndarray, exact: Exact) -> dict[str, float]:
    """The four norms of the module docstring, against the scene's `[exact]` solution."""
    sq = dict.fromkeys(NORMS, 0.0)
    for b, disp, phi in _fields(model, u):
        m = b.mesh
        sq["u_H1"] += assembly.l2_error(m, disp.ravel(), exact.u, 2) ** 2
        sq["u_H1"] += assembly.h1_seminorm_error(m, disp.ravel(), exact.grad_u, 2) ** 2
        if phi is not None and exact.phi is not None:
            l2 = assembly.l2_error(m, phi, exact.phi, 1) ** 2
            sq["phi_L2"] += l2
            sq["phi_H1"] += l2 + assembly.h1_seminorm_error(m, phi, exact.grad_phi, 1) ** 2
    if model.contact is not None:
        tr, gam, alp = _multiplier(model, lam)
        P = model.contact.slave.mesh.points[tr.nodes]  # (N, 2)
        n_seg, n_q = tr.facets.shape[0], GAUSS_T.size
        seg = np.repeat(np.arange(n_seg), n_q)  # (n_seg·n_q,)
        t = np.tile(GAUSS_T, n_seg)  # (n_seg·n_q,)
        A, B = P[tr.facets[seg, 0]], P[tr.facets[seg, 1]]  # (n_seg·n_q, 2)
        X = (1 - t)[:, None] * A + t[:, None] * B  # (n_seg·n_q, 2)
        ex = exact.lam(X[:, 0], X[:, 1])  # (n_seg·n_q, 2): (λ·n, λ·τ)
        d2 = (_dual_values(gam, seg, t) - ex[:, 0]) ** 2
        d2 += (_dual_values(alp, seg, t) - ex[:, 1]) ** 2  # (n_seg·n_q,)
        w = np.tile(GAUSS_W, n_seg) * tr.measures[seg] ** 2  # h_E · |E| · Gauss weight
        sq["lam"] = float(w @ d2)
    return {k: float(np.sqrt(v)) for k, v in sq.items()}


# ------------------------------------------------------------------ transfer between levels
def _locate_on_trace(tr, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment index and local t ∈ [0, 1] of normalised arc lengths s ∈ [0, 1] (both (M,))."""
    edges = np.concatenate([[0.0], np.cumsum(tr.measures)]) / tr.measures.sum()  # (n_seg + 1,)
    seg = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, tr.measures.size - 1)
    t = np.clip((s - edges[seg]) / (edges[seg + 1] - edges[seg]), 0.0, 1.0)
    return seg, t


def reference_errors(
    model: Any, u: np.ndarray, lam: np.ndarray, ref: Any, u_ref: np.ndarray, lam_ref
) -> dict[str, float]:
    """The four norms against the solution (u_ref, lam_ref) of a finer level `ref`."""
    sq = dict.fromkeys(NORMS, 0.0)
    coarse = {b.name: (b, disp, phi) for b, disp, phi in _fields(model, u)}
    for bf, disp_f, phi_f in _fields(ref, u_ref):
        b, disp, phi = coarse[bf.name]
        m = bf.mesh
        H1 = (assembly.mass_matrix(m) + assembly.stiffness_matrix(m)).tocsr()
        nodal = disp if phi is None else np.column_stack([disp, phi])  # (N, 2 or 3)
        d = np.column_stack([disp_f] + ([phi_f] if phi_f is not None else []))
        d = d - evaluate(b.mesh, nodal, m.points)  # (N_ref, 2 or 3)
        sq["u_H1"] += float(sum(d[:, c] @ (H1 @ d[:, c]) for c in range(2)))
        if phi_f is not None:
            sq["phi_H1"] += float(d[:, 2] @ (H1 @ d[:, 2]))
            sq["phi_L2"] += float(d[:, 2] @ (assembly.mass_matrix(m) @ d[:, 2]))
    if model.contact is not None:
        tr, gam, alp = _multiplier(model, lam)
        trf, gam_f, alp_f = _multiplier(ref, lam_ref)
        n_seg, n_q = trf.facets.shape[0], GAUSS_T.size
        seg_f = np.repeat(np.arange(n_seg), n_q)  # (n_seg·n_q,)
        t_f = np.tile(GAUSS_T, n_seg)
        s = np.concatenate([[0.0], np.cumsum(trf.measures)])[seg_f] + t_f * trf.measures[seg_f]
        seg, t = _locate_on_trace(tr, s / trf.measures.sum())
        d2 = (_dual_values(gam_f, seg_f, t_f) - _dual_values(gam, seg, t)) ** 2
        d2 += (_dual_values(alp_f, seg_f, t_f) - _dual_values(alp, seg, t)) ** 2
        w = np.tile(GAUSS_W, n_seg) * trf.measures[seg_f] * tr.measures[seg]  # |E_f| w_q · h_E
        sq["lam"] = float(w @ d2)
    return {k: float(np.sqrt(v)) for k, v in sq.items()}
