"""The contact interface Γ3 of a 2D or 3D scene (`Interface`) and what its two builders share,
written once: the master side (`Coupling`), the multiplier classes and their rows
(`class_blocks`, `contact_rows`, `assemble`), node names in error texts, the checked
friction-bound integrand, the rigid foundation's gap, the multiplier rows handed to the mixed
VI, the layout-free part of the contact state (jumps, pressure scale, thresholds, Lemma 4.2)
and the friction warnings.

A 2D contact node is a 3D "line" node: its one tangent is its line direction. So one
`Interface` holds both, per slave trace node k (the nodes of a boundary curve or surface):
rows_n (normal), disc (two tangents, 3D only) and line (one tangent) with the frames (normals,
t1, t2; 2D: t1 the tangent, t2 None). Each dimension builds its trace, frames, crosspoint
classes and master mortar (2D: `curve_contact`, segment traces and the distance along the
slave normal; 3D: `surface_contact`, polygon-clipping mortar and the weighted mortar gap) and
hands them to `assemble`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from fem.facets import Trace, dual_mass, multiplier_basis
from problems.errors import SceneError
from vi_core import Ball, Box, Free, NonNegative, Solution, product
from vi_core import states as node_states

# Quadrature order of the 3D contact surface integrals (W, normals, g_k, the dual basis of the
# mortar): Q1 faces of a curved surface are not planar and |∂x/∂ξ × ∂x/∂η| is not polynomial
# (order 4 leaves 7e-11 in the rigid-body rows of spherical_cap, order 8 3e-15); P1 faces are
# flat (order 4 exact).
SURFACE_ORDER = {"hexahedron": 8, "tetra": 4}


def node_at(body: Any, tr: Trace, i: int) -> str:
    """'node 12 at [0.0, 1.0]' for trace index i of `body`'s contact boundary `tr`."""
    node = int(tr.nodes[i])
    return f"node {node} at {body.mesh.points[node].tolist()}"


def checked_bound(fun: Any) -> Callable[..., np.ndarray]:
    """The friction bound g (Tresca) or coefficient F (Coulomb), an expression of the
    coordinates whose `path` ends in .g or .F, as an integrand that refuses a negative value
    at a quadrature point (SceneError naming the field)."""
    what = "a friction bound g" if fun.path.endswith(".g") else "a friction coefficient F"

    def checked(*x: np.ndarray) -> np.ndarray:
        v = fun(*x)
        if (v < 0).any():
            raise SceneError(fun.path, float(v.min()), f"{what} ≥ 0 everywhere on Γ3")
        return v

    return checked


def rigid_gap(gap: Any, points: np.ndarray) -> np.ndarray:
    """(k,) the scene's initial gap to a rigid foundation at the points (k, d); 0 without a
    `gap` field; SceneError where it is negative."""
    if gap is None:
        return np.zeros(points.shape[0])
    out = np.broadcast_to(np.asarray(gap(*points.T), float), points.shape[:1]).copy()
    if (out < 0).any():
        raise SceneError(gap.path, float(out.min()), "a distance ≥ 0 at every node of Γ3")
    return out


@dataclass
class Coupling:
    """The master side of a two-body interface (`None` in `Interface` = rigid foundation).

    M_loc (m·n_f, n_master_nodes): the face-local mortar matrix ∫_e ψ_{e,a} φ_j^m of
    `fem.mortar` (a class's rows are Q_c M_loc, `class_blocks`); dofs (n_master_nodes, d) the
    master's full displacement dofs; covered (k,) the master lies behind the slave node's whole
    support; `patch_defect` max over the rows of |W_c,k − Σ_j M_c,kj| / W_c,k (`assemble`).
    """

    body: Any  # the master Body
    part: str
    M_loc: sp.csr_matrix
    dofs: np.ndarray
    covered: np.ndarray
    patch_defect: float = np.nan


