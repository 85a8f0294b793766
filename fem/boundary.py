"""Traces of P1/Q1 spaces on boundary parts and the dual (biorthogonal) basis of (4.1).

On a boundary part the trace of a P1 or Q1 space is the piecewise linear space on the part's
segments. The dual basis on a segment with end nodes 1, 2 is ψ_1 = 2φ_1 − φ_2, ψ_2 = 2φ_2 − φ_1,
so that ∫ψ_i φ_j = δ_ij ∫φ_j and the mortar matrix D = diag(∫φ_i) is diagonal.

Multiplier bases are written in the SEGMENT-LOCAL dual functions ψ_{e,a} (a = 0, 1: the first
and second node of segment e; column 2e + a of every "local" matrix): ψ̃_k = Σ Q[k, 2e+a] ψ_{e,a}
(`multiplier_basis`). Nodes may carry no multiplier (crosspoints with Dirichlet sides); then

- ends="keep": the remaining nodes keep their dual functions unchanged (the dropped node's
  local functions are dropped with it);
- ends="merge" (Wohlmuth's modification at the ends of the multiplier part): on a segment where
  exactly one node carries a multiplier, the other node's local function is added to it, so
  ψ̃ = ψ_{e,0} + ψ_{e,1} = 1 on that segment.

Both keep biorthogonality among carrying nodes, ∫ψ̃_k φ_j = δ_kj ∫φ_j for carrying j; "merge"
also keeps Σ_k ψ̃_k = 1 on every segment with a carrying node (constants are in the multiplier
space, so a rigid translation is transferred and the tied patch test passes up to the end).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .mesh import Mesh

ENDS = ("merge", "keep")  # multiplier end treatments, see the module docstring


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


def dual_mass(tr: Trace) -> sp.csr_matrix:
    """(2·n_seg, k) the local slave block: ∫_e ψ_{e,a} φ_j = δ(j = node a of e) · |e|/2."""
    n_seg = tr.segments.shape[0]
    rows = np.arange(2 * n_seg)
    vals = np.repeat(0.5 * tr.lengths, 2)  # (2 n_seg,)
    return sp.csr_matrix((vals, (rows, tr.segments.ravel())), shape=(2 * n_seg, tr.size))


def multiplier_basis(tr: Trace, carry: np.ndarray, ends: str = "merge") -> sp.csr_matrix:
    """Q (n_carry, 2·n_seg): ψ̃_k = Σ_(e,a) Q[k, 2e+a] ψ_{e,a} for the nodes with carry True.

    Rows follow the carrying nodes in trace order; ends is "keep" or "merge" (module
    docstring). Local slave block of the multipliers: Q @ dual_mass(tr); any other local matrix
    (mortar, loads) is mapped the same way.
    """
    if ends not in ENDS:
        raise ValueError(f"ends must be one of {ENDS}, got {ends!r}")
    carry = np.asarray(carry, dtype=bool)
    if carry.shape != (tr.size,):
        raise ValueError(f"carry must have shape ({tr.size},), got {carry.shape}")
    row_of = np.cumsum(carry) - 1  # (k,) row index of each carrying node
    own = tr.segments  # (n_seg, 2): the node each local function belongs to
    target = np.where(carry[own], own, -1)  # (n_seg, 2) the node whose ψ̃ gets ψ_{e,a}
    if ends == "merge":
        other = own[:, ::-1]
        lone = ~carry[own] & carry[other]  # this node drops, the segment's other one carries
        target = np.where(lone, other, target)
    cols = np.flatnonzero(target.ravel() >= 0)
    rows = row_of[target.ravel()[cols]]
    n_carry = int(carry.sum())
    return sp.csr_matrix(
        (np.ones(cols.size), (rows, cols)), shape=(n_carry, 2 * tr.segments.shape[0])
    )


def segment_loads(mesh: Mesh, tr: Trace, func) -> np.ndarray:
    """(n_seg, 2) ∫_e f φ_{e,a} ds for a scalar field f(x, y), 3-point Gauss per segment.

    Summed over segments this is `fem.assembly.boundary_load` on the same part; kept per
    segment so that it can be mapped through `multiplier_basis`.
    """
    g, w = np.polynomial.legendre.leggauss(3)
    t, w = 0.5 * (g + 1.0), 0.5 * w  # (3,) on [0, 1]
    P = mesh.points[tr.nodes[tr.segments]]  # (n_seg, 2, 2)
    x = P[:, None, 0] + t[None, :, None] * (P[:, None, 1] - P[:, None, 0])  # (n_seg, 3, 2)
    f = np.broadcast_to(
        np.asarray(func(x[..., 0], x[..., 1]), dtype=float), x.shape[:2]
    )  # (n_seg, 3)
    phi = np.stack([1.0 - t, t], axis=-1)  # (3, 2)
    return np.einsum("e,q,qa,eq->ea", tr.lengths, w, phi, f)
