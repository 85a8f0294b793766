"""An independent check of a candidate (u, λ) of a mixed VI: its KKT (natural-map) residual.

This module shares no code with the solvers (ssn, conic, homotopy) nor with `MixedVI.residual`,
`natural_residual`, `MixedVI.scaling` or `ConvexSet.project`: it reads only the assembled blocks
A, B, f, gap and the *data* of Λ (block kind and size, Box lo/hi, Ball radius/dim) and computes

- its own equilibration: s_u = |diag A|^{-1/2}, s_λ = 1 / (row norms of B diag(s_u)), averaged
  over each ball (the same definition as the solvers', written again);
- its own projection per set kind (Free: identity, NonNegative: max(y, 0), Box: min(max(y, lo),
  hi), Ball: radial scaling);
- the natural map F(u', λ') = [A'u' + B'ᵀλ' − f' ; λ' − P_Λ'(λ' + B'u' − gap')] in equilibrated
  variables, reported relative to max(‖f'‖, ‖gap'‖) (`KKT.relative`, comparable with
  `Solution.residual`), and the complementarity identity λᵀz = σ_Λ(z), z = Bu − gap
  (`KKT.complementarity`: the discrete Lemma 4.2 for Tresca rows, σ the support function);
- an estimate of ‖J⁻¹‖₁ for the generalised Jacobian J of F at a point (`inverse_norm`), and
  from it the difference two approximate solutions may have (`compare`, formula there).

A fault in a solver, in `natural_residual` or in a set's `project` therefore cannot hide from
this check, whereas a fault in the assembled blocks reaches it as it reaches every solver (those
are caught by exact solutions, patch tests and balances: README "What catches which fault").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

SAFETY = 10.0  # `compare`: allowance for the 1-norm estimate and for changes of active piece


@dataclass(frozen=True)
class Block:
    """One elementary block of Λ as data: kind, coordinate range and parameters."""

    kind: str  # "free", "nonnegative", "box", "ball"
    start: int
    stop: int
    lo: np.ndarray | None = None  # box (k,)
    hi: np.ndarray | None = None  # box (k,)
    radius: np.ndarray | None = None  # ball (k_balls,)
    dim: int = 1  # ball dimension


def blocks_of(Lambda: Any) -> list[Block]:
    """Read the data of Λ's elementary blocks (by class name and attributes only)."""
    out, start = [], 0
    parts = Lambda.blocks() if hasattr(Lambda, "blocks") else [Lambda]
    for b in parts:
        kind = type(b).__name__.lower()
        size = int(b.size)
        if size == 0:
            continue
        if kind == "box":
            lo = np.broadcast_to(np.asarray(b.lo, float), (size,)).copy()
            hi = np.broadcast_to(np.asarray(b.hi, float), (size,)).copy()
            out.append(Block("box", start, start + size, lo=lo, hi=hi))
        elif kind == "ball":
            r = np.asarray(b.radius, float).ravel()
            out.append(Block("ball", start, start + size, radius=r, dim=int(b.dim)))
        elif kind in ("free", "nonnegative"):
            out.append(Block(kind, start, start + size))
        else:
            raise TypeError(f"the KKT checker does not know the set {b!r}")
        start += size
    return out


def _scales(A: sp.csr_matrix, B: sp.csr_matrix, blocks: list[Block]):
    """(s_u (n,), s_λ (m,)) of the equilibration described in the module docstring."""
    d = np.abs(A.diagonal())
    s_u = 1.0 / np.sqrt(d)
    Bs = B.tocoo()
    vals = Bs.data * s_u[Bs.col]
    row = np.sqrt(np.bincount(Bs.row, weights=vals * vals, minlength=B.shape[0]))  # (m,)
    s_lam = np.where(row > 0, 1.0 / np.where(row > 0, row, 1.0), 1.0)
    for blk in blocks:
        if blk.kind == "ball":
            seg = s_lam[blk.start : blk.stop].reshape(-1, blk.dim)  # (k, dim)
            s_lam[blk.start : blk.stop] = np.repeat(seg.mean(axis=1), blk.dim)
    return s_u, s_lam


def _project(blocks: list[Block], y: np.ndarray, s_lam: np.ndarray) -> np.ndarray:
    """Projection onto Λ' = Λ / s_λ (the equilibrated set), block by block."""
    p = y.copy()
    for blk in blocks:
        sl = slice(blk.start, blk.stop)
        yb, t = y[sl], s_lam[sl]
        if blk.kind == "nonnegative":
            p[sl] = np.where(yb > 0.0, yb, 0.0)
        elif blk.kind == "box":
            lo, hi = blk.lo / t, blk.hi / t
            p[sl] = np.where(yb < lo, lo, np.where(yb > hi, hi, yb))
        elif blk.kind == "ball":
            Y = yb.reshape(-1, blk.dim)  # (k, dim)
            r = blk.radius / t.reshape(-1, blk.dim)[:, 0]  # (k,)
            nrm = np.sqrt((Y * Y).sum(axis=1))  # (k,)
            fac = np.where(nrm > r, r / np.where(nrm > 0, nrm, 1.0), 1.0)
            p[sl] = (Y * fac[:, None]).ravel()
    return p


