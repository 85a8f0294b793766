"""Traces of 3D P1/Q1 spaces on boundary surfaces (`Surface`: the contact surface of
`problems.plugins.contact3d` and both sides of the mortar `fem.mortar3d`), nodal normals,
tangent frames, dual basis.

On a boundary part of a `Mesh3D` (triangles of a tetrahedral mesh, bilinear quadrilaterals of a
hexahedral one) the trace space is P1 / Q1 on the faces. The dual (biorthogonal) basis of a
face e with local mass matrix M_e (M_e[a, b] = ∫_e φ_a φ_b) and D_e = diag(Σ_b M_e[a, b]) is
ψ_{e,a} = Σ_b A_e[a, b] φ_b with A_e = D_e M_e⁻¹, so that ∫_e ψ_{e,a} φ_b = δ_ab ∫_e φ_a and the
slave mortar matrix D = diag(∫_Γ φ_k) is diagonal (`Surface.dual`; on a flat triangle
A_e has 3 on the diagonal and −1 off it, on a parallelogram it is the tensor product of the 1D
(2, −1) rule).

Face integrals use one rule per face type and order (`face_rule`): Gauss on the quadrilateral,
collapsed Gauss on the triangle (any order).

Nodal normals are the outward unit vectors n_k ∝ ∫_Γ φ_k n dA (the φ_k-weighted mean of the
face normals: exact on a plane, continuous on curved surfaces). Tangent frames (t1, t2) are
built from one reference direction a for the whole surface: t1 = (a − (a·n)n)/|…|,
t2 = n × t1, so (t1, t2, n) is right-handed (t1 × t2 = n) and varies continuously with n; a is
the coordinate axis least aligned with any nodal normal (`frames`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .elements import FACET_TYPE as FACE_TYPE
from .elements import reference_element
from .mesh3d import Mesh3D

FRAME_LIMIT = np.cos(np.radians(10.0))  # refuse a surface whose normals come this close to a


@dataclass(frozen=True, eq=False)
class Surface:
    """The trace of a 3D mesh on one or more boundary parts.

    nodes : (k,) global node ids of the surface (sorted).
    faces : (n_f, m) local indices into `nodes` (m = 3 or 4), counterclockwise seen from
        outside.
    face_type : "triangle" or "quad" (the 2D reference element of a face).
    points : (k, 3) node coordinates.
    normals : (k, 3) outward unit nodal normals ∝ ∫_Γ φ_k n dA.
    weights : (k,) ∫_Γ φ_k dA, the diagonal of D.
    face_weights : (n_f, m) ∫_e φ_a dA.
    areas : (n_f,) face areas.
    dual : (n_f, m, m) the coefficients A_e = D_e M_e⁻¹ of ψ_{e,a} (module docstring).
    """

    nodes: np.ndarray
    faces: np.ndarray
    face_type: str
    points: np.ndarray
    normals: np.ndarray
    weights: np.ndarray
    face_weights: np.ndarray
    areas: np.ndarray
    dual: np.ndarray

    @property
    def size(self) -> int:
        """Number of surface nodes."""
        return self.nodes.size

    def node_sizes(self) -> np.ndarray:
        """(k,) local mesh size per node: the largest √area of its faces."""
        h = np.zeros(self.size)
        for a in range(self.faces.shape[1]):
            np.maximum.at(h, self.faces[:, a], np.sqrt(self.areas))
        return h

    def edges(self) -> np.ndarray:
        """(n_e, 2) the unique face edges as local node pairs (sorted)."""
        e = np.stack([self.faces, np.roll(self.faces, -1, axis=1)], axis=2).reshape(-1, 2)
        return np.unique(np.sort(e, axis=1), axis=0)


def triangle_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Collapsed Gauss on the reference triangle: points (n², 2), weights (n²,) summing to 1/2,
    exact for total degree ≤ `order` (n = ⌈(order + 2)/2⌉)."""
    n = (order + 3) // 2
    g, w = np.polynomial.legendre.leggauss(n)
    g, w = 0.5 * (g + 1.0), 0.5 * w  # (n,) on [0, 1]
    a, b = np.meshgrid(g, g, indexing="ij")
    pts = np.stack([a.ravel(), (b * (1 - a)).ravel()], axis=1)  # (n², 2)
    return pts, (np.outer(w, w) * (1 - a)).ravel()