# names of the former 2D `Contact` and 3D `SolidContact` that cannot come back, and what to use
GONE = {
    "pairs": "the unilateral rows of a node stand side by side, [n, t1, t2] per disc node, "
    "[n, t] per line node, then the normal-only nodes: use Interface.rows() for the rows of "
    "each kind (the former 2D pairs [n, τ] are the line nodes, line.size of them)",
}


@dataclass
class Interface:
    """The contact interface Γ3 of a 2D or 3D scene: slave trace, frames, multiplier rows,
    bounds (module docstring).

    Trace arrays are per slave trace node (k); rows_n (N_n,), disc (N_b,) and line (N_l,) index
    the nodes carrying a normal multiplier, two tangential ones (3D), one tangential one (2D:
    every tangential row). A `line` node keeps the tangent t1 (line_slot 0) or t2 (line_slot
    1): `line_dir`. Q_n (N_n, m·n_f), Q_t (N_t, m·n_f): the multiplier bases of the nodes
    rows_n and rows_t in the face-local dual functions.
    """

    slave: Any  # the slave Body
    slave_part: str
    tr: Trace  # the slave trace (2D: a curve, 3D: a surface)
    normals: np.ndarray  # (k, d)
    t1: np.ndarray  # (k, d) the first tangent (2D: the tangent)
    t2: np.ndarray | None  # (k, 3) the second tangent (2D: None)
    rows_n: np.ndarray  # (N_n,)
    disc: np.ndarray  # (N_b,)
    line: np.ndarray  # (N_l,)
    line_slot: np.ndarray  # (N_l,) 0: the kept tangent is t1, 1: it is t2
    g: np.ndarray  # (k,) g_k = ∫gφ̃_k / W_t,k (Coulomb: 0)
    B_full: sp.csr_matrix  # (N_n + 2 N_b + N_l, n_full)
    W_n: np.ndarray  # (k,) ∫ψ̃_k of the normal class (W where the node carries no λ_n)
    W_t: np.ndarray  # (k,) ∫ψ̃_k of the tangential class (W where no tangential row)
    Q_n: sp.csr_matrix  # (N_n, m·n_f)
    Q_t: sp.csr_matrix  # (N_t, m·n_f)
    covered: np.ndarray  # (k,) the master lies behind the node's support (all: rigid)
    uncovered: np.ndarray  # trace indices the rules give rows but no master lies behind
    ends: str = "merge"  # the crosspoint basis: "keep" or "merge" (`class_blocks`)
    coupling: Coupling | None = None  # the master side (None: rigid foundation)
    law: str = "bilateral"  # or "unilateral" (`law.LAWS`)
    friction: str = "tresca"  # or "coulomb" (`law.FRICTIONS`)
    F: np.ndarray | None = None  # (k,) Coulomb F_k = ∫Fφ̃_k / W_t,k (friction = "coulomb")
    gap0: np.ndarray | None = None  # (N_n,) initial gap rows Σ_j S_n,kj gap_j (unilateral)
    order: np.ndarray | None = None  # (m,) row of the bilateral order at each row of B_full
    gap_field: Callable | None = None  # the scene's gap to a rigid foundation (unilateral)
    bound_field: Callable | None = None  # the scene's g (tresca) or F field
    # 2D extras: the largest initial gap bilateral contact of two bodies closes (m); the mortar
    # mean of u_m·τ_k per tangential row (N_t, n_full) and of a piezoelectric master's
    # potential Σ_j M_kj φ_m,j / W_k per normal row (N_n, n_full)
    closed_gap: float = 0.0
    master_proj: sp.csr_matrix | None = None
    master_phi: sp.csr_matrix | None = None

    def __getattr__(self, name: str) -> Any:
        """An AttributeError; for a name of the former 2D `Contact` or 3D `SolidContact` that
        has no counterpart here (`GONE`), it says what to use instead."""
        if name in GONE:
            raise AttributeError(f"Interface.{name} is gone (issue 30): {GONE[name]}")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def surf(self) -> Trace:
        """Deprecated (3D `SolidContact.surf`): the slave trace `tr`."""
        warnings.warn(
            "Interface.surf is deprecated: use Interface.tr (the slave trace, 2D and 3D)",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.tr

    @property
    def g_weights(self) -> np.ndarray:
        """Deprecated (2D `Contact.g_weights`): (N_t,) ∫gφ̃_k = g_k W_t,k per tangential row in
        the order of rows_t (0 under Coulomb friction, where g is 0)."""
        warnings.warn(
            "Interface.g_weights is deprecated: use Interface.g[rows_t] * Interface.W_t[rows_t] "
            "(g and W_t are per trace node)",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.g[self.rows_t] * self.W_t[self.rows_t]

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.normals.shape[1])

    @property
    def master(self) -> Any:
        """The master Body, None for a rigid foundation."""
        return None if self.coupling is None else self.coupling.body

    @property
    def master_part(self) -> str | None:
        """The master's contact boundary, None for a rigid foundation."""
        return None if self.coupling is None else self.coupling.part

    @property
    def patch_defect(self) -> float:
        """max_k |W_c,k − Σ_j M_c,kj| / W_c,k over the rows (0 for a rigid foundation)."""
        return 0.0 if self.coupling is None else self.coupling.patch_defect

    @property
    def W(self) -> np.ndarray:
        """(k,) W_k = ∫_Γ3 φ_k, the nodal quadrature weights (the diagonal of each class's
        slave block; its row sums are W_n, W_t)."""
        return self.tr.weights

    @property
    def rows_t(self) -> np.ndarray:
        """(N_t,) the nodes carrying a tangential multiplier (2D: `line`)."""
        return np.union1d(self.disc, self.line)

    @property
    def sizes(self) -> tuple[int, int, int]:
        """(N_n, N_b, N_l)."""
        return self.rows_n.size, self.disc.size, self.line.size

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

    @property
    def idx_n(self) -> np.ndarray:
        """(N_n,) the row of B_full (and λ) of each normal row (`rows`)."""
        return self.rows()[0]

    @property
    def idx_t(self) -> np.ndarray:
        """(N_l,) the row of B_full (and λ) of each line node's tangential row (2D: of every
        tangential row, in the order of rows_t)."""
        return self.rows()[2]

    def normal(self, v: np.ndarray) -> np.ndarray:
        """The normal rows (N_n,) of a vector in the row order of B_full (λ, B u)."""
        return v[self.idx_n]

    def tangential(self, v: np.ndarray) -> np.ndarray:
        """The line rows (N_l,) of a vector in the row order of B_full (2D: every tangential
        row)."""
        return v[self.idx_t]

    @property
    def line_dir(self) -> np.ndarray:
        """(N_l, d) the tangent each line node keeps."""
        if self.t2 is None:
            return self.t1[self.line]
        return np.where(self.line_slot[:, None] == 0, self.t1[self.line], self.t2[self.line])

    def row_weights(self) -> np.ndarray:
        """(m,) the weight ∫ψ̃_k of every row of B_full (W_n on the normal rows, W_t on the
        tangential ones): (B u)_r / w_r is the row's mean jump."""
        idx_n, idx_b, idx_l = self.rows()
        w = np.empty(self.B_full.shape[0])
        w[idx_n] = self.W_n[self.rows_n]
        w[idx_b] = self.W_t[self.disc, None]
        w[idx_l] = self.W_t[self.line]
        return w

    def gram_weights(self) -> np.ndarray:
        """(m,) h_k W_c,k per row of B_full (W_c the row's class weight, `row_weights`): the
        diagonal of Y (`multiplier_rows`)."""
        return self.tr.node_sizes()[row_nodes(self)] * self.row_weights()

    def bound(self, lam: np.ndarray) -> np.ndarray:
        """(k,) the friction radius per trace node at the multiplier λ (B_full's row order):
        g (bilateral), g where λ_n > 0 and 0 elsewhere (unilateral Tresca), F·max(λ_n, 0)
        (Coulomb); λ_n = 0 where a node carries no normal row."""
        if self.law == "bilateral":
            return self.g
        lam_n = np.zeros(self.tr.size)
        lam_n[self.rows_n] = lam[self.idx_n]
        if self.friction == "coulomb":
            return self.F * np.maximum(lam_n, 0.0)
        return self.g * (lam_n > 0)

    def Lambda(self):
        """Bilateral: Λ_h = Free(N_n) × Ball(g, 2) over the disc nodes × Box(−g, g) over the
        line nodes. Unilateral: the contact set of the disc nodes in R³ (a friction disc), that
        of the line nodes in R² (one tangent), NonNegative over the normal-only nodes
        (`law.pair_set`: Coulomb(F) or contact-only UnilateralTresca(g))."""
        from . import law as contact_law

        if self.law == "bilateral":
            gb, gl = self.g[self.disc], self.g[self.line]
            return product(Free(self.rows_n.size), Ball(gb, 2), Box(-gl, gl))
        bound = self.F if self.friction == "coulomb" else self.g
        sets = [contact_law.pair_set(self.friction, bound[self.disc], 3)]
        sets.append(contact_law.pair_set(self.friction, bound[self.line], 2))
        sets.append(NonNegative(self.rows_n.size - self.disc.size - self.line.size))
        return product(*sets)


def row_nodes(c: Interface) -> np.ndarray:
    """(m,) the trace node of every row of B_full, in its row order."""
    idx_n, idx_b, idx_l = c.rows()
    k = np.empty(c.B_full.shape[0], dtype=int)
    k[idx_n], k[idx_b], k[idx_l] = c.rows_n, c.disc[:, None], c.line
    return k


def class_blocks(
    tr: Trace,
    carry: np.ndarray,
    covered: np.ndarray,
    ends: str,
    M_loc: sp.csr_matrix | None = None,
) -> tuple[sp.csr_matrix, sp.csr_matrix | None, np.ndarray, sp.csr_matrix]:
    """The rows of one multiplier class (normal, or tangential) in the basis ψ̃ = Q ψ of
    `fem.facets.multiplier_basis(tr, carry, ends)`: carry (k,) the nodes the crosspoint
    rules give a row of the class ("merge": the others give their dual functions to their
    neighbours in each face; "keep": they are dropped). Rows of nodes whose support the master
    does not cover (covered (k,) False) are then dropped as they are (never merged).

    Returns S (k, k) the slave block Q_c D_loc (row k zero where node k has no row of the
    class; S_kk = W_k by biorthogonality, S_kj ≠ 0 for j ≠ k only at nodes j that gave their
    function away), Mc (k, k_m) = Q_c M_loc (None without a master), Wc (k,) the row sums
    ∫ψ̃_k = W_k + what node k received (W_k where it has no row or received nothing) and
    Qk (k, m·n_f) the basis in node rows.
    """
    idx = np.flatnonzero(carry)  # (n_c,) the node of each row of Q
    Q = multiplier_basis(tr, carry, ends)  # (n_c, m n_f)
    sel = covered[idx]
    P = sp.csr_matrix(
        (np.ones(int(sel.sum())), (idx[sel], np.flatnonzero(sel))), shape=(tr.size, idx.size)
    )
    Qk = (P @ Q).tocsr()  # (k, m n_f)
    S = (Qk @ dual_mass(tr)).tocsr()  # (k, k)
    C = Qk.tocoo()
    given = tr.facets.ravel()[C.col] != C.row  # (nnz,) entries of another node's function
    fw = tr.facet_weights.ravel()  # (m n_f,) ∫_e φ_a = ∫_e ψ_{e,a}
    received = np.bincount(C.row[given], C.data[given] * fw[C.col[given]], tr.size)  # (k,)
    Wc = tr.weights + received  # (k,) = W exactly where nothing was merged in
    Mc = None if M_loc is None else (Qk @ M_loc).tocsr()
    return S, Mc, Wc, Qk


def contact_rows(
    dirs: list[tuple[np.ndarray, np.ndarray, sp.csr_matrix, sp.csr_matrix | None]],
    slave_dofs: np.ndarray,
    n_full: int,
    master_dofs: np.ndarray | None = None,
) -> sp.csr_matrix:
    """Rows Σ_j S_kj d_rᵀu_s,j − Σ_j M_kj d_rᵀu_m,j for each (nodes (r,), directions (r, d),
    S (k, k), M (k, k_m) or None) of `dirs`, in order (S, M a class's blocks, `class_blocks`).
    slave_dofs (k, d) full dofs of the trace nodes, master_dofs (k_m, d) the master's."""
    rows, cols, vals, offset = [], [], [], 0
    for nodes, d, S, M in dirs:
        for mat, dofs, sign in ((S, slave_dofs, 1.0), (M, master_dofs, -1.0)):
            if mat is None:
                continue
            C = mat[nodes].tocoo()  # (r, ·)
            for c in range(slave_dofs.shape[1]):
                rows.append(offset + C.row)
                cols.append(dofs[C.col, c])
                vals.append(sign * C.data * d[C.row, c])
        offset += nodes.size
    B = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(offset, n_full)
    )
    B.eliminate_zeros()
    return B


