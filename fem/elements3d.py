"""3D reference elements: P1 on the tetrahedron, Q1 on the hexahedron [−1, 1]³.

Names and local node orders are meshio's/VTK's: "tetra" has the vertices (0,0,0), (1,0,0),
(0,1,0), (0,0,1) (positively oriented: det J > 0 for a cell with the same orientation);
"hexahedron" has the bottom face (ζ = −1) counterclockwise seen from above, then the top face:
(−,−,−), (+,−,−), (+,+,−), (−,+,−), (−,−,+), (+,−,+), (+,+,+), (−,+,+).

Quadrature rules integrate polynomials of total degree `order` exactly (tetrahedron) or of
degree `order` in each variable (hexahedron, tensor Gauss–Legendre).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Local faces with the outward normal by the right-hand rule (counterclockwise seen from
# outside), as local node indices; FACE_TYPE[cell] is the 2D reference element of a face.
FACES: dict[str, np.ndarray] = {
    "tetra": np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]),
    "hexahedron": np.array(
        [
            [0, 4, 7, 3],  # ξ = −1
            [1, 2, 6, 5],  # ξ = +1
            [0, 1, 5, 4],  # η = −1
            [2, 3, 7, 6],  # η = +1
            [0, 3, 2, 1],  # ζ = −1
            [4, 5, 6, 7],  # ζ = +1
        ]
    ),
}
FACE_TYPE = {"tetra": "triangle", "hexahedron": "quad"}
CELL_TYPES = ("hexahedron", "tetra")

_HEX_VERTICES = np.array(
    [
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
        [1.0, -1.0, 1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, 1.0],
    ]
)
_TET_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def _gauss01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n-point Gauss–Legendre on [0, 1]: points (n,), weights (n,) summing to 1."""
    t, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (t + 1.0), 0.5 * w


def _tet_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (n_qp, 3) and weights (n_qp,) (sum 1/6) on the reference tetrahedron."""
    if order < 0:
        raise ValueError(f"quadrature order must be non-negative, got {order}")
    if order <= 1:
        return np.full((1, 3), 0.25), np.array([1.0 / 6.0])
    if order == 2:  # the symmetric 4-point rule, a = (5 + 3√5)/20, b = (5 − √5)/20
        a, b = (5 + 3 * np.sqrt(5)) / 20, (5 - np.sqrt(5)) / 20
        bary = np.full((4, 4), b)  # (4 points, barycentrics λ0..λ3)
        np.fill_diagonal(bary, a)
        return bary[:, 1:], np.full(4, 1.0 / 24.0)
    # Collapsed (Duffy) Gauss product: s = a, t = b(1 − a), u = c(1 − a)(1 − b), Jacobian
    # (1 − a)²(1 − b); a monomial of total degree d becomes degree ≤ d + 2 in each variable.
    n = (order + 4) // 2  # 2n − 1 ≥ order + 2
    x, w = _gauss01(n)
    A, B, Cc = np.meshgrid(x, x, x, indexing="ij")  # (n, n, n) each
    W = np.einsum("i,j,k->ijk", w, w, w)  # (n, n, n)
    s, t, u = A, B * (1 - A), Cc * (1 - A) * (1 - B)
    jac = (1 - A) ** 2 * (1 - B)
    return np.stack([s.ravel(), t.ravel(), u.ravel()], axis=1), (W * jac).ravel()


def _hex_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    if order < 0:
        raise ValueError(f"quadrature order must be non-negative, got {order}")
    t, w = np.polynomial.legendre.leggauss(order // 2 + 1)  # exact to degree 2n − 1 ≥ order
    X, Y, Z = np.meshgrid(t, t, t, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1), np.einsum(
        "i,j,k->ijk", w, w, w
    ).ravel()


@dataclass(frozen=True)
class ReferenceElement3D:
    """Shape functions, reference gradients and quadrature of P1 ("tetra") or Q1 ("hexahedron")."""

    name: str

    @property
    def n_loc(self) -> int:
        """Number of local nodes (shape functions)."""
        return 4 if self.name == "tetra" else 8

    @property
    def vertices(self) -> np.ndarray:
        """(n_loc, 3) reference coordinates of the local nodes."""
        return (_TET_VERTICES if self.name == "tetra" else _HEX_VERTICES).copy()

    @property
    def centroid(self) -> np.ndarray:
        """(3,) reference coordinates of the centroid."""
        return self.vertices.mean(axis=0)

    @property
    def volume(self) -> float:
        """Volume of the reference cell."""
        return 1.0 / 6.0 if self.name == "tetra" else 8.0

    def values(self, pts: np.ndarray) -> np.ndarray:
        """Shape function values at reference points `pts` (n_pts, 3): (n_pts, n_loc)."""
        p = np.asarray(pts, dtype=float)  # (n_pts, 3)
        if self.name == "tetra":
            return np.concatenate([1 - p.sum(axis=1, keepdims=True), p], axis=1)
        return 0.125 * np.prod(1 + p[:, None, :] * _HEX_VERTICES[None], axis=2)  # (n_pts, 8)

    def gradients(self, pts: np.ndarray) -> np.ndarray:
        """Reference gradients at `pts` (n_pts, 3): (n_pts, n_loc, 3)."""
        p = np.asarray(pts, dtype=float)  # (n_pts, 3)
        if self.name == "tetra":
            g = np.concatenate([-np.ones((1, 3)), np.eye(3)])  # (4, 3)
            return np.broadcast_to(g, (p.shape[0], 4, 3)).copy()
        f = 1 + p[:, None, :] * _HEX_VERTICES[None]  # (n_pts, 8, 3) the three 1D factors
        g = np.empty_like(f)  # (n_pts, 8, 3)
        for i in range(3):
            others = [j for j in range(3) if j != i]
            g[..., i] = 0.125 * _HEX_VERTICES[:, i] * f[..., others[0]] * f[..., others[1]]
        return g

    def quadrature(self, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Points (n_qp, 3) and weights (n_qp,) exact for polynomials of degree `order`."""
        return _tet_rule(order) if self.name == "tetra" else _hex_rule(order)


def reference_element3d(cell_type: str) -> ReferenceElement3D:
    """The reference element of a 3D mesh's `cell_type` ("tetra" or "hexahedron")."""
    if cell_type not in CELL_TYPES:
        raise ValueError(f"unknown cell type {cell_type!r}; expected one of {CELL_TYPES}")
    return ReferenceElement3D(cell_type)
