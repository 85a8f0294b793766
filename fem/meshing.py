"""Structured meshes: rectangles (2D), boxes (3D), extrusions of 2D quadrilateral meshes, and
moved nodes (`transform`).

Node numbering of `rectangle`: node (i, j) (i along x, j along y) has index i + j (nx + 1).
Triangle meshes split every square along the diagonal from its lower-left to its upper-right
corner (all diagonals point the same way).

`box` numbers node (i, j, k) (i along x, j along y, k along z) as i + (nx+1)(j + (ny+1) k).
Tetrahedral boxes split every hexahedron into 6 tetrahedra around its diagonal from the corner
of smallest to the corner of largest coordinates (Kuhn's subdivision): neighbouring cells then
split their common face along the same diagonal (conforming), and every tetrahedron is
positively oriented. A level multiplies the cells per direction by 2 (8 times the cells).
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import permutations

import numpy as np

from .elements import CELL_TYPES
from .jacobians import check_cells
from .mesh import Mesh, exterior_facets

SIDES = ("left", "right", "front", "back", "bottom", "top")  # box sides x0, x1, y0, y1, z0, z1
_ELEMENTS = ("quad", "triangle")


def graded(t: np.ndarray, lo: float, hi: float, c: float, p: float) -> np.ndarray:
    """Coordinates t in [lo, hi] moved towards c ∈ [lo, hi] by the power p ≥ 1:
    c + (t − c)·(|t − c| / D)^(p−1), D = hi − c above c and c − lo below (ends and c fixed,
    monotone; the spacing near c shrinks like h^p). p = 1 is the identity."""
    t = np.asarray(t, dtype=float)
    if p == 1.0:
        return t
    D = np.where(t >= c, hi - c, c - lo)  # (len(t),)
    r = np.divide(np.abs(t - c), D, out=np.zeros_like(t), where=D > 0)
    return c + (t - c) * r ** (p - 1.0)


def rectangle(
    x: tuple[float, float],
    y: tuple[float, float],
    cells: tuple[int, int],
    element: str = "quad",
    focus: tuple[float, float] | None = None,
    grading: tuple[float, float] = (1.0, 1.0),
) -> Mesh:
    """Structured mesh of [x0, x1] × [y0, y1] with nx × ny cells ("quad" Q1 or "triangle" P1).

    Triangles: each square is split along its lower-left → upper-right diagonal. With `focus`
    (a point of the rectangle) the node lines are graded towards it, coordinate by coordinate
    (`graded` with the powers `grading`); refinement levels built with 2^L × the cells are
    then nested (the map is applied to nested uniform grids).

    Boundary parts "bottom" (left → right), "right" (bottom → top), "top" (right → left) and
    "left" (top → bottom): counterclockwise, with the domain on the left of each edge.
    """
    (x0, x1), (y0, y1), (nx, ny) = x, y, cells
    if element not in _ELEMENTS:
        raise ValueError(f"unknown element {element!r}; expected one of {_ELEMENTS}")
    if int(nx) != nx or int(ny) != ny or nx < 1 or ny < 1:
        raise ValueError(f"cell counts must be positive integers, got {cells!r}")
    if not (x0 < x1 and y0 < y1):
        raise ValueError(f"need x0 < x1 and y0 < y1, got x={x!r}, y={y!r}")
    nx, ny = int(nx), int(ny)
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    if focus is not None:
        (fx, fy), (px, py) = focus, grading
        if not (x0 <= fx <= x1 and y0 <= fy <= y1) or min(px, py) < 1.0:
            raise ValueError(
                f"focus {focus!r} inside the rectangle and grading ≥ 1, got {grading!r}"
            )
        xs, ys = graded(xs, x0, x1, fx, px), graded(ys, y0, y1, fy, py)
    X, Y = np.meshgrid(xs, ys)  # (ny+1, nx+1)
    points = np.stack([X.ravel(), Y.ravel()], axis=1)  # (n_nodes, 2)
    idx = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)  # idx[j, i]
    ll, lr = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()  # (nx ny,) lower-left / lower-right
    ur, ul = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()  # (nx ny,) upper-right / upper-left
    if element == "quad":
        conn = np.stack([ll, lr, ur, ul], axis=1)  # (n_cells, 4)
    else:
        lower = np.stack([ll, lr, ur], axis=1)  # (nx ny, 3)
        upper = np.stack([ll, ur, ul], axis=1)  # (nx ny, 3)
        conn = np.stack([lower, upper], axis=1).reshape(-1, 3)  # (n_cells, 3)

    def chain(nodes: np.ndarray) -> np.ndarray:
        return np.stack([nodes[:-1], nodes[1:]], axis=1)  # (n_edges, 2)

    boundaries = {
        "bottom": chain(idx[0, :]),
        "right": chain(idx[:, -1]),
        "top": chain(idx[-1, ::-1]),
        "left": chain(idx[::-1, 0]),
    }
    return Mesh(points, conn, boundaries)


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
) -> Mesh:
    """Structured mesh of [x0, x1] × [y0, y1] × [z0, z1] with (nx, ny, nz)·2^level cells.

    element "hexahedron" (Q1) or "tetra" (P1, 6 Kuhn tetrahedra per hexahedron). Boundary parts
    "left"/"right" (x = x0/x1), "front"/"back" (y = y0/y1), "bottom"/"top" (z = z0/z1), faces
    oriented outward.
    """
    if element not in CELL_TYPES[3]:
        raise ValueError(f"unknown element {element!r}; expected one of {CELL_TYPES[3]}")
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
    faces = exterior_facets(conn, element)  # (n_ext, k)
    F = points[faces]  # (n_ext, k, 3)
    boundaries = {}
    for s, name in enumerate(SIDES):
        axis, end = divmod(s, 2)
        on = np.isclose(F[:, :, axis], bounds[axis][end], rtol=0, atol=1e-12).all(axis=1)
        boundaries[name] = faces[on]
    mesh = Mesh(points, conn, boundaries)
    check_cells(mesh)
    return mesh


def transform(mesh: Mesh, func: Callable[[np.ndarray], np.ndarray]) -> Mesh:
    """The mesh (2D or 3D) with nodes moved to func(points) ((n, d) -> (n, d)); same cells and
    parts.

    Raises ValueError (via `check_cells`) if the map inverts a cell.
    """
    pts = np.asarray(func(mesh.points.copy()), dtype=float)
    if pts.shape != mesh.points.shape:
        raise ValueError(f"func returned shape {pts.shape}, expected {mesh.points.shape}")
    out = Mesh(pts, mesh.cells, mesh.boundaries)
    check_cells(out)
    return out


END_PARTS = ("z0", "z1")  # the end faces of an extruded mesh


def extrude(mesh2d: Mesh, z: tuple[float, float], layers: int = 1) -> Mesh:
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
    out = Mesh(points, cells, boundaries)
    check_cells(out)
    return out
