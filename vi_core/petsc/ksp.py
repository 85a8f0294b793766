"""The linear solves of the condensed Newton steps on PETSc: one `mpiaij` matrix per Newton
loop, the fixed rows written once and the slave rows rewritten at every step, solved by MUMPS LU
(one KSP for the loop: the symbolic analysis is kept) or by GMRES(15) preconditioned by GAMG
with the near-null space, with a MUMPS fallback. The iterative path makes its KSP (and
fieldsplit's index sets) at each step and destroys it after the solve; the near-null spaces are
made once; every PETSc object is destroyed with the loop (`LinearSolve.destroy`: PETSc's own
allocations, -malloc_debug, are back to what they were before it, and constant from step to
step). Why not one KSP for the loop: GAMG builds its hierarchy anew at each step anyway (its
matrix changed), and a kept KSP holds it, fieldsplit's blocks and GMRES's basis through the
step's damping and multiplier recovery: paper_two_body level 4 on 2 ranks, peak 104 / 107 →
107 / 112 MiB above the imports. What a KSP per step costs instead is heap the process keeps
after the destroyed hierarchies (glibc's, not PETSc's objects): block3d level 2's first step
solved 12 times on 2 ranks, rank 0's peak rose 180.0 → 184.7 MiB over the first five solves,
then stayed (one KSP: flat at 180.3); block3d level 2's four steps end ~2 MiB higher than with
one KSP (docs/benchmarks.md, "Memory").

Preconditioners of the iterative path (``linear_solver="amg"``), chosen by the PETSc option
``-mixvi_amg_pc`` (PETSC_OPTIONS; default ``fieldsplit`` where the problem has several fields):

* ``fieldsplit``: PCFIELDSPLIT over the `MixedVI.fields` (displacement, potential), block
  lower triangular (multiplicative, the serial amg path's `vi_core.block_amg` order), one
  GAMG V-cycle per field (``preonly``); the displacement block gets its rigid-body modes
  (`MixedVI.near_null`) as GAMG's near-null space, composed on the field's IS, and its
  components per node as the IS's block size where every rank's rows of it come in whole nodes
  (`node_block`): GAMG then aggregates nodes, its graph one entry per pair of nodes, not per
  pair of dofs (the squared graph of the dofs was the largest transient of the set-up:
  paper_two_body level 4 on 2 ranks, rank 0's peak 106 → 85 MiB above the imports with the
  Galerkin products below, 49 → 45 GMRES iterations).
* ``gamg``: GAMG on the whole condensed matrix, each field's near-null vectors on its rows and a
  constant on each field without any.

On several ranks GAMG's Galerkin products P^T A P are formed by PETSc's "allatonce" algorithm
(the global option ``-matptap_via allatonce``, set unless PETSC_OPTIONS gives ``-matptap_via``:
PETSc reads it without a prefix; a sequential matrix, one rank, has no such algorithm): the
default "scalable" keeps intermediate products that were the rest of the set-up's peak
(paper_two_body level 4 on 2 ranks: rank 1, 110 → 101 MiB alone; both changes: 106 / 110 → 85
/ 94; docs/benchmarks.md, "Memory").

Any ``-mixvi_*`` option (``-mixvi_ksp_rtol``, ``-mixvi_fieldsplit_displacement_pc_gamg_*``, …)
overrides the defaults set here.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp

from .layout import Layout
from .runtime import Reductions

KINDS = ("mumps", "gamg")
AMG_PCS = ("fieldsplit", "gamg")
GMRES_RTOL = 1e-12  # relative residual of a GMRES solve (an inexact step moves u by ~rtol·|u|)
GMRES_MAX_IT = 500
# GMRES(15), not PETSc's GMRES(30): its Krylov basis is a rank's largest array after the
# preconditioner (15 vectors of the owned rows fewer: paper_two_body level 4 on 2 ranks, 118 →
# 112 MiB per rank above the imports, 45 → 49 iterations; docs/benchmarks.md)
GMRES_RESTART = 15


class Fields(Protocol):
    """What the preconditioner reads of the equilibrated VI: `MixedVI.fields` and
    `MixedVI.near_null` (a MixedVI, or the engine's VI without A, `newton._Kept`)."""

    fields: dict | None
    near_null: dict | None


def orthonormal(local: np.ndarray, red: Reductions) -> np.ndarray:
    """(k, r) this rank's rows of an orthonormal basis of the span of the columns whose rows
    the ranks hold (`local`, (k, d) here), r ≤ d: the directions that are dependent (singular
    values below 1e-6 of the largest: rounding in the Gram matrix's eigenvalues is ~1e-16 of
    the largest) are dropped first (the rigid-body modes restricted to the free
    dofs of a coarse, much-constrained mesh: paper_two_body_extruded level 0), then Cholesky QR
    twice (CholeskyQR2: orthonormal to rounding), one d × d allreduce each."""
    G = red.comm.allreduce(local.T @ local)  # (d, d) the global Gram matrix
    w, V = np.linalg.eigh(G)  # ascending
    keep = w > 1e-12 * max(w[-1], 0.0)  # σ_i > 1e-6 σ_max
    Q = local @ (V[:, keep] / np.sqrt(w[keep]))  # (k, r) orthonormal up to rounding
    for _ in range(2):
        G = red.comm.allreduce(Q.T @ Q)  # (r, r)
        L = np.linalg.cholesky(G)
        Q = np.linalg.solve(L, Q.T).T  # (k, r) Q L^{-T}
    return Q


def node_block(N: np.ndarray) -> int:
    """The components per node c of a field whose near-null vectors N ((k_f, d): a rank's rows
    of the field, in the rows' order) begin with one translation per component (columns
    nonzero on their component's rows only, each row nonzero in exactly one of them:
    `MixedVI.near_null`'s rigid-body modes, scaled as the equilibrated VI scales them), where
    the rows come in whole nodes (c consecutive rows, components 0, …, c − 1); 1 otherwise (no
    such columns, a node cut, a component missing); 0 for no rows (no say: `LinearSolve` takes
    the ranks' common answer)."""
    k, d = N.shape
    if k == 0:
        return 0
    T = N != 0.0  # (k, d) the rows each column is nonzero on
    # c: the leading columns whose rows are disjoint, the translations (a component without
    # rows on this rank counts: its column is empty)
    c = 1
    while c < d and not (T[:, c] & T[:, :c].any(axis=1)).any():
        c += 1
    if c < 2 or k % c or (T[:, :c].sum(axis=1) != 1).any():
        return 1
    comp = T[:, :c].argmax(axis=1).reshape(-1, c)  # (k / c, c) each row's component by node
    return c if (comp == np.arange(c)).all() else 1


def near_null_rows(e: Fields, name: str, layout: Layout) -> np.ndarray:
    """(k_f, d) the near-null vectors of field `name` on this rank's rows of the field
    (`layout`), in the rows' order; one constant column for a field without any."""
    at = layout.field_positions(e.fields[name])  # (k_f,) rows of the field's vectors
    N = (e.near_null or {}).get(name)
    return np.ones((at.size, 1)) if N is None else N[at]


class LinearSolve:
    """The condensed Newton matrix of one Newton loop on the ranks of `comm` and its KSP.

    K_local : (k, n) csr, this rank's rows of the matrix in `layout` (its rows' order; columns
        as PETSc rows, `Layout.new`), on its fixed pattern (the rows `set_rows` rewrites hold
        their every possible entry, explicit zeros included).
    kind : "mumps" (LU) or "gamg" (GMRES with the preconditioner ``-mixvi_amg_pc``)."""

    def __init__(
        self,
        PETSc: Any,
        comm: Any,
        kind: str,
        e: Fields,
        layout: Layout,
        K_local: sp.csr_matrix,
    ):
        if kind not in KINDS:
            raise ValueError(f"petsc linear solver {kind!r} unknown; allowed: {', '.join(KINDS)}")
        self.PETSc, self.comm, self.kind = PETSc, comm, kind
        self.red = Reductions(comm)
        self.layout = layout
        k, n = K_local.shape
        self.K = PETSc.Mat().createAIJ(
            size=((k, n), (k, n)),
            csr=(
                K_local.indptr.astype(PETSc.IntType, copy=False),
                K_local.indices.astype(PETSc.IntType, copy=False),
                K_local.data,
            ),
            comm=comm,
        )
        self.K.setOption(PETSc.Mat.Option.NEW_NONZERO_LOCATION_ERR, True)  # the pattern is fixed
        self.K.assemble()
        self.b, self.x = self.K.createVecs()
        self.e = e
        self.pc = self._amg_pc(e) if kind == "gamg" else None
        self._nullspaces: dict[str, Any] = {}  # by field ("" for the whole matrix), made once
        self._index: list[Any] = []  # fieldsplit's index sets, made once
        self._block_sizes: dict[str, int] = {}  # by field (`_block_size`)
        self.ksp = self._ksp(kind, e)
        self.iterations = 0  # GMRES iterations so far
        self.steps: list[dict] = []  # per solve: its KSP, iterations, reason
        # fieldsplit's: field → [rows, near-null dim, block size]
        self.blocks: dict[str, list[int]] = {}

    def _amg_pc(self, e: Fields) -> str:
        """The preconditioner of the iterative path: ``-mixvi_amg_pc`` or the default."""
        opts = self.PETSc.Options()
        if not opts.hasName("mixvi_amg_pc"):
            return "fieldsplit" if e.fields and len(e.fields) > 1 else "gamg"
        asked = opts.getString("mixvi_amg_pc")
        if asked not in AMG_PCS:
            raise ValueError(f"-mixvi_amg_pc {asked!r} unknown; allowed: {', '.join(AMG_PCS)}")
        return asked

    def _nullspace(self, key: str, local: Callable[[], np.ndarray]) -> Any:
        """The PETSc near-null space `key` (a field, "" for the whole matrix) of the vectors
        whose rows this rank holds (`local()`, (k, d)), made at the first call and kept."""
        if key in self._nullspaces:
            return self._nullspaces[key]
        PETSc = self.PETSc
        Q = orthonormal(local(), self.red)  # MatNullSpace asks for orthonormal vectors
        vecs = []
        for j in range(Q.shape[1]):
            v = PETSc.Vec().createMPI((Q.shape[0], PETSc.DECIDE), comm=self.comm)
            v.setArray(Q[:, j])
            vecs.append(v)
        space = PETSc.NullSpace().create(vectors=vecs, comm=self.comm)
        self._nullspaces[key] = space
        return space

    def _whole_near_null(self, e: Fields) -> np.ndarray:
        """(k, Σ d_f) each field's near-null vectors on its rows here, 0 on the others."""
        cols, rows = [], self.layout.rows
        for name, mask in e.fields.items():
            N = near_null_rows(e, name, self.layout)  # (k_f, d)
            Z = np.zeros((rows.size, N.shape[1]))
            Z[mask[rows]] = N
            cols.append(Z)
        return np.hstack(cols)

    def _ksp(self, kind: str, e: Fields | None = None) -> Any:
        PETSc = self.PETSc
        ksp = PETSc.KSP().create(comm=self.comm)
        ksp.setOptionsPrefix("mixvi_")
        ksp.setOperators(self.K)
        pc = ksp.getPC()
        if kind == "mumps":
            ksp.setType("preonly")
            pc.setType("lu")
            pc.setFactorSolverType("mumps")
        else:
            ksp.setType("gmres")
            ksp.setTolerances(rtol=GMRES_RTOL, atol=0.0, max_it=GMRES_MAX_IT)
            ksp.setGMRESRestart(GMRES_RESTART)
            ksp.setInitialGuessNonzero(True)
            opts = PETSc.Options()
            if self.comm.getSize() > 1 and not opts.hasName("matptap_via"):
                opts.setValue("matptap_via", "allatonce")  # GAMG's P^T A P (module docstring)
            if self.pc == "fieldsplit":
                self._fieldsplit(pc, e)
            else:
                pc.setType("gamg")
                if e.fields:
                    self.K.setNearNullSpace(self._nullspace("", lambda: self._whole_near_null(e)))
        ksp.setFromOptions()
        return ksp

    def _fieldsplit(self, pc: Any, e: Fields) -> None:
        """PCFIELDSPLIT over e.fields (module docstring); defaults only where no -mixvi_ option
        says otherwise."""
        PETSc = self.PETSc
        pc.setType("fieldsplit")
        pc.setFieldSplitType(PETSc.PC.CompositeType.MULTIPLICATIVE)
        opts = PETSc.Options()
        for name, mask in e.fields.items():
            rows = self.layout.field_rows(mask)  # (k_f,) the field's PETSc rows here
            index = PETSc.IS().createGeneral(rows.astype(PETSc.IntType), comm=self.comm)
            if (e.near_null or {}).get(name) is not None:
                # PCFIELDSPLIT hands a "nearnullspace" composed on the IS to its block
                near = self._nullspace(name, partial(near_null_rows, e, name, self.layout))
                index.compose("nearnullspace", near)
                index.setBlockSize(self._block_size(name, rows.size))  # GAMG's nodes
            pc.setFieldSplitIS((name, index))
            self._index.append(index)
            for key, value in (("ksp_type", "preonly"), ("pc_type", "gamg")):
                if not opts.hasName(f"mixvi_fieldsplit_{name}_{key}"):
                    opts.setValue(f"mixvi_fieldsplit_{name}_{key}", value)

    def _block_size(self, name: str, count: int) -> int:
        """Field `name`'s components per node where every rank's rows of it come in whole
        nodes (`node_block`, the ranks' common answer; made once per field), else 1; 1 also
        where a rank's index set of the field (`count` rows) is not its near-null rows."""
        if name not in self._block_sizes:
            N = near_null_rows(self.e, name, self.layout)  # (k_f, d)
            mine = node_block(N) if N.shape[0] == count else 1
            said = {c for c in self.red.comm.allgather(mine) if c}  # the ranks with rows
            self._block_sizes[name] = said.pop() if len(said) == 1 else 1
        return self._block_sizes[name]

    def _record_blocks(self) -> None:
        """Each field's block as PCFIELDSPLIT solves it: its rows, the dimension of the
        near-null space its GAMG got (0: none, GAMG's constant) and its block size."""
        subs = self.ksp.getPC().getFieldSplitSubKSP()
        for name, sub in zip(self.e.fields, subs, strict=True):
            A = sub.getOperators()[0]
            near = A.getNearNullSpace()
            dim = len(near.getVecs()) if near.handle else 0
            self.blocks[name] = [A.getSize()[0], dim, A.getBlockSize()]

    def set_rows(self, rows: np.ndarray, pattern: sp.csr_matrix, values: np.ndarray) -> None:
        """Rows `rows` ((r,) PETSc rows, this rank's) of the matrix overwritten with `values`
        (pattern.nnz,) on `pattern` ((r, n) csr, the rows' fixed pattern, columns as PETSc
        rows), then the matrix assembled."""
        K, ip, insert = self.K, pattern.indptr, self.PETSc.InsertMode.INSERT_VALUES
        idx = pattern.indices.astype(self.PETSc.IntType)
        for i, row in enumerate(rows):
            K.setValues(int(row), idx[ip[i] : ip[i + 1]], values[ip[i] : ip[i + 1]], insert)
        K.assemble()

    def solve(self, rhs: np.ndarray, guess: np.ndarray) -> np.ndarray:
        """x (k,) this rank's part of the solution of K x = rhs (rhs (k,), guess (k,) its
        parts: the entries of `layout.rows`; the guess starts GMRES)."""
        b, x = self.b, self.x
        b.setArray(rhs)
        x.setArray(guess)
        if self.ksp is None:
            self.ksp = self._ksp(self.kind, self.e)
        self.ksp.setOperators(self.K)  # its values changed (`set_rows`): the PC is set up again
        self.ksp.solve(b, x)
        if self.pc == "fieldsplit" and not self.blocks:
            self._record_blocks()
        record = {
            "ksp": self.kind,
            "iterations": self.ksp.getIterationNumber(),
            "reason": int(self.ksp.getConvergedReason()),
        }
        if self.kind == "gamg":
            record["pc"] = self.pc
            record["rtol"] = float(self.ksp.getTolerances()[0])  # asked of GMRES (-mixvi_ksp_rtol)
            self.iterations += record["iterations"]
            if record["reason"] < 0:  # GMRES did not converge: MUMPS for this step
                direct = self._ksp("mumps")
                direct.solve(b, x)
                direct.destroy()
                record["fallback"] = "mumps"
            self.ksp.destroy()
            self.ksp = None
            for index in self._index:
                index.destroy()
            self._index = []
        self.steps.append(record)
        return x.getArray().copy()

    def destroy(self) -> None:
        """Free the loop's PETSc objects (collective): the KSP (its PC, sub-KSPs and
        sub-matrices with it), the matrix, the vectors, the index sets and near-null spaces."""
        kept = [self.ksp] if self.ksp is not None else []
        for obj in (*kept, self.K, self.b, self.x, *self._index, *self._nullspaces.values()):
            obj.destroy()

    def accuracy(self) -> float | None:
        """The relative accuracy of the last solve beyond what its residual shows: the rtol
        GMRES was asked for where GMRES solved it (GMRES_RTOL unless ``-mixvi_ksp_rtol`` says
        otherwise; a solve that took no GMRES iteration, its guess already within rtol,
        included: the step is no more accurate than that), 0 after a direct solve (MUMPS, or
        the fallback: exact to rounding), None on the direct path (as the serial direct path:
        the residual alone) or before any solve. The states' thresholds read it
        (`vi_core.states.solution_thresholds`)."""
        if self.kind != "gamg" or not self.steps:
            return None
        last = self.steps[-1]
        return last["rtol"] if last["ksp"] == "gamg" and "fallback" not in last else 0.0

    def info(self) -> dict:
        """What the solves did, for Solution.info (the serial amg path's keys where they mean
        the same: krylov_iterations per step and the steps that fell back to a direct solve)."""
        out = {"linear_solver": f"petsc-{self.kind}", "petsc_solves": self.steps}
        if self.kind == "gamg":
            out["preconditioner"] = self.pc
            if self.blocks:
                out["fieldsplit"] = self.blocks
            out["krylov_iterations"] = [s["iterations"] for s in self.steps]
            out["fallback"] = [
                {"step": i + 1, "reason": f"KSP reason {s['reason']}: MUMPS"}
                for i, s in enumerate(self.steps)
                if "fallback" in s
            ]
        return out
