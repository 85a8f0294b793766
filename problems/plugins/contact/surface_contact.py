"""The contact interface of a 3D scene: the slave surface, its frames, the crosspoint classes
and the contact rows (`SolidContact`, built by `slave_contact`), with the master side of a
two-body interface (`Coupling`, `mortar_coupling`).

Per contact node k of the slave surface Γ3 (a boundary part of a 3D body): a normal multiplier
λ_n,k (free: bilateral contact) and a tangential one λ_t,k in the tangent plane with the
friction disc |λ_t,k| ≤ g_k (`vi_core.Ball(g, 2)`); λ_h = Σ_k (λ_n,k n_k + λ_t1,k t1_k +
λ_t2,k t2_k) ψ̃_k with the dual basis ψ̃_k of the contact faces (Q1 quadrilaterals or P1
triangles, `fem.facets`), so that ∫ψ̃_k φ_j = δ_kj W_k with W_k = ∫_Γ3 φ_k and the slave
block D = diag(W) is diagonal. g_k = ∫g φ_k / W_k. Frames (t1, t2, n) are right-handed and
continuous on curved surfaces (`fem.facets.frames`). With a rigid foundation (the slave
surface itself, flat or curved: bilateral contact has no initial gap) the rows are
W_k n_kᵀu_k and W_k t_kᵀu_k; a master body adds −Σ_j M_kj (·)ᵀu_m,j (a `Coupling`: the 3D dual
mortar of `fem.mortar`, `mortar_coupling`; docs/fem3d.md "Two bodies in contact3d").

Multiplier order: the normal rows, then the disc nodes (t1, t2 per node), then the nodes that
keep one tangent only. Crosspoint rules (per node, from its prescribed displacement
components, which must span a sub-frame of (n, t1, t2) after turning the tangents): nothing
prescribed → n, t1, t2; all prescribed → no multiplier; one component e_c with e_c ⟂ n → n and
the tangent n × e_c (a line |λ_t| ≤ g); e_c ∥ n → the two tangents only (a disc); two
components with the free one e_f ∥ n → n only; with e_f ⟂ n → the tangent e_f only; anything
else is refused (SceneError naming the nodes).

Crosspoint basis (`[contact] ends`, `class_blocks`), per class (normal; tangential): "keep"
drops the dual functions of the nodes the rules give no row of the class; "merge" (default;
Wohlmuth's modification, the 2D default too) gives them to the class's carrying neighbours in each
face (`fem.facets.multiplier_basis`), so that Σ_k ψ̃_k = 1 on every face with a carrier. A
line node keeps its tangential class (it cannot give away one tangent's function: the
neighbours' rows would re-impose the tangent it keeps); its other tangent's function is dropped.
The rows of node k in class c are then Σ_j S_c,kj d_kᵀu_s,j − Σ_j M_c,kj d_kᵀu_m,j with
S_c = Q_c D_loc (S_c,kk = W_k; entries at the dropped nodes, whose displacement is prescribed,
go into the gap) and M_c = Q_c M_loc; the class weights W_n,k, W_t,k = ∫ψ̃_k dA (row sums; = W_k
under "keep") scale the jumps (B u)/W_c, the Lemma 4.2 sum, the force, the areas and Y, and
g_k = ∫gφ̃_k / W_t,k (φ̃ = Q_t φ, as 2D).

Unilateral contact (`[contact] law = "unilateral"`, the keys of `contact_law`): λ_n ≥ 0,
gap ≥ 0, λ_n·gap = 0 and |λ_t| ≤ ρ with ρ = F_k λ_n (Coulomb, F_k = ∫Fφ̃_k / W_t,k) or g_k where
the node touches (Tresca). The rows of a node are then side by side (`SolidContact.rows`):
[n, t1, t2] per disc node (vi_core's contact set with dim 3), [n, t] per line node (dim 2),
then the normal-only nodes (NonNegative); a node whose normal displacement is prescribed is
refused. The initial gap is Σ_j S_n,kj gap(x_j) for a rigid foundation (the scene's field) and
the weighted mortar gap −n_k·(Σ_j S_n,kj x_s,j − Σ_j M_n,kj x_m,j) for two bodies, which may
start apart (an overlap beyond separation.SEPARATION_TOL × the level-0 node size is refused).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from fem import mortar as dual_mortar
from fem.facets import Trace, dual_mass, facet_integrals, frames, multiplier_basis, trace
from problems.errors import SceneError
from vi_core import Ball, Box, Free, NonNegative, product

from ..contract import check_meshed
from . import interface, separation
from . import law as contact_law
from .bodies import Body
from .interface import SURFACE_ORDER
from .scene_model import ContactSection

ALIGN_TOL = 1e-10  # sine of the angle under which a prescribed direction counts as n or ⟂ n


@dataclass
class Coupling:
    """The master side of a two-body interface (`None` in `SolidContact` = rigid foundation).

    M_loc (m·n_f, n_master_nodes): the face-local mortar matrix ∫_e ψ_{e,a} φ_j^m dA of
    `fem.mortar` (a class's rows are Q_c M_loc, `class_blocks`); dofs (n_master_nodes, 3) the
    master's full displacement dofs; `patch_defect` max over the rows of
    |W_c,k − Σ_j M_c,kj| / W_c,k.
    """

    body: Body
    part: str
    M_loc: sp.csr_matrix
    dofs: np.ndarray
    patch_defect: float
    covered: np.ndarray | None = None  # (k_slave,) the master is behind the node's support
    n_cells: int = 0  # integration cells of the mortar


@dataclass
class SolidContact:
    """The contact interface Γ3 of a 3D scene: slave surface, frames, multiplier rows, bounds.

    Trace arrays are per slave surface node (k); rows_n (N_n,), disc (N_b,) and line (N_l,)
    index the nodes carrying a normal multiplier, two tangential ones, one tangential one.
    A `line` node keeps the tangent t1 (line_slot 0) or t2 (line_slot 1): `line_dir`.
    """

    slave: Body
    slave_part: str
    surf: Trace
    normals: np.ndarray  # (k, 3)
    t1: np.ndarray  # (k, 3)
    t2: np.ndarray  # (k, 3)
    rows_n: np.ndarray  # (N_n,)
    disc: np.ndarray  # (N_b,)
    line: np.ndarray  # (N_l,)
    line_slot: np.ndarray  # (N_l,) 0: the kept tangent is t1, 1: it is t2
    g: np.ndarray  # (k,) g_k = ∫gφ̃_k / W_t,k (Coulomb: 0)
    B_full: sp.csr_matrix  # (N_n + 2 N_b + N_l, n_full)
    W_n: np.ndarray  # (k,) ∫ψ̃_k dA of the normal class (W where the node carries no λ_n)
    W_t: np.ndarray  # (k,) ∫ψ̃_k dA of the tangential class (W where no tangential row)
    ends: str = "merge"  # the crosspoint basis: "keep" or "merge" (`class_blocks`)
    master: Coupling | None = None
    law: str = contact_law.LAWS[0]  # "bilateral" or "unilateral"
    friction: str = contact_law.FRICTIONS[0]  # "tresca" or "coulomb"
    F: np.ndarray | None = None  # (k,) Coulomb F_k = ∫Fφ̃_k / W_t,k (friction = "coulomb")
    gap0: np.ndarray | None = None  # (N_n,) initial gap rows Σ_j S_n,kj gap_j (unilateral)
    order: np.ndarray | None = None  # (m,) row of the bilateral order at each row of B_full
    gap_field: Callable | None = None  # the scene's gap(x, y, z) to a rigid foundation
    bound_field: Callable | None = None  # the scene's g(x, y, z) (tresca) or F(x, y, z)

    def rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(idx_n (N_n,), idx_disc (N_b, 2), idx_line (N_l,)): the row of B_full (and λ) of
        each normal row, disc pair (t1, t2) and line row. Bilateral: normals, discs, lines in
        turn; unilateral: the nodes [n, t1, t2] (discs), then [n, t] (lines) side by side, then
        the normal-only nodes (vi_core.coulomb's node-by-node order)."""
        N_n, N_b, N_l = self.sizes
        at = np.arange(N_n + 2 * N_b + N_l)
        if self.order is not None:
            at = np.argsort(self.order)  # bilateral row → row of B_full
        return at[:N_n], at[N_n : N_n + 2 * N_b].reshape(N_b, 2), at[N_n + 2 * N_b :]

    def bound(self, lam: np.ndarray) -> np.ndarray:
        """(k,) the friction radius per surface node at the multiplier λ (B_full's row order):
        g (bilateral), g where λ_n > 0 and 0 elsewhere (unilateral Tresca), F·max(λ_n, 0)
        (Coulomb); λ_n = 0 where a node carries no normal row."""
        return interface.friction_radius(self, lam, self.surf.size)

    @property
    def idx_n(self) -> np.ndarray:
        """(N_n,) the row of B_full (and λ) of each normal row (`rows`)."""
        return self.rows()[0]

    @property
    def W(self) -> np.ndarray:
        """(k,) W_k = ∫_Γ3 φ_k dA, the nodal quadrature weights (the diagonal of each class's
        slave block; its row sums are W_n, W_t)."""
        return self.surf.weights

    def row_weights(self) -> np.ndarray:
        """(m,) the weight ∫ψ̃_k dA of every row of B_full (W_n on the normal rows, W_t on the
        tangential ones): (B u)_r / w_r is the row's mean jump."""
        idx_n, idx_b, idx_l = self.rows()
        w = np.empty(self.B_full.shape[0])
        w[idx_n] = self.W_n[self.rows_n]
        w[idx_b] = self.W_t[self.disc, None]
        w[idx_l] = self.W_t[self.line]
        return w

    def gram_weights(self) -> np.ndarray:
        """(m,) h_k W_c,k per row of B_full (W_c the row's class weight, `row_weights`): the
        diagonal of Y (`interface.multiplier_rows`)."""
        return self.surf.node_sizes()[row_nodes(self)] * self.row_weights()

    @property
    def line_dir(self) -> np.ndarray:
        """(N_l, 3) the tangent each line node keeps."""
        return np.where(self.line_slot[:, None] == 0, self.t1[self.line], self.t2[self.line])

    @property
    def sizes(self) -> tuple[int, int, int]:
        """(N_n, N_b, N_l)."""
        return self.rows_n.size, self.disc.size, self.line.size

    def Lambda(self):
        """Bilateral: Λ_h = Free(N_n) × Ball(g, 2) over the disc nodes × Box(−g, g) over the
        line nodes. Unilateral: the contact set of the disc nodes in R³ (a friction disc), that
        of the line nodes in R² (one tangent), NonNegative over the normal-only nodes
        (`contact_law.pair_set`: Coulomb(F) or contact-only UnilateralTresca(g))."""
        if self.law == "bilateral":
            gb, gl = self.g[self.disc], self.g[self.line]
            return product(Free(self.rows_n.size), Ball(gb, 2), Box(-gl, gl))
        bound = self.F if self.friction == "coulomb" else self.g
        sets = [contact_law.pair_set(self.friction, bound[self.disc], 3)]
        sets.append(contact_law.pair_set(self.friction, bound[self.line], 2))
        sets.append(NonNegative(self.rows_n.size - self.disc.size - self.line.size))
        return product(*sets)


def from_scene(
    bodies: dict[str, Body], ct: ContactSection, n_full: int, level: int
) -> SolidContact:
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


def row_nodes(c: SolidContact) -> np.ndarray:
    """(m,) the surface node of every row of B_full, in its row order."""
    idx_n, idx_b, idx_l = c.rows()
    k = np.empty(c.B_full.shape[0], dtype=int)
    k[idx_n], k[idx_b], k[idx_l] = c.rows_n, c.disc[:, None], c.line
    return k


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


def class_blocks(
    surf: Trace,
    carry: np.ndarray,
    covered: np.ndarray,
    ends: str,
    M_loc: sp.csr_matrix | None = None,
) -> tuple[sp.csr_matrix, sp.csr_matrix | None, np.ndarray, sp.csr_matrix]:
    """The rows of one multiplier class (normal, or tangential) in the basis ψ̃ = Q ψ of
    `fem.facets.multiplier_basis(surf, carry, ends)`: carry (k,) the nodes the crosspoint
    rules give a row of the class ("merge": the others give their dual functions to their
    neighbours in each face; "keep": they are dropped). Rows of nodes whose support the master
    does not cover (covered (k,) False) are then dropped as they are (never merged).

    Returns S (k, k) the slave block Q_c D_loc (row k zero where node k has no row of the
    class; S_kk = W_k by biorthogonality, S_kj ≠ 0 for j ≠ k only at nodes j that gave their
    function away), Mc (k, k_m) = Q_c M_loc (None without a master), Wc (k,) the row sums
    ∫ψ̃_k dA = W_k + what node k received (W_k where it has no row or received nothing) and
    Qk (k, m·n_f) the basis in node rows.
    """
    idx = np.flatnonzero(carry)  # (n_c,) the node of each row of Q
    Q = multiplier_basis(surf, carry, ends)  # (n_c, m n_f)
    sel = covered[idx]
    P = sp.csr_matrix(
        (np.ones(int(sel.sum())), (idx[sel], np.flatnonzero(sel))), shape=(surf.size, idx.size)
    )
    Qk = (P @ Q).tocsr()  # (k, m n_f)
    S = (Qk @ dual_mass(surf)).tocsr()  # (k, k)
    C = Qk.tocoo()
    given = surf.facets.ravel()[C.col] != C.row  # (nnz,) entries of another node's function
    fw = surf.facet_weights.ravel()  # (m n_f,) ∫_e φ_a = ∫_e ψ_{e,a}
    received = np.bincount(C.row[given], C.data[given] * fw[C.col[given]], surf.size)  # (k,)
    Wc = surf.weights + received  # (k,) = W exactly where nothing was merged in
    Mc = None if M_loc is None else (Qk @ M_loc).tocsr()
    return S, Mc, Wc, Qk


def contact_rows(
    dirs: list[tuple[np.ndarray, np.ndarray, sp.csr_matrix, sp.csr_matrix | None]],
    slave_dofs: np.ndarray,
    n_full: int,
    master_dofs: np.ndarray | None = None,
) -> sp.csr_matrix:
    """Rows Σ_j S_kj d_rᵀu_s,j − Σ_j M_kj d_rᵀu_m,j for each (nodes (r,), directions (r, 3),
    S (k, k), M (k, k_m) or None) of `dirs`, in order (S, M a class's blocks, `class_blocks`).
    slave_dofs (k, 3) full dofs of the surface nodes, master_dofs (k_m, 3) the master's."""
    rows, cols, vals, offset = [], [], [], 0
    for nodes, d, S, M in dirs:
        for mat, dofs, sign in ((S, slave_dofs, 1.0), (M, master_dofs, -1.0)):
            if mat is None:
                continue
            C = mat[nodes].tocoo()  # (r, ·)
            for c in range(3):
                rows.append(offset + C.row)
                cols.append(dofs[C.col, c])
                vals.append(sign * C.data * d[C.row, c])
        offset += nodes.size
    B = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(offset, n_full)
    )
    B.eliminate_zeros()
    return B


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
    return Coupling(master, mpart, mo.M, dofs, np.nan, dual_mortar.covered_nodes(mo), mo.n_cells)


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
) -> SolidContact:
    """The contact of `slave`'s boundary `part` (a rigid foundation along it, or `master`):
    surface, frames, crosspoint rules, g_k (or F_k) and the rows; `law` is the [contact]
    table (`ContactSection`: law, friction, g or F, gap). Unilateral contact puts the rows of a
    node side by side (`SolidContact.rows`) and builds the initial gap rows: Σ_j S_n,kj gap(x_j)
    for a rigid foundation, the weighted mortar gap −(D x_s − M x_m)·n_k of the geometry for two
    bodies (an overlap beyond `separation.SEPARATION_TOL` × the level-0 node size is refused)."""
    unilateral = law.law == "unilateral"
    gfun = law.g if law.friction == "tresca" else law.F
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
    # the two classes' bases from the crosspoint rules (a line node keeps its tangential class:
    # it cannot give away one tangent's function), then the rows the master covers
    covered = np.ones(surf.size, dtype=bool) if master is None else master.covered
    if master is not None and not covered.any():  # no multiplier at all: say why
        raise SceneError(
            "contact.master",
            f"{master.body.name}.{master.part}",
            separation.not_facing(surf, master),
        )
    M_loc = None if master is None else master.M_loc
    S_n, M_n, W_n, _ = class_blocks(surf, carry_n, covered, law.ends, M_loc)
    S_t, M_t, W_t, Q_t = class_blocks(surf, n_tan > 0, covered, law.ends, M_loc)
    carry_n &= covered
    n_tan = np.where(covered, n_tan, 0)
    if master is not None:  # the rigid-body rows: Σ_j M_c,kj = W_c,k where covered
        rel = [
            np.abs(Wc - np.asarray(Mc.sum(axis=1)).ravel())[has] / Wc[has]
            for Wc, Mc, has in ((W_n, M_n, carry_n), (W_t, M_t, n_tan > 0))
        ]
        master.patch_defect = float(np.concatenate(rel).max(initial=0.0))
    if bad:
        where = "; ".join(interface.node_at(slave, surf, i) for i in bad[:6])
        raise SceneError(
            key,
            f"{slave.name}.{part}",
            "contact nodes whose prescribed displacement components span the contact normal, "
            "the tangent plane, or a normal–tangent pair (a roller across or along Γ3); "
            f"{len(bad)} node(s) have a prescribed direction at an angle to the surface: {where}",
        )
    if not (carry_n | (n_tan > 0)).any():
        raise SceneError(
            key,
            f"{slave.name}.{part}",
            "a contact boundary with nodes whose displacement is not fully prescribed",
        )

    if unilateral and (n_tan > carry_n * 2).any():
        i = int(np.flatnonzero(n_tan > carry_n * 2)[0])
        raise SceneError(
            "contact.law",
            "unilateral",
            f"contact nodes free to separate; {interface.node_at(slave, surf, i)} has its normal "
            "displacement prescribed (a roller across Γ3): with unilateral contact prescribe "
            "all its components, or only tangential ones (or use law = 'bilateral')",
        )
    order = SURFACE_ORDER[slave.mesh.cell_type]
    gloc = facet_integrals(
        slave.mesh, surf, interface.checked_bound(gfun), order
    )  # (n_f, m) ∫_e g φ_e,a
    g = np.where(  # ∫gφ̃_k / W_t,k; the plain nodal mean ∫gφ_k / W_k at the other nodes
        n_tan > 0,
        (Q_t @ gloc.ravel()) / W_t,
        np.bincount(surf.facets.ravel(), gloc.ravel(), surf.size) / surf.weights,
    )
    rows_n = np.flatnonzero(carry_n)
    disc = np.flatnonzero(n_tan == 2)
    line = np.flatnonzero(n_tan == 1)
    # disc rows interleaved (t1, t2) per node: rows 2j, 2j+1 of the disc block
    disc_nodes = np.repeat(disc, 2)
    disc_dirs = np.stack([t1[disc], t2[disc]], axis=1).reshape(-1, 3)
    dirs = [
        (rows_n, surf.normals[rows_n], S_n, M_n),
        (disc_nodes, disc_dirs, S_t, M_t),
        (line, np.where(slot[line, None] == 0, t1[line], t2[line]), S_t, M_t),
    ]
    sdofs, mdofs = slave.u_dofs(surf.nodes), None if master is None else master.dofs
    B = contact_rows(dirs, sdofs, n_full, mdofs)
    perm = gap0 = None
    if unilateral:
        N_n, N_b = rows_n.size, disc.size
        at_n = np.full(surf.size, -1)
        at_n[rows_n] = np.arange(N_n)  # normal row of each surface node
        t_disc = N_n + 2 * np.arange(N_b)
        t_line = N_n + 2 * N_b + np.arange(line.size)
        alone = np.setdiff1d(rows_n, np.concatenate([disc, line]))  # normal-only nodes
        perm = np.concatenate(
            [
                np.stack([at_n[disc], t_disc, t_disc + 1], axis=1).ravel(),
                np.stack([at_n[line], t_line], axis=1).ravel(),
                at_n[alone],
            ]
        )  # (m,) the bilateral row of each row of B_full
        B = B[perm]
        if master is None:  # Σ_j S_n,kj gap(x_j)
            gap0 = S_n[rows_n] @ interface.rigid_gap(law.gap, slave.mesh.points[surf.nodes])
        else:
            B_n = contact_rows(dirs[:1], sdofs, n_full, mdofs)
            gap0 = -(B_n @ _positions([slave, master.body], n_full))  # (N_n,)
            h0 = surf.node_sizes()[rows_n] * 2.0**level  # the level-0 node size
            rel = gap0 / W_n[rows_n] / h0
            if (rel < -separation.SEPARATION_TOL).any():
                i = int(np.argmin(rel))
                raise SceneError(
                    "contact.master",
                    f"{master.body.name}.{master.part}",
                    f"a master surface that does not overlap the slave {slave.name}.{part} in "
                    f"the reference configuration by more than {separation.SEPARATION_TOL:g} × "
                    f"the level-0 node size: it overlaps by {-rel[i] * h0[i]:.3g} ({-rel[i]:.2f} × "
                    f"{h0[i]:.3g}) at {interface.node_at(slave, surf, int(rows_n[i]))}",
                )
    return SolidContact(
        slave=slave,
        slave_part=part,
        surf=surf,
        normals=surf.normals,
        t1=t1,
        t2=t2,
        rows_n=rows_n,
        disc=disc,
        line=line,
        line_slot=slot[line],
        g=g if law.friction == "tresca" else np.zeros(surf.size),
        B_full=B,
        W_n=W_n,
        W_t=W_t,
        ends=law.ends,
        master=master,
        law=law.law,
        friction=law.friction,
        F=g if law.friction == "coulomb" else None,
        gap0=gap0,
        order=perm,
        gap_field=law.gap if unilateral and master is None else None,
        bound_field=gfun,
    )