def check_carrying(
    slave: Any, part: str, tr: Trace, carry_n: np.ndarray, n_tan: np.ndarray, law: str
) -> None:
    """SceneError if the crosspoint rules leave no multiplier on Γ3 (every node clamped), or
    if unilateral contact meets a node with a tangential row but no normal one (its normal
    displacement prescribed: a roller across Γ3)."""
    if not (carry_n | (n_tan > 0)).any():
        raise SceneError(
            "contact.slave",
            f"{slave.name}.{part}",
            "a contact boundary with nodes whose displacement is not fully prescribed: every "
            "node of this one is clamped by a [[displacement]] part, so no contact remains; "
            "remove the Dirichlet condition on it or the [contact] table",
        )
    if law == "unilateral" and ((n_tan > 0) & ~carry_n).any():
        i = int(np.flatnonzero((n_tan > 0) & ~carry_n)[0])
        raise SceneError(
            "contact.law",
            "unilateral",
            f"contact nodes free to separate; {node_at(slave, tr, i)} has its normal "
            "displacement prescribed (a roller across Γ3): with unilateral contact prescribe "
            "all its components, or only tangential ones (or use law = 'bilateral')",
        )


def assemble(
    slave: Any,
    part: str,
    tr: Trace,
    frame: tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray],
    carry_n: np.ndarray,
    n_tan: np.ndarray,
    section: Any,
    gloc: np.ndarray,
    n_full: int,
    coupling: Coupling | None = None,
    gap_nodes: np.ndarray | None = None,
) -> Interface:
    """The `Interface` of `slave`'s boundary `part` from what its dimension's builder made:
    the trace `tr`, frame = (normals, t1, t2 (None in 2D), slot (k,): the kept tangent of a
    line node), the crosspoint classes carry_n (k,) and n_tan (k,) 0/1/2, the [contact] table
    `section` (law, friction, ends, gap, g or F), gloc (n_f, m) ∫_e g φ_e,a (Coulomb: F) and
    the master side `coupling`. The rows: the classes' bases (`class_blocks`), the nodes
    the master covers, g_k (F_k) = ∫gφ̃_k / W_t,k (the plain nodal mean ∫gφ_k / W_k at the
    nodes without a tangential row), the rows normal, disc (t1, t2 per node), line
    (`contact_rows`), with law = "unilateral" put side by side per node (`Interface.rows`) and
    the initial gap rows Σ_j S_n,kj gap_j of `gap_nodes` (k,) if given."""
    normals, t1, t2, slot = frame
    unilateral = section.law == "unilateral"
    covered = np.ones(tr.size, dtype=bool) if coupling is None else coupling.covered
    M_loc = None if coupling is None else coupling.M_loc
    S_n, M_n, W_n, Q_n = class_blocks(tr, carry_n, covered, section.ends, M_loc)
    S_t, M_t, W_t, Q_t = class_blocks(tr, n_tan > 0, covered, section.ends, M_loc)
    uncovered = np.flatnonzero((carry_n | (n_tan > 0)) & ~covered)
    carry_n = carry_n & covered
    n_tan = np.where(covered, n_tan, 0)
    if not (carry_n | (n_tan > 0)).any():
        raise SceneError(
            "contact.master",
            "rigid" if coupling is None else f"{coupling.body.name}.{coupling.part}",
            f"a master boundary behind the slave boundary {slave.name}.{part}: no slave node "
            f"has the master behind its support (nodes {tr.nodes.tolist()}); make the two "
            "boundaries face each other and overlap",
        )
    if coupling is not None:  # the rigid-body rows: Σ_j M_c,kj = W_c,k where covered
        rel = [
            np.abs(Wc - np.asarray(Mc.sum(axis=1)).ravel())[has] / Wc[has]
            for Wc, Mc, has in ((W_n, M_n, carry_n), (W_t, M_t, n_tan > 0))
        ]
        coupling.patch_defect = float(np.concatenate(rel).max(initial=0.0))
    g = np.where(  # ∫gφ̃_k / W_t,k; the plain nodal mean ∫gφ_k / W_k at the other nodes
        n_tan > 0,
        (Q_t @ gloc.ravel()) / W_t,
        np.bincount(tr.facets.ravel(), gloc.ravel(), tr.size) / tr.weights,
    )
    rows_n = np.flatnonzero(carry_n)
    disc = np.flatnonzero(n_tan == 2)
    line = np.flatnonzero(n_tan == 1)
    line_dir = t1[line] if t2 is None else np.where(slot[line, None] == 0, t1[line], t2[line])
    # disc rows interleaved (t1, t2) per node: rows 2j, 2j+1 of the disc block
    disc_dirs = np.zeros((0, 3)) if t2 is None else np.stack([t1[disc], t2[disc]], 1)
    dirs = [
        (rows_n, normals[rows_n], S_n, M_n),
        (np.repeat(disc, 2), disc_dirs.reshape(-1, normals.shape[1]), S_t, M_t),
        (line, line_dir, S_t, M_t),
    ]
    sdofs = slave.u_dofs(tr.nodes)  # (k, d)
    B = contact_rows(dirs, sdofs, n_full, None if coupling is None else coupling.dofs)
    perm = gap0 = None
    if unilateral:
        N_n, N_b = rows_n.size, disc.size
        at_n = np.full(tr.size, -1)
        at_n[rows_n] = np.arange(N_n)  # normal row of each trace node
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
        if gap_nodes is not None:
            gap0 = S_n[rows_n] @ gap_nodes  # (N_n,)
    tresca = section.friction == "tresca"
    return Interface(
        slave=slave,
        slave_part=part,
        tr=tr,
        normals=normals,
        t1=t1,
        t2=t2,
        rows_n=rows_n,
        disc=disc,
        line=line,
        line_slot=np.zeros(line.size, dtype=int) if slot is None else slot[line],
        g=g if tresca else np.zeros(tr.size),
        B_full=B,
        W_n=W_n,
        W_t=W_t,
        Q_n=Q_n[rows_n],
        Q_t=Q_t[np.union1d(disc, line)],
        covered=covered,
        uncovered=uncovered,
        ends=section.ends,
        coupling=coupling,
        law=section.law,
        friction=section.friction,
        F=None if tresca else g,
        gap0=gap0,
        order=perm,
        gap_field=section.gap if unilateral and coupling is None else None,
        bound_field=section.g if tresca else section.F,
    )


