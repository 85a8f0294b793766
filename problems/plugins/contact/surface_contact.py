"""The contact interface of a 3D scene: the slave surface, its frames and crosspoint classes,
the master side of a two-body interface (`mortar_coupling`) and its weighted mortar gap, built
into an `interface.Interface` by `slave_contact` (the rows themselves: `rows.assemble`).

Per contact node k of the slave surface Γ3 (a boundary part of a 3D body): a normal multiplier
λ_n,k (free: bilateral contact) and a tangential one λ_t,k in the tangent plane with the
friction disc |λ_t,k| ≤ g_k (`vi_core.Ball(g, 2)`); λ_h = Σ_k (λ_n,k n_k + λ_t1,k t1_k + λ_t2,k
t2_k) ψ̃_k with the dual basis ψ̃_k of the contact faces (Q1 quadrilaterals or P1 triangles,
`fem.facets`), so that ∫ψ̃_k φ_j = δ_kj W_k with W_k = ∫_Γ3 φ_k and the slave block D = diag(W)
is diagonal. g_k = ∫g φ_k / W_k. Frames (t1, t2, n) are right-handed and continuous on curved
surfaces (`fem.facets.frames`). With a rigid foundation (the slave surface itself, flat or
curved: bilateral contact has no initial gap) the rows are W_k n_kᵀu_k and W_k t_kᵀu_k; a
master body adds −Σ_j M_kj (·)ᵀu_m,j (an `interface.Coupling`: the 3D dual mortar of
`fem.mortar`, `mortar_coupling`; docs/fem3d.md "Two bodies in 3D").

Multiplier order: the normal rows, then the disc nodes (t1, t2 per node), then the nodes that
keep one tangent only. Crosspoint rules (per node, from its prescribed displacement
components, which must span a sub-frame of (n, t1, t2) after turning the tangents): nothing
prescribed → n, t1, t2; all prescribed → no multiplier; one component e_c with e_c ⟂ n → n and
the tangent n × e_c (a line |λ_t| ≤ g); e_c ∥ n → the two tangents only (a disc); two
components with the free one e_f ∥ n → n only; with e_f ⟂ n → the tangent e_f only; anything
else is refused (SceneError naming the nodes).

Crosspoint basis (`[contact] ends`, `rows.class_blocks`), per class (normal; tangential):
"keep" drops the dual functions of the nodes the rules give no row of the class; "merge"
(default; Wohlmuth's modification, the 2D default too) gives them to the class's carrying
neighbours in each face (`fem.facets.multiplier_basis`), so that Σ_k ψ̃_k = 1 on every face
with a carrier. A line node keeps its tangential class (it cannot give away one tangent's
function: the neighbours' rows would re-impose the tangent it keeps); its other tangent's
function is dropped. The rows of node k in class c are then Σ_j S_c,kj d_kᵀu_s,j − Σ_j M_c,kj
d_kᵀu_m,j with S_c = Q_c D_loc (S_c,kk = W_k; entries at the dropped nodes, whose displacement
is prescribed, go into the gap) and M_c = Q_c M_loc; the class weights W_n,k, W_t,k = ∫ψ̃_k dA
(row sums; = W_k under "keep") scale the jumps (B u)/W_c, the Lemma 4.2 sum, the force, the
areas and Y, and g_k = ∫gφ̃_k / W_t,k (φ̃ = Q_t φ, as 2D).

Unilateral contact (`[contact] law = "unilateral"`, the keys of `contact_law`): λ_n ≥ 0,
gap ≥ 0, λ_n·gap = 0 and |λ_t| ≤ ρ with ρ = F_k λ_n (Coulomb, F_k = ∫Fφ̃_k / W_t,k) or g_k where
the node touches (Tresca). The rows of a node are then side by side (`Interface.rows`):
[n, t1, t2] per disc node (vi_core's contact set with dim 3), [n, t] per line node (dim 2),
then the normal-only nodes (NonNegative); a node whose normal displacement is prescribed is
refused. The initial gap is Σ_j S_n,kj gap(x_j) for a rigid foundation (the scene's field) and
the weighted mortar gap −n_k·(Σ_j S_n,kj x_s,j − Σ_j M_n,kj x_m,j) for two bodies, which may
start apart (an overlap beyond separation.SEPARATION_TOL × the level-0 node size is refused).
"""

