"""Semismooth Newton on the natural map = primal-dual active set strategy.

F(u, λ) = [A u + Bᵀλ − f ; λ − P_Λ(λ + B u − gap)] = 0 on the equilibrated problem (c = 1).
With J ∈ ∂P_Λ(y), y = λ + Bu − gap, p = P_Λ(y), W = I − J, one Newton step for the new
iterate (u⁺, λ⁺) solves

    A u⁺ + Bᵀλ⁺ = f,        W λ⁺ − J B u⁺ = p − J y − J gap.

For a Box, J is 0/1 (active/inactive sets); for a Ball, J = (r/‖y‖)(I − ŷŷᵀ) outside.
Works for non-symmetric A as it is; a backtracking damping on the residual guards against
active-set cycling.

**Condensation.** When B has a block-diagonal "slave" part — columns S, each used by one
small group of rows only, as with dual mortar multipliers — λ = D^{-T}(f_S − A_S u) with
D = B[:, S], and the step is a linear system in u alone of size n. A row group is the largest
row set of its small columns (a column may touch only part of its node's rows: an exact zero in
a 3D contact frame); a row group with more private columns than rows (a master node coupled to
a single slave node, e.g. next to a crosspoint) keeps the best-conditioned ones.

**Fixed sparsity pattern.** The Newton matrix (condensed or not) is stored on the pattern it has
when every entry of J and W (block diagonal, blocks of Λ) is structurally present, explicit
zeros kept: its pattern is the same at every step whatever the active set, so PARDISO analyses
it once per solve (`linalg.Refactorizer`; `info["symbolic_analyses"]`).

**Iterative path.** linear_solver="amg" solves the condensed steps inexactly with GMRES and
algebraic multigrid (`vi_core.krylov`: forcing terms, hierarchy reuse, direct fallback).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .amg import bodies
from .condensed_newton import CondensedNewton
from .forcing import ETA_MAX, ETA_MAX_WARM, forcing_term
from .krylov import KrylovSolver
from .linalg import FactorizationTooLarge, Refactorizer, condition_estimate, resolve_backend
from .linear_solvers import LINEAR_SOLVERS, auto_linear_solver, thread_settings
from .problem import MixedVI, natural_residual
from .sets import Free
from .solution import Solution
from .tied_preconditioner import TiedPreconditioner


@dataclass(frozen=True)
class Condensation:
    """B[:, S] = D block diagonal (rows grouped), S = columns private to their row group."""

    S: np.ndarray  # (m,) column assigned to each row of B
    R: np.ndarray  # (n − m,) the remaining columns
    D: sp.csr_matrix  # (m, m) B[:, S], block diagonal in row order
    Dt_inv: sp.csr_matrix  # (m, m) D^{-T}

    @staticmethod
    def detect(B: sp.csr_matrix, max_block: int = 3) -> Condensation | None:
        """Find S, or None if B has no invertible block-diagonal private part."""
        m, n = B.shape
        if m == 0 or m > n:
            return None
        Bc = sp.csc_matrix(B)
        Bc.eliminate_zeros()
        counts = np.diff(Bc.indptr)  # (n,) nonzeros per column
        small = np.flatnonzero((counts >= 1) & (counts <= max_block))
        # group the small columns by their exact row set
        exact: dict[tuple, list[int]] = {}
        for j in small:
            rows = tuple(Bc.indices[Bc.indptr[j] : Bc.indptr[j + 1]].tolist())
            exact.setdefault(rows, []).append(int(j))
        groups = _merge_subsets(exact)
        S = -np.ones(m, dtype=int)
        inv_r, inv_c, inv_v = [], [], []  # D^{-T}, block by block, in row numbering
        for rows, cols in groups.items():
            if len(cols) < len(rows) or (S[list(rows)] >= 0).any():
                continue
            block = np.zeros((len(rows), len(cols)))  # B[rows, cols], read from the CSC arrays
            pos = {r: i for i, r in enumerate(rows)}
            for c, j in enumerate(cols):
                lo, hi = Bc.indptr[j], Bc.indptr[j + 1]
                for r, v in zip(Bc.indices[lo:hi], Bc.data[lo:hi], strict=True):
                    block[pos[r], c] = v
            if len(cols) > len(rows):
                # more private columns than rows (e.g. a master node coupled to one slave node
                # only, next to a crosspoint): keep the best-conditioned ones (pivoted QR)
                pick = np.sort(sla.qr(block, pivoting=True, mode="r")[1][: len(rows)])
                block, cols = block[:, pick], [cols[i] for i in pick]
            if np.linalg.cond(block) > 1e8:
                continue
            S[list(rows)] = cols
            # with S[rows] = cols, D = B[:, S] has the block D[rows, rows] = block
            rr = np.asarray(rows)
            inv_r.append(np.repeat(rr, len(rr)))
            inv_c.append(np.tile(rr, len(rr)))
            inv_v.append(np.linalg.inv(block.T).ravel())
        if (S < 0).any():
            return None
        D = sp.csr_matrix(B[:, S])
        Dt_inv = sp.csr_matrix(
            (np.concatenate(inv_v), (np.concatenate(inv_r), np.concatenate(inv_c))), shape=(m, m)
        )
        keep = np.ones(n, dtype=bool)  # (n,) the remaining columns, in order (a mask: numpy's
        keep[S] = False  # setdiff1d sorted n values, 0.3 s per call at 386k unknowns)
        R = np.flatnonzero(keep)
        return Condensation(S=S, R=R, D=D, Dt_inv=Dt_inv)


def _merge_subsets(groups: dict[tuple, list[int]]) -> dict[tuple, list[int]]:
    """Columns grouped by exact row set → a deficient group joins the row set containing it.

    A node's columns need not all touch all of its rows: where a frame vector of a 3D contact
    node is orthogonal to a coordinate axis, that displacement component has an exact zero in
    the tangential row (e.g. u_z of a node whose tangent t2 lies in the x-y plane touches the
    normal row and t1 only). Its row set is then a proper subset of the node's, and on its own
    it would be a group with fewer columns than rows. Such a deficient group joins the largest
    row set holding all of its rows, if one set holds them all (no chaining of two groups); a
    group with as many columns as rows stays as it is (a slave column of a scalar problem, whose
    row is also touched by a master column reaching two nodes)."""
    owner: dict[int, tuple] = {}  # row → the largest row set seen that holds it
    merged: dict[tuple, list[int]] = {}
    # the largest row sets first, and among equal ones those with more columns (a node's own
    # columns before a single column reaching into two nodes)
    for rows in sorted(groups, key=lambda r: (len(r), len(groups[r])), reverse=True):
        owners = {owner.get(r) for r in rows}
        into = owners.pop() if len(owners) == 1 else None
        if into is not None and len(groups[rows]) < len(rows):
            merged[into].extend(groups[rows])
            continue
        merged[rows] = list(groups[rows])
        for r in rows:
            owner.setdefault(r, rows)
    return merged


def _structure(M: sp.spmatrix) -> sp.csr_matrix:
    """The sparsity structure of M as a csr matrix of ones (no cancellation possible)."""
    S = sp.csr_matrix(M, copy=True)
    S.data = np.ones_like(S.data)
    return S


def _block_structure(sizes: np.ndarray) -> sp.csr_matrix:
    """Ones on the diagonal blocks of the given sizes (the structure of J and W)."""
    return (
        sp.block_diag([np.ones((k, k)) for k in sizes], format="csr")
        if sizes.size
        else (sp.csr_matrix((0, 0)))
    )


def _on_pattern(M: sp.spmatrix, pattern: sp.csr_matrix) -> sp.csr_matrix:
    """M stored on `pattern` (sorted csr ⊇ the structure of M), explicit zeros kept."""
    M = sp.csr_matrix(M)
    ncol = np.int64(pattern.shape[1])
    # flat keys row · ncol + col, computed in place (few full-size temporaries: memory)
    keys_p = np.repeat(np.arange(pattern.shape[0], dtype=np.int64), np.diff(pattern.indptr))
    keys_p *= ncol
    keys_p += pattern.indices  # (nnz_p,) increasing (sorted csr)
    keys = np.repeat(np.arange(M.shape[0], dtype=np.int64), np.diff(M.indptr))
    keys *= ncol
    keys += M.indices  # (nnz_M,)
    pos = np.searchsorted(keys_p, keys)  # (nnz_M,)
    del keys_p, keys
    data = np.zeros(pattern.nnz)
    np.add.at(data, pos, M.data)
    return sp.csr_matrix((data, pattern.indices, pattern.indptr), shape=pattern.shape)


class _Stepper:
    """Computes Newton iterates (u⁺, λ⁺) for the equilibrated VI `e`."""

    def __init__(self, e: MixedVI, condense: bool, linear_solver: str, tol: float = 0.0):
        self.e = e
        self.linear_solver = linear_solver
        iterative = linear_solver == "amg"
        self.factorize = Refactorizer("auto" if iterative else linear_solver)
        self.last = None  # factorisation of the last Newton matrix
        self.nnz: list[int] = []  # nonzeros of each Newton matrix stored (constant; the
        # iterative path stores one only for a direct fallback)
        self.cond = Condensation.detect(e.B) if condense else None
        self.tol = tol
        self.krylov = None  # the iterative path (condensed steps only)
        if iterative and self.cond is not None:
            self.krylov = KrylovSolver(
                TiedPreconditioner(
                    e.A.tocsr(), e.B, self.cond, e.fields, e.near_null, parts=bodies(e.A)
                )
            )
        if self.cond is not None:
            c = self.cond
            A = e.A.tocsr()
            self.A_S = A[c.S]  # (m, n)
            self.f_S = e.f[c.S]
            self.BR_t = sp.csr_matrix(e.B[:, c.R].T)  # (n−m, m)
            self.rhs_R = e.f[c.R] - self.BR_t @ (c.Dt_inv @ self.f_S)
        if self.krylov is not None:
            return  # the iterative path applies K without storing it (`CondensedNewton`)
        G = _block_structure(e.Lambda.block_sizes())  # (m, m) structure of J and W
        if self.cond is not None:
            c = self.cond
            # fixed rows: A_R − B_Rᵀ D^{-T} A_S
            self.K_R = (A[c.R] - self.BR_t @ (c.Dt_inv @ self.A_S)).tocsr()
            # row permutation: rows stacked [R; S] go to their natural dof positions
            n = e.n
            rows = np.concatenate([c.R, c.S])
            self.P = sp.csr_matrix((np.ones(n), (rows, np.arange(n))), shape=(n, n))
            XB = _structure(c.Dt_inv @ self.A_S) + _structure(e.B)
            KS = _structure(c.D.T) @ (G @ XB)
            self.pattern = _structure(self.P @ sp.vstack([_structure(self.K_R), KS]))
        else:
            self.pattern = _structure(
                sp.bmat([[_structure(e.A), _structure(e.B.T)], [G @ _structure(e.B), G]])
            )
        self.pattern.sort_indices()
        self.pattern.data = np.ones(self.pattern.nnz, dtype=np.int8)  # only its structure is used
        if self.cond is not None:
            # the condensed Newton matrix, kept on the pattern: its R rows are written once and
            # every step overwrites the data of its S rows in place (no copy of K_R, no new K)
            c = self.cond
            K_R = self.P @ sp.vstack([self.K_R, sp.csr_matrix((e.m, e.n))], format="csr")
            self.K = _on_pattern(K_R, self.pattern)
            del K_R, self.K_R
            self.pattern_S = self.pattern[c.S]  # (m, n) its S rows, in the order of S
            ip = self.pattern.indptr
            lengths = np.diff(ip)[c.S]
            # (nnz of pattern_S,) where each entry of pattern_S sits in K.data
            self.S_pos = np.repeat(ip[c.S] - np.cumsum(lengths) + lengths, lengths) + np.arange(
                lengths.sum()
            )

    def step(self, J, W, rhs_c, guess=None, forcing=0.0):
        """Solve A u⁺ + Bᵀλ⁺ = f, W λ⁺ − J B u⁺ = rhs_c (iterative path: from u⁺ = guess, to
        the relative linear residual `forcing`, see `krylov.KrylovSolver`)."""
        e = self.e
        self.last = None  # the previous factor is freed before the next matrix is assembled
        self.factorize.release()
        if self.cond is None:
            K = _on_pattern(sp.bmat([[e.A, e.B.T], [-J @ e.B, W]], format="csr"), self.pattern)
            self.nnz.append(K.nnz)
            self.last = self.factorize(K)
            x = self.last(np.concatenate([e.f, rhs_c]))
            return x[: e.n], x[e.n :]
        c = self.cond
        Dt = c.D.T
        # Dᵀ(W D^{-T} A_S + J B) u = Dᵀ(W D^{-T} f_S − rhs_c)   (rhs_c = p − Jy − J gap)
        K_S = (Dt @ (W @ (c.Dt_inv @ self.A_S)) + Dt @ (J @ e.B)).tocsr()
        rhs_S = Dt @ (W @ (c.Dt_inv @ self.f_S) - rhs_c)
        rhs = np.empty(e.n)  # the rows stacked [R; S] at their natural dof positions
        rhs[c.R], rhs[c.S] = self.rhs_R, rhs_S
        if self.krylov is not None:
            K = CondensedNewton(e.A, c.R, c.S, self.BR_t, c.Dt_inv, K_S)
            tied = np.asarray(abs(W).sum(axis=1)).ravel() == 0  # (m,) rows (B u)_i = …
            u_new, _ = self.krylov(K, rhs, guess, forcing, self.tol, tied, W, J)
            if u_new is not None:
                lam_new = c.Dt_inv @ (self.f_S - self.A_S @ u_new)
                return u_new, lam_new
            K = K.tocsr()  # the Krylov solve's fallback: a direct solve of K assembled
        else:
            K = self.K
            K.data[self.S_pos] = _on_pattern(K_S, self.pattern_S).data
        del K_S  # what the factorisation does not need is freed before it runs
        self.nnz.append(K.nnz)
        self.last = self.factorize(K)
        u_new = self.last(rhs)
        lam_new = c.Dt_inv @ (self.f_S - self.A_S @ u_new)
        return u_new, lam_new


def tied_start(
    vi: MixedVI, u0: np.ndarray, lam0: np.ndarray, tied: np.ndarray | None = None
) -> np.ndarray | None:
    """u0 (n,) moved on the slave columns of the condensation so that (B u)_i = gap_i on the
    rows that the first Newton step from (u = 0, λ0) ties (W = I − J(y) zero in row i, y the
    equilibrated λ0 − gap: stick, bilateral or touching rows, where the answer has
    B u = gap), or on the rows `tied` (m,) bool where the caller knows them, every other row
    of B u0 unchanged; None where B has no condensation (`Condensation`). From (u0, λ0) the
    first step then ties the same rows (y is the same on them): the active set λ0 predicts,
    with u0's fields. (A 3D friction disc gives `tied`: its λ0 on the bound has |y| = radius
    to rounding, which J counts as inside, the 3D contact plug-in's `warm_start`.)

    Why: a warm start u0 carried from another mesh (nested iteration) does not satisfy the
    fine level's tying conditions, and its residual there, added to λ0 in the first active set
    (y = λ + B u − gap), calls rows slip that λ0 predicts stick (paper scene, level 3: the new
    nodes beside both stick/slip transitions, |λ0| at 87 % of the bound plus a jump of 17 %,
    and a second Newton step). Why y from λ0 − gap, not λ0: rows apart by a gap whose λ0 is
    rounding (> 0) are not touching (hertz_piezo, level 2)."""
    cond = Condensation.detect(sp.csr_matrix(vi.B))
    if cond is None:
        return None
    if tied is None:
        e, sc = vi.equilibrated_parts(), vi.scaling  # no whole-size copy of A for Λ', gap'
        y = np.asarray(lam0, float) / sc.s_lam - e["gap"]  # (m,) ssn's y at (0, λ0)
        W = sp.identity(vi.m, format="csr") - e["Lambda"].jacobian(y)
        tied = np.asarray(abs(W).sum(axis=1)).ravel() == 0  # (m,)
    u = np.array(u0, dtype=float)
    # B[:, S] = D: moving u_S by D^{-1} e moves B u by e, on the rows of e only
    u[cond.S] += cond.Dt_inv.T @ np.where(tied, vi.gap - vi.B @ u, 0.0)
    return u


def solve_ssn(
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
    """Semismooth Newton / primal-dual active set for `vi` (see module docstring).

    Stops when the relative natural-map residual (`MixedVI.residual`) is ≤ tol.
    linear_solver : auto|splu|pardiso|amg; "auto" is the iterative path for a large condensable
        problem (`linear_solvers.auto_linear_solver`), a direct backend otherwise. A direct
        factorisation over its budget (`linalg.FactorizationTooLarge`) restarts the solve on
        the iterative path where the steps condense: ``info["factorisation_fallback"]`` and a
        warning say so.
    estimate_condition : also estimate the 1-norm condition of the last (equilibrated,
        condensed) Newton matrix into ``info["condition_estimate"]`` (a few extra solves;
        with PARDISO one extra factorisation).
    on_step : progress, called with a dict after each Newton step ("done": True) and, on the
        iterative path, after each GMRES iteration of a step ("done": False): "step" k,
        "residual" (after step k; while it runs, before it), "active" and "slip" (the rows of
        step k's active set: y = λ + Bu − gap inside Λ, so P(y) = y; and clipped to a nonzero
        boundary point, a friction bound), "krylov_iterations" (GMRES iterations of this solve
        so far; None on the direct path). It must not raise; it may be slow only at its peril.
    """
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(
            f"linear solver {linear_solver!r} unknown; allowed: {', '.join(LINEAR_SOLVERS)}"
        )
    e = vi.equilibrated
    asked = linear_solver
    if linear_solver == "auto":
        condensable = condense and Condensation.detect(e.B) is not None
        linear_solver = auto_linear_solver(e.A.nnz, e.n, condensable)
    args = (vi, tol, max_iter, u0, lam0)
    try:
        sol = _solve_ssn(*args, linear_solver, condense, damping, estimate_condition, on_step)
    except FactorizationTooLarge as err:
        if linear_solver == "amg" or not condense or Condensation.detect(e.B) is None:
            raise
        sol = _solve_ssn(*args, "amg", condense, damping, estimate_condition, on_step)
        note = f"direct factorisation over budget ({err}); solved with amg"
        sol.info["factorisation_fallback"] = note
        sol.warnings.insert(0, note)
    sol.info["linear_solver_asked"] = asked
    return sol


def _solve_ssn(
    vi: MixedVI,
    tol: float,
    max_iter: int,
    u0: np.ndarray | None,
    lam0: np.ndarray | None,
    linear_solver: str,
    condense: bool,
    damping: bool,
    estimate_condition: bool,
    on_step: Callable[[dict], None] | None,
) -> Solution:
    """`solve_ssn` with a concrete linear solver (splu|pardiso|amg, or auto: a direct one)."""
    t0 = time.perf_counter()
    e = vi.equilibrated
    sc = vi.scaling
    u = np.zeros(e.n) if u0 is None else np.asarray(u0, float) / sc.s_u
    lam = np.zeros(e.m) if lam0 is None else np.asarray(lam0, float) / sc.s_lam
    stepper = _Stepper(e, condense=condense, linear_solver=linear_solver, tol=tol)
    Lam = e.Lambda

    res = natural_residual(e, u, lam).relative
    steps = NewtonSteps(tol, [res])
    k = 0
    eta = None  # forcing term of the last inexact step (iterative path)
    linear = all(isinstance(b, Free) for b in Lam.blocks())
    eta_max = ETA_MAX if u0 is None and lam0 is None else ETA_MAX_WARM
    progress: dict = {}  # what on_step is told (its docstring)
    if on_step is not None and stepper.krylov is not None:
        done_before = [0]  # GMRES iterations of the steps before

        def on_iteration(its: int) -> None:
            progress["krylov_iterations"] = done_before[0] + its
            on_step(dict(progress, done=False))

        stepper.krylov.on_iteration = on_iteration
    while not steps.converged and k < max_iter:
        k += 1
        y = lam + e.B @ u - e.gap
        p = Lam.project(y)
        if on_step is not None:
            slip = int(((p != y) & (p != 0.0)).sum())
            progress.update(step=k, residual=res, active=int((p == y).sum()), slip=slip)
            progress.setdefault("krylov_iterations", None)
        J = Lam.jacobian(y)
        W = sp.identity(e.m, format="csr") - J
        rhs_c = p - J @ y - J @ e.gap
        if stepper.krylov is not None:
            eta = forcing_term(res, steps.history[-2] if k > 1 else None, tol, eta_max)
            if linear:  # Λ = Rᵐ: the first Newton step is the solution, solve it to tol at once
                eta = min(eta, 0.1 * tol / res)
        u_new, lam_new = stepper.step(J, W, rhs_c, guess=u, forcing=eta)
        u, lam, t, res = damped_step(
            lambda u, lam: natural_residual(e, u, lam).relative, u, lam, u_new, lam_new, res,
            damping,
        )  # fmt: skip
        steps.record(t, res)
        if on_step is not None:
            if stepper.krylov is not None:
                done_before[0] = sum(s["iterations"] for s in stepper.krylov.steps)
                progress["krylov_iterations"] = done_before[0]
            on_step(dict(progress, residual=res, done=True))

    sol = finish(
        e, Lam, sc, u, lam, (res, steps.converged), tol,
        lambda lam: natural_residual(e, u, lam).relative, steps.history, k, t0,
    )  # fmt: skip
    res, converged = sol.residual, sol.converged
    sol.info = {
        "condensed": stepper.cond is not None,
        "damped_steps": steps.damped,
        "inside": sol.info["inside"],
        "linear_solver": linear_solver
        if stepper.krylov is not None
        else resolve_backend("auto" if linear_solver == "amg" else linear_solver, e.n),
        "threads": thread_settings(),
        "newton_nnz": sorted(set(stepper.nnz)),  # one value: the pattern is fixed
        "symbolic_analyses": stepper.factorize.analyses,
        "factor_fill": [round(f, 2) for f in stepper.factorize.fills],
    }
    if stepper.krylov is not None:
        sol.info.update(stepper.krylov.info())
        if stepper.krylov.accuracy() is not None:  # the states read the last step's accuracy
            sol.info["states"] = {"accuracy": stepper.krylov.accuracy()}
    elif linear_solver == "amg":
        sol.info["fallback"] = [{"step": None, "reason": "not condensable: direct solves"}]
    if stepper.factorize.fallbacks:
        sol.info["factorisation_fallback"] = "; ".join(stepper.factorize.fallbacks)
        sol.warnings.append(f"SuperLU: {stepper.factorize.fallbacks[0]}")
    if estimate_condition and stepper.last is not None:
        sol.info["condition_estimate"] = condition_estimate(stepper.last)
    if not converged:
        sol.warnings.append(
            f"ssn: residual {res:.3e} did not reach tol {tol:.1e} in {k} iterations"
        )
    return sol


@dataclass
class NewtonSteps:
    """The bookkeeping of a semismooth Newton loop, serial (`solve_ssn`) or on PETSc: the
    residual after each step (`history`, the starting residual first), how many steps were
    damped (t < 1: `damped_step`) and whether the last residual is within `tol`."""

    tol: float
    history: list[float]
    damped: int = 0

    @property
    def converged(self) -> bool:
        """Whether the last residual is within tol."""
        return self.history[-1] <= self.tol

    def record(self, t: float, res: float) -> None:
        """One step taken with step length t, its residual res."""
        self.damped += int(t < 1.0)
        self.history.append(res)


def damped_step(
    residual_at: Callable[[np.ndarray, np.ndarray], float],
    u: np.ndarray,
    lam: np.ndarray,
    u_new: np.ndarray,
    lam_new: np.ndarray,
    res: float,
    damping: bool,
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The step from (u, λ) towards the Newton iterate (u_new, λ_new), serial or on PETSc:
    t = 1, halved while the residual (`residual_at(u, λ)`, a global reduction on PETSc) does not
    fall by the Armijo factor 1 − 1e-4·t below `res`, down to t = 1/64; the best t tried wins.
    Without damping t = 1. Returns (u + t·du, λ + t·dλ, t, its residual)."""
    du, dl = u_new - u, lam_new - lam  # (n,), (m,)
    t, best = 1.0, None
    while True:
        cand = residual_at(u + t * du, lam + t * dl)
        if best is None or cand < best[1]:
            best = (t, cand)
        if not damping or cand <= (1.0 - 1e-4 * t) * res or t < 1.0 / 64:
            break
        t *= 0.5
    t, res = best
    return u + t * du, lam + t * dl, t, res