@dataclass
class Jumps:
    """The dimension-free part of a contact state (`jumps`).

    x_full (n_full,) the full solution; Bu (m,) B_full x, the weighted jumps in B_full's row
    order; Bi (m,) the same since the load path's previous step (`model.incremental`; Bu
    without one); gap_rows (m,) the initial gap on the normal rows (unilateral), 0 elsewhere;
    pressure the pressure scale (unilateral: the largest λ_n or the elastic nodal forces per
    smallest normal row weight, `jumps`; 0 for bilateral contact); th the state thresholds of
    `vi_core.states`.
    """

    x_full: np.ndarray
    Bu: np.ndarray
    Bi: np.ndarray
    gap_rows: np.ndarray
    pressure: float
    th: Any


def jumps(model: Any, sol: Solution, radius: np.ndarray) -> Jumps:
    """The `Jumps` of `sol`; radius the friction radius at λ (`contact.bound`). The states'
    thresholds scale with the achieved residual, the stress scale (the whole λ: with ρ ≪ λ_n a
    rounding shortfall of |λ_t| relative to λ is no stick evidence) and the displacement scale.

    The pressure scale (unilateral contact; 0 for bilateral) is the larger of the largest λ_n
    and the largest elastic nodal force |A u| over the displacement dofs turned into a
    pressure by the smallest weight W_n,k of a normal row, 2D and 3D alike. A state threshold
    decides whether a λ_n is zero, so it must be relative to the λ_n the forces could produce:
    λ_n is conjugate to the row (B u)_k = W_n,k [u]_n,k, so a nodal force f carried by row k is
    the pressure λ_n,k = f / W_n,k, and the largest is f / min_k W_n,k over the rows that carry
    a λ_n. It is the same quantity in any dimension (W_n,k a length in 2D, an area in 3D: the
    row sums of the normal class, `class_blocks`), and it ignores the weights of nodes without
    a normal row (clamped crosspoints, uncovered nodes), which no force can load as a λ_n. (3D
    took the smallest nodal W of any trace node before issue 30, those nodes included.)"""
    c = model.contact
    x_full = model.full(sol.u)
    Bu = c.B_full @ x_full  # (m,)
    gap_rows = np.zeros(Bu.size)
    pressure = 0.0
    disp = model.unknown_fields().get("displacement", slice(None))  # unnamed fields: all of u
    if c.law == "unilateral":
        gap_rows[c.idx_n] = c.gap0
        # the elastic nodal forces per area: the pressure scale when the bodies are apart (all
        # of λ is rounding then)
        w_min = float(c.W_n[c.rows_n].min())  # the smallest normal row weight (docstring)
        force = float(np.abs((model.vi.A @ sol.u)[disp]).max(initial=0.0)) / w_min
        pressure = max(float(sol.lam[c.idx_n].max(initial=0.0)), force)
    Bi = Bu if model.slip_origin is None else Bu - model.slip_origin  # slip since the origin
    th = node_states.solution_thresholds(
        sol,
        max(float(np.abs(sol.lam).max(initial=0.0)), float(radius.max(initial=0.0)), pressure),
        float(np.abs(sol.u[disp]).max(initial=0.0)),
    )
    return Jumps(x_full, Bu, Bi, gap_rows, pressure, th)


