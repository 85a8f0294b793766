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
from .mesh import CellMesh, Mesh

SIDES = ("left", "right", "front", "back", "bottom", "top")  # x0, x1, y0, y1, z0, z1


@dataclass(frozen=True, eq=False)
class Mesh3D(CellMesh):
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

    def refined_nodes(self, times: int) -> int:
        """Nodes after `times` uniform refinements (`refine`: every cell into 8), counted
        without refining. With V nodes, E edges, F faces and C cells one refinement gives,
        for tetrahedra (new nodes at edge midpoints), V + E nodes, 2E + 3F + C edges, 4F + 8C
        faces; for hexahedra (also face and cell centres) V + E + F + C nodes, 2E + 4F + 6C
        edges, 4F + 12C faces; 8C cells."""
        ctype, C = self.cell_type, self.n_cells

        def distinct(local: np.ndarray) -> int:  # local: (n_local, k) node lists per cell
            items = self.cells[:, local].reshape(-1, local.shape[1])  # (C n_local, k)
            return len(np.unique(np.sort(items, axis=1), axis=0))

        V, E, F = self.n_nodes, distinct(EDGES[ctype]), distinct(FACES[ctype])
        for _ in range(times):
            if ctype == "tetra":
                V, E, F = V + E, 2 * E + 3 * F + C, 4 * F + 8 * C
            else:
                V, E, F = V + E + F + C, 2 * E + 4 * F + 6 * C, 4 * F + 12 * C
            C *= 8
        return V


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


