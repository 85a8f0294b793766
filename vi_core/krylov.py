"""An iterative linear path for the semismooth Newton steps: GMRES with algebraic multigrid.

`ssn` condenses the dual-mortar multipliers out of every Newton system; what remains is the
non-symmetric n × n system K u⁺ = b in the primal unknowns, with rows R fixed over the Newton
steps (A_R − B_Rᵀ D^{-T} A_S) and rows S (the slave dofs) replaced by the active-set conditions
Dᵀ(W D^{-T} A_S + J B), which change from step to step.

**Preconditioner** (right, for restarted GMRES): block lower triangular in the split (R, S),

    M = [[P_RR, 0], [K_SR, K_SS]],   P_RR ≈ K_RR by one V-cycle per field,  K_SS by SuperLU.

K_RR (rows and columns R) does not change over the Newton steps, so its hierarchies are built
once per solve and reused; K_SS (m × m, a band along the contact interface) is factorised at
every step — the contact rows, scaled quite differently from the stiffness rows (a stick row is
a mortar tying condition, a slip row a stiffness row), never enter the multigrid hierarchy.
P_RR is itself block lower triangular over the fields of the problem (`MixedVI.fields`, e.g.
displacement then potential): one pyamg smoothed-aggregation hierarchy per field, built on the
symmetric part of its diagonal block, with the field's near-null space (`MixedVI.near_null`,
the rigid-body modes for displacement) or the constant vector; the coupling blocks below the
diagonal (the piezoelectric coupling) are applied exactly. Measured on the paper scene
(level 3, 24k unknowns, GMRES to 1e-10 from zero): 36–45 iterations per Newton step; a
hierarchy of the original stiffness without the (R, S) split: 53–56; the same split with an
exact K_RR: 10–21 (the rest is the coupling of slip rows to the interior).

**Inexact Newton.** Each step starts from the current iterate and stops when the linear residual
is ≤ η_k times its initial value (Eisenstat–Walker, choice 2: η_k = 0.9 (F_k/F_{k−1})², at most
ETA_MAX, or ETA_MAX_WARM from a warm start), but never asks for more than 0.1·tol relative to
‖b‖: the step that brings the natural residual below tol is solved to about the requested
tolerance, and convergence is judged from the natural residual of the iterate itself, as with a
direct solve.

**Fallback.** A solve whose true residual falls by less than a factor 0.9 over a restart cycle,
or does not reach its tolerance within `max_cycles` cycles, is redone by the direct solver; the
step and the reason are recorded in `info["fallback"]`.
"""

from __future__ import annotations

import os
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .linalg import BACKENDS

LINEAR_SOLVERS = (*BACKENDS, "amg")  # the direct backends and the iterative path
# the loosest relative linear tolerance of a Newton step, from a cold start and from a warm
# start (u0/λ0 given: nested iteration, where the active set is nearly right and Newton needs 1–2
# exact steps, so an inexact step only adds steps). Measured with the fine level of the paper
# scene (FGMRES iterations / Newton steps): level 3 cold, 0.1 → 78 / 9, 1e-3 → 97 / 7; level 4
# nested, 1e-4 → 98 / 4, 1e-8 → 71 / 2 (each step also costs a K_SS factorisation, residuals
# and the line search)
ETA_MAX = 0.1
ETA_MAX_WARM = 1e-8
# prolongation smoothing: energy minimisation (two CG steps) instead of one Jacobi step; CG on
# the displacement block of the paper scene to 1e-8, levels 3, 4, 5: 14, 15, 17 iterations with
# Jacobi, 11, 12, 12 with energy minimisation (set-up about twice as long)
SMOOTH = ("energy", {"krylov": "cg", "maxiter": 2, "degree": 1, "weighting": "local"})
MAX_LEVELS = 30  # more than any hierarchy has (pyamg's default max_levels is 10)
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def thread_settings() -> dict:
    """The thread-count environment variables as set (None = library default), the cores, and
    the threads each loaded BLAS/OpenMP library uses now (threadpoolctl)."""
    from threadpoolctl import threadpool_info

    pools = {f"{p['internal_api']}:{p['user_api']}": p["num_threads"] for p in threadpool_info()}
    env = {k: os.environ.get(k) for k in THREAD_VARIABLES}
    return {**env, "cpu_count": os.cpu_count(), "thread_pools": pools}


def forcing_term(res: float, res_prev: float | None, tol: float, eta_max: float = ETA_MAX) -> float:
    """Eisenstat–Walker (choice 2, γ = 0.9, α = 2) forcing term for the next Newton step:
    η = 0.9 (res / res_prev)², at most eta_max (also on the first step, res_prev None), and not
    below 0.1·tol/res (no step solved more accurately than reaching tol needs)."""
    eta = eta_max if not res_prev else 0.9 * (res / res_prev) ** 2
    floor = 0.1 * tol / res if res > 0 else eta_max
    return float(min(eta_max, max(eta, floor)))