def lemma_4_2(lam: np.ndarray, j: Jumps, g_abs: float, weight: float) -> dict:
    """The Lemma 4.2 identity λᵀ(B u − gap₀) = Σ_k ρ_k W_k |[u]_t,k| of a solution: its two
    sides and the relative defect, relative to the larger of Σ ρ W |[u]_t| (`g_abs`) and the
    pressure scale times Σ|B u − gap₀| (unilateral), floored by rounding of Σ ρ W (`weight`)
    times the largest |x|."""
    b_uh_lam = float(lam @ (j.Bi - j.gap_rows))
    tiny = np.finfo(float).eps * weight * max(np.abs(j.x_full).max(), 1e-300)
    scale = max(g_abs, j.pressure * float(np.abs(j.Bi - j.gap_rows).sum()))
    return {
        "b_uh_lam": b_uh_lam,
        "int_g_abs_u": g_abs,
        "lemma_4_2": float(abs(b_uh_lam - g_abs) / max(scale, tiny, 1e-300)),
    }


def multiplier_rows(contact: Any) -> tuple:
    """(B_full (m, n_full), the gap rows not from Dirichlet data (m,): the initial gap on the
    normal rows, Λ_h, the Y Gram matrix (m, m): diag h_k w_r, a mesh-dependent H^{-1/2}
    stand-in) of a front's contact (`model.mixed_vi`); the front's contact tells its
    `Lambda()` and `gram_weights()`."""
    gap = np.zeros(contact.B_full.shape[0])  # (m,)
    if contact.gap0 is not None:
        gap[contact.idx_n] += contact.gap0
    return contact.B_full, gap, contact.Lambda(), sp.diags(contact.gram_weights())