# Local edges (pairs of local nodes) of each cell type.
EDGES: dict[str, np.ndarray] = {
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
# The eight children of a tetrahedron [x0, x1, x2, x3] in terms of its 10 nodes (0–3 the
# vertices, 4 + e the midpoint of local edge e of EDGES["tetra"]): the four corner tetrahedra
# and the inner octahedron split into 4 along one of its 3 diagonals x01–x23, x02–x13, x03–x12
# (the shortest is chosen per cell, which keeps repeated refinement from degrading the cells).
_X01, _X02, _X03, _X12, _X13, _X23 = range(4, 10)
_CORNERS = [
    [0, _X01, _X02, _X03],
    [_X01, 1, _X12, _X13],
    [_X02, _X12, 2, _X23],
    [_X03, _X13, _X23, 3],
]
_DIAGONALS = [(_X01, _X23), (_X02, _X13), (_X03, _X12)]


def _octahedron(d: int) -> list[list[int]]:
    """The 4 tetrahedra of the inner octahedron around diagonal `d` of `_DIAGONALS`."""
    p, q = _DIAGONALS[d]
    (r1, r2), (s1, s2) = [_DIAGONALS[k] for k in range(3) if k != d]
    return [[p, q, r1, s1], [p, q, s1, r2], [p, q, r2, s2], [p, q, s2, r1]]


def _oriented(children: np.ndarray, ref_points: np.ndarray) -> np.ndarray:
    """Swap the 2nd and 3rd node of the children (k, 4) that are negative on the reference."""
    P = ref_points[children]  # (k, 4, 3)
    neg = np.linalg.det(P[:, 1:] - P[:, :1]) < 0  # (k,)
    out = children.copy()
    out[neg, 1], out[neg, 2] = children[neg, 2], children[neg, 1]
    return out


def _sorted_keys(items: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of the sorted node tuples `items` (n, k): (unique (m, k), inverse (n,))."""
    u, inv = np.unique(np.sort(items, axis=1), axis=0, return_inverse=True)
    return u, inv.ravel()


def _find(keys: np.ndarray, items: np.ndarray) -> np.ndarray:
    """Row index in the sorted unique `keys` (m, k) of each sorted row of `items` (n, k)."""
    s = np.sort(items, axis=1)
    kv = keys.view([("", keys.dtype)] * keys.shape[1]).ravel()
    sv = np.ascontiguousarray(s).view([("", s.dtype)] * s.shape[1]).ravel()
    pos = np.minimum(np.searchsorted(kv, sv), kv.size - 1)
    if (kv[pos] != sv).any():
        raise ValueError("a boundary face is not a face of the mesh's cells")
    return pos


def _refine_once(mesh: Mesh3D) -> Mesh3D:
    n, ctype = mesh.n_nodes, mesh.cell_type
    cells = mesh.cells  # (n_cells, k)
    local_edges = EDGES[ctype]  # (n_e, 2)
    edges = cells[:, local_edges]  # (n_cells, n_e, 2)
    ukeys, einv = _sorted_keys(edges.reshape(-1, 2))  # (n_edges, 2), (n_cells n_e,)
    mid = n + einv.reshape(cells.shape[0], -1)  # (n_cells, n_e) midpoint node of each edge
    points = [mesh.points, mesh.points[ukeys].mean(axis=1)]  # (n, 3), (n_edges, 3)
    fkeys = None
    if ctype == "tetra":
        ref10 = np.concatenate(
            [
                reference_element3d("tetra").vertices,
                reference_element3d("tetra").vertices[local_edges].mean(axis=1),
            ]
        )  # (10, 3)
        nodes = np.concatenate([cells, mid], axis=1)  # (n_cells, 10)
        patterns = np.stack(
            [_oriented(np.array(_CORNERS + _octahedron(d)), ref10) for d in range(3)]
        )  # (3, 8, 4)
        P = np.concatenate(points)[nodes]  # (n_cells, 10, 3)
        diag = np.array(_DIAGONALS)  # (3, 2)
        length = np.linalg.norm(P[:, diag[:, 0]] - P[:, diag[:, 1]], axis=2)  # (n_cells, 3)
        choice = np.argmin(length, axis=1)  # (n_cells,)
        children = np.take_along_axis(
            nodes[:, None, :], patterns[choice].reshape(len(nodes), -1)[:, None, :], axis=2
        ).reshape(len(nodes), 8, 4)  # (n_cells, 8, 4)
    else:
        local_faces = FACES["hexahedron"]  # (6, 4)
        fkeys, finv = _sorted_keys(cells[:, local_faces].reshape(-1, 4))  # (n_faces, 4)
        fc = n + ukeys.shape[0] + finv.reshape(cells.shape[0], 6)  # (n_cells, 6) face centres
        cc = n + ukeys.shape[0] + fkeys.shape[0] + np.arange(cells.shape[0])  # (n_cells,)
        points += [mesh.points[fkeys].mean(axis=1), mesh.points[cells].mean(axis=1)]
        V = reference_element3d("hexahedron").vertices.astype(int)  # (8, 3) in {−1, 1}
        grid = np.empty((cells.shape[0], 3, 3, 3), dtype=cells.dtype)  # node at ref point − 1
        grid[(slice(None), *(V + 1).T)] = cells
        e_pos = (V[local_edges[:, 0]] + V[local_edges[:, 1]]) // 2 + 1  # (12, 3)
        grid[(slice(None), *e_pos.T)] = mid
        f_pos = V[local_faces].sum(axis=1) // 4 + 1  # (6, 3)
        grid[(slice(None), *f_pos.T)] = fc
        grid[:, 1, 1, 1] = cc
        offsets = (V + 1) // 2  # (8, 3) lower corner of each octant in index space
        idx = offsets[:, None, :] + (V[None, :, :] + 1) // 2  # (8 children, 8 nodes, 3)
        children = grid[:, idx[..., 0], idx[..., 1], idx[..., 2]]  # (n_cells, 8, 8)
    boundaries = {}
    for name, faces in mesh.boundaries.items():
        k = faces.shape[1]
        fe = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2)  # (n_b, k, 2) face edges
        m = n + _find(ukeys, fe.reshape(-1, 2)).reshape(-1, k)  # (n_b, k) m_i on (f_i, f_i+1)
        if k == 3:
            a, b, c = faces.T
            mab, mbc, mca = m.T
            sub = [[a, mab, mca], [mab, b, mbc], [mca, mbc, c], [mab, mbc, mca]]
        else:
            f = n + ukeys.shape[0] + _find(fkeys, faces)  # (n_b,) face centres
            a, b, c, d = faces.T
            mab, mbc, mcd, mda = m.T
            sub = [[a, mab, f, mda], [mab, b, mbc, f], [f, mbc, c, mcd], [mda, f, mcd, d]]
        boundaries[name] = np.stack([np.stack(s, axis=1) for s in sub], axis=1).reshape(-1, k)
    return Mesh3D(np.concatenate(points), children.reshape(-1, cells.shape[1]), boundaries)


def refine(mesh: Mesh3D, times: int = 1) -> Mesh3D:
    """Uniform refinement, `times` times: each cell into 8, each boundary face into 4.

    Nested: the parent nodes keep their indices, then come the edge midpoints (and for
    hexahedra the face and cell centres, the points of the trilinear map); so a parent nodal
    vector is the restriction of the child's to its first n_nodes entries. Tetrahedra are split
    into 4 corner tetrahedra and the inner octahedron along its shortest diagonal, children
    oriented to det J > 0; parts keep their names and outward orientation.
    """
    if int(times) != times or times < 0:
        raise ValueError(f"times must be a non-negative integer, got {times!r}")
    for _ in range(int(times)):
        mesh = _refine_once(mesh)
        check_cells(mesh)
    return mesh


END_PARTS = ("z0", "z1")  # the end faces of an extruded mesh


def extrude(mesh2d: Mesh, z: tuple[float, float], layers: int = 1) -> Mesh3D:
    """The 2D quadrilateral mesh `mesh2d` (x–y plane) extruded over [z0, z1] in `layers` layers
    of hexahedra.

    Node (i, layer l) is i + l·n (the 2D numbering repeated per layer); a 2D boundary part
    becomes the quadrilaterals [a, b, b', a'] over its edges (a, b) (outward, as the 2D edges
    have the domain on their left); the end faces are the parts "z0" (z = z0) and "z1".
    ValueError for triangles, a part named like an end, or bad z/layers.
    """
    if mesh2d.cells.shape[1] != 4:
        raise ValueError(f"extrude needs quadrilateral cells, got {mesh2d.cells.shape[1]} nodes")
    if int(layers) != layers or layers < 1:
        raise ValueError(f"layers must be a positive integer, got {layers!r}")
    if not z[0] < z[1]:
        raise ValueError(f"need z0 < z1, got z={z!r}")
    clash = sorted(set(END_PARTS) & set(mesh2d.boundaries))
    if clash:
        raise ValueError(f"the 2D mesh has parts named {clash}, reserved for the end faces")
    n, L = mesh2d.points.shape[0], int(layers)
    zs = np.linspace(z[0], z[1], L + 1)  # (L + 1,)
    points = np.concatenate([np.column_stack([mesh2d.points, np.full(n, zk)]) for zk in zs])
    off = n * np.arange(L)[:, None, None]  # (L, 1, 1)
    q = mesh2d.cells  # (n_c, 4) counterclockwise seen from +z
    cells = np.concatenate([q + off, q + off + n], axis=2).reshape(-1, 8)  # (L n_c, 8)
    boundaries = {
        name: np.concatenate(
            [np.stack([e[:, 0], e[:, 1], e[:, 1] + n, e[:, 0] + n], 1) + k * n for k in range(L)]
        )  # (L n_e, 4) layer by layer
        for name, e in mesh2d.boundaries.items()
    }
    boundaries[END_PARTS[0]] = q[:, ::-1].copy()
    boundaries[END_PARTS[1]] = q + L * n
    out = Mesh3D(points, cells, boundaries)
    check_cells(out)
    return out
