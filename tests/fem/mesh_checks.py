"""Meshes and checks shared by the mesh tests (fem.mesh, fem.meshing, fem.refine, ...)."""

import numpy as np

from fem.elements import EDGES
from fem.mesh import Mesh

BOUNDS = ((0.0, 2.0), (-0.5, 0.5), (0.0, 1.5))  # the test box


def wavy(p: np.ndarray, amount: float = 0.06) -> np.ndarray:
    """A smooth distortion of the box BOUNDS that keeps its faces plane."""
    x, y, z = p.T
    bx = x * (2 - x)  # vanishes on x = 0, 2
    by = (y + 0.5) * (0.5 - y)
    bz = z * (1.5 - z)
    q = p.copy()
    q[:, 0] += amount * np.sin(3 * y + 2 * z) * bx
    q[:, 1] += amount * np.cos(2 * x - z) * by * 4
    q[:, 2] += amount * np.sin(x + 2 * y) * bz
    return q


def cell_volumes(mesh: Mesh) -> np.ndarray:
    from fem.assembly import cell_geometry

    return cell_geometry(mesh, order=2).w.sum(axis=1)


def tet_quality(mesh: Mesh) -> float:
    """min over cells of 6√2 V / L_max³ (1 for the regular tetrahedron)."""
    P = mesh.points[mesh.cells]  # (n_cells, 4, 3)
    V = np.abs(np.linalg.det(P[:, 1:] - P[:, :1])) / 6
    L = np.max([np.linalg.norm(P[:, a] - P[:, b], axis=1) for a, b in EDGES["tetra"]], axis=0)
    return float((6 * np.sqrt(2) * V / L**3).min())


def signed_areas(mesh: Mesh) -> np.ndarray:
    """Shoelace formula per cell: positive for counterclockwise cells."""
    P = mesh.points[mesh.cells]  # (n_cells, k, 2)
    Q = np.roll(P, -1, axis=1)  # (n_cells, k, 2)
    return 0.5 * (P[..., 0] * Q[..., 1] - Q[..., 0] * P[..., 1]).sum(axis=1)


def part_length(mesh: Mesh, name: str) -> float:
    e = mesh.boundaries[name]
    return float(np.linalg.norm(mesh.points[e[:, 1]] - mesh.points[e[:, 0]], axis=1).sum())


def directed_cell_edges(mesh: Mesh) -> set[tuple[int, int]]:
    c = mesh.cells
    return set(zip(c.ravel().tolist(), np.roll(c, -1, axis=1).ravel().tolist(), strict=True))


def check_mesh(mesh: Mesh) -> None:
    """Cells ccw; boundary parts ordered chains, domain on the left, covering ∂Ω exactly."""
    assert (signed_areas(mesh) > 0).all()
    cell_edges = directed_cell_edges(mesh)
    all_bnd = []
    for name, e in mesh.boundaries.items():
        assert (e[1:, 0] == e[:-1, 1]).all(), f"{name} edges not ordered along the part"
        directed = set(map(tuple, e.tolist()))
        # the cell having (a, b) as a ccw edge lies on the left of (a, b)
        assert directed <= cell_edges, f"{name} has the domain on its right"
        all_bnd += [tuple(sorted(p)) for p in e.tolist()]
    undirected = [tuple(sorted(p)) for p in cell_edges]
    vals, counts = np.unique(np.array(undirected), axis=0, return_counts=True)
    outer = set(map(tuple, vals[counts == 1].tolist()))
    assert sorted(all_bnd) == sorted(outer)
