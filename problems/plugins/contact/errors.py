"""Error norms of `mixvi study` for the contact plug-in, 2D and 3D (Theorem 4.1).

Against the scene's `[exact]` table (`EXACT_NORMS`, absolute, SI units, summed over bodies):

- ``u_L2`` = ‖u − u_h‖_{L²(Ω)}, ``u_H1`` = ‖u − u_h‖_{H¹(Ω)} = (‖·‖²_{L²} + |·|²_{H¹})^{1/2} (the
  full norm; the seminorm is (u_H1² − u_L2²)^{1/2}), by order-4 cell quadrature (`fem.assembly`);
- ``phi_L2``, ``phi_H1`` the same for φ (piezoelectric bodies only; 0 if there are none);
- ``lam``: in 2D (Σ_E h_E ‖λ − λ_h‖²_{L²(E)})^{1/2} over the segments E of Γ3, the mesh-weighted
  stand-in for H^{-1/2}(Γ3), with λ_h = Σ_k (γ_k n_k + α_k τ_k) ψ̃_k as a function (the dual
  basis with its end treatment), compared component-wise in the nodal frame by 4-point Gauss;
  in 3D the discrete (Σ_k W_k |λ_k − λ(x_k)|²)^{1/2} over the nodes carrying multipliers
  (λ_k = λ_n,k n_k + λ_t,k, W_k = ∫_Γ3 φ_k dA).

Against a finer level `ref` (`REFERENCE_NORMS`): in 2D the same u_H1, phi_H1, phi_L2 and lam,
the coarse solution evaluated at the reference nodes (`transfer.nodal_reference_errors`: exact
for nested meshes, an O(h²) transfer for mapped curved blocks) and λ_h of the coarse level at
Gauss points of the reference Γ3 located by normalised arc length, weighted by the coarse h_E;
in 3D the relative RMS differences at the coarse nodes (nested: each is a fine node) of u, φ
(``u_nodes``, ``phi_nodes``: pooled over the bodies, Σ_b Σ |u_h − u_ref|² / Σ_b Σ |u_ref|²)
and of λ over the contact nodes weighted by W_k (``lam_nodes``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from fem import assembly
from fem.facets import SEGMENT_DUAL, facet_values
from problems.scene.exact import Exact
from vi_core import Solution

from ..transfer import nodal_reference_errors

GAUSS_T, GAUSS_W = np.polynomial.legendre.leggauss(4)
GAUSS_T, GAUSS_W = 0.5 * (GAUSS_T + 1), 0.5 * GAUSS_W  # (4,) on [0, 1], weights sum 1
EXACT_NORMS = ("u_L2", "u_H1", "phi_L2", "phi_H1", "lam")
REFERENCE_NORMS = {2: ("u_H1", "phi_H1", "phi_L2", "lam"), 3: ("u_nodes", "phi_nodes", "lam_nodes")}
State = Callable[[Any, Solution], dict]  # the front's contact_state(model, sol)


def _fields(model: Any, u: np.ndarray) -> list:
    """Per body: (body, displacement (N, d), potential (N,) or None) of the full solution."""
    x = model.full(u)
    return [(b, *b.split(x[b.offset : b.offset + b.size])) for b in model.bodies]


def exact_errors(scene_model: type, state: State, model: Any, sol: Solution) -> dict | None:
    """The EXACT_NORMS of the module docstring against the scene's `[exact]` table (None
    without one); `scene_model` validates the scene, `state` is the front's contact_state."""
    section = model.scene.validated(scene_model).exact
    return None if section is None else against(model, sol, section.compiled(), state)


def against(model: Any, sol: Solution, exact: Exact, state: State) -> dict[str, float]:
    """The EXACT_NORMS of `sol` against the compiled exact fields `exact`."""
    sq = dict.fromkeys(EXACT_NORMS, 0.0)
    d = model.dimension
    for b, disp, phi in _fields(model, sol.u):
        m = b.mesh
        sq["u_L2"] += (l2 := assembly.l2_error(m, disp.ravel(), exact.u, d) ** 2)
        sq["u_H1"] += l2 + assembly.h1_seminorm_error(m, disp.ravel(), exact.grad_u, d) ** 2
        if phi is not None and exact.phi is not None:
            sq["phi_L2"] += (l2 := assembly.l2_error(m, phi, exact.phi, 1) ** 2)
            sq["phi_H1"] += l2 + assembly.h1_seminorm_error(m, phi, exact.grad_phi, 1) ** 2
    if model.contact is not None:
        sq["lam"] = (
            _lam_plane(model, sol.lam, exact) if d == 2 else _lam_solid(model, sol, exact, state)
        )
    return {k: float(np.sqrt(v)) for k, v in sq.items()}


