"""3D meshes of tetrahedra (P1) or hexahedra (Q1) with named boundary parts; structured boxes.

`box` numbers node (i, j, k) (i along x, j along y, k along z) as i + (nx+1)(j + (ny+1) k).
Tetrahedral boxes split every hexahedron into 6 tetrahedra around its diagonal from the corner
of smallest to the corner of largest coordinates (Kuhn's subdivision): neighbouring cells then
split their common face along the same diagonal (conforming), and every tetrahedron is
positively oriented. A level multiplies the cells per direction by 2 (8 times the cells).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import permutations

import numpy as np

from .elements3d import CELL_TYPES, FACES, reference_element3d

SIDES = ("left", "right", "front", "back", "bottom", "top")  # x0, x1, y0, y1, z0, z1


@dataclass(frozen=True, eq=False)
class Mesh3D:
    """A 3D mesh.

    points : (n_nodes, 3) float coordinates.
    cells : (n_cells, 4) tetrahedra or (n_cells, 8) hexahedra, local order of `fem.elements3d`,
        positively oriented (det J > 0).
    boundaries : name -> (n_faces, 3) triangles or (n_faces, 4) quadrilaterals with the outward
        normal by the right-hand rule (counterclockwise seen from outside).
    """

    points: np.ndarray
    cells: np.ndarray
    boundaries: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def cell_type(self) -> str:
        """'tetra' or 'hexahedron' (meshio's names)."""
        return "tetra" if self.cells.shape[1] == 4 else "hexahedron"

    @property
    def n_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def n_cells(self) -> int:
        return self.cells.shape[0]

    def boundary_nodes(self, name: str) -> np.ndarray:
        """Sorted unique node indices of the boundary part `name`."""
        if name not in self.boundaries:
            raise KeyError(
                f"unknown boundary {name!r}; this mesh has: {', '.join(sorted(self.boundaries))}"
            )
        return np.unique(self.boundaries[name])

    @property
    def h(self) -> float:
        """Mesh size: the largest cell diameter."""
        P = self.points[self.cells]  # (n_cells, k, 3)
        d = np.linalg.norm(P[:, :, None, :] - P[:, None, :, :], axis=-1)  # (n_cells, k, k)
        return float(d.max())


def cofactors(J: np.ndarray) -> np.ndarray:
    """Cofactor matrices of a stack of 3×3 matrices (..., 3, 3): cof = det(J) J⁻ᵀ."""
    a, b = np.roll(J, -1, axis=-1), np.roll(J, -2, axis=-1)  # columns j+1, j+2 (cyclic)
    # cof_ij = J_{i+1, j+1} J_{i+2, j+2} − J_{i+1, j+2} J_{i+2, j+1} (indices cyclic)
    return np.roll(a, -1, axis=-2) * np.roll(b, -2, axis=-2) - np.roll(b, -1, axis=-2) * np.roll(
        a, -2, axis=-2
    )


def jacobian_determinants(mesh: Mesh3D, pts: np.ndarray) -> np.ndarray:
    """det ∂x/∂ξ of every cell at reference points `pts` (n_pts, 3): (n_cells, n_pts)."""
    ref = reference_element3d(mesh.cell_type)
    X = mesh.points[mesh.cells]  # (n_cells, n_loc, 3)
    J = np.einsum("cai,qaj->cqij", X, ref.gradients(pts), optimize=True)  # (n_c, n_pts, 3, 3)
    return np.einsum("...j,...j->...", J[..., 0, :], cofactors(J)[..., 0, :])  # along row 0


def check_cells(mesh: Mesh3D) -> None:
    """Refuse inverted or degenerate cells: ValueError naming the first cell with det J ≤ 0.

    det J is constant on a tetrahedron; on a hexahedron it is checked at the 8 corners
    (positivity there is necessary: they are 6 × the volumes of the corner tetrahedra) and at
    the 27 points of the 3×3×3 Gauss rule, where the integrals use it.
    """
    if mesh.cell_type not in CELL_TYPES or mesh.points.shape[1:] != (3,):
        raise ValueError(
            f"need points (n, 3) and cells (n, 4) or (n, 8), got {mesh.points.shape}, "
            f"{mesh.cells.shape}"
        )
    ref = reference_element3d(mesh.cell_type)
    if mesh.cell_type == "tetra":
        pts = ref.centroid[None, :]  # (1, 3)
    else:
        pts = np.concatenate([ref.vertices, ref.quadrature(4)[0]])  # (35, 3)
    det = jacobian_determinants(mesh, pts)  # (n_cells, n_pts)
    scale = np.ptp(mesh.points, axis=0).max() ** 3 if mesh.n_nodes else 1.0
    bad = np.flatnonzero((det <= 1e-14 * scale).any(axis=1))  # (n_bad,)
    if bad.size:
        raise ValueError(
            f"inverted or degenerate cell {bad[0]} (nodes {mesh.cells[bad[0]].tolist()}): "
            f"det J <= 0; {bad.size} bad cell(s) in total"
        )


def exterior_faces(cells: np.ndarray, cell_type: str) -> np.ndarray:
    """The faces (n_faces, 3|4) that belong to one cell only, outward (from positive cells)."""
    local = FACES[cell_type]  # (n_f, k)
    faces = cells[:, local].reshape(-1, local.shape[1])  # (n_cells n_f, k)
    key = np.sort(faces, axis=1)  # (n_cells n_f, k)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[count[inv.ravel()] == 1]


def _kuhn_tets() -> np.ndarray:
    """(6, 4) hexahedron-local node indices of the 6 positively oriented Kuhn tetrahedra."""
    corner = {(0, 0, 0): 0, (1, 0, 0): 1, (1, 1, 0): 2, (0, 1, 0): 3}
    corner |= {(0, 0, 1): 4, (1, 0, 1): 5, (1, 1, 1): 6, (0, 1, 1): 7}
    tets = []
    for p in permutations(range(3)):
        path = [np.zeros(3, dtype=int)]
        for axis in p:
            path.append(path[-1] + np.eye(3, dtype=int)[axis])
        t = [corner[tuple(v)] for v in path]  # (4,)
        if np.linalg.det(np.array(path[1:]) - path[0]) < 0:
            t[1], t[2] = t[2], t[1]
        tets.append(t)
    return np.array(tets)


def box(
    x: tuple[float, float],
    y: tuple[float, float],
    z: tuple[float, float],
    cells: tuple[int, int, int],
    element: str = "hexahedron",
    level: int = 0,
) -> Mesh3D:
    """Structured mesh of [x0, x1] × [y0, y1] × [z0, z1] with (nx, ny, nz)·2^level cells.

    element "hexahedron" (Q1) or "tetra" (P1, 6 Kuhn tetrahedra per hexahedron). Boundary parts
    "left"/"right" (x = x0/x1), "front"/"back" (y = y0/y1), "bottom"/"top" (z = z0/z1), faces
    oriented outward.
    """
    if element not in CELL_TYPES:
        raise ValueError(f"unknown element {element!r}; expected one of {CELL_TYPES}")
    if int(level) != level or level < 0:
        raise ValueError(f"level must be a non-negative integer, got {level!r}")
    if len(cells) != 3 or any(int(n) != n or n < 1 for n in cells):
        raise ValueError(f"cell counts must be three positive integers, got {cells!r}")
    bounds = (x, y, z)
    if not all(a < b for a, b in bounds):
        raise ValueError(f"need x0 < x1, y0 < y1, z0 < z1, got x={x!r}, y={y!r}, z={z!r}")
    n = [int(c) * 2 ** int(level) for c in cells]
    axes = [np.linspace(a, b, k + 1) for (a, b), k in zip(bounds, n, strict=True)]
    Z, Y, X = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")  # (nz+1, ny+1, nx+1)
    points = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)  # (n_nodes, 3)
    idx = np.arange(points.shape[0]).reshape(n[2] + 1, n[1] + 1, n[0] + 1)  # idx[k, j, i]

    def corner(di: int, dj: int, dk: int) -> np.ndarray:
        return idx[dk : dk + n[2], dj : dj + n[1], di : di + n[0]].ravel()  # (n_hex,)

    order = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    hexes = np.stack([corner(*c) for c in order], axis=1)  # (n_hex, 8)
    conn = hexes if element == "hexahedron" else hexes[:, _kuhn_tets()].reshape(-1, 4)
    faces = exterior_faces(conn, element)  # (n_ext, k)
    F = points[faces]  # (n_ext, k, 3)
    boundaries = {}
    for s, name in enumerate(SIDES):
        axis, end = divmod(s, 2)
        on = np.isclose(F[:, :, axis], bounds[axis][end], rtol=0, atol=1e-12).all(axis=1)
        boundaries[name] = faces[on]
    mesh = Mesh3D(points, conn, boundaries)
    check_cells(mesh)
    return mesh


def transform(mesh: Mesh3D, func: Callable[[np.ndarray], np.ndarray]) -> Mesh3D:
    """The mesh with nodes moved to func(points) ((n, 3) -> (n, 3)); same cells and parts.

    Raises ValueError (via `check_cells`) if the map inverts a cell.
    """
    pts = np.asarray(func(mesh.points.copy()), dtype=float)
    if pts.shape != mesh.points.shape:
        raise ValueError(f"func returned shape {pts.shape}, expected {mesh.points.shape}")
    out = Mesh3D(pts, mesh.cells, mesh.boundaries)
    check_cells(out)
    return out
