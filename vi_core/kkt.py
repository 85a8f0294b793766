"""An independent check of a candidate (u, λ) of a mixed VI: its KKT (natural-map) residual.

This module shares no code with the solvers (ssn, conic, homotopy) nor with `MixedVI.residual`,
`natural_residual`, `MixedVI.scaling` or `ConvexSet.project`: it reads only the assembled blocks
A, B, f, gap and the *data* of Λ (block kind and size, Box lo/hi, Ball radius/dim) and computes

- its own equilibration: s_u = |diag A|^{-1/2}, s_λ = 1 / (row norms of B diag(s_u)), averaged
  over each ball (the same definition as the solvers', written again);
- its own projection per set kind (Free: identity, NonNegative: max(y, 0), Box: min(max(y, lo),
  hi), Ball: radial scaling; contact blocks (`Coulomb`, `UnilateralTresca`): max(y_n, 0) and the
  disc of radius ρ(λ) = F·max(λ_n, 0), g·[λ_n > 0] or g, **taken at λ** — the quasi-variational
  natural map itself, not the solvers' combined map, whose radius is taken at y);
- the natural map F(u', λ') = [A'u' + B'ᵀλ' − f' ; λ' − P_Λ'(λ' + B'u' − gap')] in equilibrated
  variables, reported relative to max(‖f'‖, ‖gap'‖) (`KKT.relative`, comparable with
  `Solution.residual`), and the complementarity identity λᵀz = σ_Λ(z), z = Bu − gap
  (`KKT.complementarity`: the discrete Lemma 4.2 for Tresca rows, σ the support function; for a
  contact block σ(z) = ρ(λ)|z_t| on z_n ≤ 0);
- for contact blocks, each condition on its own (`Checker.contact`, `ContactKKT`): λ_n ≥ 0,
  gap ≥ 0, λ_n·gap = 0, |λ_t| ≤ ρ(λ), stick/slip alignment, and the stick/slip/open counts;
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
OPEN = (
    1e-10  # a contact node with λ'_n ≤ OPEN · (largest λ'_n) is apart (counts, contact-only Tresca)
)


@dataclass(frozen=True)
class Block:
    """One elementary block of Λ as data: kind, coordinate range and parameters."""

    kind: str  # "free", "nonnegative", "box", "ball", "contact"
    start: int
    stop: int
    lo: np.ndarray | None = None  # box (k,)
    hi: np.ndarray | None = None  # box (k,)
    radius: np.ndarray | None = None  # ball (k_balls,)
    dim: int = 1  # ball dimension; contact: node dimension
    friction: np.ndarray | None = None  # contact (k_nodes,): F (law "coulomb") or g
    law: str = ""  # contact: "coulomb", "tresca" (g everywhere), "tresca_contact" (where λ_n > 0)


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
        elif kind == "coulomb":
            F = np.asarray(b.F, float).ravel()
            out.append(Block("contact", start, start + size, dim=int(b.dim), friction=F, law=kind))
        elif kind == "unilateraltresca":
            law = "tresca_contact" if b.contact_only else "tresca"
            g = np.asarray(b.g, float).ravel()
            out.append(Block("contact", start, start + size, dim=int(b.dim), friction=g, law=law))
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
        if blk.kind in ("ball", "contact"):
            seg = s_lam[blk.start : blk.stop].reshape(-1, blk.dim)  # (k, dim)
            s_lam[blk.start : blk.stop] = np.repeat(seg.mean(axis=1), blk.dim)
    return s_u, s_lam


def _radius(blk: Block, lam_n: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Friction radius (k,) of a contact block at the equilibrated normal multipliers λ'_n
    (t: the node scales s_λ): F·max(λ'_n, 0), g/t·[touching] or g/t. Contact-only Tresca
    counts a node as touching where λ'_n > OPEN · (the block's largest λ'_n): its radius jumps
    from 0 to g there, and a solver's rounding-level λ_n at a node that is apart (measured:
    1e-15 of the largest pressure) must not switch the bound on."""
    if blk.law == "coulomb":
        return blk.friction * np.where(lam_n > 0, lam_n, 0.0)
    g = blk.friction / t
    if blk.law != "tresca_contact":
        return g
    return np.where(lam_n > OPEN * max(float(lam_n.max(initial=0.0)), 0.0), g, 0.0)


