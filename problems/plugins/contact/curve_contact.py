"""The contact interface of a 2D scene: the slave trace on a boundary curve, its crosspoint
rules and the 2D dual mortar of a master body, built into an `interface.Interface` by
`slave_contact` (a 2D node is a 3D "line" node: its tangent is its line direction; the rows
themselves: `rows.assemble`).

Dual (biorthogonal) multipliers on the slave side Γ3: λ_h = Σ_k γ_k ψ̃_k n_k + Σ_k α_k ψ̃_k τ_k,
and Λ_h = product(Free(N_n), Box(−g_k, g_k)) with g_k = ∫g φ̃_k / ∫φ̃_k (docs/design.md §3; φ̃_k = φ_k
unless an end treatment merged a neighbour in). With a rigid foundation the constraint rows are
Σ_j Ds_kj n_kᵀu_j (normal) and the same with τ_k (tangential); with a master body they act on
the mortar jump Ds u_s − M u_m (`fem.mortar`).


Contact rules (README "Contact interfaces"):

- crosspoints: a slave node whose displacement is fully prescribed carries no multiplier; at a
  node where one component is prescribed and that direction is the contact tangent (normal),
  only the tangential (normal) multiplier is dropped; any other partially prescribed node is
  refused, per node. `[contact] ends` = "merge" (default, Wohlmuth's end-node modification of
  the dual basis) or "keep" (`fem.facets.multiplier_basis`).
- coverage: a slave node carries a multiplier only if the master lies behind its whole support;
  the others are left free and listed (warning, summary `contact.uncovered_nodes`); if no node
  is covered the scene is refused.
- patch test: `contact.mortar_patch_defect` = max_k |Σ_j Ds_kj − Σ_j M_kj| / Σ_j Ds_kj over the
  multiplier rows (0 by construction for the rigid foundation, which has no master side).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from fem.facets import Trace, facet_integrals, trace
from fem.mesh import Mesh
from problems.errors import SceneError
from problems.scene.fields import renamed
from problems.scene.imported import require_curve

from ..contract import check_meshed
from . import reports, rows, separation
from .bodies import Body
from .interface import Coupling, Interface
from .scene_model import ContactSection

# A prescribed displacement component at a contact node counts as along the contact normal or
# tangent if the sine of the angle between them is at most ALIGN_TOL (a roller on a side
# perpendicular to a flat contact: exactly 0).
ALIGN_TOL = 1e-10


def from_scene(bodies: dict[str, Body], ct: ContactSection, n_full: int, level: int) -> Interface:
    """The contact of a [contact] table between the built `bodies` (by name): its boundaries
    checked (meshed, curves), then `slave_contact`."""
    sname, slave_part = ct.slave.split(".", 1)
    slave, master, mpart = bodies[sname], None, None
    refs = [(ct.key("slave"), slave, slave_part)]
    if ct.master != "rigid":
        mname, mpart = ct.master.split(".", 1)
        master = bodies[mname]
        refs.append((ct.key("master"), master, mpart))
    for key, b, part in refs:
        check_meshed(b.mesh, [(key, part)])
        require_curve(b.mesh, part, key, f"{b.name}.{part}")
    return slave_contact(slave, slave_part, master, mpart, ct, n_full, level)


def carrying(slave: Body, part: str, tr: Trace) -> tuple[np.ndarray, np.ndarray]:
    """(carry_n, carry_t) per slave trace node: which multiplier components it carries.

    Crosspoint rules (module docstring); SceneError listing every unsupported node.
    """
    fixed = slave.fixed[slave.u_dofs(tr.nodes) - slave.offset]  # (N, 2); body-local dofs
    carry_n, carry_t = ~fixed.all(axis=1), ~fixed.all(axis=1)  # (N,) each
    bad = []
    for i in np.flatnonzero(fixed.any(axis=1) & ~fixed.all(axis=1)):
        c = int(np.flatnonzero(fixed[i])[0])
        n = tr.normals[i]
        if abs(n[c]) <= ALIGN_TOL:  # the prescribed direction e_c is the tangent
            carry_t[i] = False
        elif abs(n[1 - c]) <= ALIGN_TOL:  # e_c is the normal
            carry_n[i] = False
        else:
            angle = np.degrees(np.arccos(min(abs(n[c]), 1.0)))
            bad.append(
                f"{reports.node_at(slave, tr, i)}: only u_{'xy'[c]} is prescribed, a direction "
                f"{angle:.3g}° off the contact normal n = [{n[0]:.6g}, {n[1]:.6g}]"
            )
    if bad:
        raise SceneError(
            "contact.slave",
            f"{slave.name}.{part}",
            "contact nodes whose prescribed displacement is complete (clamped) or one component "
            "along the contact normal or tangent (a roller across or along Γ3); unsupported: "
            + "; ".join(bad)
            + ". A prescribed component at an angle to Γ3 would fight the contact multipliers:"
            " clamp these nodes (prescribe both components), free them, or move the side's "
            "roller so that its direction is the contact normal or tangent there",
        )
    return carry_n, carry_t


def slave_contact(
    slave: Body,
    part: str,
    master: Body | None,
    mpart: str | None,
    ct: ContactSection,
    n_full: int,
    level: int = 0,
) -> Interface:
    """The contact rows (`rows.assemble`): normal Σ_j Ds_kj n_kᵀu_s,j − Σ_j M_kj n_kᵀu_m,j
    (M = 0 for a rigid foundation), then the same with τ_k; with law = "unilateral" the rows of
    a node side by side [n, τ] (vi_core.coulomb) and the initial gap rows Σ_j Ds_kj gap(x_j)
    (gap: the scene's field for a rigid foundation, the distance along n_j to the master
    polyline for two bodies). Nodes without the master behind their whole support carry no
    multiplier. With a master, its mortar means of u_m·τ_k and (piezoelectric) of φ_m."""
    from fem.mortar import COVER_TOL, mortar_coupling

    unilateral = ct.law == "unilateral"
    tr = trace(slave.mesh, part)
    carry_n, carry_t = carrying(slave, part, tr)
    rows.check_carrying(slave, part, tr, carry_n, carry_t.astype(int), ct.law)
    gap_nodes = np.zeros(tr.size)  # (N,) initial normal gap at the slave nodes
    closed = 0.0  # the initial gap bilateral contact closes
    coupling = None
    if master is not None:
        if unilateral:
            gap_nodes = separation.initial_gap(slave, part, tr, tr.normals, master, mpart, level)
        else:
            closed = separation.check_separation(slave, part, tr, tr.normals, master, mpart, level)
        reach = 1.0 + float(np.max(gap_nodes, initial=0.0) / tr.measures.min())
        mort = mortar_coupling(slave.mesh, part, master.mesh, mpart, reach=reach)
        assert np.array_equal(tr.nodes, mort.slave_nodes)
        covered = np.ones(tr.size, dtype=bool)  # the master behind every segment at the node
        covered[tr.facets[mort.coverage < 1.0 - COVER_TOL].ravel()] = False
        mdofs = master.u_dofs(mort.master_nodes)  # (nm, 2)
        coupling = Coupling(master, mpart, mort.M, mdofs, covered)
    else:
        gap_nodes = rows.rigid_gap(ct.gap, slave.mesh.points[tr.nodes])
    bfun = ct.g if ct.friction == "tresca" else ct.F
    c = rows.assemble(
        slave, part, tr, (tr.normals, tr.tangents, None, None), carry_n, carry_t.astype(int), ct,
        friction_local(slave.mesh, tr, bfun), n_full, coupling, gap_nodes if unilateral else None,
    )  # fmt: skip
    c.closed_gap = closed
    if master is not None:  # mortar means over the row's support: u_m·τ_k, (φ_m)
        M = coupling.M_t[c.line].tocoo()  # (N_t, nm) Q_t M
        W_t = c.W_t[c.line]
        pv = [M.data * tr.tangents[c.line[M.row], i] / W_t[M.row] for i in range(2)]
        c.master_proj = sp.csr_matrix(
            (
                np.concatenate(pv),
                (np.tile(M.row, 2), np.concatenate([mdofs[M.col, i] for i in range(2)])),
            ),
            shape=(c.line.size, n_full),
        )
        if master.has_potential:  # normal rows: Σ_j M_kj φ_m,j / W_k
            M = coupling.M_n[c.rows_n].tocoo()  # (N_n, nm) Q_n M
            c.master_phi = sp.csr_matrix(
                (
                    M.data / c.W_n[c.rows_n][M.row],
                    (M.row, master.phi_dofs(mort.master_nodes)[M.col]),
                ),
                shape=(c.rows_n.size, n_full),
            )
    return c


def friction_local(mesh: Mesh, tr: Trace, gfun) -> np.ndarray:
    """(n_seg, 2) ∫_e g φ_{e,a} ds (g ≥ 0 checked at every quadrature point: `rows.checked_bound`;
    g is the Tresca bound or the Coulomb coefficient F)."""
    return facet_integrals(mesh, tr, rows.checked_bound(gfun))


__getattr__ = renamed(__name__, {"Contact": "problems.plugins.contact.interface.Interface"})
