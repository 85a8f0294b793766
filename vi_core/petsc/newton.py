"""The semismooth Newton loop of `vi_core.ssn` with its condensed steps solved by PETSc over
the ranks of COMM_WORLD.

What is distributed and what is not (docs/distributed.md):

* **Rows.** The model's row partition (PETSc's default layout: each rank a contiguous range
  [lo, hi) of the n primal unknowns, what it assembled of A) gives the equilibrium residual's
  rows and the condensed Newton matrix K's fixed rows R (A_R − B_Rᵀ D^{-T} A_S), assembled
  there once and moved to the linear solve's layout (`layout.Layout`: each field's dofs and
  its slave dofs split evenly over the ranks, so every rank holds its share of each field's
  preconditioner; one all-to-all). In that layout each rank writes the slave rows S
  (Dᵀ(W D^{-T} A_S + J B)) of its multipliers at every step into the ``mpiaij`` matrix and
  solves.
* **Multipliers follow their slave dof.** Multiplier row i is owned by the rank whose layout
  rows hold dof S[i] (the condensation's slave column): its condensed row, its recovery
  λ_i = (D^{-T}(f_S − A_S u))_i and its part of the complementarity residual are computed
  there (from replicated data: D, B, A_S), with no communication but the gather of the new
  iterate.
* **Reductions.** The residual norms (damping line search included) are sums of squares over
  owned parts, summed over the ranks (`runtime.Reductions`): every rank takes the same
  decisions.
* **Linear solves.** KSP: MUMPS LU (``preonly``) by default, GMRES with GAMG and the
  plug-in's near-null space (`MixedVI.near_null`, rigid-body modes) for
  ``linear_solver="amg"``, MUMPS again for a step GMRES does not solve. PETSc options
  (``-mixvi_ksp_*``, ``-mixvi_pc_*``) override through PETSC_OPTIONS.

* **A by rows.** A VI that holds A by rows (`MixedVI.partition`: the contact model built
  under the engine, each rank assembling only its rows) is read by its rows: the equilibrium
  residual from them, scaled (s_u ⊙ (A (s_u ⊙ u'))), the owned fixed rows of A'
  (`MixedVI.equilibrated_rows`) and the slave rows, which every rank needs (the multipliers'
  recovery and the condensed rows read D^{-T} A_S): each rank scales those it owns and the
  m rows (the interface's) are gathered (`_slave_rows`). The equilibrated VI is never formed
  whole (`MixedVI.equilibrated_parts`: B', f', gap', Λ'). A VI with A whole (the scalar
  plug-ins) is read the same way, through a view of the rank's rows.

Not yet distributed (what remains, stated in docs/distributed.md): B is assembled whole on
every rank, u and λ are replicated after each step (an allgather), and the active-set map of Λ
is evaluated on the replicated y (O(m), the interface) with each rank using its owned rows
(docs/benchmarks.md, "The petsc engine").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from vi_core.engine import gathered_rows, row_partition
from vi_core.problem import MixedVI
from vi_core.solution import Solution
from vi_core.ssn import (
    Condensation,
    NewtonSteps,
    _block_structure,
    _on_pattern,
    _structure,
    damped_step,
    finish,
)

from .ksp import LinearSolve, node_block
from .layout import Layout, chosen
from .runtime import Reductions, RowPartition, peak_mb, petsc


def _row_view(M: sp.csr_matrix, lo: int, hi: int) -> sp.csr_matrix:
    """(hi − lo, n) rows [lo, hi) of the canonical csr M on M's own arrays (no copy)."""
    p0, p1 = M.indptr[lo], M.indptr[hi]
    return sp.csr_matrix(
        (M.data[p0:p1], M.indices[p0:p1], M.indptr[lo : hi + 1] - p0), shape=(hi - lo, M.shape[1])
    )


@dataclass(frozen=True)
class _Kept:
    """The equilibrated VI without its A (`MixedVI.equilibrated_parts`): the interface-sized
    data (B, Λ, gap), f and the field metadata; A' is read by owned rows only
    (`MixedVI.equilibrated_rows`). The duck type `finish` (B, gap) and `LinearSolve` (fields,
    near_null) read."""

    B: sp.csr_matrix  # (m, n)
    f: np.ndarray  # (n,)
    gap: np.ndarray  # (m,)
    Lambda: Any
    fields: dict | None
    near_null: dict | None
    n: int
    m: int


