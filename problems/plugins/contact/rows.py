"""The multiplier rows of an `interface.Interface`, written once for 2D and 3D: the builders'
checked scene fields (the friction bound or coefficient `checked_bound`, the rigid foundation's
gap `rigid_gap`), the crosspoint check (`check_carrying`), the rows of each multiplier class
(`class_blocks`), the rows themselves (`contact_rows`) and `assemble`, which makes the
`Interface` of what a dimension's builder made (`curve_contact`, `surface_contact`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from fem.facets import Trace, dual_mass, multiplier_basis
from problems.errors import SceneError

from .interface import Coupling, Interface, kept_tangents
from .reports import node_at


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
        coupling.M_n, coupling.M_t = M_n, M_t
    g = np.where(  # ∫gφ̃_k / W_t,k; the plain nodal mean ∫gφ_k / W_k at the other nodes
        n_tan > 0,
        (Q_t @ gloc.ravel()) / W_t,
        np.bincount(tr.facets.ravel(), gloc.ravel(), tr.size) / tr.weights,
    )
    rows_n = np.flatnonzero(carry_n)
    disc = np.flatnonzero(n_tan == 2)
    line = np.flatnonzero(n_tan == 1)
    line_slot = np.zeros(line.size, dtype=int) if slot is None else slot[line]  # (N_l,)
    # disc rows interleaved (t1, t2) per node: rows 2j, 2j+1 of the disc block
    disc_dirs = np.zeros((0, 3)) if t2 is None else np.stack([t1[disc], t2[disc]], 1)
    dirs = [
        (rows_n, normals[rows_n], S_n, M_n),
        (np.repeat(disc, 2), disc_dirs.reshape(-1, normals.shape[1]), S_t, M_t),
        (line, kept_tangents(t1, t2, line, line_slot), S_t, M_t),
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
        line_slot=line_slot,
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