def finish(
    e: MixedVI,
    Lam,
    sc,
    u: np.ndarray,
    lam: np.ndarray,
    last: tuple[float, bool],
    tol: float,
    residual_at: Callable[[np.ndarray], float],
    history: list[float],
    k: int,
    t0: float,
) -> Solution:
    """The end of a semismooth Newton run (serial or on PETSc): λ replaced by its projection
    onto Λ where that keeps the residual (`residual_at(λ)`) within max(residual, tol) — once
    converged it moves λ by rounding only, and the answer is then exactly feasible — and the
    Solution in physical units (`sc.to_physical`) with info "inside": the coordinates where
    λ + Bu − gap lies strictly inside Λ. `last` is (residual, converged) of the last step."""
    res, converged = last
    lam_feasible = Lam.project(lam)
    res_feasible = residual_at(lam_feasible)
    if res_feasible <= max(res, tol):
        lam, res = lam_feasible, res_feasible
        history[-1] = res
        converged = res <= tol
    y = lam + e.B @ u - e.gap
    inner = int((np.abs(y - Lam.project(y)) == 0).sum())
    info = {"inside": inner}  # coordinates with λ + Bu − gap strictly inside Λ
    return Solution.of("ssn", *sc.to_physical(u, lam), res, converged, k, history, t0, info=info)