def _held_rows(vi: MixedVI, lo: int, hi: int) -> sp.csr_matrix:
    """(hi − lo, n) vi's (physical) rows [lo, hi) of A: vi.A itself where vi holds A by rows
    (`MixedVI.partition`, the contact model built under the engine), else a view of the whole
    A's rows (no copy)."""
    if vi.partition is not None:
        if vi.row_range != (lo, hi):
            raise ValueError(
                f"vi holds the rows {vi.row_range} of A, the engine's layout gives this rank "
                f"[{lo}, {hi})"
            )
        return vi.A
    return _row_view(vi.A.tocsr(), lo, hi)


def _slave_rows(vi: MixedVI, S: np.ndarray, lo: int, hi: int, red: Reductions) -> sp.csr_matrix:
    """(m, n) the slave rows S (m,) of A' in the order of S, on every rank: each rank scales
    the slave rows it owns (`MixedVI.equilibrated_rows`), the ranks' blocks gathered
    (`gathered_rows`, m rows: the interface's) and put in S's order. Every row is the one
    `equilibrated_rows(S)` of the whole A gives, bit for bit."""
    mine = np.flatnonzero((S >= lo) & (S < hi))  # (k_m,) the multipliers whose slave dof is here
    rows = gathered_rows(red.gatherv, vi.equilibrated_rows(S[mine]), vi.n)  # (m, n) rank order
    order = red.gatherv(mine.astype(np.int64))  # (m,) the multiplier of each gathered row
    return rows[np.argsort(order)]


def _kept(vi: MixedVI) -> _Kept:
    """vi's equilibrated parts without A; vi's cached equilibrated copy, if a serial path made
    one (a whole-size copy of A's values), dropped."""
    vi.__dict__.pop("equilibrated", None)  # the cached_property's value
    p = vi.equilibrated_parts()
    return _Kept(p["B"], p["f"], p["gap"], p["Lambda"], p["fields"], p["near_null"], vi.n, vi.m)