def _support(blocks: list[Block], z: np.ndarray, s_lam: np.ndarray) -> tuple[float, float]:
    """σ_Λ'(z) of the equilibrated set Λ' = Λ / s_λ over Box and Ball blocks, and the distance
    of z from dom σ (Free: z = 0, NonNegative: z ≤ 0)."""
    sigma, off = 0.0, 0.0
    for blk in blocks:
        zb, t = z[blk.start : blk.stop], s_lam[blk.start : blk.stop]
        if blk.kind == "box":
            sigma += float(np.sum(np.maximum(blk.lo / t * zb, blk.hi / t * zb)))
        elif blk.kind == "ball":
            Z = zb.reshape(-1, blk.dim)
            r = blk.radius / t.reshape(-1, blk.dim)[:, 0]
            sigma += float(r @ np.sqrt((Z * Z).sum(axis=1)))
        elif blk.kind == "free":
            off += float(zb @ zb)
        else:
            pos = np.maximum(zb, 0.0)
            off += float(pos @ pos)
    return sigma, float(np.sqrt(off))


@dataclass(frozen=True)
class KKT:
    """The checker's verdict on one candidate (u, λ).

    relative : ‖F‖₂ / max(‖f'‖₂, ‖gap'‖₂) (natural map, equilibrated; like `Solution.residual`).
    absolute : ‖F‖₂ in equilibrated variables (used by `compare`).
    equilibrium, projection : ‖A'u' + B'ᵀλ' − f'‖₂ and ‖λ' − P_Λ'(λ' + B'u' − gap')‖₂.
    feasibility : max |λ' − P_Λ'(λ')| (λ ∈ Λ up to this), relative to max(‖λ'‖_∞, tiny).
    complementarity : (|λ'ᵀz' − σ_Λ'(z')| / ‖λ'‖ + dist(z', dom σ_Λ')) / max(‖z'‖, ‖u'‖, ‖gap'‖)
        with z' = B'u' − gap': the identity λᵀ(Bu − gap) = σ_Λ(Bu − gap) (Lemma 4.2 for
        Tresca rows; dom σ: z = 0 on Free rows, z ≤ 0 on NonNegative rows), zero exactly at a
        solution, measured against the natural size of z' (rows of B' have unit norm).
    """

    relative: float
    absolute: float
    equilibrium: float
    projection: float
    feasibility: float
    complementarity: float