def _lam_solid(model: Any, sol: Solution, exact: Exact, state: State) -> float:
    """Σ_k W_k |λ_k − λ(x_k)|² over the 3D contact nodes carrying multipliers."""
    c, st = model.contact, state(model, sol)
    carried = np.isfinite(st["lam_n"]) | st["has_t"]  # (k,)
    P = c.slave.mesh.points[c.tr.nodes]  # (k, 3)
    d = _nodal_lam(st, c.normals) - exact.lam(P[:, 0], P[:, 1], P[:, 2])  # (k, 3)
    return float(np.sum((c.W[:, None] * d**2)[carried]))


def _nodal_lam(st: dict, normals: np.ndarray) -> np.ndarray:
    """(k, 3) the nodal multiplier vectors λ_n,k n_k + λ_t,k of a 3D contact state."""
    return np.nan_to_num(st["lam_n"])[:, None] * normals + st["lam_t_vec"]


def _multiplier(model: Any, lam: np.ndarray):
    """(trace, γ, α) of the 2D contact multiplier as segment-local dual coefficients
    (n_seg, 2): λ·n = Σ_(e,a) γ[e, a] ψ_{e,a} (the multiplier basis, end treatment included)."""
    c = model.contact
    gam = (c.Q_n.T @ c.normal(lam)).reshape(-1, 2)  # (n_seg, 2)
    alp = (c.Q_t.T @ c.tangential(lam)).reshape(-1, 2)  # (n_seg, 2)
    return c.tr, gam, alp


