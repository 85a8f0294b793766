"""The preconditioner of the condensed Newton matrix (`vi_core.condensed_newton`) on the
iterative path: the tied contact rows eliminated exactly, one multigrid cycle per field for the
rest (`vi_core.block_amg`).

Right preconditioning, for restarted GMRES (`vi_core.krylov`). Premultiplied by D^{-T}, row i of
S reads (W D^{-T} A_S u + J B u)_i. Where row i of W is zero (a stick or bilateral-normal row:
"tied") it is the tying condition (B u)_i = …; elsewhere (J = 0: slip, inactive) it is the
stiffness row (D^{-T} A_S u)_i. In the coordinates y = (u_R, s_F), s = C^{-1} D u_S the slave
dofs in their node's frame (C the row norms of D) with F the free rows, the slave dofs of the
tied rows follow the others: u = T0 y + u_p, u_S = D^{-1}(C E_F s_F − E_T (B_R u_R)_T) + u_p,S.
With 0/1 rows of J this turns K u = r into Â y = T0ᵀ(…) with the symmetric Â = T0ᵀ A T0 — the
stiffness of the bodies glued where they stick and free to slide where they slip — so a
hierarchy of Â and an exact tied part make the preconditioner exact
(`test_tied_preconditioner`).

Rows with fractional J (a slip disc in 3D: J = γ(I − ŷŷᵀ), γ = g/|y_t| < 1, W = I − J) are free
rows with a spring: on the free rows F, W_FF λ_F = J_F·(B u) − q_F (W_FT = 0 but for Coulomb's
dρ/dλ_n), so λ_F = M (B u)_F − W_FF^{-1}(q_F − J_FT q_T) with M = W_FF^{-1} J_FF, symmetric and
≥ 0, and the glued stiffness gains the spring: Â = T0ᵀ (A + B_Fᵀ M B_F) T0 — exact
(`test_tied_preconditioner`, a Ball with fractional rows). The spring κ = γ/(1 − γ) is unbounded
where a disc has only just started to slip (γ → 1; γ = 1 to rounding occurs, W_FF singular), and
a multigrid hierarchy of a matrix with springs of 1e16 fails (bracket3d level 2, first fine
step, GMRES iterations to 1e-8: 12 counting the slip rows free, 192 with the exact springs), so
κ is capped smoothly at SPRING_CAP: exact where κ ≪ SPRING_CAP, a stiff spring between free and
tied above. Measured on the same step and two later ones (hierarchy rebuilt, caps 0.1, 1, 10,
1e3, none): 12, 11, 10, 19, 192 / 18, 13, 11, 14, 14 / 16, 12, 10, 11, 11, against 12 / 21 / 19
with the slip rows free. Coulomb's coupling W_FT of a slip row to its (tied) normal multiplier
is left out (GMRES makes up that difference). Â is block lower triangular over the fields of the
problem (`MixedVI.fields`, e.g. displacement then potential): one pyamg smoothed-aggregation
hierarchy per field, built on the symmetric part of its diagonal block, with the field's
near-null space (`MixedVI.near_null`, the rigid-body modes for displacement, carried to s by
C^{-1}D) or the constant vector, aggregates within one body on every level, energy-minimising
prolongation; the coupling blocks below the diagonal (the piezoelectric coupling) are applied
exactly. The hierarchies depend on which rows are tied: they are rebuilt when more than REUSE of
the rows changed type since they were built; below that the whole preconditioner of the old tied
rows is kept — the exact inverse (with exact hierarchies) of a Newton matrix that differs from K
in the changed S rows only, a low-rank difference GMRES absorbs in a few iterations (passing the
old hierarchy on with the changed rows merely left out made GMRES stagnate).

Measured on the paper scene (`mixvi bench --scenes paper_two_body --levels 2..5 --linear-solvers
amg`; the tied linear system to 1e-11 from zero): 14, 15, 16, 16 GMRES iterations at levels 2–5
(16 at level 6, 1.5M unknowns) with this preconditioner and W-cycles; 19, 23, 28, 35 with the
previous one (the R rows' operator A_R − B_Rᵀ D^{-T} A_S with a direct solve of K_SS, which
misses the coupling of the slave dofs to the rest: its Schur complement differs from it by a
term of the rank of the interface). On the Newton systems of the first nested fine step (an
experiment on those matrices saved, GMRES to 1e-8 from zero), V-cycles: 14, 16, 20, 24 (levels
2–5), W-cycles 14, 14, 17, 18, and W costs less time at level 5 (6.6 s against 9.3 s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .block_amg import BlockAMG, field_blocks, field_masks
from .condensed_newton import Split
from .sparse_blocks import lone_entries

CYCLE = "W"  # see the module docstring for the measurements
# the hierarchy is rebuilt only when more than this fraction of the rows changed between tied
# and free since it was built; otherwise the preconditioner of the old tied rows is used as it
# is (module docstring). Paper scene, level 4 from a cold start: 10.5 s with 8 set-ups at 0,
# 6.2 s with 2 at 0.1, 6.5 s with 1 at 1.0 (more GMRES iterations); nested to level 5: one
# set-up on the fine level instead of two, 13 and 12 iterations either way
REUSE = 0.1
SPRING_CAP = 10.0  # the largest spring of a slip row (equilibrated units; module docstring)


def block_inverse(W: sp.spmatrix) -> sp.csr_matrix:
    """W⁻¹ of a block-diagonal W whose blocks (the connected components of its graph) are
    small: the blocks of one size inverted together."""
    from scipy.sparse.csgraph import connected_components

    W = sp.csr_matrix(W)
    k = W.shape[0]
    _, comp = connected_components(W, directed=False)  # (k,) block of each row
    order = np.argsort(comp, kind="stable")  # (k,) rows block by block
    sizes = np.bincount(comp)  # (n_blocks,)
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])  # (n_blocks,) first row of each
    rows, cols, vals = [], [], []
    for size in np.unique(sizes):
        first = start[sizes == size]  # (b,)
        idx = order[first[:, None] + np.arange(size)]  # (b, size) the rows of each block
        r = np.repeat(idx, size, axis=1).ravel()  # (b·size²,) entry (i, j) of each block
        c = np.tile(idx, (1, size)).ravel()  # (b·size²,)
        dense = np.asarray(W[r, c]).reshape(-1, size, size)  # (b, size, size)
        rows.append(r)
        cols.append(c)
        vals.append(np.linalg.inv(dense).ravel())
    if not rows:
        return sp.csr_matrix((k, k))
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(k, k)
    )


@dataclass
class Spring:
    """The free rows F with fractional J (3D slip discs) of one Newton matrix: on them
    λ_F = M (B u)_F − Wi (q_F − J_FT q_T) (module docstring)."""

    M: sp.csr_matrix  # (k_F, k_F) W_FF^{-1} J_FF, symmetric ≥ 0 (block diagonal)
    Wi: sp.csr_matrix  # (k_F, k_F) W_FF^{-1}
    J_FT: sp.csr_matrix  # (k_F, k_T) J[F, T]
    rows: np.ndarray  # (m,) bool: the free rows with J ≠ 0 (the springs)

    @staticmethod
    def of(tied: np.ndarray, W: sp.spmatrix | None, J: sp.spmatrix | None) -> Spring | None:
        """The springs of the free rows, None where there are none (J = 0 on the free rows:
        every 2D step, and 3D steps without a slip disc)."""
        if W is None or J is None:
            return None
        F, T = np.flatnonzero(~tied), np.flatnonzero(tied)
        J_F = sp.csr_matrix(J)[F]  # (k_F, m)
        J_F.eliminate_zeros()
        if J_F.nnz == 0:
            return None
        rows = np.zeros(tied.size, dtype=bool)
        rows[F[np.diff(J_F.indptr) > 0]] = True
        J_FF = J_F[:, F]
        # M = W_FF^{-1} J_FF with its stiffness κ = γ/(1 − γ) capped smoothly at SPRING_CAP:
        # (W_FF + J_FF/c)^{-1} J_FF = κ/(1 + κ/c) (never singular, also where γ = 1 exactly)
        M = (block_inverse(sp.csr_matrix(W)[F][:, F] + J_FF / SPRING_CAP) @ J_FF).tocsr()
        return Spring(M, (sp.identity(F.size) + M).tocsr(), J_F[:, T].tocsr(), rows)


def _springs(spring: Spring | None, tied: np.ndarray) -> np.ndarray:
    """(m,) bool: the rows that are springs (none without a Spring)."""
    return np.zeros(tied.size, dtype=bool) if spring is None else spring.rows


class TiedPreconditioner:
    """The preconditioners of the condensed Newton matrices K of one ssn run (module docstring):
    `self(tied, spring)` is x ≈ K⁻¹ r for the Newton matrix with these tied rows and free rows'
    springs; its hierarchies are kept from call to call while few rows change type (REUSE).

    A, B : the equilibrated operator (n, n) and constraint rows (m, n).
    cond : the condensation of B (`ssn.Condensation`: R, S, D, Dt_inv).
    fields, near_null : `MixedVI.fields` / `MixedVI.near_null` of the equilibrated problem.
    couple : apply the coupling blocks below the diagonal (`BlockAMG`).
    parts : optional (n,) body of each unknown (`amg.bodies`): no aggregate spans two bodies.
    cycle : the multigrid cycle of each application ("V" or "W").
    """

    def __init__(
        self,
        A: sp.csr_matrix,
        B: sp.csr_matrix,
        cond: Split,
        fields: dict | None = None,
        near_null: dict | None = None,
        couple: bool = True,
        parts: np.ndarray | None = None,
        cycle: str = CYCLE,
    ):
        self.A = A
        self.R, self.S = np.asarray(cond.R), np.asarray(cond.S)
        self.Dt_inv = cond.Dt_inv  # (m, m) D^{-T}
        self.D_inv = sp.csr_matrix(cond.Dt_inv.T)  # (m, m) D^{-1}
        self.B = sp.csr_matrix(B)  # (m, n)
        self.B_R = sp.csr_matrix(B[:, self.R])  # (m, n_R)
        D = sp.csr_matrix(cond.D)
        self.scale = np.sqrt(np.asarray(D.multiply(D).sum(axis=1)).ravel())  # (m,) row norms
        self.D = D
        self.parts = None if parts is None else np.asarray(parts)
        self.n = self.R.size + self.S.size
        self.fields, self.near_null = fields, near_null
        self.couple, self.cycle = couple, cycle
        self.amg: BlockAMG | None = None
        self.lone: tuple | None = None  # `lone_entries(A)`, found at the first set-up
        self.tied: np.ndarray | None = None  # (m,) the tied rows the hierarchy was built for
        self.spring: Spring | None = None  # the free rows' springs it was built with
        self.setups: list[float] = []  # seconds of each hierarchy set-up

    def _U_S(self, tied: np.ndarray) -> sp.csr_matrix:
        """(m, n_R + n_F) y = (u_R, s_F) ↦ u_S = D^{-1}(C E_F s_F − E_T (B_R u_R)_T)."""
        F = np.flatnonzero(~tied)
        keep_T = sp.diags(tied.astype(float))
        E_F = sp.csr_matrix((self.scale[F], (F, np.arange(F.size))), shape=(tied.size, F.size))
        return sp.hstack([-(self.D_inv @ (keep_T @ self.B_R)), self.D_inv @ E_F]).tocsr()

    def _P_R(self, n_y: int) -> sp.csr_matrix:
        """(n, n_y) y ↦ u_R at the positions R (zero on S)."""
        R = self.R
        return sp.csr_matrix((np.ones(R.size), (R, np.arange(R.size))), shape=(self.n, n_y))

    def _blocks(self, tied: np.ndarray, spring: Spring | None = None) -> list[dict]:
        """The field blocks (`field_blocks`) of Â = T0ᵀ (A + B_Fᵀ M B_F) T0 (n_y, n_y), never
        formed: with T0 = P_R + P_S U_S and U_S (m, n_y) of the few contact rows,
        Â = P_Rᵀ A P_R + P_Rᵀ (A P_S) U_S + U_Sᵀ (P_Sᵀ A P_R + A_SS U_S) + (B T0)_Fᵀ M (B T0)_F:
        A restricted to R × R plus corrections of rank ≤ m (`_corrections`), each block
        gathered from A's index arrays. Forming T0ᵀ (A T0) made three full-size products
        (paper scene level 5: 365 → 685 MB)."""
        if self.lone is None:  # A is fixed: its lone entries are found once
            self.lone = lone_entries(self.A)
        Z = sum(self._corrections(tied, spring))
        return field_blocks(self.A, self._fields_y(tied), self.couple, self.R, Z, self.lone)

    def _corrections(self, tied: np.ndarray, spring: Spring | None) -> list[sp.csr_matrix]:
        """The terms of Â beyond A's R × R block (`_blocks`), each (n_y, n_y) with few rows."""
        U_S = self._U_S(tied)  # (m, n_y)
        P_R = self._P_R(U_S.shape[1])  # (n, n_y)
        AU = self.A[:, self.S] @ U_S  # (n, n_y) A P_S U_S: the rows near the contact
        out = [P_R.T @ AU, U_S.T @ (self.A[self.S] @ P_R), U_S.T @ AU[self.S]]
        if spring is not None:
            F = np.flatnonzero(~tied)
            BT = self.B[F] @ P_R + self.D[F] @ U_S  # (k_F, n_y) (B T0)_F = (B u)_F in y
            out.append(BT.T @ (spring.M @ BT))
        return out

    def _fields_y(self, tied: np.ndarray) -> list[tuple]:
        """The fields over y = (u_R, s_F) (masks, near-null rows): s_i = (C^{-1} D u_S)_i is the
        field of its slave column S[i], its near-null rows C^{-1} D N_S."""
        free = ~tied
        S_F = self.S[free]
        out = []
        for name, mask, nn in field_masks(self.n, self.fields, self.near_null):
            my = np.concatenate([mask[self.R], mask[S_F]])
            if nn is None:
                out.append((name, my, None))
                continue
            nn = np.asarray(nn, float).reshape(int(mask.sum()), -1)
            N = np.zeros((self.n, nn.shape[1]))  # (n, d) the field's vectors, zero elsewhere
            N[mask] = nn
            N_s = (self.D @ N[self.S]) / self.scale[:, None]  # (m, d)
            out.append((name, my, np.vstack([N[self.R][mask[self.R]], N_s[free][mask[S_F]]])))
        return out

    def _hierarchy(self, tied: np.ndarray, spring: Spring | None = None) -> None:
        """(Re)build the hierarchies of Â = T0ᵀ (A + B_Fᵀ M B_F) T0 for these tied rows and the
        free rows' springs M (kept while the tied rows stay)."""
        self.amg = None  # the old hierarchy is freed before the new one is built
        blocks = self._blocks(tied, spring)
        parts = None
        if self.parts is not None:
            parts = np.concatenate([self.parts[self.R], self.parts[self.S][~tied]])
        self.amg = BlockAMG(blocks, parts=parts, cycle=self.cycle)
        self.tied, self.spring = tied.copy(), spring
        self.setups.append(self.amg.setup_time)

    def __call__(self, tied: np.ndarray, spring: Spring | None = None):
        """x ≈ K⁻¹ r for the Newton matrix K with these tied rows and free rows' springs
        (`Spring.of(tied, W, J)`; None: J = 0 on the free rows) (module docstring)."""
        if (
            self.tied is None
            or ((tied != self.tied) | (_springs(spring, tied) != _springs(self.spring, tied))).sum()
            > REUSE * tied.size
        ):
            self._hierarchy(tied, spring)
        tied, spring = self.tied, self.spring  # the exact inverse of a Newton matrix differing
        A, R, S, amg = self.A, self.R, self.S, self.amg  # in a few S rows (and springs)
        free = ~tied
        scale_F = self.scale[free]
        n_R = R.size

        def T0(y):  # (n_R + n_F,) → (n,)
            z = np.zeros(S.size)
            z[free] = scale_F * y[n_R:]
            z[tied] = -(self.B_R @ y[:n_R])[tied]
            u = np.empty(self.n)
            u[R] = y[:n_R]
            u[S] = self.D_inv @ z
            return u

        def T0t(v):  # (n,) → (n_R + n_F,)
            w = self.Dt_inv @ v[S]
            return np.concatenate([v[R] - self.B_R.T @ np.where(tied, w, 0.0), scale_F * w[free]])

        def precondition(r):
            q = self.Dt_inv @ r[S]  # the S rows in multiplier coordinates
            u_p = self._lift(q, tied)
            q_F = q[free] if spring is None else spring.Wi @ (q[free] - spring.J_FT @ q[tied])
            z = np.zeros(S.size)
            z[free] = q_F
            rhs = np.concatenate([r[R] + self.B_R.T @ z, scale_F * q_F])
            return T0(amg(rhs - T0t(A @ u_p))) + u_p

        return precondition

    def _lift(self, q: np.ndarray, tied: np.ndarray) -> np.ndarray:
        """(n,) u_p: zero but on S, where D u_p,S = q on the tied rows and 0 on the others."""
        u_p = np.zeros(self.n)
        u_p[self.S] = self.D_inv @ np.where(tied, q, 0.0)
        return u_p
