"""The contact interface Γ3 of a 2D or 3D scene (`Interface`): the slave trace, its frames,
the multiplier rows and bounds, the master side (`Coupling`), the row order (`Interface.rows`,
`row_nodes`) and the rows handed to the mixed VI (`multiplier_rows`).

A 2D contact node is a 3D "line" node: its one tangent is its line direction. So one
`Interface` holds both, per slave trace node k (the nodes of a boundary curve or surface):
rows_n (normal), disc (two tangents, 3D only) and line (one tangent) with the frames (normals,
t1, t2; 2D: t1 the tangent, t2 None). Each dimension builds its trace, frames, crosspoint
classes and master mortar (2D: `curve_contact`, segment traces and the distance along the
slave normal; 3D: `surface_contact`, polygon-clipping mortar and the weighted mortar gap) and
hands them to `rows.assemble`, which builds the rows once for both. What the interface tells
the user (node names, summaries, warnings) is `reports`'; the contact state of a solution
(jumps, states, the Lemma 4.2 identity) is `contact_state`'s.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from fem.facets import Trace
from vi_core import Ball, Box, Free, NonNegative, product

# Quadrature order of the 3D contact surface integrals (W, normals, g_k, the dual basis of the
# mortar): Q1 faces of a curved surface are not planar and |∂x/∂ξ × ∂x/∂η| is not polynomial
# (order 4 leaves 7e-11 in the rigid-body rows of spherical_cap, order 8 3e-15); P1 faces are
# flat (order 4 exact).
SURFACE_ORDER = {"hexahedron": 8, "tetra": 4}


@dataclass
class Coupling:
    """The master side of a two-body interface (`None` in `Interface` = rigid foundation).

    M_loc (m·n_f, n_master_nodes): the face-local mortar matrix ∫_e ψ_{e,a} φ_j^m of
    `fem.mortar` (a class's rows are Q_c M_loc, `rows.class_blocks`); dofs (n_master_nodes, d) the
    master's full displacement dofs; covered (k,) the master lies behind the slave node's whole
    support; set by `rows.assemble`: `patch_defect` max over the rows of |W_c,k − Σ_j M_c,kj| /
    W_c,k and the class blocks M_n, M_t (k, n_master_nodes) = Q_c M_loc in node rows (row k zero
    where node k has no row of the class).
    """

    body: Any  # the master Body
    part: str
    M_loc: sp.csr_matrix
    dofs: np.ndarray
    covered: np.ndarray
    patch_defect: float = np.nan
    M_n: sp.csr_matrix | None = None
    M_t: sp.csr_matrix | None = None


class Gone:
    """A class attribute for a name the class had before the 2D and 3D contact plug-ins
    became one and cannot have again:
    reading it raises an AttributeError with `message` (what to use instead). A descriptor,
    not a `__getattr__`: Python also calls `__getattr__` when a property raises AttributeError
    inside, and the hint would hide that error."""

    def __init__(self, message: str) -> None:
        self.message = message

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        raise AttributeError(self.message)


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
    ends: str = "merge"  # the crosspoint basis: "keep" or "merge" (`rows.class_blocks`)
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
    # a name of the former 2D `Contact` and 3D `SolidContact` that cannot come back
    pairs = Gone(
        "Interface.pairs is gone: the unilateral rows of a node stand side by side, "
        "[n, t1, t2] per disc node, [n, t] per line node, then the normal-only nodes: use "
        "Interface.rows() for the rows of each kind (the former 2D pairs [n, τ] are the line "
        "nodes, line.size of them)"
    )

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
        return kept_tangents(self.t1, self.t2, self.line, self.line_slot)

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


def kept_tangents(
    t1: np.ndarray, t2: np.ndarray | None, line: np.ndarray, slot: np.ndarray
) -> np.ndarray:
    """(N_l, d) the tangent each line node keeps: t1 (slot 0) or t2 (slot 1) of the nodes
    `line` (N_l,) with slot (N_l,); t1 in 2D (t2 None)."""
    if t2 is None:
        return t1[line]
    return np.where(slot[:, None] == 0, t1[line], t2[line])


def multiplier_rows(contact: Any) -> tuple:
    """(B_full (m, n_full), the gap rows not from Dirichlet data (m,): the initial gap on the
    normal rows, Λ_h, the Y Gram matrix (m, m): diag h_k w_r, a mesh-dependent H^{-1/2}
    stand-in) of a front's contact (`model.mixed_vi`); the front's contact tells its
    `Lambda()` and `gram_weights()`."""
    gap = np.zeros(contact.B_full.shape[0])  # (m,)
    if contact.gap0 is not None:
        gap[contact.idx_n] += contact.gap0
    return contact.B_full, gap, contact.Lambda(), sp.diags(contact.gram_weights())