def friction_warnings(
    states: np.ndarray, g: np.ndarray, lam_t: np.ndarray, slip: np.ndarray, touch: np.ndarray
) -> list[str]:
    """What a user must know about the friction bound of a solution: no node touching, g = 0,
    no node slipping (how much of the bound λ_t uses), and `vi_core.states.warnings`. `states`,
    `touch` per contact node; g (friction radius) and |λ_t| (both (k_t,)) and `slip` per node
    carrying a tangential multiplier."""
    if not touch.any():
        return ["no node of Γ3 touches: the bodies are apart (λ = 0)"]
    out = node_states.warnings(states)
    if not g.any():
        return [*out, "g = 0 on Γ3: frictionless sliding (a linear problem)"]
    if not slip.any():
        used = float(np.max(np.abs(lam_t) / np.where(g > 0, g, np.inf)))
        out.append(
            f"no node slips: the tangential multiplier uses at most {used:.3g} of the friction "
            "bound, so the problem is tied (g above every tangential stress)"
        )
    return out


def interface_summary(c: Interface) -> dict:
    """summary.json's interface entries, 2D and 3D alike: the master, the mortar patch defect,
    the crosspoint basis, the multipliers per kind (2D: normal, tangential; 3D: normal, disc,
    line), the crosspoint nodes (covered nodes without every multiplier component) and the
    uncovered ones (no master behind their whole support: no multiplier)."""
    full_t = c.line if c.dim == 2 else c.disc  # the nodes with every tangential component
    dropped = np.setdiff1d(np.arange(c.tr.size), np.intersect1d(c.rows_n, full_t))
    dropped = np.setdiff1d(dropped, c.uncovered)
    kinds = (
        {"tangential": c.line.size} if c.dim == 2 else {"disc": c.disc.size, "line": c.line.size}
    )
    return {
        "master": "rigid" if c.master is None else c.master.name,
        "mortar_patch_defect": c.patch_defect,
        "ends": c.ends,
        "multipliers": {"normal": int(c.rows_n.size), **{k: int(v) for k, v in kinds.items()}},
        "crosspoint_nodes": c.tr.nodes[dropped].tolist(),
        "uncovered_nodes": c.tr.nodes[c.uncovered].tolist(),
    }


