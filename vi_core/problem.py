"""Problem 3.1 in matrix form: the mixed variational inequality.

Find u ∈ R^n, λ ∈ Λ ⊂ R^m with

    A u + Bᵀ λ = f,        (B u − gap)ᵀ (μ − λ) ≤ 0   for all μ ∈ Λ,

A sparse with A + Aᵀ positive definite (possibly non-symmetric), Λ closed and convex.
`gap` (default 0) generalises the paper's Problem 3.1 to obstacle and Signorini problems.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .sets import ConvexSet, as_product


@dataclass(frozen=True)
class Scaling:
    """Diagonal equilibration u = s_u ⊙ u', λ = s_lam ⊙ λ' (see `MixedVI.equilibrated`)."""

    s_u: np.ndarray  # (n,)
    s_lam: np.ndarray  # (m,)

    def to_scaled(self, u: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return u / self.s_u, lam / self.s_lam

    def to_physical(self, u: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return u * self.s_u, lam * self.s_lam


@dataclass(frozen=True)
class Residual:
    """The natural-map residual of a candidate (u, λ), in equilibrated variables.

    r1 = A'u' + B'ᵀλ' − f',  r2 = λ' − P_Λ'(λ' + c (B'u' − gap')) with c = 1 (the equilibrated
    problem has unit diagonal in A' and unit rows in B'). `relative` = ‖(r1, r2)‖₂ / scale with
    scale = max(‖f'‖₂, ‖gap'‖₂) (1 when both vanish: then the solution is 0).
    """

    equilibrium: float  # ‖r1‖₂
    complementarity: float  # ‖r2‖₂
    scale: float
    relative: float


@dataclass(eq=False)
class MixedVI:
    """The discrete mixed VI  A u + Bᵀλ = f, λ ∈ Λ, (Bu − gap)ᵀ(μ − λ) ≤ 0 ∀ μ ∈ Λ.

    Parameters
    ----------
    A : (n, n) sparse, A + Aᵀ positive definite (not necessarily symmetric).
    B : (m, n) sparse, full row rank (discrete inf-sup), m = Lambda.size.
    f : (n,) right-hand side.
    Lambda : the convex set, e.g. ``product(Free(k), Box(-g, g))``; rows of B follow its blocks.
    gap : (m,) optional offset of the constraint (default 0, the paper's Problem 3.1).
    X, Y : optional Gram matrices of the norms of X (n × n) and Y (m × m) for `constants`, or
        functions returning them (assembled when `constants` asks: a model need not hold an
        n × n matrix through its solve).
    info : free-form metadata of the plug-in (names of fields, dof counts, …).
    fields : optional {name: indices or boolean mask (n,)} of the unknowns' fields, in the order
        a block-triangular preconditioner takes them (e.g. displacement, then potential);
        used by the iterative linear path (`vi_core.krylov`).
    near_null : optional {field name: (k, d) array} near-null space of that field's block of A,
        rows in the field's order (e.g. the rigid-body modes of the displacement block).
    partition : optional row partition of A over processes (`vi_core.engine.row_partition`: an
        object with ``owned(n) -> (lo, hi)`` and the reductions ``gatherv``, ``all_true``,
        ``norm``); A is then (hi − lo, n), this process's rows [lo, hi) of the whole A, and
        what reads A does so by owned rows and reductions (the checks, `scaling`, `residual`,
        `matvec`, `equilibrated_rows`); B, f, gap, Λ are whole on every process. What needs
        the whole A (`equilibrated`, `A0`, `C`, `structure`: the serial solvers) refuses.
        None: A whole, (n, n).
    """

    A: Any
    B: Any
    f: Any
    Lambda: ConvexSet
    gap: Any = None
    X: Any = None
    Y: Any = None
    info: dict = field(default_factory=dict)
    fields: dict | None = None
    near_null: dict | None = None
    partition: Any = None

    def __post_init__(self):
        self.A = sp.csr_matrix(self.A, dtype=float)
        if self.partition is None:
            n = self.A.shape[0]
            if self.A.shape != (n, n):
                raise ValueError(f"A must be square, got shape {self.A.shape}")
        else:
            n = self.A.shape[1]
            lo, hi = self.partition.owned(n)
            if self.A.shape != (hi - lo, n):
                raise ValueError(
                    f"A must hold the rows [{lo}, {hi}) of an {n}×{n} matrix under its "
                    f"partition, got shape {self.A.shape}"
                )
        self.B = sp.csr_matrix(self.B, dtype=float)
        if self.B.shape[1] != n:
            raise ValueError(f"B must have {n} columns (A is {n}×{n}), got shape {self.B.shape}")
        if not isinstance(self.Lambda, ConvexSet):
            raise TypeError("Lambda must be a ConvexSet (Box, Ball, Free, NonNegative, product)")
        self.Lambda = as_product(self.Lambda)
        m = self.B.shape[0]
        if self.Lambda.size != m:
            raise ValueError(f"Lambda has {self.Lambda.size} coordinates but B has {m} rows")
        self.f = np.asarray(self.f, dtype=float).ravel()
        if self.f.shape != (n,):
            raise ValueError(f"f must have {n} entries, got {self.f.size}")
        self.gap = np.zeros(m) if self.gap is None else np.asarray(self.gap, float).ravel()
        if self.gap.shape != (m,):
            raise ValueError(f"gap must have {m} entries, got {self.gap.size}")
        finite = np.isfinite(self.A.data).all()
        if not (finite if self.partition is None else self.partition.all_true(finite)):
            raise ValueError("A contains NaN or inf")
        if not np.isfinite(self.B.data).all():
            raise ValueError("B contains NaN or inf")
        for name in ("f", "gap"):
            if not np.isfinite(getattr(self, name)).all():
                raise ValueError(f"{name} contains NaN or inf")
        self._check_fields(n)
        d = self._diagonal()  # (hi − lo,) the owned rows'
        bad = np.flatnonzero(d <= 0)[:1]  # the first nonpositive one here, if any
        lo = self.row_range[0]
        where, value = lo + bad.astype(np.int64), d[bad]  # (0,) or (1,)
        if self.partition is not None:  # every process: the first over all of them
            where, value = self.partition.gatherv(where), self.partition.gatherv(value)
        if where.size:
            i = int(where[0])
            raise ValueError(
                f"A must have a positive diagonal (A + Aᵀ > 0); A[{i},{i}] = {value[0]}"
            )

    def _check_fields(self, n: int) -> None:
        """fields as boolean masks (n,), disjoint; near_null rows = the field's size."""
        if self.fields is None:
            if self.near_null:
                raise ValueError("near_null needs fields (which unknowns each block holds)")
            return
        masks, seen = {}, np.zeros(n, dtype=bool)
        for name, sel in self.fields.items():
            mask = np.zeros(n, dtype=bool)
            mask[np.asarray(sel)] = True
            if (mask & seen).any():
                raise ValueError(f"field {name!r} overlaps an earlier field")
            seen |= mask
            masks[name] = mask
        self.fields = masks
        near = {}
        for name, N in (self.near_null or {}).items():
            k = int(masks[name].sum()) if name in masks else None
            N = np.asarray(N, dtype=float)
            if k is None or N.ndim != 2 or N.shape[0] != k or not np.isfinite(N).all():
                raise ValueError(
                    f"near_null[{name!r}] must be a finite ({k}, d) array for field {name!r}"
                )
            near[name] = N
        self.near_null = near or None

    @property
    def n(self) -> int:
        return self.A.shape[1]

    @property
    def row_range(self) -> tuple[int, int]:
        """[lo, hi): the rows of the whole A this process holds (all of them without a
        partition)."""
        return (0, self.n) if self.partition is None else self.partition.owned(self.n)

    def _diagonal(self) -> np.ndarray:
        """(hi − lo,) the diagonal entries of the rows held here."""
        return self.A.diagonal(k=self.row_range[0])

    def _whole_A(self) -> sp.csr_matrix:
        """A, which must be whole (ValueError under a partition: a serial reader)."""
        if self.partition is not None:
            lo, hi = self.row_range
            raise ValueError(
                f"this MixedVI holds the rows [{lo}, {hi}) of A only (a row partition): "
                "a reader of the whole A (the serial solvers, equilibrated, structure) cannot "
                "run on it"
            )
        return self.A

    def matvec(self, u: np.ndarray) -> np.ndarray:
        """A u (n,), whole on every process: under a partition each process's rows' product,
        gathered (every entry bit for bit the whole A's product's; a collective), and kept
        with u: asked again at the same u (the answer, by the post-processing that one
        process runs alone after the solve: the engine gathers A u at its answer on every
        process, `vi_core.petsc.solve_ssn_petsc`) it is returned with no communication."""
        u = np.asarray(u, dtype=float)
        if self.partition is None:
            return self.A @ u
        kept = self.__dict__.get("_product")
        if kept is not None and np.array_equal(kept[0], u):
            return kept[1].copy()
        Au = self.partition.gatherv(self.A @ u)  # (n,)
        self._product = (u.copy(), Au)
        return Au.copy()

    def rows_of(self, M: Any) -> Any:
        """The rows [lo, hi) held here (`row_range`) of M, an (n, ·) matrix or vector in A's
        row numbering (M itself without a partition): to add to A, e.g. A + rows_of(Gᵀ D G)."""
        if self.partition is None:
            return M
        lo, hi = self.row_range
        return M[lo:hi]

    @property
    def m(self) -> int:
        return self.B.shape[0]

    @cached_property
    def A0(self) -> sp.csr_matrix:
        """Symmetric part (A + Aᵀ)/2."""
        A = self._whole_A()
        return ((A + A.T) * 0.5).tocsr()

    @cached_property
    def C(self) -> sp.csr_matrix:
        """Skew part (A − Aᵀ)/2."""
        A = self._whole_A()
        C = ((A - A.T) * 0.5).tocsr()
        C.eliminate_zeros()
        return C

    @cached_property
    def structure(self) -> str:
        """'symmetric', 'skew-coupled' or 'general' (see `skew_split`)."""
        C = self.C
        scale = max(abs(self.A).max(), 1e-300) if self.A.nnz else 1.0
        if C.nnz == 0 or abs(C).max() <= 1e-14 * scale:
            return "symmetric"
        return "skew-coupled" if self.skew_split is not None else "general"

    @cached_property
    def skew_split(self) -> np.ndarray | None:
        """Mask `first` with A = [[K, Gᵀ], [−G, P]] in the split (first, ~first), K and P
        symmetric, and B acting on the first block only; None if A has no such structure."""
        n = self.n
        A0 = self.A0.tocoo()
        C = self.C.tocoo()
        tol = 1e-13 * max(abs(self.A).max(), 1e-300)
        keep0 = np.abs(A0.data) > tol
        keepc = np.abs(C.data) > tol
        g0 = sp.csr_matrix((np.ones(keep0.sum()), (A0.row[keep0], A0.col[keep0])), shape=(n, n))
        ncomp, label = connected_components(g0, directed=False)
        # C edges must join different components, and the component graph must be 2-colourable
        ci, cj = label[C.row[keepc]], label[C.col[keepc]]
        if (ci == cj).any():
            return None
        q = sp.csr_matrix((np.ones(ci.size), (ci, cj)), shape=(ncomp, ncomp))
        colour = -np.ones(ncomp, dtype=int)
        indptr, indices = q.indptr, q.indices
        for start in range(ncomp):
            if colour[start] >= 0:
                continue
            colour[start] = 0
            stack = [start]
            while stack:
                a = stack.pop()
                for b in indices[indptr[a] : indptr[a + 1]]:
                    if colour[b] < 0:
                        colour[b] = 1 - colour[a]
                        stack.append(b)
                    elif colour[b] == colour[a]:
                        return None
        first = colour[label] == 0
        cols = np.unique(self.B.tocoo().col)
        if cols.size and not first[cols].all():
            if (~first)[cols].all():
                first = ~first
            else:
                return None
        return first

    # ----------------------------------------------------------------- scaling
    @cached_property
    def scaling(self) -> Scaling:
        """Jacobi equilibration: s_u = diag(A)^{-1/2}; s_lam makes the rows of B' unit.

        The equilibrated problem is invariant under a change of units of any field (up to
        rounding), which makes every solver unit-invariant.
        """
        s_u = 1.0 / np.sqrt(self._diagonal())  # (hi − lo,) the rows held here
        if self.partition is not None:
            s_u = self.partition.gatherv(s_u)  # (n,)
        Bs = self.B @ sp.diags(s_u)
        row = np.sqrt(np.asarray(Bs.multiply(Bs).sum(axis=1)).ravel())  # (m,)
        row[row == 0] = 1.0
        s_lam = 1.0 / row
        # balls must be scaled uniformly: use the block mean
        sizes = self.Lambda.block_sizes()
        if (sizes > 1).any():
            starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
            means = np.add.reduceat(s_lam, starts) / sizes
            s_lam = np.repeat(means, sizes)
        return Scaling(s_u=s_u, s_lam=s_lam)

    @cached_property
    def equilibrated(self) -> MixedVI:
        """The same VI in variables u' = u / s_u, λ' = λ / s_lam (unit diagonal, unit rows)."""
        return MixedVI(A=self._scaled_A(), **self.equilibrated_parts())

    def equilibrated_parts(self) -> dict:
        """Everything of `equilibrated` but its A (B, f, Lambda, gap, info, fields, near_null;
        interface- and vector-sized), for a solver that reads A' by rows (`equilibrated_rows`)
        and so never holds a whole-size copy of A's values."""
        s = self.scaling
        Su, Sl = sp.diags(s.s_u), sp.diags(s.s_lam)
        # A u + Bᵀλ = f  →  (Su A Su) u' + (Su Bᵀ Sl) λ' = Su f
        # (Bu − gap) ∈ N_Λ(λ)  ⇔  Sl (B Su u' − gap) ∈ N_{Λ/s_lam}(λ')   (Sl diagonal > 0)
        return dict(
            B=(Sl @ self.B @ Su).tocsr(),
            f=self.f * s.s_u,
            Lambda=self.Lambda.scaled(s.s_lam),
            gap=self.gap * s.s_lam,
            info={"equilibrated": True},
            fields=self.fields,
            # u = Su u': a near-null vector z of A is Su^{-1} z for the equilibrated A'
            near_null={
                k: N / s.s_u[self.fields[k]][:, None] for k, N in (self.near_null or {}).items()
            }
            or None,
        )

    def equilibrated_rows(self, rows: np.ndarray) -> sp.csr_matrix:
        """(r, n) the rows `rows` (r,) of `equilibrated`.A, the same values, built from those
        rows of A alone (a distributed solver's owned rows: no whole-size copy); under a
        partition `rows` must be held here (`row_range`)."""
        A, s_u = self._canonical_A(), self.scaling.s_u
        rows = np.asarray(rows, dtype=np.intp)
        lo, hi = self.row_range
        if rows.size and (rows.min() < lo or rows.max() >= hi):
            raise ValueError(f"equilibrated_rows: rows outside [{lo}, {hi}), the rows held here")
        Ar = A[rows - lo]  # (r, n) a canonical copy of the rows
        data = np.repeat(s_u[rows], np.diff(Ar.indptr))  # (nnz_r,) s_i of each entry's row
        data *= Ar.data
        data *= s_u[Ar.indices]
        Ar.data = data
        return Ar

    def _canonical_A(self) -> sp.csr_matrix:
        """A in canonical form (sorted, no duplicates) without explicit zeros: A itself, or a
        canonical copy (the same matrix; the caller's arrays untouched) that replaces it, so no
        later operation reorders indices shared with a scaled copy."""
        A = self.A
        if not A.has_canonical_format or not A.data.all():
            A = self.A = A.copy()
            A.sum_duplicates()
            A.eliminate_zeros()
        return A

    def _scaled_A(self) -> sp.csr_matrix:
        """Su A Su on A's own index arrays (shared, not copied: a third of a copy of A less;
        paper scene level 5: 34 MB), A canonical first (`_canonical_A`), so e.A has the
        structure of the product Su A Su (which drops zeros: a direct solver's ordering follows
        the structure)."""
        self._whole_A()
        A, s_u = self._canonical_A(), self.scaling.s_u
        data = np.repeat(s_u, np.diff(A.indptr))  # (nnz,) s_i of each entry's row
        data *= A.data
        data *= s_u[A.indices]
        return sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)

    # ---------------------------------------------------------------- residual
    def residual(self, u: np.ndarray, lam: np.ndarray) -> Residual:
        """Natural-map residual of (u, λ) in equilibrated variables (see `Residual`); under a
        partition from the rows held here, r1's norm a reduction (`owned_residual`)."""
        up, lp = self.scaling.to_scaled(np.asarray(u, float), np.asarray(lam, float))
        if self.partition is None:
            return natural_residual(self.equilibrated, up, lp)
        return owned_residual(self, up, lp)

    def with_rhs(self, f: np.ndarray | None = None, gap: np.ndarray | None = None) -> MixedVI:
        """A copy with another right-hand side (same A, B, Λ)."""
        return MixedVI(
            A=self.A,
            B=self.B,
            f=self.f if f is None else f,
            Lambda=self.Lambda,
            gap=self.gap if gap is None else gap,
            X=self.X,
            Y=self.Y,
            info=dict(self.info),
            fields=self.fields,
            near_null=self.near_null,
            partition=self.partition,
        )

    def __repr__(self):
        kind = self.structure if self.partition is None else "rows [{}, {})".format(*self.row_range)
        return f"MixedVI(n={self.n}, m={self.m}, Lambda={self.Lambda!r}, {kind})"


