"""The linear solve of a condensed Newton step on PETSc: one set-up / solve object per Newton
loop (MUMPS LU, or GMRES with GAMG and the near-null space with a MUMPS fallback)."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from vi_core.problem import MixedVI

KINDS = ("mumps", "gamg")
GMRES_RTOL = 1e-12  # relative residual of a GMRES solve (an inexact step moves u by ~rtol·|u|)
GMRES_MAX_IT = 500


def near_null_vectors(e: MixedVI) -> np.ndarray | None:
    """(n, d) orthonormal columns: each field's near-null vectors (`MixedVI.near_null`) on the
    field's rows, zero elsewhere, and a constant on each field without any; None without
    fields."""
    if not e.fields:
        return None
    cols = []
    for name, mask in e.fields.items():
        N = (e.near_null or {}).get(name)
        N = np.ones((int(mask.sum()), 1)) if N is None else N  # (k, d)
        Z = np.zeros((e.n, N.shape[1]))
        Z[mask] = N
        cols.append(Z)
    Q, _ = np.linalg.qr(np.hstack(cols))  # (n, d) orthonormal (MatNullSpace asks for it)
    return Q


class LinearSolve:
    """Set up for a matrix, then solve with it, on the ranks of `comm` (each passes its owned
    rows [lo, lo + k) as a csr (k, n) matrix and its part (k,) of the right-hand side)."""

    def __init__(self, PETSc: Any, comm: Any, kind: str, e: MixedVI, lo: int):
        if kind not in KINDS:
            raise ValueError(f"petsc linear solver {kind!r} unknown; allowed: {', '.join(KINDS)}")
        self.PETSc, self.comm, self.kind, self.n, self.lo = PETSc, comm, kind, e.n, lo
        self.near = near_null_vectors(e) if kind == "gamg" else None
        self.iterations = 0  # GMRES iterations so far
        self.steps: list[dict] = []  # per solve: its KSP, iterations, reason

    def _ksp(self, K: Any, kind: str) -> Any:
        PETSc = self.PETSc
        ksp = PETSc.KSP().create(comm=self.comm)
        ksp.setOptionsPrefix("mixvi_")
        ksp.setOperators(K)
        pc = ksp.getPC()
        if kind == "mumps":
            ksp.setType("preonly")
            pc.setType("lu")
            pc.setFactorSolverType("mumps")
        else:
            ksp.setType("gmres")
            ksp.setTolerances(rtol=GMRES_RTOL, atol=0.0, max_it=GMRES_MAX_IT)
            pc.setType("gamg")
        ksp.setFromOptions()
        return ksp

    def solve(self, K_local: sp.csr_matrix, rhs: np.ndarray, guess: np.ndarray, _tol=None):
        """x (k,) owned part of the solution of K x = rhs."""
        PETSc, k = self.PETSc, K_local.shape[0]
        K = PETSc.Mat().createAIJ(
            size=((k, self.n), (k, self.n)),
            csr=(
                K_local.indptr.astype(PETSc.IntType),
                K_local.indices.astype(PETSc.IntType),
                K_local.data,
            ),
            comm=self.comm,
        )
        K.assemble()
        if self.near is not None:
            vecs = []
            for j in range(self.near.shape[1]):
                v = K.createVecRight()
                v.setArray(self.near[self.lo : self.lo + k, j])
                vecs.append(v)
            K.setNearNullSpace(PETSc.NullSpace().create(vectors=vecs, comm=self.comm))
        b = K.createVecLeft()
        b.setArray(rhs)
        x = K.createVecRight()
        kind = self.kind
        ksp = self._ksp(K, kind)
        if kind == "gamg":
            x.setArray(guess)
            ksp.setInitialGuessNonzero(True)
        ksp.solve(b, x)
        record = {
            "ksp": kind,
            "iterations": ksp.getIterationNumber(),
            "reason": int(ksp.getConvergedReason()),
        }
        if kind == "gamg":
            self.iterations += record["iterations"]
            if record["reason"] < 0:  # GMRES did not converge: MUMPS for this step
                ksp.destroy()
                ksp = self._ksp(K, "mumps")
                ksp.solve(b, x)
                record["fallback"] = "mumps"
        self.steps.append(record)
        out = x.getArray().copy()
        for obj in (ksp, K, b, x):
            obj.destroy()
        return out

    def info(self) -> dict:
        """What the solves did, for Solution.info (the serial amg path's keys where they mean
        the same: krylov_iterations per step and the steps that fell back to a direct solve)."""
        out = {"linear_solver": f"petsc-{self.kind}", "petsc_solves": self.steps}
        if self.kind == "gamg":
            out["krylov_iterations"] = [s["iterations"] for s in self.steps]
            out["fallback"] = [
                {"step": i + 1, "reason": f"KSP reason {s['reason']}: MUMPS"}
                for i, s in enumerate(self.steps)
                if "fallback" in s
            ]
        return out
