"""Structured rectangle meshes and uniform refinement.

Node numbering of `rectangle`: node (i, j) (i along x, j along y) has index i + j (nx + 1).
Triangle meshes split every square along the diagonal from its lower-left to its upper-right
corner (all diagonals point the same way). `refine` keeps the parent nodes first (same indices),
then appends edge midpoints and, for quads, cell centres; so meshes of a refinement hierarchy are
nested and a parent nodal vector is the restriction of the child's to its first n_nodes entries.
"""

from __future__ import annotations

import numpy as np

from .mesh import Mesh

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


def _edge_keys(edges: np.ndarray, n_nodes: int) -> np.ndarray:
    """Orientation-independent integer key of each edge (a, b): min · n_nodes + max."""
    e = np.sort(edges, axis=1).astype(np.int64)  # (n_edges, 2)
    return e[:, 0] * n_nodes + e[:, 1]


def _refine_once(mesh: Mesh) -> Mesh:
    n, k = mesh.n_nodes, mesh.cells.shape[1]
    cells = mesh.cells  # (n_cells, k)
    local = np.stack([cells, np.roll(cells, -1, axis=1)], axis=2)  # (n_cells, k, 2) cell edges
    keys = _edge_keys(local.reshape(-1, 2), n)  # (n_cells k,)
    ukeys, first, inv = np.unique(keys, return_index=True, return_inverse=True)
    uedges = local.reshape(-1, 2)[first]  # (n_edges, 2)
    mid = n + inv.reshape(cells.shape)  # (n_cells, k) midpoint of edge (v_i, v_{i+1})
    new_points = [mesh.points, mesh.points[uedges].mean(axis=1)]  # (n, 2), (n_edges, 2)
    v = cells
    if k == 3:
        m01, m12, m20 = mid.T
        children = [
            [v[:, 0], m01, m20],
            [m01, v[:, 1], m12],
            [m20, m12, v[:, 2]],
            [m01, m12, m20],
        ]
    else:
        m01, m12, m23, m30 = mid.T
        c = n + ukeys.size + np.arange(mesh.n_cells)  # (n_cells,) cell centres
        new_points.append(mesh.points[cells].mean(axis=1))  # (n_cells, 2)
        children = [
            [v[:, 0], m01, c, m30],
            [m01, v[:, 1], m12, c],
            [c, m12, v[:, 2], m23],
            [m30, c, m23, v[:, 3]],
        ]
    new_cells = np.stack([np.stack(ch, axis=1) for ch in children], axis=1)  # (n_cells, 4, k)
    boundaries = {}
    for name, edges in mesh.boundaries.items():
        bkeys = _edge_keys(edges, n)  # (n_b,)
        pos = np.minimum(np.searchsorted(ukeys, bkeys), ukeys.size - 1)  # (n_b,)
        if (ukeys[pos] != bkeys).any():
            raise ValueError(f"boundary part {name!r} has an edge that is not a cell edge")
        m = n + pos  # (n_b,)
        split = np.stack([np.stack([edges[:, 0], m], 1), np.stack([m, edges[:, 1]], 1)], 1)
        boundaries[name] = split.reshape(-1, 2)  # (2 n_b, 2)
    return Mesh(np.concatenate(new_points), new_cells.reshape(-1, k), boundaries)


def refine(mesh: Mesh, times: int = 1) -> Mesh:
    """Uniform refinement, `times` times: each cell into 4, each boundary edge into 2.

    Triangles are split at their edge midpoints, quads at edge midpoints and the cell centre;
    boundary part names and edge order are kept, shared midpoints are created once.
    """
    if int(times) != times or times < 0:
        raise ValueError(f"times must be a non-negative integer, got {times!r}")
    for _ in range(int(times)):
        mesh = _refine_once(mesh)
    return mesh