def natural_residual(vi: MixedVI, u: np.ndarray, lam: np.ndarray, c: float = 1.0) -> Residual:
    """Natural-map residual of (u, λ) for `vi` as given (no equilibration; see `Residual`)."""
    r1 = vi.A @ u + vi.B.T @ lam - vi.f
    r2 = lam - vi.Lambda.project(lam + c * (vi.B @ u - vi.gap))
    scale = max(float(np.linalg.norm(vi.f)), float(np.linalg.norm(vi.gap))) or 1.0
    n1, n2 = float(np.linalg.norm(r1)), float(np.linalg.norm(r2))
    return Residual(n1, n2, scale, float(np.hypot(n1, n2) / scale))


def owned_residual(vi: MixedVI, u: np.ndarray, lam: np.ndarray) -> Residual:
    """`natural_residual` of vi's equilibrated problem at (u', λ') (equilibrated, (n,), (m,)),
    vi's A held by rows (`MixedVI.partition`): r1's rows [lo, hi) from A's rows held here,
    A' u' = s_u ⊙ (A (s_u ⊙ u')) (the equilibrated A' never formed), its norm a reduction over
    the processes; r2, f' and gap' whole on each."""
    s_u, part = vi.scaling.s_u, vi.partition
    lo, hi = vi.row_range
    e = vi.equilibrated_parts()
    r1 = s_u[lo:hi] * (vi.A @ (s_u * u)) + (e["B"].T @ lam)[lo:hi] - e["f"][lo:hi]  # (hi − lo,)
    r2 = lam - e["Lambda"].project(lam + (e["B"] @ u - e["gap"]))  # (m,)
    scale = max(float(np.linalg.norm(e["f"])), float(np.linalg.norm(e["gap"]))) or 1.0
    n1, n2 = part.norm(r1), float(np.linalg.norm(r2))
    return Residual(n1, n2, scale, float(np.hypot(n1, n2) / scale))
