"""Reference elements: P1 on the triangle (0,0)-(1,0)-(0,1), Q1 on the square [−1, 1]².

Local node order is counterclockwise, matching `Mesh.cells`. Quadrature rules integrate
polynomials of total degree `order` exactly (triangle) or of degree `order` in each variable
(quad, tensor Gauss–Legendre).
"""

from __future__ import annotations

from dataclasses import dataclass

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


def _triangle_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    avail = [o for o in sorted(_TRIANGLE_RULES) if o >= order]
    if order < 0 or not avail:
        raise ValueError(
            f"no triangle rule of order {order}; available up to {max(_TRIANGLE_RULES)}"
        )
    pts, wts = [], []
    for a, w in _TRIANGLE_RULES[avail[0]]:
        orbit = [(a, a)] if np.isclose(a, 1 / 3) else [(a, a), (1 - 2 * a, a), (a, 1 - 2 * a)]
        pts += orbit
        wts += [w] * len(orbit)
    return np.array(pts), 0.5 * np.array(wts)


def _quad_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    if order < 0:
        raise ValueError(f"quadrature order must be non-negative, got {order}")
    t, w = np.polynomial.legendre.leggauss(order // 2 + 1)  # exact to degree 2n − 1 ≥ order
    X, Y = np.meshgrid(t, t, indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1), np.outer(w, w).ravel()


@dataclass(frozen=True)
class ReferenceElement:
    """Shape functions, reference gradients and quadrature of P1 ("triangle") or Q1 ("quad")."""

    name: str

    @property
    def n_loc(self) -> int:
        """Number of local nodes (shape functions)."""
        return 3 if self.name == "triangle" else 4

    @property
    def vertices(self) -> np.ndarray:
        """(n_loc, 2) reference coordinates of the local nodes."""
        if self.name == "triangle":
            return np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        return np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])

    @property
    def centroid(self) -> np.ndarray:
        """(2,) reference coordinates of the centroid."""
        return self.vertices.mean(axis=0)

    def values(self, pts: np.ndarray) -> np.ndarray:
        """Shape function values at reference points `pts` (n_pts, 2): (n_pts, n_loc)."""
        s, t = np.asarray(pts, dtype=float).T  # (n_pts,) each
        if self.name == "triangle":
            return np.stack([1 - s - t, s, t], axis=1)
        xs, ys = self.vertices.T  # (4,) each
        return 0.25 * (1 + s[:, None] * xs) * (1 + t[:, None] * ys)

    def gradients(self, pts: np.ndarray) -> np.ndarray:
        """Reference gradients at `pts` (n_pts, 2): (n_pts, n_loc, 2)."""
        s, t = np.asarray(pts, dtype=float).T  # (n_pts,) each
        if self.name == "triangle":
            g = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])  # (3, 2)
            return np.broadcast_to(g, (s.size, 3, 2)).copy()
        xs, ys = self.vertices.T  # (4,) each
        ds = 0.25 * xs * (1 + t[:, None] * ys)  # (n_pts, 4)
        dt = 0.25 * ys * (1 + s[:, None] * xs)  # (n_pts, 4)
        return np.stack([ds, dt], axis=2)

    def quadrature(self, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Points (n_qp, 2) and weights (n_qp,) exact for polynomials of degree `order`."""
        return _triangle_rule(order) if self.name == "triangle" else _quad_rule(order)


def reference_element(cell_type: str) -> ReferenceElement:
    """The reference element of a mesh's `cell_type` ("triangle" or "quad")."""
    if cell_type not in ("triangle", "quad"):
        raise ValueError(f"unknown cell type {cell_type!r}; expected 'triangle' or 'quad'")
    return ReferenceElement(cell_type)