PATCH_DEFECT_LIMIT = 1e-8  # above it `mixvi solve` warns and exits 1 (unless --allow-defect)


def interface_warnings(contact: Interface) -> list[str]:
    """Console warnings about the interface: uncovered slave nodes and the patch defect."""
    out = []
    tr = contact.tr
    if contact.uncovered.size:
        where = ", ".join(node_at(contact.slave, tr, int(i)) for i in contact.uncovered[:6])
        more = f" and {contact.uncovered.size - 6} more" if contact.uncovered.size > 6 else ""
        out.append(
            f"contact: {contact.uncovered.size} slave node(s) of {contact.slave.name}."
            f"{contact.slave_part} have no master behind their whole support and carry no "
            f"multiplier (left free): {where}{more}"
        )
    if contact.patch_defect > PATCH_DEFECT_LIMIT:
        out.append(
            f"contact: mortar patch defect {contact.patch_defect:.3g} > {PATCH_DEFECT_LIMIT:g}: "
            "a rigid translation of both bodies is not transferred across the interface — the "
            "mortar projection is wrong for this geometry; results are not trustworthy"
        )
    return out


def unilateral_summary(contact: Any, open_nodes: int, remaining: np.ndarray) -> dict:
    """summary.json's contact entries only unilateral contact has, 2D and 3D alike: the law,
    the friction, the number of open nodes and the smallest remaining gap (`remaining` per
    node or normal row, NaN where a node has none)."""
    return {
        "law": contact.law,
        "friction": contact.friction,
        "open": int(open_nodes),
        "min_gap": float(np.nanmin(remaining, initial=np.inf)),
    }