class _Owned:
    """What a rank's steps need: the model's rows [lo, hi) it holds of A (the equilibrium
    residual's rows, and the condensed matrix's fixed rows, assembled here once: `first`), and
    the unknowns of its rows in the PETSc layout (`layout.Layout`: the linear solve's rows, the
    multipliers of the slave dofs among them, their condensed rows at every step, the
    right-hand side). The equilibrium residual's rows are vi's own (physical) A's, not copied:
    A' = S A S with S = diag(s_u) (`MixedVI.scaling`)."""

    def __init__(
        self,
        vi: MixedVI,
        e: _Kept,
        cond: Condensation,
        A_S: sp.csr_matrix,
        lo: int,
        hi: int,
        layout: Layout,
    ):
        self.lo, self.hi = lo, hi
        R, S = cond.R, cond.S
        self.rows = layout.rows  # (k,) the unknowns of this rank's rows in the layout
        here = np.zeros(e.n, dtype=bool)
        here[self.rows] = True
        R_model = R[(R >= lo) & (R < hi)]  # (k_R,) fixed rows assembled here (A's rows)
        R_own = R[here[R]]  # (k_R',) fixed rows in the layout's rows here (right-hand side)
        self.mult = np.flatnonzero(here[S])  # (k_m,) multipliers whose slave dof is here
        A_R = vi.equilibrated_rows(R_model)  # (k_R, n) the model's fixed rows of A' here
        self.A_own = _held_rows(vi, lo, hi)  # (hi − lo, n) physical rows, no copy
        self.s_u = vi.scaling.s_u  # (n,)
        self.A_S = A_S  # (m, n) the slave rows of A' (a multiplier's recovery reads its D
        # block's)
        self.f_S = e.f[S]  # (m,)
        self.X = (cond.Dt_inv @ self.A_S).tocsr()  # (m, n) D^{-T} A_S
        Dt = cond.D.T.tocsr()  # (m, m)
        self.Dt = Dt[self.mult]  # (k_m, m) rows of Dᵀ of the multipliers here
        self.Dt_inv = cond.Dt_inv[self.mult]  # (k_m, m) their rows of D^{-T}
        self.Bt_own = sp.csr_matrix(e.B.T)[lo:hi]  # (hi − lo, m)
        self.rhs_R = e.f[R_own] - sp.csr_matrix(e.B[:, R_own].T) @ (
            cond.Dt_inv @ self.f_S
        )  # (k_R',)
        # the slave rows' pattern: Dᵀ(W D^{-T} A_S + J B) with every entry of J and W present
        # (blocks of Λ), the same at every step whatever the active set
        G = _block_structure(e.Lambda.block_sizes())  # (m, m)
        reach = G @ (_structure(self.X) + _structure(e.B))  # (m, n)

        def pattern(mult: np.ndarray) -> sp.csr_matrix:
            P = _structure(_structure(Dt[mult]) @ reach)  # (len(mult), n)
            P.sort_indices()
            return P

        self.pattern_S = pattern(self.mult)  # (k_m, n)
        rows_S = S[self.mult]  # (k_m,) their unknowns
        # their PETSc rows, and their pattern with the columns as PETSc rows (`set_rows`)
        self.petsc_S = layout.new[rows_S]  # (k_m,)
        self.petsc_pattern_S = sp.csr_matrix(
            (self.pattern_S.data, layout.new[self.pattern_S.indices], self.pattern_S.indptr),
            shape=self.pattern_S.shape,
        )
        # the right-hand side [owned R; owned S] put in the layout's row order
        self.order = np.argsort(np.searchsorted(self.rows, np.concatenate([R_own, rows_S])))
        # the model's rows here: the fixed rows, and the slave rows' pattern (zeros), stacked
        # in the order `Layout.moved` sends them
        slaves = np.flatnonzero((S >= lo) & (S < hi))  # (k_s,) slave dofs in [lo, hi)
        self._zeros = pattern(slaves)  # (k_s, n)
        model = np.concatenate([R_model, S[slaves]])  # (hi − lo,) the stacked rows' unknowns
        self._send = np.argsort(model)[layout.sending(lo, hi)]  # (hi − lo,)
        self._layout = layout
        BR_t = sp.csr_matrix(e.B[:, R_model].T)  # (k_R, m) model rows of B_Rᵀ
        self.K_R = (A_R - BR_t @ self.X).tocsr()  # (k_R, n) A_R − B_Rᵀ D^{-T} A_S

    def first(self, comm: Any) -> sp.csr_matrix:
        """(k, n) this rank's rows of the condensed Newton matrix in the layout (columns as
        PETSc rows): the fixed rows, and the slave rows on their pattern with explicit zeros
        (`set_rows` fills them), assembled on the model's rows [lo, hi) and moved
        (`Layout.moved`, mpi4py's `comm`); the scipy copies here are released."""
        zeros = self._zeros
        zeros.data[:] = 0.0
        stacked = sp.vstack([self.K_R, zeros], format="csr")
        self.K_R = self._zeros = None
        stacked = stacked[self._send]  # (hi − lo, n) in sending order
        return self._layout.moved(stacked, self.lo, self.hi, comm)

    def slave_rows(self, e: MixedVI, J: sp.csr_matrix, W: sp.csr_matrix) -> np.ndarray:
        """(pattern_S.nnz,) the slave rows Dᵀ(W D^{-T} A_S + J B) here on their pattern."""
        K_S = self.Dt @ (W @ self.X) + self.Dt @ (J @ e.B)  # (k_m, n)
        return _on_pattern(K_S, self.pattern_S).data


def _residual(e: _Kept, own: _Owned, red: Reductions, u, lam, scale: float) -> float:
    """The relative natural-map residual (`vi_core.natural_residual`) from owned parts."""
    Au = own.s_u[own.lo : own.hi] * (own.A_own @ (own.s_u * u))  # (k,) owned rows of A'u
    r1 = Au + own.Bt_own @ lam - e.f[own.lo : own.hi]  # (k,)
    p = e.Lambda.project(lam + e.B @ u - e.gap)  # (m,) replicated (the interface)
    r2 = lam[own.mult] - p[own.mult]  # (k_m,)
    return float(np.hypot(red.norm(r1), red.norm(r2)) / scale)