def face_rule(face_type: str, order: int) -> tuple[np.ndarray, np.ndarray]:
    """The rule of every face integral: points (n_qp, 2), weights (n_qp,) on the reference
    face, exact to degree `order` (collapsed Gauss on a triangle, Gauss on a quadrilateral)."""
    if face_type == "triangle":
        return triangle_rule(order)
    return reference_element(face_type).quadrature(order)


def _face_quadrature(points: np.ndarray, face_type: str, order: int):
    """x (n_f, n_qp, 3), N (n_f, n_qp, 3) = ∂x/∂s × ∂x/∂t, w (n_qp,), phi (n_qp, k)."""
    ref = reference_element(face_type)
    pts, w = face_rule(face_type, order)  # (n_qp, 2), (n_qp,)
    phi = ref.values(pts)  # (n_qp, k)
    T = np.einsum("fai,qaj->fqij", points, ref.gradients(pts), optimize=True)  # (n_f, n_qp, 3, 2)
    N = np.cross(T[..., 0], T[..., 1])  # (n_f, n_qp, 3)
    return phi @ points, N, w, phi


def surface(mesh: Mesh3D, names: str | Sequence[str], order: int = 4) -> Surface:
    """The trace of `mesh` on the boundary part(s) `names` (KeyError for an unknown part,
    ValueError for a face of zero area)."""
    names = [names] if isinstance(names, str) else list(names)
    for nm in names:
        if nm not in mesh.boundaries:
            raise KeyError(
                f"unknown boundary {nm!r}; this mesh has: {', '.join(sorted(mesh.boundaries))}"
            )
    glob = np.concatenate([mesh.boundaries[nm] for nm in names])  # (n_f, k)
    if glob.size == 0:
        raise ValueError(f"boundary part {'+'.join(names)!r} has no faces")
    nodes, inv = np.unique(glob, return_inverse=True)
    faces = inv.reshape(glob.shape)  # (n_f, k)
    ftype = FACE_TYPE[mesh.cell_type]
    _, N, w, phi = _face_quadrature(mesh.points[glob], ftype, order)
    dA = np.linalg.norm(N, axis=-1) * w[None, :]  # (n_f, n_qp)
    areas = dA.sum(axis=1)  # (n_f,)
    if (areas <= 0).any():
        raise ValueError(f"boundary part {'+'.join(names)!r} has a face of zero area")
    mass = np.einsum("fq,qa,qb->fab", dA, phi, phi)  # (n_f, m, m) M_e
    fw = mass.sum(axis=2)  # (n_f, m) ∫_e φ_a dA
    k = nodes.size
    weights = np.bincount(faces.ravel(), fw.ravel(), minlength=k)  # (k,)
    nloc = np.einsum("q,qa,fqi->fai", w, phi, N)  # (n_f, m, 3) ∫_e φ_a n dA
    nsum = np.stack([np.bincount(faces.ravel(), nloc[..., i].ravel(), k) for i in range(3)], 1)
    normals = nsum / np.linalg.norm(nsum, axis=1)[:, None]  # (k, 3)
    dual = fw[:, :, None] * np.linalg.inv(mass)  # (n_f, m, m) A_e = D_e M_e⁻¹
    return Surface(nodes, faces, ftype, mesh.points[nodes], normals, weights, fw, areas, dual)


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


def frames(normals: np.ndarray, a: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tangents (t1, t2), each (k, 3), of the right-handed frames (t1, t2, n): t1 = the
    projection of the reference direction `a` (default `reference_direction`) onto the tangent
    plane, normalised; t2 = n × t1."""
    n = np.asarray(normals, dtype=float)  # (k, 3)
    a = reference_direction(n) if a is None else np.asarray(a, dtype=float)
    t1 = a[None, :] - (n @ a)[:, None] * n  # (k, 3)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(n, t1)


def face_integrals(
    mesh: Mesh3D,
    surf: Surface,
    func: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
    order: int = 4,
) -> np.ndarray:
    """(n_f, m) ∫_e f φ_{e,a} dA of a scalar field f(x, y, z) (values at the quadrature
    points) per face e and local node a; a multiplier basis Q (`fem.mortar3d.multiplier_basis`)
    turns them into ∫ f φ̃_k dA (Q @ result.ravel()), np.bincount(faces, …) into ∫ f φ_k dA."""
    x, N, w, phi = _face_quadrature(mesh.points[surf.nodes[surf.faces]], surf.face_type, order)
    dA = np.linalg.norm(N, axis=-1) * w[None, :]  # (n_f, n_qp)
    f = np.broadcast_to(np.asarray(func(x[..., 0], x[..., 1], x[..., 2]), float), dA.shape)
    return (dA * f) @ phi  # (n_f, m)