def _project(blocks: list[Block], y: np.ndarray, s_lam: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Projection onto Λ' = Λ / s_λ (the equilibrated set), block by block; a contact block
    projects onto R₊ × disc(ρ(λ')) with the radius at the multiplier `lam` (equilibrated)."""
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
        elif blk.kind == "contact":
            Y = yb.reshape(-1, blk.dim)  # (k, dim): [y_n, y_t]
            r = _radius(blk, lam[sl].reshape(-1, blk.dim)[:, 0], t.reshape(-1, blk.dim)[:, 0])
            nrm = np.sqrt((Y[:, 1:] ** 2).sum(axis=1))  # (k,) |y_t|
            fac = np.where(nrm > r, r / np.where(nrm > 0, nrm, 1.0), 1.0)
            P = np.empty_like(Y)
            P[:, 0] = np.where(Y[:, 0] > 0, Y[:, 0], 0.0)
            P[:, 1:] = Y[:, 1:] * fac[:, None]
            p[sl] = P.ravel()
    return p


def _support(
    blocks: list[Block], z: np.ndarray, s_lam: np.ndarray, lam: np.ndarray
) -> tuple[float, float]:
    """σ_Λ'(z) of the equilibrated set Λ' = Λ / s_λ over Box, Ball and contact blocks (radius
    at the multiplier `lam`), and the distance of z from dom σ (Free: z = 0, NonNegative and
    the normal rows of contact blocks: z ≤ 0)."""
    sigma, off = 0.0, 0.0
    for blk in blocks:
        sl = slice(blk.start, blk.stop)
        zb, t = z[sl], s_lam[sl]
        if blk.kind == "box":
            sigma += float(np.sum(np.maximum(blk.lo / t * zb, blk.hi / t * zb)))
        elif blk.kind == "ball":
            Z = zb.reshape(-1, blk.dim)
            r = blk.radius / t.reshape(-1, blk.dim)[:, 0]
            sigma += float(r @ np.sqrt((Z * Z).sum(axis=1)))
        elif blk.kind == "contact":
            Z = zb.reshape(-1, blk.dim)
            r = _radius(blk, lam[sl].reshape(-1, blk.dim)[:, 0], t.reshape(-1, blk.dim)[:, 0])
            sigma += float(r @ np.sqrt((Z[:, 1:] ** 2).sum(axis=1)))
            pos = np.maximum(Z[:, 0], 0.0)
            off += float(pos @ pos)
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


@dataclass(frozen=True)
class ContactKKT:
    """The conditions of the contact blocks, each on its own (equilibrated variables; maxima over
    the nodes). With z = B'u' − gap' per node [z_n, z_t], ρ the friction radius at λ,
    L = max(‖λ'‖_∞, tiny) and Z = max(‖z'‖_∞, ‖u'‖_∞, ‖gap'‖_∞):

    normal_sign : max(−λ_n, 0) / L                         (λ_n ≥ 0)
    penetration : max(z_n, 0) / Z                          (gap − (Bu)_n ≥ 0)
    normal_complementarity : |λ_n z_n| / (L Z)             (λ_n·gap = 0)
    cone : max(|λ_t| − ρ, 0) / L                           (|λ_t| ≤ F λ_n, or g)
    alignment : (|λ_t||z_t| − λ_t·z_t + max(ρ − |λ_t|, 0)|z_t|) / (L Z): zero iff the node
        sticks (z_t = 0) or slips along λ_t (z_t = a λ_t, a ≥ 0) with |λ_t| = ρ.
    open, stick, slip : node counts: open λ_n ≤ 1e-10 L; else slip if |z_t| > 1e-8 Z, else stick.
    """

    normal_sign: float
    penetration: float
    normal_complementarity: float
    cone: float
    alignment: float
    open: int
    stick: int
    slip: int

    @property
    def worst(self) -> float:
        """The largest of the five condition measures."""
        return max(
            self.normal_sign,
            self.penetration,
            self.normal_complementarity,
            self.cone,
            self.alignment,
        )


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
        r2 = lp - _project(self.blocks, lp + self.Be @ up - self.ge, self.s_lam, lp)
        n1, n2 = float(np.linalg.norm(r1)), float(np.linalg.norm(r2))
        absolute = float(np.hypot(n1, n2))
        feas = lp - _project(self.blocks, lp, self.s_lam, lp)
        lmax = max(float(np.max(np.abs(lp), initial=0.0)), 1e-300)
        feasibility = float(np.max(np.abs(feas), initial=0.0)) / lmax
        z = self.Be @ up - self.ge  # (m,) equilibrated: λ'ᵀz' = λᵀ(Bu − gap)
        sigma, off = _support(self.blocks, z, self.s_lam, lp)
        size = float(max(np.linalg.norm(z), np.linalg.norm(up), np.linalg.norm(self.ge))) or 1.0
        nl = float(np.linalg.norm(lp)) or 1.0
        comp = abs(float(lp @ z) - sigma) / (nl * size) + off / size
        return KKT(absolute / self.scale, absolute, n1, n2, feasibility, comp)

    def contact(self, u: np.ndarray, lam: np.ndarray) -> ContactKKT:
        """The contact conditions of (u, λ), each on its own (`ContactKKT`)."""
        up, lp = self.scaled(u, lam)
        z = self.Be @ up - self.ge  # (m,)
        L = max(float(np.max(np.abs(lp), initial=0.0)), 1e-300)
        Z = max(float(np.max(np.abs(v), initial=0.0)) for v in (z, up, self.ge)) or 1.0
        worst = np.zeros(5)
        counts = np.zeros(3, dtype=int)
        for blk in self.blocks:
            if blk.kind != "contact":
                continue
            sl, d = slice(blk.start, blk.stop), blk.dim
            lam_b, z_b = lp[sl].reshape(-1, d), z[sl].reshape(-1, d)  # (k, d)
            ln, lt, zn, zt = lam_b[:, 0], lam_b[:, 1:], z_b[:, 0], z_b[:, 1:]
            r = _radius(blk, ln, self.s_lam[sl].reshape(-1, d)[:, 0])  # (k,)
            nlt = np.sqrt((lt * lt).sum(axis=1))  # (k,)
            nzt = np.sqrt((zt * zt).sum(axis=1))  # (k,)
            align = nlt * nzt - (lt * zt).sum(axis=1) + np.maximum(r - nlt, 0.0) * nzt
            measures = [
                np.maximum(-ln, 0.0) / L,
                np.maximum(zn, 0.0) / Z,
                np.abs(ln * zn) / (L * Z),
                np.maximum(nlt - r, 0.0) / L,
                align / (L * Z),
            ]
            worst = np.maximum(worst, [float(np.max(x, initial=0.0)) for x in measures])
            is_open = ln <= OPEN * L
            is_slip = ~is_open & (nzt > 1e-8 * Z)
            counts += [int(is_open.sum()), int((~is_open & ~is_slip).sum()), int(is_slip.sum())]
        return ContactKKT(*map(float, worst), *map(int, counts))

    def jacobian(self, u: np.ndarray, lam: np.ndarray) -> sp.csr_matrix:
        """An element J of the generalised Jacobian of F at (u, λ), equilibrated variables:
        [[A', B'ᵀ], [−P B', I − P − Q]] with P ∈ ∂_y P_Λ'(λ')(y), y = λ' + B'u' − gap', and Q
        the derivative of the projection through its dependence on λ' (contact blocks: the
        radius ρ(λ'_n); zero for fixed sets)."""
        up, lp = self.scaled(u, lam)
        y = lp + self.Be @ up - self.ge
        mats, qmats = [], []
        for blk in self.blocks:
            sl = slice(blk.start, blk.stop)
            yb, t = y[sl], self.s_lam[sl]
            qmats.append(sp.csr_matrix((yb.size, yb.size)))
            if blk.kind == "free":
                mats.append(sp.identity(yb.size))
            elif blk.kind == "nonnegative":
                mats.append(sp.diags((yb > 0).astype(float)))
            elif blk.kind == "box":
                inside = (yb > blk.lo / t) & (yb < blk.hi / t)
                mats.append(sp.diags(inside.astype(float)))
            elif blk.kind == "contact":
                p_cells, q_cells = self._contact_cells(blk, yb, lp[sl], t)
                mats.append(sp.block_diag(p_cells))
                qmats[-1] = sp.block_diag(q_cells)
            else:
                d = blk.dim
                Y = yb.reshape(-1, d)
                r = blk.radius / t.reshape(-1, d)[:, 0]
                nrm = np.sqrt((Y * Y).sum(axis=1))
                out = nrm > r  # (k,) I inside, (r/|y|)(I − ŷŷᵀ) outside
                yh = Y / np.where(out, nrm, 1.0)[:, None]  # (k, d)
                g = np.where(out, r / np.where(out, nrm, 1.0), 1.0)[:, None, None]  # (k, 1, 1)
                cells = g * (np.eye(d) - out[:, None, None] * yh[:, :, None] * yh[:, None, :])
                mats.append(sp.block_diag(list(cells)))
        m = self.Be.shape[0]
        P = sp.block_diag(mats, format="csr") if mats else sp.csr_matrix((0, 0))
        Q = sp.block_diag(qmats, format="csr") if qmats else sp.csr_matrix((0, 0))
        return sp.bmat(
            [[self.Ae, self.Be.T], [-(P @ self.Be), sp.identity(m) - P - Q]], format="csc"
        )

    @staticmethod
    def _contact_cells(blk: Block, yb: np.ndarray, lb: np.ndarray, t: np.ndarray):
        """Per node (d × d): ∂_y of [max(y_n, 0), P_disc(ρ)(y_t)] and its ∂_λ through ρ(λ_n)."""
        d = blk.dim
        Y, Lm = yb.reshape(-1, d), lb.reshape(-1, d)
        tn = t.reshape(-1, d)[:, 0]
        r = _radius(blk, Lm[:, 0], tn)
        slope = blk.friction * (Lm[:, 0] > 0) if blk.law == "coulomb" else np.zeros(r.size)
        p_cells, q_cells = [], []
        for yk, rk, sk in zip(Y, r, slope, strict=True):
            p, q = np.zeros((d, d)), np.zeros((d, d))
            p[0, 0] = 1.0 if yk[0] > 0 else 0.0
            nt = float(np.sqrt(yk[1:] @ yk[1:]))
            if rk > 0 and nt <= rk:
                p[1:, 1:] = np.eye(d - 1)
            elif rk > 0:
                yh = yk[1:] / nt
                p[1:, 1:] = (rk / nt) * (np.eye(d - 1) - np.outer(yh, yh))
                q[1:, 0] = sk * yh
            p_cells.append(p)
            q_cells.append(q)
        return p_cells, q_cells

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