def bodies(A: sp.spmatrix) -> np.ndarray:
    """(n,) the connected component of each unknown in the graph of A: the bodies of a contact
    problem, which only the multipliers couple."""
    from scipy.sparse.csgraph import connected_components

    return connected_components(A, directed=False)[1]


@dataclass
class FieldBlock:
    """One field of the R block: its positions in R and its multigrid hierarchy."""

    name: str
    index: np.ndarray  # (k,) positions within R
    ml: object  # pyamg MultilevelSolver
    lower: list = field(default_factory=list)  # [(j, K_RR[self, field j])] for earlier fields j


def _fields(n: int, fields: dict | None, near_null: dict | None) -> list[tuple]:
    """[(name, mask (n,), near-null rows or None)], covering every unknown exactly once."""
    out, covered = [], np.zeros(n, dtype=bool)
    for name, sel in (fields or {}).items():
        mask = np.zeros(n, dtype=bool)
        mask[sel] = True
        if (mask & covered).any():
            raise ValueError(f"field {name!r} overlaps an earlier field")
        covered |= mask
        if mask.any():
            out.append((name, mask, None if near_null is None else near_null.get(name)))
    if not covered.all():
        out.append(("rest", ~covered, None))
    return out


def strength_within_parts(A: sp.csr_matrix, part: np.ndarray | None) -> list:
    """pyamg's `strength` argument: the symmetric strength of connection (θ = 0) of A on the
    finest level with every connection between two parts (bodies) dropped, so no aggregate
    spans two bodies; the default on coarser levels.

    Why: where bodies slide along each other (slip rows), an aggregate across the interface
    ties their tangential motions together, and the coarse spaces cannot represent the slip;
    the FGMRES iterations then grow with the level (paper scene, CG on the glued displacement
    block to 1e-8: 25, 26, 38 at levels 3–5 aggregating across, 19, 22, 31 within the bodies;
    with energy-minimising prolongation 19, 20, 28 against 13, 17, 20)."""
    from pyamg.strength import symmetric_strength_of_connection

    if part is None or np.unique(part).size < 2:
        return ["symmetric"] * MAX_LEVELS
    C = symmetric_strength_of_connection(A, 0.0).tocoo()
    keep = part[C.row] == part[C.col]
    C = sp.csr_matrix((C.data[keep], (C.row[keep], C.col[keep])), shape=A.shape)
    return [("predefined", {"C": C})] + ["symmetric"] * MAX_LEVELS


class BlockAMG:
    """x_R ≈ K_RR⁻¹ r_R: one V-cycle per field, block lower triangular over the fields.

    parts : optional (n_R,) label of each unknown's body (aggregates stay within one body)."""

    def __init__(
        self,
        K_RR: sp.csr_matrix,
        fields: list[tuple],
        couple: bool = True,
        parts: np.ndarray | None = None,
    ):
        import pyamg

        t = time.perf_counter()
        self.blocks: list[FieldBlock] = []
        for name, mask, nn in fields:
            index = np.flatnonzero(mask)
            if index.size == 0:
                continue
            Kf = K_RR[index][:, index]
            sym = ((Kf + Kf.T) * 0.5).tocsr()
            del Kf
            kw = {} if nn is None else {"B": np.asarray(nn, float).reshape(index.size, -1)}
            ml = pyamg.smoothed_aggregation_solver(
                sym,
                max_coarse=500,
                coarse_solver="splu",
                smooth=SMOOTH,
                strength=strength_within_parts(sym, None if parts is None else parts[index]),
                **kw,
            )
            del sym
            blk = FieldBlock(name, index, ml)
            if couple:
                for j, prev in enumerate(self.blocks):
                    C = K_RR[index][:, prev.index].tocsr()
                    C.eliminate_zeros()
                    if C.nnz:
                        blk.lower.append((j, C))
            self.blocks.append(blk)
        self.setup_time = time.perf_counter() - t

    def __call__(self, r: np.ndarray) -> np.ndarray:
        x = np.zeros_like(r)
        parts = []
        for blk in self.blocks:
            rhs = r[blk.index]
            for j, C in blk.lower:
                rhs = rhs - C @ parts[j]
            xb = blk.ml.solve(rhs, x0=np.zeros_like(rhs), tol=0.0, maxiter=1, cycle="V")
            parts.append(xb)
            x[blk.index] = xb
        return x

    def describe(self) -> dict:
        return {
            b.name: {
                "size": int(b.index.size),
                "levels": len(b.ml.levels),
                "operator_complexity": float(b.ml.operator_complexity()),
                "near_null_dim": int(b.ml.levels[0].B.shape[1]),
            }
            for b in self.blocks
        }


