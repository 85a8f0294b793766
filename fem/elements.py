"""Reference elements of P1/Q1 in 1D, 2D and 3D as data: one `ReferenceElement` type.

Cells: P1 on the triangle (0,0)-(1,0)-(0,1) ("triangle") and the tetrahedron (0,0,0), (1,0,0),
(0,1,0), (0,0,1) ("tetra"); Q1 on the square [−1, 1]² ("quad") and the cube [−1, 1]³
("hexahedron"). Facets of 2D cells: P1 on the segment [0, 1] ("line"). Names and local node
orders are meshio's/VTK's: triangles and quads counterclockwise (as `fem.mesh.Mesh.cells`);
tetrahedra positively oriented (det J > 0); hexahedra with the bottom face (ζ = −1)
counterclockwise seen from above, then the top face.

Quadrature rules integrate polynomials of total degree `order` exactly on simplices (Dunavant
on the triangle up to order 5; the centroid and the symmetric 4-point rule on the tetrahedron;
collapsed Gauss products beyond) or of degree `order` in each variable on tensor cells
(Gauss–Legendre products). Every integral of fem (cells, facets, mortar pieces) takes its rule
from here.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import reduce

import numpy as np

# Symmetric triangle rules on the reference triangle (area 1/2): order -> (orbits), where an
# orbit (a, w) is the 3 points (a, a), (1 − 2a, a), (a, 1 − 2a) with weight w each, or the
# centroid when a = 1/3 (one point). Dunavant (1985), weights normalised to sum to 1.
_TRIANGLE_RULES: dict[int, list[tuple[float, float]]] = {
    1: [(1 / 3, 1.0)],
    2: [(1 / 6, 1 / 3)],
    4: [
        (0.445948490915965, 0.223381589678011),
        (0.091576213509771, 0.109951743655322),
    ],
    5: [
        (1 / 3, 0.225),
        (0.470142064105115, 0.132394152788506),
        (0.101286507323456, 0.125939180544827),
    ],
}


def _check_order(order: int) -> None:
    if order < 0:
        raise ValueError(f"quadrature order must be non-negative, got {order}")


def _gauss_product(n: int, dim: int) -> tuple[list[np.ndarray], np.ndarray]:
    """The n-point Gauss–Legendre product on [−1, 1]^dim: coordinates (dim arrays (n, …, n))
    and weights (n, …, n)."""
    t, w = np.polynomial.legendre.leggauss(n)
    return np.meshgrid(*[t] * dim, indexing="ij"), reduce(np.multiply.outer, [w] * dim)


def _collapsed_rule(order: int, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Collapsed (Duffy) Gauss product on the reference simplex of `dim`, exact for total
    degree ≤ `order`: points (n^dim, dim), weights (n^dim,) summing to 1/dim! (dim = 1: Gauss
    on the segment [0, 1]).

    ξ_0 = a_0, ξ_i = a_i Π_{j<i} (1 − a_j) on the cube [0, 1]^dim, Jacobian
    Π_i (1 − a_i)^(dim − 1 − i); a monomial of total degree k becomes degree ≤ k + dim − 1 in
    each a_i, so n = ⌈(order + dim)/2⌉ Gauss points per direction suffice.
    """
    _check_order(order)
    t, W = _gauss_product((order + dim + 1) // 2, dim)  # 2n − 1 ≥ order + dim − 1
    a, W = [0.5 * (g + 1.0) for g in t], 0.5**dim * W  # the product on [0, 1]^dim
    pts, jac = [], 1.0
    for i in range(dim):
        p = a[i]
        for j in range(i):
            p = p * (1 - a[j])
        pts.append(p.ravel())
        jac = jac * (1 - a[i]) ** (dim - 1 - i)
    return np.stack(pts, axis=1), (W * jac).ravel()


def _triangle_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (n_qp, 2) and weights (n_qp,) (sum 1/2) on the reference triangle: Dunavant's
    symmetric rules up to order 5, collapsed Gauss beyond."""
    _check_order(order)
    avail = [o for o in sorted(_TRIANGLE_RULES) if o >= order]
    if not avail:
        return _collapsed_rule(order, 2)
    pts, wts = [], []
    for a, w in _TRIANGLE_RULES[avail[0]]:
        orbit = [(a, a)] if np.isclose(a, 1 / 3) else [(a, a), (1 - 2 * a, a), (a, 1 - 2 * a)]
        pts += orbit
        wts += [w] * len(orbit)
    return np.array(pts), 0.5 * np.array(wts)


def _tet_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (n_qp, 3) and weights (n_qp,) (sum 1/6) on the reference tetrahedron."""
    _check_order(order)
    if order <= 1:
        return np.full((1, 3), 0.25), np.array([1.0 / 6.0])
    if order == 2:  # the symmetric 4-point rule, a = (5 + 3√5)/20, b = (5 − √5)/20
        a, b = (5 + 3 * np.sqrt(5)) / 20, (5 - np.sqrt(5)) / 20
        bary = np.full((4, 4), b)  # (4 points, barycentrics λ0..λ3)
        np.fill_diagonal(bary, a)
        return bary[:, 1:], np.full(4, 1.0 / 24.0)
    return _collapsed_rule(order, 3)


def _tensor_rule(order: int, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre product on [−1, 1]^dim: points (n^dim, dim), weights (n^dim,)."""
    _check_order(order)
    grids, W = _gauss_product(order // 2 + 1, dim)  # exact to degree 2n − 1 ≥ order
    return np.stack([g.ravel() for g in grids], axis=1), W.ravel()


_RULES = {
    "line": lambda order: _collapsed_rule(order, 1),
    "triangle": _triangle_rule,
    "tetra": _tet_rule,
    "quad": lambda order: _tensor_rule(order, 2),
    "hexahedron": lambda order: _tensor_rule(order, 3),
}


@dataclass(frozen=True, eq=False)
class ReferenceElement:
    """One reference element as data: its local nodes, facets and quadrature orders.

    name : meshio's cell type name.
    vertices : (n_loc, d) reference coordinates of the local nodes.
    simplex : P1 (shape functions barycentric) or else Q1 (tensor products of 1D hats).
    facets : (n_facets, k) local nodes of the facets, outward (2D: the domain on the left of
        each edge; 3D: counterclockwise seen from outside); (0, 1) empty for "line".
    facet_type : name of the facets' reference element ("" for "line").
    form_order : quadrature order of the forms ∫ ∇φ·∇θ (exact: constant gradients on a simplex,
        degree 2 in each variable on a parallelogram/parallelepiped).
    mass_order : quadrature order of ∫ φ θ (exact: det J of a Q1 map has degree d − 1 in each
        variable, so the integrand has degree 2 + (d − 1) ≤ 2n − 1 with n = 2 (2D) or 3 (3D)).
    """

    name: str
    vertices: np.ndarray
    simplex: bool
    facets: np.ndarray
    facet_type: str
    form_order: int
    mass_order: int

    @property
    def dim(self) -> int:
        """Dimension of the reference cell."""
        return self.vertices.shape[1]

    @property
    def n_loc(self) -> int:
        """Number of local nodes (shape functions)."""
        return self.vertices.shape[0]

    @property
    def centroid(self) -> np.ndarray:
        """(d,) reference coordinates of the centroid."""
        return self.vertices.mean(axis=0)

    @property
    def check_points(self) -> np.ndarray:
        """(n_pts, d) points where det J > 0 is checked: constant on a simplex; affine in each
        variable on a quad, so its vertices suffice; on a hexahedron of degree 2 in each
        variable, checked at the vertices (necessary: 6 × the corner tetrahedra's volumes) and
        at the 3×3×3 Gauss points, where the integrals use it."""
        if self.simplex:
            return self.centroid[None, :]
        if self.dim < 3:
            return self.vertices
        return np.concatenate([self.vertices, self.quadrature(4)[0]])  # (8 + 27, 3)

    def values(self, pts: np.ndarray) -> np.ndarray:
        """Shape function values at reference points `pts` (n_pts, d): (n_pts, n_loc)."""
        p = np.asarray(pts, dtype=float)  # (n_pts, d)
        if self.simplex:
            return np.concatenate([1 - p.sum(axis=1, keepdims=True), p], axis=1)
        # Π_i (1 + ξ_i v_ai) / 2^d
        return 0.5**self.dim * np.prod(1 + p[:, None, :] * self.vertices[None], axis=2)

    def gradients(self, pts: np.ndarray) -> np.ndarray:
        """Reference gradients at `pts` (n_pts, d): (n_pts, n_loc, d)."""
        p = np.asarray(pts, dtype=float)  # (n_pts, d)
        d = self.dim
        if self.simplex:
            g = np.concatenate([-np.ones((1, d)), np.eye(d)])  # (d + 1, d)
            return np.broadcast_to(g, (p.shape[0], d + 1, d)).copy()
        f = 1 + p[:, None, :] * self.vertices[None]  # (n_pts, n_loc, d) the 1D factors
        g = np.empty_like(f)  # (n_pts, n_loc, d)
        for i in range(d):
            others = np.prod(np.delete(f, i, axis=2), axis=2)  # (n_pts, n_loc)
            g[..., i] = 0.5**d * self.vertices[:, i] * others
        return g

    def quadrature(self, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Points (n_qp, d) and weights (n_qp,) exact for polynomials of degree `order`."""
        return _RULES[self.name](order)

    def jacobians(self, X: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """J_ij = ∂x_i/∂ξ_j of cells with nodes X (n_cells, n_loc, d) at `pts` (n_pts, d):
        (n_cells, n_pts, d, d)."""
        return np.einsum("cai,qaj->cqij", X, self.gradients(pts), optimize=True)


# the hexahedron's vertices: the bottom face (ζ = −1) counterclockwise from above, then the top
_HEX = np.array(
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
ELEMENTS: dict[str, ReferenceElement] = {
    e.name: e
    for e in (
        ReferenceElement("line", np.array([[0.0], [1.0]]), True, np.zeros((0, 1), int), "", 0, 2),
        ReferenceElement(
            "triangle",
            np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
            True,
            np.array([[0, 1], [1, 2], [2, 0]]),
            "line",
            0,
            2,
        ),
        ReferenceElement(
            "quad",
            np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]),
            False,
            np.array([[0, 1], [1, 2], [2, 3], [3, 0]]),
            "line",
            2,
            2,
        ),
        ReferenceElement(
            "tetra",
            np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
            True,
            np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]),
            "triangle",
            0,
            2,
        ),
        ReferenceElement(
            "hexahedron",
            _HEX,
            False,
            np.array(
                [
                    [0, 4, 7, 3],  # ξ = −1
                    [1, 2, 6, 5],  # ξ = +1
                    [0, 1, 5, 4],  # η = −1
                    [2, 3, 7, 6],  # η = +1
                    [0, 3, 2, 1],  # ζ = −1
                    [4, 5, 6, 7],  # ζ = +1
                ]
            ),
            "quad",
            2,
            4,
        ),
    )
}
# (dimension, nodes per cell) -> the cell type of a mesh, and the cell types of each dimension
CELL_TYPE: dict[tuple[int, int], str] = {
    (e.dim, e.n_loc): n for n, e in ELEMENTS.items() if e.facet_type
}
CELL_TYPES: dict[int, tuple[str, ...]] = {
    d: tuple(n for (k, _), n in CELL_TYPE.items() if k == d) for d in (2, 3)
}
# Local facets (the cell's boundary entities of dimension d − 1) oriented outward, and their type
FACETS: dict[str, np.ndarray] = {n: e.facets for n, e in ELEMENTS.items() if e.facet_type}
FACET_TYPE: dict[str, str] = {n: e.facet_type for n, e in ELEMENTS.items() if e.facet_type}


def _cycle(k: int) -> np.ndarray:
    """(k, 2) the sides (i, i+1 mod k) of a polygon with k corners."""
    return np.stack([np.arange(k), np.roll(np.arange(k), -1)], axis=1)


# Local edges (pairs of local nodes) of each cell type; a polygon's follow its corners.
EDGES: dict[str, np.ndarray] = {
    "line": np.array([[0, 1]]),
    "triangle": _cycle(3),
    "quad": _cycle(4),
    "tetra": np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]),
    "hexahedron": np.array(
        [
            [0, 1],
            [1, 2],
            [3, 2],
            [0, 3],
            [4, 5],
            [5, 6],
            [7, 6],
            [4, 7],
            [0, 4],
            [1, 5],
            [2, 6],
            [3, 7],
        ]
    ),
}


def reference_element(cell_type: str) -> ReferenceElement:
    """The reference element of `cell_type` (a mesh's cell type, or "line" for 2D facets)."""
    if cell_type not in ELEMENTS:
        raise ValueError(f"unknown cell type {cell_type!r}; expected one of {tuple(ELEMENTS)}")
    return ELEMENTS[cell_type]
