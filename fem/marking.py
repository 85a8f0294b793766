"""Marking strategies for adaptive refinement: Dörfler (bulk) marking."""

from __future__ import annotations

import numpy as np

TIE = 1e-9  # relative: indicators this close to the last marked one count as equal


def dorfler_mark(eta: np.ndarray, theta: float) -> np.ndarray:
    """The smallest set M of cells with Σ_{T∈M} η_T² ≥ θ Σ_T η_T² (Dörfler 1996), completed by
    ties, as a bool mask (n_cells,): the cells with the largest indicators, taken in decreasing
    order, then every cell whose η_T equals the last one taken to TIE (relative): cells that a
    symmetry makes equal are marked together, so a symmetric problem keeps a symmetric mesh.

    eta : (n_cells,) the per-cell error indicators η_T ≥ 0 (not squared).
    theta : the bulk fraction, 0 < θ ≤ 1 (θ = 1 marks every cell with η_T > 0).
    An all-zero eta marks nothing. ValueError for a bad eta or theta.
    """
    e = np.asarray(eta, dtype=float)
    if e.ndim != 1:
        raise ValueError(f"eta: one indicator per cell, shape (n_cells,), got shape {e.shape}")
    if not np.isfinite(e).all() or (e < 0).any():
        raise ValueError("eta: indicators must be finite and >= 0")
    if not 0.0 < theta <= 1.0:
        raise ValueError(f"theta: the bulk fraction must lie in (0, 1], got {theta!r}")
    mask = np.zeros(e.size, dtype=bool)
    order = np.argsort(-e, kind="stable")  # (n_cells,) largest first
    acc = np.cumsum(e[order] ** 2)  # (n_cells,) the partial sums, acc[-1] the total
    if e.size == 0 or acc[-1] == 0.0:
        return mask
    k = int(np.searchsorted(acc, theta * acc[-1], side="left")) + 1  # cells needed
    last = e[order[min(k, e.size) - 1]]
    mask[e >= last * (1.0 - TIE)] = True
    return mask
