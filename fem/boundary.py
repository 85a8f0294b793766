"""Traces of P1/Q1 spaces on boundary parts and the dual (biorthogonal) basis of (4.1).

On a boundary part the trace of a P1 or Q1 space is the piecewise linear space on the part's
segments. The dual basis on a segment with end nodes 1, 2 is ψ_1 = 2φ_1 − φ_2, ψ_2 = 2φ_2 − φ_1,
so that ∫ψ_i φ_j = δ_ij ∫φ_j and the mortar matrix D = diag(∫φ_i) is diagonal.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .mesh import Mesh


@dataclass(frozen=True, eq=False)
class Trace:
    """The trace of a mesh on one boundary part (a chain of segments).

    nodes : (k,) global node ids, ordered along the part (counterclockwise about the body).
    segments : (k − 1, 2) local indices into `nodes` (or (k, 2) for a closed loop).
    lengths : (n_seg,) segment lengths.
    weights : (k,) ∫_Γ φ_i ds, the diagonal of D.
    normals : (k, 2) outward unit nodal normals (length-weighted mean of segment normals).
    tangents : (k, 2) unit tangents τ = (−n_y, n_x) (direction of traversal).
    s : (k,) arc length from the first node.
    """

    nodes: np.ndarray
    segments: np.ndarray
    lengths: np.ndarray
    weights: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    s: np.ndarray

    @property
    def size(self) -> int:
        return self.nodes.size


def _chain(edges: np.ndarray, name: str) -> np.ndarray:
    """Order directed edges (a, b) into one chain of node ids."""
    nxt = {int(a): int(b) for a, b in edges}
    if len(nxt) != len(edges):
        raise ValueError(f"boundary part {name!r} is not a simple chain of edges")
    heads = set(nxt) - set(nxt.values())
    start = heads.pop() if heads else int(edges[0, 0])
    if heads:
        raise ValueError(f"boundary part {name!r} has several disconnected pieces")
    chain = [start]
    while chain[-1] in nxt and len(chain) <= len(edges):
        chain.append(nxt[chain[-1]])
    if len(chain) != len(edges) + 1:
        raise ValueError(f"boundary part {name!r} has several disconnected pieces")
    return np.array(chain, dtype=int)


def trace(mesh: Mesh, names: str | Sequence[str]) -> Trace:
    """The trace of `mesh` on the boundary part(s) `names` (joined into one chain)."""
    names = [names] if isinstance(names, str) else list(names)
    for nm in names:
        if nm not in mesh.boundaries:
            raise KeyError(
                f"unknown boundary {nm!r}; this mesh has: {', '.join(sorted(mesh.boundaries))}"
            )
    edges = np.concatenate([mesh.boundaries[nm] for nm in names])  # (n_seg, 2)
    chain = _chain(edges, "+".join(names))
    closed = chain[0] == chain[-1]
    nodes = chain[:-1] if closed else chain
    k = nodes.size
    segments = np.stack([np.arange(len(chain) - 1), np.arange(1, len(chain))], axis=1) % k
    P = mesh.points[nodes]  # (k, 2)
    d = P[segments[:, 1]] - P[segments[:, 0]]  # (n_seg, 2)
    lengths = np.linalg.norm(d, axis=1)
    if (lengths <= 0).any():
        raise ValueError(f"boundary part {'+'.join(names)!r} has a segment of zero length")
    seg_n = np.stack([d[:, 1], -d[:, 0]], axis=1) / lengths[:, None]  # outward (domain on left)
    weights = np.zeros(k)
    np.add.at(weights, segments[:, 0], 0.5 * lengths)
    np.add.at(weights, segments[:, 1], 0.5 * lengths)
    nsum = np.zeros((k, 2))
    np.add.at(nsum, segments[:, 0], seg_n * lengths[:, None])
    np.add.at(nsum, segments[:, 1], seg_n * lengths[:, None])
    normals = nsum / np.linalg.norm(nsum, axis=1)[:, None]
    tangents = np.stack([-normals[:, 1], normals[:, 0]], axis=1)
    s = np.concatenate([[0.0], np.cumsum(lengths)])[:k]
    return Trace(nodes, segments, lengths, weights, normals, tangents, s)


def dual_basis_on_segment(t: np.ndarray) -> np.ndarray:
    """Values of (ψ_1, ψ_2) at reference points t ∈ [0, 1] of a segment: (len(t), 2)."""
    t = np.asarray(t, dtype=float)
    phi1, phi2 = 1.0 - t, t
    return np.stack([2 * phi1 - phi2, 2 * phi2 - phi1], axis=-1)
