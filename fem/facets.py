"""Traces of P1/Q1 spaces on tagged boundary parts (the contact surfaces of the mortar
`fem.mortar` and of the contact plug-ins), in 2D and 3D: facets, nodal normals, tangent frames,
the dual (biorthogonal) basis and the multiplier bases built from it.

A trace (`Trace`, built by `trace`) is the set of boundary facets of one or more tagged parts:
segments of a 2D mesh (a chain, its nodes in order along it), triangles of a tetrahedral mesh
or bilinear quadrilaterals of a hexahedral one (its nodes sorted). The trace space is P1/Q1 on
the facets. The dual basis of a facet e with local mass matrix M_e (M_e[a, b] = ∫_e φ_a φ_b)
and D_e = diag(Σ_b M_e[a, b]) is

    ψ_{e,a} = Σ_b A_e[a, b] φ_b,   A_e = D_e M_e⁻¹   (`Trace.dual`),

so that ∫_e ψ_{e,a} φ_b = δ_ab ∫_e φ_a and the slave mortar matrix D = diag(∫_Γ φ_k) is
diagonal. On a segment A_e = [[2, −1], [−1, 2]] (ψ_1 = 2φ_1 − φ_2), on a flat triangle 3 on
the diagonal and −1 off it, on a parallelogram the tensor product of the segment's rule.

Facet integrals (`facet_quadrature`) use the rules of the facets' reference elements
(`fem.elements`).

Nodal normals are the outward unit vectors n_k ∝ ∫_Γ φ_k n (the φ_k-weighted mean of the facet
normals: exact on a line or plane, continuous on curved boundaries). Tangents (`frames`): in 2D
τ = (−n_y, n_x), the direction of traversal; in 3D the right-handed frames (t1, t2, n) built
from one reference direction a for the whole surface, t1 = (a − (a·n)n)/|…|, t2 = n × t1, a the
coordinate axis least aligned with any nodal normal.

Multiplier bases are written in the FACET-LOCAL dual functions ψ_{e,a} (column m·e + a of every
"local" matrix, m nodes per facet): ψ̃_k = Σ Q[k, m e + a] ψ_{e,a} (`multiplier_basis`). Nodes
may carry no multiplier (crosspoints on a Dirichlet side, uncovered nodes); then

- ends="keep": the remaining nodes keep their dual functions unchanged (the dropped node's
  local functions are dropped with it);
- ends="merge" (Wohlmuth's modification at the ends of the multiplier part): ψ_{e,b} of a
  dropped node b is shared equally by the carrying nodes of facet e joined to b by a facet
  edge, or by all carrying nodes of e if none is (on a segment: the other node, if it carries,
  gets it whole, so ψ̃ = ψ_{e,0} + ψ_{e,1} = 1 there).

Both keep biorthogonality among carrying nodes, ∫ψ̃_k φ_j = δ_kj ∫φ_j for carrying j; "merge"
also keeps Σ_k ψ̃_k = 1 on every facet with a carrying node (constants are in the multiplier
space, so a rigid translation is transferred and the tied patch test passes up to the rim).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .elements import FACET_TYPE, reference_element
from .mesh import Mesh

ENDS = ("merge", "keep")  # multiplier end treatments, see the module docstring
FRAME_LIMIT = np.cos(np.radians(10.0))  # refuse normals within 10° of every coordinate axis
SEGMENT_DUAL = np.array([[2.0, -1.0], [-1.0, 2.0]])  # A_e of every segment


@dataclass(frozen=True, eq=False)
class Trace:
    """The trace of a mesh on one or more boundary parts (d = 2 or 3 the mesh's dimension).

    nodes : (k,) global node ids: in 2D ordered along the chain (counterclockwise about the
        body), in 3D sorted.
    facets : (n_f, m) local indices into `nodes`, m = 2 (segments) or 3, 4 (faces,
        counterclockwise seen from outside); a 2D chain's segment e is (e, e + 1) (mod k).
    facet_type : "line" (segments), "triangle" or "quad": `fem.elements` names.
    points : (k, d) node coordinates.
    normals : (k, d) outward unit nodal normals ∝ ∫_Γ φ_k n.
    weights : (k,) ∫_Γ φ_k, the diagonal of D.
    facet_weights : (n_f, m) ∫_e φ_a.
    measures : (n_f,) facet lengths (2D) or areas (3D).
    dual : (n_f, m, m) the coefficients A_e = D_e M_e⁻¹ of ψ_{e,a} (module docstring).
    """

    nodes: np.ndarray
    facets: np.ndarray
    facet_type: str
    points: np.ndarray
    normals: np.ndarray
    weights: np.ndarray
    facet_weights: np.ndarray
    measures: np.ndarray
    dual: np.ndarray

    @property
    def size(self) -> int:
        """Number of trace nodes."""
        return self.nodes.size

    @property
    def tangents(self) -> np.ndarray:
        """(k, d) the first tangent field of `frames`: τ = (−n_y, n_x) in 2D, t1 in 3D."""
        return frames(self.normals)[0]

    @property
    def s(self) -> np.ndarray:
        """(k,) arc length from the first node of a 2D chain (ValueError in 3D)."""
        if self.facet_type != "line":
            raise ValueError("arc length is defined on a 2D trace (a chain of segments) only")
        return np.concatenate([[0.0], np.cumsum(self.measures)])[: self.size]

    def node_sizes(self) -> np.ndarray:
        """(k,) local mesh size per node: the largest length (2D) or √area (3D) of its facets."""
        h = np.zeros(self.size)
        size = self.measures if self.facet_type == "line" else np.sqrt(self.measures)
        for a in range(self.facets.shape[1]):
            np.maximum.at(h, self.facets[:, a], size)
        return h

    def edges(self) -> np.ndarray:
        """(n_e, 2) the unique facet edges as local node pairs (sorted)."""
        e = np.stack([self.facets, np.roll(self.facets, -1, axis=1)], axis=2).reshape(-1, 2)
        return np.unique(np.sort(e, axis=1), axis=0)


def facet_values(facet_type: str, xi: np.ndarray) -> np.ndarray:
    """Shape function values (..., m) at reference points xi (..., d − 1) (`fem.elements`: a
    segment's reference is [0, 1] with φ = (1 − t, t))."""
    ref = reference_element(facet_type)
    return ref.values(xi.reshape(-1, ref.dim)).reshape(*xi.shape[:-1], ref.n_loc)


def facet_quadrature(
    points: np.ndarray, facet_type: str, order: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rule of `order` (`fem.elements`) on facets with nodes `points` (n_f, m, d): straight
    edges (2D), flat triangles or bilinear quadrilaterals (3D).

    Returns x (n_f, n_qp, d) the physical points, w (n_qp,) the reference weights, N (n_f,
    n_qp, d) the outward normals scaled by the measure density (|N| dA_ref = dA: in 2D the
    tangent ∂x/∂t turned right, the domain on its left; in 3D ∂x/∂s × ∂x/∂t) and phi (n_qp, m)
    the facet shape values.
    """
    ref = reference_element(facet_type)
    pts, w = ref.quadrature(order)  # (n_qp, d − 1), (n_qp,)
    phi = ref.values(pts)  # (n_qp, m)
    T = ref.jacobians(points, pts)  # (n_f, n_qp, d, d − 1) tangents ∂x/∂s (, ∂x/∂t)
    if T.shape[-1] == 1:
        N = np.stack([T[..., 1, 0], -T[..., 0, 0]], axis=-1)  # (n_f, n_qp, 2)
    else:
        N = np.cross(T[..., 0], T[..., 1])  # (n_f, n_qp, 3)
    return phi @ points, w, N, phi


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


def _segments(mesh: Mesh, edges: np.ndarray, name: str) -> Trace:
    """The trace on boundary edges (n_seg, 2) of a 2D mesh, joined into one chain (closed or
    not); its normals, weights and dual basis in closed form."""
    chain = _chain(edges, name)
    closed = chain[0] == chain[-1]
    nodes = chain[:-1] if closed else chain
    k = nodes.size
    segments = np.stack([np.arange(len(chain) - 1), np.arange(1, len(chain))], axis=1) % k
    P = mesh.points[nodes]  # (k, 2)
    d = P[segments[:, 1]] - P[segments[:, 0]]  # (n_seg, 2)
    lengths = np.linalg.norm(d, axis=1)
    if (lengths <= 0).any():
        raise ValueError(f"boundary part {name!r} has a segment of zero length")
    seg_n = np.stack([d[:, 1], -d[:, 0]], axis=1) / lengths[:, None]  # outward (domain on left)
    fw = np.repeat(0.5 * lengths[:, None], 2, axis=1)  # (n_seg, 2) ∫_e φ_a
    nloc = np.repeat(0.5 * (seg_n * lengths[:, None])[:, None], 2, axis=1)  # (n_seg, 2, 2)
    dual = np.broadcast_to(SEGMENT_DUAL, (len(segments), 2, 2))
    return _gather(nodes, segments, "line", P, fw, nloc, lengths, dual)


def _faces(mesh: Mesh, glob: np.ndarray, name: str, order: int) -> Trace:
    """The trace on boundary faces (n_f, m) of a 3D mesh: quadrature of the face mass
    matrices, normals and weights at `order`."""
    if glob.size == 0:
        raise ValueError(f"boundary part {name!r} has no faces")
    nodes, inv = np.unique(glob, return_inverse=True)
    faces = inv.reshape(glob.shape)  # (n_f, m)
    ftype = FACET_TYPE[mesh.cell_type]
    _, w, N, phi = facet_quadrature(mesh.points[glob], ftype, order)
    dA = np.linalg.norm(N, axis=-1) * w[None, :]  # (n_f, n_qp)
    areas = dA.sum(axis=1)  # (n_f,)
    if (areas <= 0).any():
        raise ValueError(f"boundary part {name!r} has a face of zero area")
    mass = np.einsum("fq,qa,qb->fab", dA, phi, phi)  # (n_f, m, m) M_e
    fw = mass.sum(axis=2)  # (n_f, m) ∫_e φ_a dA
    nloc = np.einsum("q,qa,fqi->fai", w, phi, N)  # (n_f, m, 3) ∫_e φ_a n dA
    dual = fw[:, :, None] * np.linalg.inv(mass)  # (n_f, m, m) A_e = D_e M_e⁻¹
    return _gather(nodes, faces, ftype, mesh.points[nodes], fw, nloc, areas, dual)


def _gather(nodes, facets, ftype, points, fw, nloc, measures, dual) -> Trace:
    """The `Trace` from per-facet ∫_e φ_a (n_f, m) and ∫_e φ_a n (n_f, m, d): nodal weights
    and unit normals summed over the facets around each node."""
    k, d = nodes.size, points.shape[1]
    weights = np.bincount(facets.ravel(), fw.ravel(), minlength=k)  # (k,)
    nsum = np.stack([np.bincount(facets.ravel(), nloc[..., i].ravel(), k) for i in range(d)], 1)
    normals = nsum / np.linalg.norm(nsum, axis=1)[:, None]  # (k, d)
    return Trace(nodes, facets, ftype, points, normals, weights, fw, measures, dual)


def trace(mesh: Mesh, names: str | Sequence[str], order: int = 4) -> Trace:
    """The trace of `mesh` on the boundary part(s) `names` (KeyError for an unknown part,
    ValueError for a 2D part that is not one chain of segments or a facet of zero measure).

    order : quadrature order of a 3D face's mass matrix and normal (segments: closed form).
    """
    names = [names] if isinstance(names, str) else list(names)
    glob = np.concatenate([mesh.boundary(nm) for nm in names])  # (n_f, m) global ids
    if mesh.points.shape[1] == 2:
        return _segments(mesh, glob, "+".join(names))
    return _faces(mesh, glob, "+".join(names), order)


def reference_direction(normals: np.ndarray) -> np.ndarray:
    """The coordinate axis (3,) least aligned with any of `normals` (k, 3); ValueError if even
    that one comes within 10° of a normal (the surface turns too far for one frame chart)."""
    worst = np.abs(normals).max(axis=0)  # (3,) max_k |n_k · e_i|
    i = int(np.argmin(worst))
    if worst[i] > FRAME_LIMIT:
        raise ValueError(
            "the contact surface's normals turn too far for one tangent frame (every "
            f"coordinate axis comes within 10° of a normal; closest {worst.tolist()})"
        )
    return np.eye(3)[i]


def frames(normals: np.ndarray, a: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """The d − 1 unit tangent fields, each (k, d), of nodal `normals` (k, d): in 2D (τ,) with
    τ = (−n_y, n_x); in 3D (t1, t2) of the right-handed frames (t1, t2, n): t1 = the projection
    of the reference direction `a` (default `reference_direction`) onto the tangent plane,
    normalised; t2 = n × t1."""
    n = np.asarray(normals, dtype=float)  # (k, d)
    if n.shape[1] == 2:
        return (np.stack([-n[:, 1], n[:, 0]], axis=1),)
    a = reference_direction(n) if a is None else np.asarray(a, dtype=float)
    t1 = a[None, :] - (n @ a)[:, None] * n  # (k, 3)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(n, t1)


def facet_integrals(
    mesh: Mesh,
    tr: Trace,
    func: Callable[..., np.ndarray],
    order: int = 4,
) -> np.ndarray:
    """(n_f, m) ∫_e f φ_{e,a} of a scalar field f(x, y) or f(x, y, z) (values at the
    quadrature points) per facet e and local node a; a multiplier basis Q (`multiplier_basis`)
    turns them into ∫ f φ̃_k (Q @ result.ravel()), np.bincount(facets, …) into ∫ f φ_k."""
    x, w, N, phi = facet_quadrature(mesh.points[tr.nodes[tr.facets]], tr.facet_type, order)
    dA = np.linalg.norm(N, axis=-1) * w[None, :]  # (n_f, n_qp)
    f = np.broadcast_to(np.asarray(func(*np.moveaxis(x, -1, 0)), float), dA.shape)
    return (dA * f) @ phi  # (n_f, m)


def rim_nodes(facets: np.ndarray) -> np.ndarray:
    """(r,) local indices of the nodes on the rim of a 3D surface (edges of one face only)."""
    e = np.stack([facets, np.roll(facets, -1, axis=1)], axis=2).reshape(-1, 2)  # (n_f m, 2)
    key, count = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    return np.unique(key[count == 1])


def dual_mass(tr: Trace) -> sp.csr_matrix:
    """(m·n_f, k) the local slave block: ∫_e ψ_{e,a} φ_j = δ(j = node a of e) ∫_e φ_a."""
    rows = np.arange(tr.facets.size)
    return sp.csr_matrix(
        (tr.facet_weights.ravel(), (rows, tr.facets.ravel())), (rows.size, tr.size)
    )


def multiplier_basis(tr: Trace, carry: np.ndarray, ends: str = "merge") -> sp.csr_matrix:
    """Q (n_carry, m·n_f): ψ̃_k = Σ_(e,a) Q[k, m e + a] ψ_{e,a} for the nodes with carry True.

    Rows follow the carrying nodes in the order of `tr.nodes`; ends is "keep" or "merge"
    (module docstring). Local slave block of the multipliers: Q @ dual_mass(tr); any other
    local matrix (mortar, loads) is mapped the same way.
    """
    if ends not in ENDS:
        raise ValueError(f"ends must be one of {ENDS}, got {ends!r}")
    carry = np.asarray(carry, dtype=bool)
    if carry.shape != (tr.size,):
        raise ValueError(f"carry must have shape ({tr.size},), got {carry.shape}")
    n_f, m = tr.facets.shape
    row_of = np.cumsum(carry) - 1  # (k,)
    c = carry[tr.facets]  # (n_f, m) carrying local nodes
    W = np.where(c[:, :, None], np.eye(m)[None], 0.0)  # (n_f, m targets, m sources)
    if ends == "merge":
        adj = np.eye(m, k=1) + np.eye(m, k=-1) + np.eye(m, k=m - 1) + np.eye(m, k=1 - m) > 0
        near = adj[None] & c[:, :, None]  # (n_f, m, m): target carries and is an edge neighbour
        share = np.where(near.any(axis=1, keepdims=True), near, c[:, :, None])  # (n_f, m, m)
        share &= ~c[:, None, :]  # only dropped sources are shared
        cnt = share.sum(axis=1, keepdims=True)  # (n_f, 1, m)
        W += np.where(share, 1.0 / np.maximum(cnt, 1), 0.0)
    f, t, a = np.nonzero(W)
    return sp.csr_matrix(
        (W[f, t, a], (row_of[tr.facets[f, t]], m * f + a)), shape=(int(carry.sum()), m * n_f)
    )