def solve_ssn_petsc(
    vi: MixedVI,
    tol: float = 1e-10,
    max_iter: int = 60,
    u0: np.ndarray | None = None,
    lam0: np.ndarray | None = None,
    linear_solver: str = "auto",
    condense: bool = True,
    damping: bool = True,
    estimate_condition: bool = False,
    on_step: Callable[[dict], None] | None = None,
) -> Solution:
    """`vi_core.ssn.solve_ssn` on the ranks of PETSc's COMM_WORLD (module docstring): the same
    iterates, the same damping and stopping rule; every rank returns the same Solution.

    linear_solver : "amg" GMRES + GAMG (MUMPS where it fails), anything else MUMPS LU.
    condense must hold (the engine solves condensed steps only); estimate_condition is not
    available here and is recorded as skipped."""
    if not condense:
        raise ValueError("the petsc engine solves condensed Newton steps only (condense=True)")
    PETSc = petsc()
    comm = PETSc.COMM_WORLD
    red = row_partition() or RowPartition(PETSc)  # the layout and the reductions
    t0 = time.perf_counter()
    e, sc = _kept(vi), vi.scaling
    cond = Condensation.detect(e.B)
    if cond is None:
        raise ValueError(
            "the petsc engine condenses the multipliers: B has no block-diagonal slave part "
            "(dual mortar multipliers)"
        )
    lo, hi = red.owned(e.n)
    A_S = _slave_rows(vi, cond.S, lo, hi, red)  # (m, n) the slave rows of A', on every rank
    per_node = {name: node_block(N) for name, N in (e.near_null or {}).items()}  # (replicated)
    layout = chosen(e.n, e.fields, cond.S, _held_rows(vi, lo, hi), lo, red.comm, per_node)
    own = _Owned(vi, e, cond, A_S, lo, hi, layout)
    kind = "gamg" if linear_solver == "amg" else "mumps"
    solver = LinearSolve(PETSc, comm, kind, e, layout, own.first(red.comm))
    memory = {"set_up": red.comm.allgather(peak_mb())}
    u = np.zeros(e.n) if u0 is None else np.asarray(u0, float) / sc.s_u
    lam = np.zeros(e.m) if lam0 is None else np.asarray(lam0, float) / sc.s_lam
    Lam = e.Lambda
    scale = max(red.norm(e.f[own.lo : own.hi]), red.norm(e.gap[own.mult])) or 1.0
    res = _residual(e, own, red, u, lam, scale)
    steps, k = NewtonSteps(tol, [res]), 0
    nloc = own.rows.size
    while not steps.converged and k < max_iter:
        k += 1
        y = lam + e.B @ u - e.gap  # (m,)
        p = Lam.project(y)
        J = sp.csr_matrix(Lam.jacobian(y))  # (m, m) block diagonal
        W = sp.identity(e.m, format="csr") - J
        rhs_c = p - J @ y - J @ e.gap
        # owned slave rows: Dᵀ(W D^{-T} A_S + J B) u = Dᵀ(W D^{-T} f_S − rhs_c)
        solver.set_rows(own.petsc_S, own.petsc_pattern_S, own.slave_rows(e, J, W))
        rhs_S = own.Dt @ (W @ (cond.Dt_inv @ own.f_S) - rhs_c)  # (k_m,)
        rhs = np.concatenate([own.rhs_R, rhs_S])[own.order]  # (k,) in the layout's order
        x = solver.solve(rhs, u[own.rows])
        u_new = red.gather(own.rows, x, e.n)
        lam_own = own.Dt_inv @ (own.f_S - own.A_S @ u_new)  # (k_m,)
        lam_new = red.gather(own.mult, lam_own, e.m)
        u, lam, t, res = damped_step(
            lambda u, lam: _residual(e, own, red, u, lam, scale), u, lam, u_new, lam_new, res,
            damping,
        )  # fmt: skip
        steps.record(t, res)
        if on_step is not None:
            active = int((p == y).sum())
            slip = int(((p != y) & (p != 0.0)).sum())
            on_step(
                dict(
                    step=k,
                    residual=res,
                    active=active,
                    slip=slip,
                    done=True,
                    krylov_iterations=solver.iterations if solver.kind == "gamg" else None,
                )
            )
    sol = finish(
        e, Lam, sc, u, lam, (res, steps.converged), tol,
        lambda lam: _residual(e, own, red, u, lam, scale), steps.history, k, t0,
    )  # fmt: skip
    res, converged = sol.residual, sol.converged
    solver.destroy()
    memory["end"] = red.comm.allgather(peak_mb())
    sol.info = {
        "engine": "petsc",
        "ranks": comm.getSize(),
        "owned_rows": red.comm.allgather(int(nloc)),
        "layout": layout.kind,  # the linear solve's (`layout.chosen`)
        "condensed": True,
        "damped_steps": steps.damped,
        "inside": sol.info["inside"],
        **solver.info(),
        "peak_mb": memory,  # per rank: ru_maxrss after the set-up and at the end
    }
    if solver.accuracy() is not None:  # the states read the last step's accuracy
        sol.info["states"] = {"accuracy": solver.accuracy()}
    vi.matvec(sol.u)  # A u at the answer gathered now, on every rank: kept for the
    # post-processing, which rank 0 runs alone (`MixedVI.matvec`)
    if estimate_condition:
        sol.info["condition_estimate_skipped"] = "not available with the petsc engine"
    if not converged:
        sol.warnings.append(
            f"ssn (petsc): residual {res:.3e} did not reach tol {tol:.1e} in {k} iterations"
        )
    return sol
