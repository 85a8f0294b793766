"""Errors of a contact3d solution against the scene's `[exact]` table (`ExactSection3`; the
manufactured scene `manufactured3d`, docs/fem3d.md "Manufactured 3D solution").

Norms (absolute, SI units), summed over the bodies:

- ``u_L2`` = ‖u − u_h‖_{L²(Ω)}, ``u_H1`` = |u − u_h|_{H¹(Ω)} (the seminorm), by cell quadrature
  of order 4 (`fem.assembly`);
- ``phi_L2``, ``phi_H1`` the same for φ (piezoelectric bodies; 0 without any);
- ``lam`` = (Σ_k W_k |λ_k − λ(x_k)|²)^{1/2} over the contact nodes carrying multipliers: a
  discrete L²(Γ3) norm of the nodal multiplier vectors λ_k = λ_n,k n_k + λ_t,k (the dual-basis
  coefficients) against the exact λ = −σn at the nodes, W_k = ∫_Γ3 φ_k dA.
"""

from __future__ import annotations

import numpy as np

from fem import assembly
from problems.scene.exact import Exact
from vi_core import Solution

from .model import BodiesModel, fields

NORMS = ("u_L2", "u_H1", "phi_L2", "phi_H1", "lam")  # contact3d.EXACT_NORMS


def exact_errors(model: BodiesModel, sol: Solution, exact: Exact, state: dict | None) -> dict:
    """The NORMS of the module docstring of a contact3d model's solution `sol` against the
    compiled [exact] table `exact`; `state` is the model's contact state at `sol`
    (`contact3d.contact_state`; None without a contact interface). The plug-in's entry point
    is `contact3d.exact_errors(model, sol)`."""
    sq = dict.fromkeys(NORMS, 0.0)
    nodal = fields(model, sol)
    for b in model.bodies:
        m, disp = b.mesh, nodal[f"{b.name}.displacement"]  # (N, 3)
        sq["u_L2"] += assembly.l2_error(m, disp.ravel(), exact.u, 3) ** 2
        sq["u_H1"] += assembly.h1_seminorm_error(m, disp.ravel(), exact.grad_u, 3) ** 2
        phi = nodal.get(f"{b.name}.potential")  # (N,) or None
        if phi is not None and exact.phi is not None:
            sq["phi_L2"] += assembly.l2_error(m, phi, exact.phi, 1) ** 2
            sq["phi_H1"] += assembly.h1_seminorm_error(m, phi, exact.grad_phi, 1) ** 2
    c, st = model.contact, state
    if c is not None:
        carried = np.isfinite(st["lam_n"]) | st["has_t"]  # (k,)
        lam_h = np.nan_to_num(st["lam_n"])[:, None] * c.normals + st["lam_t_vec"]  # (k, 3)
        P = c.slave.mesh.points[c.surf.nodes]  # (k, 3)
        d = lam_h - exact.lam(P[:, 0], P[:, 1], P[:, 2])  # (k, 3)
        sq["lam"] = float(np.sum((c.W[:, None] * d**2)[carried]))
    return {k: float(np.sqrt(v)) for k, v in sq.items()}