def _dual_values(coef: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Σ_a coef[e, a] ψ_{e,a} at points t ∈ [0, 1] of segments e = `seg` (both (k,)): (k,)."""
    psi = facet_values("line", t[:, None]) @ SEGMENT_DUAL.T  # (k, 2) ψ_a = Σ_b A_ab φ_b
    return np.einsum("ka,ka->k", psi, coef[seg])


def _gauss(tr: Any) -> tuple[np.ndarray, np.ndarray]:
    """Segment index and t of the 4-point Gauss points of every segment of `tr`: (n_seg·4,)."""
    n_seg = tr.facets.shape[0]
    return np.repeat(np.arange(n_seg), GAUSS_T.size), np.tile(GAUSS_T, n_seg)


def _lam_plane(model: Any, lam: np.ndarray, exact: Exact) -> float:
    """Σ_E h_E ‖λ − λ_h‖²_{L²(E)} over the 2D contact segments."""
    tr, gam, alp = _multiplier(model, lam)
    P = model.contact.slave.mesh.points[tr.nodes]  # (N, 2)
    seg, t = _gauss(tr)
    A, B = P[tr.facets[seg, 0]], P[tr.facets[seg, 1]]  # (n_seg·n_q, 2)
    X = (1 - t)[:, None] * A + t[:, None] * B  # (n_seg·n_q, 2)
    ex = exact.lam(X[:, 0], X[:, 1])  # (n_seg·n_q, 2): (λ·n, λ·τ)
    d2 = (_dual_values(gam, seg, t) - ex[:, 0]) ** 2
    d2 += (_dual_values(alp, seg, t) - ex[:, 1]) ** 2  # (n_seg·n_q,)
    w = np.tile(GAUSS_W, tr.facets.shape[0]) * tr.measures[seg] ** 2  # h_E · |E| · weight
    return float(w @ d2)


# ------------------------------------------------------------------ against a finer level
def reference_errors(
    state: State, model: Any, sol: Solution, ref: Any, ref_sol: Solution
) -> dict[str, float]:
    """The REFERENCE_NORMS of the model's dimension against the finer level `ref`."""
    if model.dimension == 3:
        return _nodal_differences(model, sol, ref, ref_sol, state)
    sq = dict.fromkeys(REFERENCE_NORMS[2], 0.0)
    coarse = {b.name: (b, disp, phi) for b, disp, phi in _fields(model, sol.u)}
    for bf, disp_f, phi_f in _fields(ref, ref_sol.u):
        b, disp, phi = coarse[bf.name]
        sq["u_H1"] += nodal_reference_errors(b.mesh, disp, bf.mesh, disp_f)["h1"] ** 2
        if phi_f is not None:
            e = nodal_reference_errors(b.mesh, phi, bf.mesh, phi_f)
            sq["phi_H1"] += e["h1"] ** 2
            sq["phi_L2"] += e["l2"] ** 2
    if model.contact is not None:
        sq["lam"] = _lam_plane_reference(model, sol.lam, ref, ref_sol.lam)
    return {k: float(np.sqrt(v)) for k, v in sq.items()}


def _locate_on_trace(tr, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment index and local t ∈ [0, 1] of normalised arc lengths s ∈ [0, 1] (both (M,))."""
    edges = np.concatenate([[0.0], np.cumsum(tr.measures)]) / tr.measures.sum()  # (n_seg + 1,)
    seg = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, tr.measures.size - 1)
    t = np.clip((s - edges[seg]) / (edges[seg + 1] - edges[seg]), 0.0, 1.0)
    return seg, t


def _lam_plane_reference(model: Any, lam: np.ndarray, ref: Any, lam_ref: np.ndarray) -> float:
    """The squared 2D `lam` norm of the coarse λ_h against the reference level's."""
    tr, gam, alp = _multiplier(model, lam)
    trf, gam_f, alp_f = _multiplier(ref, lam_ref)
    seg_f, t_f = _gauss(trf)
    s = np.concatenate([[0.0], np.cumsum(trf.measures)])[seg_f] + t_f * trf.measures[seg_f]
    seg, t = _locate_on_trace(tr, s / trf.measures.sum())
    d2 = (_dual_values(gam_f, seg_f, t_f) - _dual_values(gam, seg, t)) ** 2
    d2 += (_dual_values(alp_f, seg_f, t_f) - _dual_values(alp, seg, t)) ** 2
    w = np.tile(GAUSS_W, trf.facets.shape[0]) * trf.measures[seg_f] * tr.measures[seg]
    return float(w @ d2)  # |E_f| w_q · h_E


def _nodal_differences(
    model: Any, sol: Solution, ref: Any, ref_sol: Solution, state: State
) -> dict[str, float]:
    """u_nodes, phi_nodes, lam_nodes of the module docstring (3D)."""
    sums: dict[str, list[float]] = {}  # norm → [Σ w d², Σ w r²] over every body

    def matched(points_c: np.ndarray, points_f: np.ndarray) -> np.ndarray:
        at = {tuple(np.round(p, 10)): i for i, p in enumerate(points_f)}
        return np.array([at[tuple(np.round(p, 10))] for p in points_c])

    def add(norm: str, d: np.ndarray, r: np.ndarray, w: Any = 1.0) -> None:
        s = sums.setdefault(norm, [0.0, 0.0])
        s[0] += float(np.sum(w * d**2))
        s[1] += float(np.sum(w * r**2))

    coarse = {b.name: (b, disp, phi) for b, disp, phi in _fields(model, sol.u)}
    for bf, *fine in _fields(ref, ref_sol.u):
        b, *fc = coarse[bf.name]
        idx = matched(b.mesh.points, bf.mesh.points)
        for norm, c, f in zip(("u_nodes", "phi_nodes"), fc, fine, strict=True):
            if c is not None:
                add(norm, c - f[idx], f[idx])
    if model.contact is not None:
        c, cf = model.contact, ref.contact
        idx = matched(c.slave.mesh.points[c.tr.nodes], cf.slave.mesh.points[cf.tr.nodes])
        r = _nodal_lam(state(ref, ref_sol), cf.normals)[idx]
        add("lam_nodes", _nodal_lam(state(model, sol), c.normals) - r, r, c.W[:, None])
    return {k: float(np.sqrt(d / max(r, 1e-300))) for k, (d, r) in sums.items()}