class Checker:
    """Independent KKT residuals for one assembled problem (A, B, f, gap, Λ).

    Accepts a `MixedVI` (only its fields A, B, f, gap, Lambda are read) or the blocks.
    """

    def __init__(self, A, B, f, Lambda, gap=None):
        self.A = sp.csr_matrix(A, dtype=float)
        self.B = sp.csr_matrix(B, dtype=float)
        self.f = np.asarray(f, float).ravel()
        m = self.B.shape[0]
        self.gap = np.zeros(m) if gap is None else np.asarray(gap, float).ravel()
        self.blocks = blocks_of(Lambda)
        self.s_u, self.s_lam = _scales(self.A, self.B, self.blocks)
        Su, Sl = sp.diags(self.s_u), sp.diags(self.s_lam)
        self.Ae = (Su @ self.A @ Su).tocsr()  # (n, n)
        self.Be = (Sl @ self.B @ Su).tocsr()  # (m, n)
        self.fe = self.f * self.s_u
        self.ge = self.gap * self.s_lam
        self.scale = max(float(np.linalg.norm(self.fe)), float(np.linalg.norm(self.ge))) or 1.0

    @classmethod
    def of(cls, vi: Any) -> Checker:
        """The checker of a `MixedVI` (reads A, B, f, gap, Lambda only)."""
        return cls(vi.A, vi.B, vi.f, vi.Lambda, vi.gap)

    def scaled(self, u: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u', λ') = (u / s_u, λ / s_λ): the variables in which residuals are measured."""
        return np.asarray(u, float) / self.s_u, np.asarray(lam, float) / self.s_lam

    def __call__(self, u: np.ndarray, lam: np.ndarray) -> KKT:
        """The KKT verdict on (u, λ) given in the caller's (physical) variables."""
        up, lp = self.scaled(u, lam)
        r1 = self.Ae @ up + self.Be.T @ lp - self.fe
        r2 = lp - _project(self.blocks, lp + self.Be @ up - self.ge, self.s_lam)
        n1, n2 = float(np.linalg.norm(r1)), float(np.linalg.norm(r2))
        absolute = float(np.hypot(n1, n2))
        feas = lp - _project(self.blocks, lp, self.s_lam)
        lmax = max(float(np.max(np.abs(lp), initial=0.0)), 1e-300)
        feasibility = float(np.max(np.abs(feas), initial=0.0)) / lmax
        z = self.Be @ up - self.ge  # (m,) equilibrated: λ'ᵀz' = λᵀ(Bu − gap)
        sigma, off = _support(self.blocks, z, self.s_lam)
        size = max(
            float(np.linalg.norm(z)), float(np.linalg.norm(up)), float(np.linalg.norm(self.ge))
        )
        size = size or 1.0
        nl = float(np.linalg.norm(lp)) or 1.0
        comp = abs(float(lp @ z) - sigma) / (nl * size) + off / size
        return KKT(absolute / self.scale, absolute, n1, n2, feasibility, comp)

    def jacobian(self, u: np.ndarray, lam: np.ndarray) -> sp.csr_matrix:
        """An element J of the generalised Jacobian of F at (u, λ), equilibrated variables:
        [[A', B'ᵀ], [−P B', I − P]] with P ∈ ∂P_Λ'(λ' + B'u' − gap')."""
        up, lp = self.scaled(u, lam)
        y = lp + self.Be @ up - self.ge
        mats = []
        for blk in self.blocks:
            sl = slice(blk.start, blk.stop)
            yb, t = y[sl], self.s_lam[sl]
            if blk.kind == "free":
                mats.append(sp.identity(yb.size))
            elif blk.kind == "nonnegative":
                mats.append(sp.diags((yb > 0).astype(float)))
            elif blk.kind == "box":
                inside = (yb > blk.lo / t) & (yb < blk.hi / t)
                mats.append(sp.diags(inside.astype(float)))
            else:
                d = blk.dim
                Y = yb.reshape(-1, d)
                r = blk.radius / t.reshape(-1, d)[:, 0]
                nrm = np.sqrt((Y * Y).sum(axis=1))
                cells = []
                for yk, nk, rk in zip(Y, nrm, r, strict=True):
                    if nk <= rk:
                        cells.append(np.eye(d))
                    else:
                        yh = yk / nk
                        cells.append((rk / nk) * (np.eye(d) - np.outer(yh, yh)))
                mats.append(sp.block_diag(cells))
        m = self.Be.shape[0]
        P = sp.block_diag(mats, format="csr") if mats else sp.csr_matrix((0, 0))
        return sp.bmat([[self.Ae, self.Be.T], [-(P @ self.Be), sp.identity(m) - P]], format="csc")

    def inverse_norm(self, u: np.ndarray, lam: np.ndarray) -> float:
        """Estimate of ‖J⁻¹‖₁ at (u, λ) (SuperLU + Hager–Higham `onenormest`); inf if singular."""
        J = self.jacobian(u, lam)
        try:
            lu = spla.splu(J)
        except RuntimeError:
            return float("inf")
        N = J.shape[0]
        op = spla.LinearOperator(
            (N, N),
            matvec=lambda b: lu.solve(np.asarray(b, float)),
            rmatvec=lambda b: lu.solve(np.asarray(b, float), trans="T"),
            dtype=float,
        )
        return float(spla.onenormest(op))

    def compare(self, a: tuple, b: tuple, inverse_norm: float) -> dict[str, float]:
        """Relative differences of two candidates a = (u_a, λ_a), b = (u_b, λ_b) and the
        difference `allowed` by their residuals:

            diff_u = ‖u'_a − u'_b‖ / ‖u'_b‖,   diff_lam = ‖λ'_a − λ'_b‖ / ‖λ'_b‖   (equilibrated),
            allowed = SAFETY · κ · (‖F(a)‖ + ‖F(b)‖) / min(‖u'_b‖, ‖λ'_b‖),

        κ = est‖J⁻¹‖₁ at a solution (`inverse_norm`). F is piecewise affine, so within one
        active piece a − b = J⁻¹(F(a) − F(b)) and ‖a − b‖ ≤ ‖J⁻¹‖(‖F(a)‖ + ‖F(b)‖); SAFETY = 10
        covers the 1-norm estimate standing in for the 2-norm and a change of piece between
        two nearby points. Norms that vanish (no multipliers) are left out of the minimum.
        """
        ua, la = self.scaled(*a)
        ub, lb = self.scaled(*b)
        nu, nl = float(np.linalg.norm(ub)), float(np.linalg.norm(lb))
        du = float(np.linalg.norm(ua - ub)) / nu if nu > 0 else float(np.linalg.norm(ua))
        dl = float(np.linalg.norm(la - lb)) / nl if nl > 0 else float(np.linalg.norm(la))
        size = min([x for x in (nu, nl) if x > 0], default=1.0)
        fa, fb = self(*a).absolute, self(*b).absolute
        allowed = SAFETY * inverse_norm * (fa + fb) / size
        return {"diff_u": du, "diff_lam": dl, "allowed": float(allowed)}