class KrylovSolver:
    """Solves the condensed Newton systems K u = b of one ssn run (module docstring).

    R, S : the fixed rows/columns and the slave columns of the condensation.
    fields, near_null : `MixedVI.fields` / `MixedVI.near_null` of the equilibrated problem.
    parts : optional (n,) body of each unknown (`bodies`): no aggregate spans two bodies.
    """

    def __init__(
        self,
        R: np.ndarray,
        S: np.ndarray,
        fields: dict | None = None,
        near_null: dict | None = None,
        restart: int = 50,
        max_cycles: int = 8,
        couple: bool = True,
        parts: np.ndarray | None = None,
    ):
        self.R, self.S = np.asarray(R), np.asarray(S)
        self.parts = None if parts is None else np.asarray(parts)[self.R]
        self.n = self.R.size + self.S.size
        self.fields, self.near_null = fields, near_null
        self.restart, self.max_cycles, self.couple = restart, max_cycles, couple
        self.amg: BlockAMG | None = None
        self.steps: list[dict] = []  # per Newton step: iterations, tolerance, residual, …
        self.time = 0.0

    def _fields_R(self) -> list[tuple]:
        """The fields restricted to R (masks over R, near-null rows of R's dofs)."""
        out = []
        inR = np.zeros(self.n, dtype=bool)
        inR[self.R] = True
        for name, mask, nn in _fields(self.n, self.fields, self.near_null):
            keep = inR[np.flatnonzero(mask)]  # which of the field's dofs are in R
            out.append((name, mask[self.R], None if nn is None else np.asarray(nn)[keep]))
        return out

    def __call__(
        self, K: sp.csr_matrix, b: np.ndarray, x0: np.ndarray | None, eta: float, tol: float
    ) -> tuple[np.ndarray | None, dict]:
        """Solve K x = b to ‖b − Kx‖ ≤ max(η‖b − K x0‖, 0.1·tol·‖b‖).

        Returns (x, record); x is None where the solve stagnated (record["fallback"] says why).
        """
        from threadpoolctl import threadpool_limits

        # the BLAS calls of set-up and Krylov vectors are far too small to gain from threads: on
        # the shared 2-core machine OpenBLAS's threads made the paper scene's level 3 solve 8×
        # slower (set-up 8.1 s → 0.3 s, FGMRES 5.9 s → 1.2 s with one thread)
        with threadpool_limits(limits=1, user_api="blas"):
            return self._solve(K, b, x0, eta, tol)

    def _solve(self, K, b, x0, eta, tol):
        from pyamg.krylov import fgmres

        t0 = time.perf_counter()
        R, S = self.R, self.S
        if self.amg is None:
            self.amg = BlockAMG(
                K[R][:, R].tocsr(), self._fields_R(), couple=self.couple, parts=self.parts
            )
        K_S = K[S]
        K_SR = K_S[:, R].tocsr()
        lu = spla.splu(sp.csc_matrix(K_S[:, S]))
        amg = self.amg

        def precondition(r):
            x = np.empty_like(r)
            xR = amg(r[R])
            x[R] = xR
            x[S] = lu.solve(r[S] - K_SR @ xR)
            return x

        M = spla.LinearOperator(K.shape, matvec=precondition, dtype=float)
        x = np.zeros(self.n) if x0 is None else np.array(x0, dtype=float)
        nb = float(np.linalg.norm(b))
        r0 = float(np.linalg.norm(b - K @ x))
        target = max(eta * r0, 0.1 * tol * nb)
        its = [0]

        def count(_):
            its[0] += 1

        record = {"eta": eta, "target": target / nb if nb else 0.0, "fallback": None}
        res, cycles = r0, 0
        while res > target:
            if cycles == self.max_cycles:
                record["fallback"] = f"no convergence in {cycles} FGMRES({self.restart}) cycles"
                break
            with warnings.catch_warnings():  # a (near) breakdown is judged by the residual below
                warnings.simplefilter("ignore", sla.LinAlgWarning)
                x, _ = fgmres(
                    K,
                    b,
                    x0=x,
                    tol=target / nb,
                    restart=min(self.restart, self.n),
                    maxiter=1,
                    M=M,
                    callback=count,
                )
            cycles += 1
            new = float(np.linalg.norm(b - K @ x))
            if new > 0.9 * res and new > target:
                record["fallback"] = f"stagnation: residual {res:.2e} → {new:.2e} in a cycle"
                res = new
                break
            res = new
        record.update(iterations=its[0], residual=res / nb if nb else 0.0)
        self.time += time.perf_counter() - t0
        self.steps.append(record)
        return (None if record["fallback"] else x), record

    def info(self) -> dict:
        """What the Newton solve's `info` reports about the iterative path."""
        return {
            "krylov": "fgmres (pyamg, right preconditioned)",
            "restart": self.restart,
            "preconditioner": "block-triangular (R: smoothed aggregation per field, S: direct)",
            "krylov_iterations": [s["iterations"] for s in self.steps],
            "krylov_residuals": [s["residual"] for s in self.steps],
            "forcing_terms": [s["eta"] for s in self.steps],
            "fallback": [
                {"step": i + 1, "reason": s["fallback"]}
                for i, s in enumerate(self.steps)
                if s["fallback"]
            ],
            "amg_setup_s": self.amg.setup_time if self.amg else 0.0,
            "amg_fields": self.amg.describe() if self.amg else {},
            "linear_time_s": self.time,
        }
