"""Fill-reducing nested-dissection ordering of a sparse matrix, from its graph alone.

`nested_dissection(A)` returns a permutation p such that the LU factors of A[p][:, p] (diagonal
pivots) fill in little: the graph of A + Aᵀ is split recursively by a vertex separator, and
every part is numbered before the separator that cuts it off from the other part, so the
elimination of one part creates no fill in the other. Separators are level sets of a
breadth-first search from a pseudo-peripheral vertex (the smallest level set leaving at least
a third of the vertices on each side), thinned by moving separator vertices without a
neighbour on the far side to the near part. Parts with at most `leaf` vertices keep their
order.

Measured against SuperLU's own orderings on the condensed Newton matrices of the paper scene
(`python benchmarks/bench_ordering.py paper_two_body@L`), these level-set separators
are not good enough: the factors fill more than with minimum degree on Aᵀ + A (which
`vi_core.linalg` therefore uses), though far less than with COLAMD. This ordering is kept as
that measured alternative; a graph partitioner's separators (METIS, as PARDISO uses) would be
the next step.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

LEAF = 64  # parts this small are not split further


def _graph(A: sp.spmatrix) -> sp.csr_matrix:
    """The symmetric adjacency structure of A (A + Aᵀ, no diagonal) as a 0/1 csr matrix."""
    S = sp.csr_matrix(A, copy=True)
    S.data = np.ones_like(S.data, dtype=np.int8)
    G = (S + S.T).tocsr()
    G.setdiag(0)
    G.eliminate_zeros()
    G.data[:] = 1
    return G


def _levels(G: sp.csr_matrix, root: int) -> np.ndarray:
    """(n,) breadth-first distance of every vertex of the connected graph G from `root`."""
    return csgraph.dijkstra(G, indices=root, unweighted=True).astype(np.int64)


def _pseudo_peripheral(G: sp.csr_matrix, degree: np.ndarray) -> tuple[int, np.ndarray]:
    """A vertex far from the others (repeated farthest-vertex search) and its BFS levels."""
    root = int(np.argmin(degree))
    lev = _levels(G, root)
    for _ in range(3):
        far = np.flatnonzero(lev == lev.max())
        cand = int(far[np.argmin(degree[far])])
        new = _levels(G, cand)
        if new.max() <= lev.max():
            break
        root, lev = cand, new
    return root, lev


def _split(G: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(part1, part2, separator) local vertex indices of the connected graph G, or None when
    no level set separates it (a clique-like part)."""
    degree = np.diff(G.indptr)  # (n,)
    _, lev = _pseudo_peripheral(G, degree)
    counts = np.bincount(lev)  # (depth + 1,)
    if counts.size < 3:
        return None
    # the smallest level set among those leaving at least a third of the vertices each side
    below = np.cumsum(counts) - counts  # (depth + 1,) vertices before each level
    above = G.shape[0] - below - counts
    ok = np.flatnonzero((below >= G.shape[0] / 3) & (above >= G.shape[0] / 3))
    if ok.size:
        mid = int(ok[np.argmin(counts[ok])])
    else:
        mid = int(np.searchsorted(np.cumsum(counts), G.shape[0] / 2))
    mid = min(max(mid, 1), counts.size - 2)
    sep = np.flatnonzero(lev == mid)
    # separator vertices with no neighbour beyond the separator belong to the near part
    rows = np.repeat(np.arange(G.shape[0]), degree)  # (nnz,)
    beyond = np.zeros(G.shape[0], dtype=bool)
    beyond[rows[lev[G.indices] > mid]] = True
    keep = beyond[sep]
    near = np.concatenate([np.flatnonzero(lev < mid), sep[~keep]])
    return near, np.flatnonzero(lev > mid), sep[keep]


def nested_dissection(A: sp.spmatrix, leaf: int = LEAF) -> np.ndarray:
    """(n,) permutation p of 0 … n−1: factorise A[p][:, p] with diagonal pivots (module
    docstring). Deterministic: depends on the sparsity structure of A only."""
    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"nested dissection needs a square matrix, got {A.shape}")
    G = _graph(A)
    order: list[np.ndarray] = []
    # explicit stack of (vertices, separator to emit after them); a separator is pushed below
    # its two parts so it is emitted after both
    stack: list[tuple[str, np.ndarray]] = [("part", np.arange(n))]
    while stack:
        kind, idx = stack.pop()
        if kind == "emit" or idx.size <= leaf:
            order.append(idx)
            continue
        sub = G[idx][:, idx]
        ncomp, label = csgraph.connected_components(sub, directed=False)
        if ncomp > 1:  # independent components: no separator needed
            for c in range(ncomp - 1, -1, -1):
                stack.append(("part", idx[label == c]))
            continue
        parts = _split(sub)
        if parts is None:
            order.append(idx)
            continue
        near, far, sep = parts
        stack.append(("emit", idx[sep]))
        stack.append(("part", idx[far]))
        stack.append(("part", idx[near]))
    return np.concatenate(order) if order else np.zeros(0, dtype=np.int64)
