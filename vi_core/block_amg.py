"""The block multigrid preconditioner of an operator with several fields (e.g. displacement then
potential): one smoothed-aggregation hierarchy per field (`vi_core.amg`), built on the
symmetric part of its diagonal block, block lower triangular over the fields (the coupling
blocks below the diagonal applied exactly).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .amg import smoothed_aggregation
from .sparse_blocks import lone_entries, restricted_plus, symmetric_part


@dataclass
class FieldBlock:
    """One field of the operator: its positions and its multigrid hierarchy."""

    name: str
    index: np.ndarray  # (k,) positions within the operator
    ml: object  # pyamg MultilevelSolver
    lower: list = field(default_factory=list)  # [(j, K[self, field j])] for earlier fields j


def field_masks(n: int, fields: dict | None, near_null: dict | None) -> list[tuple]:
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


def field_blocks(
    K: sp.csr_matrix,
    fields: list[tuple],
    couple: bool = True,
    R: np.ndarray | None = None,
    Z: sp.csr_matrix | None = None,
    lone: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[dict]:
    """The blocks of Â = K[R][:, R] in the leading block of y plus Z (n_y, n_y, few stored
    rows) — by default R all of K's rows and Z none: Â = K — for the fields over y (masks
    (n_y,)): per field (in order) its positions `index` (k,), the symmetric part `sym` (k, k)
    of its diagonal block, its near-null rows `nn`, and `lower` = [(j, Â[field, field j])] for
    the earlier fields j (empty with couple=False). Each block is gathered from K's index
    arrays (`restricted_plus`) and Â is never formed: the only full-size arrays are the
    blocks' (forming Â and taking its blocks by fancy indexing peaked at 685 MB from 365 held,
    paper scene level 5). lone: `lone_entries(K)` where known (computed otherwise). Nothing
    refers to K afterwards."""
    n_y = fields[0][1].size if fields else K.shape[0]
    R = np.arange(K.shape[0]) if R is None else np.asarray(R)
    R_y = np.full(n_y, -1, dtype=np.int64)  # (n_y,) K's row of each position, −1 beyond R
    R_y[: R.size] = R
    Z = sp.csr_matrix((n_y, n_y)) if Z is None else sp.csr_matrix(Z)
    lone = lone_entries(K) if lone is None else lone
    out: list[dict] = []
    for name, mask, nn in fields:
        index = np.flatnonzero(mask)
        if index.size == 0:
            continue
        Z_f = Z[index]  # (k, n_y) Z's rows of the field (few stored)
        lower = []
        for j, prev in enumerate(out if couple else []):
            C = restricted_plus(K, R_y[index], R_y[prev["index"]], Z_f[:, prev["index"]])
            C.eliminate_zeros()
            if C.nnz:
                lower.append((j, C))
        sym = symmetric_part(restricted_plus(K, R_y[index], R_y[index], Z_f[:, index], lone))
        out.append({"name": name, "index": index, "sym": sym, "nn": nn, "lower": lower})
    return out


class BlockAMG:
    """x ≈ K⁻¹ r: one multigrid cycle per field, block lower triangular over the fields, built
    from `field_blocks(K, ...)` (each field's symmetric block is dropped from `blocks` once its
    hierarchy is built).

    parts : optional (n_R,) label of each unknown's body (aggregates stay within one body)."""

    def __init__(self, blocks: list[dict], parts: np.ndarray | None = None, cycle: str = "V"):
        self.cycle = cycle
        t = time.perf_counter()
        self.blocks: list[FieldBlock] = []
        for blk in blocks:
            index, nn = blk["index"], blk["nn"]
            sym = blk.pop("sym")
            ml = smoothed_aggregation(sym, nn, None if parts is None else parts[index])
            del sym
            self.blocks.append(FieldBlock(blk["name"], index, ml, blk["lower"]))
        self.setup_time = time.perf_counter() - t

    def __call__(self, r: np.ndarray) -> np.ndarray:
        x = np.zeros_like(r)
        parts = []
        for blk in self.blocks:
            rhs = r[blk.index]
            for j, C in blk.lower:
                rhs = rhs - C @ parts[j]
            xb = blk.ml.solve(rhs, x0=np.zeros_like(rhs), tol=0.0, maxiter=1, cycle=self.cycle)
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
