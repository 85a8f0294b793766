"""The contact interface of a 2D scene: the slave trace on a boundary curve, its crosspoint
rules and the contact rows (`Contact`, built by `slave_contact`), with the 2D dual mortar of a
master body.

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

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from fem.facets import Trace, dual_mass, facet_integrals, multiplier_basis, trace
from fem.mesh import Mesh
from problems.errors import SceneError
from problems.scene.imported import require_curve
from vi_core import Box, Free, NonNegative, product

from ..contract import check_meshed
from . import interface, separation
from . import law as contact_law
from .bodies import Body
from .law import FRICTIONS, LAWS
from .scene_model import ContactSection

# A prescribed displacement component at a contact node counts as along the contact normal or
# tangent if the sine of the angle between them is at most ALIGN_TOL (a roller on a side
# perpendicular to a flat contact: exactly 0).
ALIGN_TOL = 1e-10


@dataclass
class Contact:
    """The contact interface Γ3: slave trace, master (None = rigid), multiplier rows, bounds.

    Multipliers: λ = (γ, α), γ on the normal rows `rows_n`, α on the tangential rows `rows_t`
    (trace indices of the nodes carrying them; all nodes unless crosspoints or uncovered nodes
    dropped some), with bases Q_n, Q_t in the segment-local dual functions.
    """

    slave: Body
    slave_part: str
    tr: Trace  # slave trace
    master: Body | None
    master_part: str | None
    ends: str  # "merge" or "keep" (fem.facets.multiplier_basis)
    rows_n: np.ndarray  # (N_n,) trace indices carrying a normal multiplier
    rows_t: np.ndarray  # (N_t,) trace indices carrying a tangential multiplier
    Q_n: sp.csr_matrix  # (N_n, 2·n_seg) normal multiplier basis
    Q_t: sp.csr_matrix  # (N_t, 2·n_seg) tangential multiplier basis
    W_n: np.ndarray  # (N_n,) row weights Σ_j Ds_kj = ∫φ̃_k of the normal rows
    W_t: np.ndarray  # (N_t,) the same for the tangential rows
    g: np.ndarray  # (N_t,) g_k = ∫gφ̃_k / ∫φ̃_k
    B_full: sp.csr_matrix  # (N_n + N_t, n_full): normal rows then tangential rows
    g_weights: np.ndarray  # (N_t,) ∫ g φ̃_k  (= g_k W_k)
    patch_defect: float  # max_k |Σ_j Ds_kj − Σ_j M_kj| / Σ_j Ds_kj (0 for a rigid master)
    uncovered: np.ndarray  # trace indices left without multiplier: no master behind them
    master_proj: sp.csr_matrix | None = None  # (N_t, n_full): u ↦ mortar-mean u_m·τ_k
    # (N_n, n_full): x ↦ mortar mean Σ_j M_kj φ_m,j / W_k of a piezoelectric master's potential
    master_phi: sp.csr_matrix | None = None
    law: str = LAWS[0]  # "bilateral" or "unilateral"
    friction: str = FRICTIONS[0]  # "tresca" or "coulomb"
    F: np.ndarray | None = None  # (N_t,) Coulomb F_k = ∫Fφ̃_k / ∫φ̃_k (friction = "coulomb")
    gap0: np.ndarray | None = None  # (N_n,) initial gap rows Σ_j Ds_kj gap(x_j) (unilateral)
    closed_gap: float = 0.0  # bilateral, two bodies: the largest initial gap it closes (m)
    idx_n: np.ndarray | None = None  # (N_n,) row of B_full (and λ) holding each normal row
    idx_t: np.ndarray | None = None  # (N_t,) the same for the tangential rows
    pairs: int = 0  # unilateral: rows 0 … 2·pairs − 1 of B_full are nodes [n, τ] interleaved

    @property
    def sizes(self) -> tuple[int, int]:
        """(N_n, N_t): numbers of normal and tangential multipliers."""
        return self.rows_n.size, self.rows_t.size

    def normal(self, v: np.ndarray) -> np.ndarray:
        """The normal rows (N_n,) of a vector in the row order of B_full (λ, B u)."""
        return v[self.idx_n]

    def tangential(self, v: np.ndarray) -> np.ndarray:
        """The tangential rows (N_t,) of a vector in the row order of B_full (λ, B u)."""
        return v[self.idx_t]

    def bound(self, lam: np.ndarray) -> np.ndarray:
        """(N_t,) the friction radius at the multiplier λ (B_full's row order): g (bilateral),
        g where λ_n > 0 and 0 elsewhere (unilateral Tresca), F·max(λ_n, 0) (Coulomb)."""
        return interface.friction_radius(self, lam, self.tr.size, self.rows_t)

    def Lambda(self):
        """Bilateral: Λ_h = Free(N_n) × Box(−g, g); unilateral: the contact set of the node
        pairs [n, τ] (`contact_law.pair_set`), NonNegative over the normal-only nodes."""
        n_n = self.rows_n.size
        if self.law == "bilateral":
            return product(Free(n_n), Box(-self.g, self.g))
        p = self.pairs  # every tangential row is paired with its node's normal row
        bound = self.F if self.friction == "coulomb" else self.g
        pairs = contact_law.pair_set(self.friction, bound, dim=2)
        return product(pairs, NonNegative(n_n - p)) if n_n > p else product(pairs)

    def gram_weights(self) -> np.ndarray:
        """(N_n + N_t,) h_k W_k per row of B_full (h_k the longer adjacent segment, W_k the
        nodal weight ∫φ_k): the diagonal of Y (`interface.multiplier_rows`)."""
        rows = np.empty(self.B_full.shape[0], dtype=int)  # trace index of each row of B_full
        rows[self.idx_n], rows[self.idx_t] = self.rows_n, self.rows_t
        return self.tr.node_sizes()[rows] * self.tr.weights[rows]


def from_scene(bodies: dict[str, Body], ct: ContactSection, n_full: int, level: int) -> Contact:
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
                f"{interface.node_at(slave, tr, i)}: only u_{'xy'[c]} is prescribed, a direction "
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
) -> Contact:
    """The contact rows: normal Σ_j Ds_kj n_kᵀu_s,j − Σ_j M_kj n_kᵀu_m,j (M = 0 for a rigid
    foundation), then the same with τ_k, for the multiplier rows of each component; with
    law = "unilateral" the rows of a node are put side by side [n, τ] (vi_core.coulomb) and the
    initial gap rows Σ_j Ds_kj gap(x_j) are built (gap: the scene's field for a rigid
    foundation, the distance along n_j to the master polyline for two bodies)."""
    from fem.mortar import COVER_TOL, mortar_coupling, patch_defect

    unilateral = ct.law == "unilateral"
    tr = trace(slave.mesh, part)
    carry = carrying(slave, part, tr)
    if unilateral and (carry[1] & ~carry[0]).any():
        i = int(np.flatnonzero(carry[1] & ~carry[0])[0])
        raise SceneError(
            "contact.law",
            "unilateral",
            f"contact nodes free to separate; {interface.node_at(slave, tr, i)} has its normal "
            "displacement prescribed (a roller across Γ3): with unilateral contact prescribe "
            "both components there or none (or use law = 'bilateral')",
        )
    if not (carry[0] | carry[1]).any():
        raise SceneError(
            "contact.slave",
            f"{slave.name}.{part}",
            "a contact boundary with nodes whose displacement is not fully prescribed: every "
            "node of this one is clamped by a [[displacement]] part, so no contact remains; "
            "remove the Dirichlet condition on it or the [contact] table",
        )
    n_seg = tr.facets.shape[0]
    uncovered_local = np.zeros(2 * n_seg, dtype=bool)
    gap_nodes = np.zeros(tr.size)  # (N,) initial normal gap at the slave nodes
    closed = 0.0  # the initial gap bilateral contact closes
    if master is not None:
        if unilateral:
            gap_nodes = separation.initial_gap(slave, part, tr, tr.normals, master, mpart, level)
        else:
            closed = separation.check_separation(slave, part, tr, tr.normals, master, mpart, level)
        reach = 1.0 + float(np.max(gap_nodes, initial=0.0) / tr.measures.min())
        mort = mortar_coupling(slave.mesh, part, master.mesh, mpart, reach=reach)
        assert np.array_equal(tr.nodes, mort.slave_nodes)
        uncovered_local = np.repeat(mort.coverage < 1.0 - COVER_TOL, 2)  # (2 n_seg,) (fem.mortar)
        mdofs = master.u_dofs(mort.master_nodes)  # (nm, 2)
    else:
        gap_nodes = interface.rigid_gap(ct.gap, slave.mesh.points[tr.nodes])
    Dloc = dual_mass(tr)  # (2 n_seg, N)
    bfun = ct.g if ct.friction == "tresca" else ct.F
    gloc = friction_local(slave.mesh, tr, bfun).ravel()  # (2 n_seg,)
    sdofs = slave.u_dofs(tr.nodes)  # (N, 2)
    uncovered = np.zeros(tr.size, dtype=bool)
    blocks, rows_c, Q_c, defects, offset = [], [], [], [0.0], 0
    for comp, vec in ((0, tr.normals), (1, tr.tangents)):
        Q = multiplier_basis(tr, carry[comp], ct.ends)
        rows = np.flatnonzero(carry[comp])
        bad = (Q @ uncovered_local) > 0  # some of the row's support has no master behind it
        uncovered[rows[bad]] = True
        Q, rows = Q[~bad], rows[~bad]
        Ds = (Q @ Dloc).tocoo()
        parts = [(Ds, sdofs, 1.0)]
        if master is not None:
            M = (Q @ mort.M).tocoo()
            parts.append((M, mdofs, -1.0))
            if rows.size:
                defects.append(float(patch_defect(Q @ Dloc, Q @ mort.M).max()))
        for mat, dofs, sign in parts:
            for c in range(2):
                r = offset + mat.row
                blocks.append((r, dofs[mat.col, c], sign * mat.data * vec[rows[mat.row], c]))
        rows_c.append(rows)
        Q_c.append(Q)
        offset += rows.size
    if offset == 0:
        raise SceneError(
            "contact.master",
            f"{master.name}.{mpart}" if master is not None else "rigid",
            f"a master boundary behind the slave boundary {slave.name}.{part}: no slave node "
            f"has the master behind its support (nodes {tr.nodes.tolist()}); make the two "
            "boundaries face each other and overlap",
        )
    r, c, v = (np.concatenate(x) for x in zip(*blocks, strict=True))
    B = sp.csr_matrix((v, (r, c)), shape=(offset, n_full))
    Q_t, rows_n, rows_t = Q_c[1], rows_c[0], rows_c[1]
    if unilateral and not np.isin(rows_t, rows_n).all():
        i = int(rows_t[~np.isin(rows_t, rows_n)][0])
        raise SceneError(
            "contact.master",
            f"{master.name}.{mpart}" if master is not None else "rigid",
            f"a master behind the normal multiplier of every slave node with a tangential one "
            f"(unilateral contact); {interface.node_at(slave, tr, i)} has none",
        )
    W_n, W_t = (np.asarray((Q @ Dloc).sum(axis=1)).ravel() for Q in Q_c)  # ∫φ̃_k per row
    gw = Q_t @ gloc  # (N_t,) ∫gφ̃_k (Coulomb: ∫Fφ̃_k)
    n_n, n_t = rows_n.size, rows_t.size
    idx_n, idx_t, pairs = np.arange(n_n), n_n + np.arange(n_t), 0
    if unilateral:  # nodes [n, τ] side by side, then the nodes with a normal row only
        paired = np.isin(rows_n, rows_t)  # (N_n,); every tangential row is paired (above)
        pairs = n_t
        idx_n = np.empty(n_n, dtype=int)
        idx_n[paired] = 2 * np.arange(pairs)
        idx_n[~paired] = 2 * pairs + np.arange(n_n - pairs)
        idx_t = 2 * np.arange(pairs) + 1
        order = np.empty(n_n + n_t, dtype=int)  # B_full row → row of B built above
        order[idx_n], order[idx_t] = np.arange(n_n), n_n + np.arange(n_t)
        B = B[order]
    gap0 = (Q_c[0] @ Dloc) @ gap_nodes if unilateral else None  # (N_n,)
    proj = None
    if master is not None:  # mortar mean of u_m·τ_k over the row's support
        M = (Q_t @ mort.M).tocoo()
        pv = [M.data * tr.tangents[rows_t[M.row], c] / W_t[M.row] for c in range(2)]
        proj = sp.csr_matrix(
            (
                np.concatenate(pv),
                (np.tile(M.row, 2), np.concatenate([mdofs[M.col, c] for c in range(2)])),
            ),
            shape=(rows_t.size, n_full),
        )
    master_phi = None
    if master is not None and master.has_potential:  # normal rows: Σ_j M_kj φ_m,j / W_k
        M = (Q_c[0] @ mort.M).tocoo()
        master_phi = sp.csr_matrix(
            (M.data / W_n[M.row], (M.row, master.phi_dofs(mort.master_nodes)[M.col])),
            shape=(rows_n.size, n_full),
        )
    return Contact(
        slave=slave,
        slave_part=part,
        tr=tr,
        master=master,
        master_part=mpart,
        ends=ct.ends,
        rows_n=rows_n,
        rows_t=rows_t,
        Q_n=Q_c[0],
        Q_t=Q_t,
        W_n=W_n,
        W_t=W_t,
        g=gw / W_t if ct.friction == "tresca" else np.zeros(n_t),
        B_full=B,
        g_weights=gw if ct.friction == "tresca" else np.zeros(n_t),
        patch_defect=max(defects),
        uncovered=np.flatnonzero(uncovered),
        master_proj=proj,
        master_phi=master_phi,
        law=ct.law,
        friction=ct.friction,
        F=gw / W_t if ct.friction == "coulomb" else None,
        gap0=gap0,
        closed_gap=closed,
        idx_n=idx_n,
        idx_t=idx_t,
        pairs=pairs,
    )


def friction_local(mesh: Mesh, tr: Trace, gfun) -> np.ndarray:
    """(n_seg, 2) ∫_e g φ_{e,a} ds (g ≥ 0 checked at every quadrature point: `checked_bound`;
    g is the Tresca bound or the Coulomb coefficient F)."""
    return facet_integrals(mesh, tr, interface.checked_bound(gfun))