from __future__ import annotations

import numpy as np

from fem import mortar as dual_mortar
from fem.facets import facet_integrals, frames, trace
from problems.errors import SceneError
from problems.scene.fields import renamed

from ..contract import check_meshed
from . import reports, rows, separation
from .bodies import Body
from .interface import SURFACE_ORDER, Coupling, Interface
from .scene_model import ContactSection

ALIGN_TOL = 1e-10  # sine of the angle under which a prescribed direction counts as n or ⟂ n


def from_scene(bodies: dict[str, Body], ct: ContactSection, n_full: int, level: int) -> Interface:
    """The contact of a [contact] table between the built `bodies` (by name): its boundaries
    checked (meshed), the master's mortar (`mortar_coupling`), then `slave_contact`."""
    sname, part = ct.slave.split(".", 1)
    check_meshed(bodies[sname].mesh, [("contact.slave", part)])
    master = None
    if ct.master != "rigid":
        mname, mpart = ct.master.split(".", 1)
        check_meshed(bodies[mname].mesh, [("contact.master", mpart)])
        master = mortar_coupling(bodies[sname], part, bodies[mname], mpart)
    return slave_contact(bodies[sname], part, ct, n_full, master, level)


def carrying(
    fixed: np.ndarray, normals: np.ndarray, t1: np.ndarray, t2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """The crosspoint rules (module docstring) per surface node.

    fixed (k, 3) which displacement components are prescribed; normals, t1, t2 (k, 3) the
    surface frames. Returns carry_n (k,) bool, n_tan (k,) 0/1/2, the frames (t1, t2) turned
    about n where one tangent is kept so that the kept one is the frame vector nearest to it,
    slot (k,) (0/1: the kept tangent is t1/t2; −1 elsewhere) and the refused nodes.
    """
    k = fixed.shape[0]
    t1, t2 = t1.copy(), t2.copy()
    n_pres = fixed.sum(axis=1)  # (k,)
    carry_n = n_pres == 0
    n_tan = np.where(n_pres == 0, 2, 0)
    slot = np.full(k, -1)
    bad = []
    eye = np.eye(3)
    for i in np.flatnonzero((n_pres > 0) & (n_pres < 3)):
        n = normals[i]
        if n_pres[i] == 1:
            d = eye[int(np.flatnonzero(fixed[i])[0])]
            if abs(n @ d) >= 1 - ALIGN_TOL:  # the prescribed direction is the normal
                n_tan[i] = 2
                continue
            if abs(n @ d) > ALIGN_TOL:
                bad.append(i)
                continue
            keep, carry_n[i] = np.cross(n, d), True
        else:
            f = eye[int(np.flatnonzero(~fixed[i])[0])]
            if abs(n @ f) >= 1 - ALIGN_TOL:  # only the normal is free
                carry_n[i] = True
                continue
            if abs(n @ f) > ALIGN_TOL:
                bad.append(i)
                continue
            keep = f
        keep = keep / np.linalg.norm(keep)
        n_tan[i] = 1
        if abs(keep @ t1[i]) >= abs(keep @ t2[i]):
            t1[i] = keep * np.sign(keep @ t1[i])
            t2[i] = np.cross(n, t1[i])
            slot[i] = 0
        else:
            t2[i] = keep * np.sign(keep @ t2[i])
            t1[i] = np.cross(t2[i], n)  # (t1, t2, n) stays right-handed
            slot[i] = 1
    return carry_n, n_tan, t1, t2, slot, bad


def mortar_coupling(slave: Body, part: str, master: Body, mpart: str) -> Coupling:
    """The master side of a two-body interface: the 3D dual mortar (`fem.mortar`), face-local
    (a class's rows are Q_c M_loc); nodes without the master behind their whole support carry
    no multiplier (`covered`); patch_defect is set by `slave_contact`."""
    try:
        order = SURFACE_ORDER[slave.mesh.cell_type]  # that of the slave block in slave_contact
        reach = 1.0 + separation.reach(slave, part, master, mpart)
        mo = dual_mortar.mortar_coupling(
            slave.mesh, part, master.mesh, mpart, face_order=order, reach=reach
        )
    except ValueError as err:
        raise SceneError(
            "contact.master", f"{master.name}.{mpart}", f"a master surface facing the slave ({err})"
        ) from None
    dofs = master.u_dofs(mo.master.nodes)  # (k_m, 3)
    covered = dual_mortar.covered_nodes(mo)
    return Coupling(master, mpart, mo.M, dofs, covered)


def _positions(bodies: list[Body], n_full: int) -> np.ndarray:
    """(n_full,) the nodal coordinates in the displacement dofs of every body, 0 elsewhere."""
    X = np.zeros(n_full)
    for b in bodies:
        X[b.u_dofs(np.arange(b.n_nodes))] = b.mesh.points
    return X


def slave_contact(
    slave: Body,
    part: str,
    law: ContactSection,
    n_full: int,
    master: Coupling | None = None,
    level: int = 0,
) -> Interface:
    """The contact of `slave`'s boundary `part` (a rigid foundation along it, or `master`):
    surface, frames, crosspoint rules, g_k (or F_k), then the rows (`rows.assemble`);
    `law` is the [contact] table (`ContactSection`: law, friction, g or F, gap). Unilateral
    contact builds the initial gap rows: Σ_j S_n,kj gap(x_j) for a rigid foundation, the
    weighted mortar gap −(D x_s − M x_m)·n_k of the geometry for two bodies (an overlap beyond
    `separation.SEPARATION_TOL` × the level-0 node size is refused)."""
    unilateral = law.law == "unilateral"
    key = "contact.slave"
    try:
        surf = trace(slave.mesh, part, SURFACE_ORDER[slave.mesh.cell_type])
        t1, t2 = frames(surf.normals)
    except ValueError as err:
        raise SceneError(
            key, f"{slave.name}.{part}", f"a contact surface with valid faces ({err})"
        ) from None
    fixed = slave.fixed[slave.u_dofs(surf.nodes) - slave.offset]  # (k, 3) body-local dofs
    carry_n, n_tan, t1, t2, slot, bad = carrying(fixed, surf.normals, t1, t2)
    if master is not None and not master.covered.any():  # no multiplier at all: say why
        raise SceneError(
            "contact.master",
            f"{master.body.name}.{master.part}",
            separation.not_facing(surf, master),
        )
    if bad:
        where = "; ".join(reports.node_at(slave, surf, i) for i in bad[:6])
        raise SceneError(
            key,
            f"{slave.name}.{part}",
            "contact nodes whose prescribed displacement components span the contact normal, "
            "the tangent plane, or a normal–tangent pair (a roller across or along Γ3); "
            f"{len(bad)} node(s) have a prescribed direction at an angle to the surface: {where}",
        )
    rows.check_carrying(slave, part, surf, carry_n, n_tan, law.law)
    gfun = law.g if law.friction == "tresca" else law.F
    order = SURFACE_ORDER[slave.mesh.cell_type]
    gloc = facet_integrals(slave.mesh, surf, rows.checked_bound(gfun), order)  # (n_f, m)
    gap_nodes = None
    if unilateral and master is None:
        gap_nodes = rows.rigid_gap(law.gap, slave.mesh.points[surf.nodes])  # (k,)
    c = rows.assemble(
        slave, part, surf, (surf.normals, t1, t2, slot), carry_n, n_tan, law, gloc, n_full,
        master, gap_nodes,
    )  # fmt: skip
    if unilateral and master is not None:  # the weighted mortar gap of the geometry
        c.gap0 = -(c.B_full[c.idx_n] @ _positions([slave, master.body], n_full))  # (N_n,)
        h0 = surf.node_sizes()[c.rows_n] * 2.0**level  # the level-0 node size
        rel = c.gap0 / c.W_n[c.rows_n] / h0
        if (rel < -separation.SEPARATION_TOL).any():
            i = int(np.argmin(rel))
            raise SceneError(
                "contact.master",
                f"{master.body.name}.{master.part}",
                f"a master surface that does not overlap the slave {slave.name}.{part} in "
                f"the reference configuration by more than {separation.SEPARATION_TOL:g} × "
                f"the level-0 node size: it overlaps by {-rel[i] * h0[i]:.3g} ({-rel[i]:.2f} × "
                f"{h0[i]:.3g}) at {reports.node_at(slave, surf, int(c.rows_n[i]))}",
            )
    return c


__getattr__ = renamed(__name__, {"SolidContact": "problems.plugins.contact.interface.Interface"})
