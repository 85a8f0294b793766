"""Mapped (transfinite / Coons) structured quadrilateral blocks with boundary nodes on true curves.

A `Curve` is a vectorised callable t ↦ x(t) from [0, 1] to R²: (n,) → (n, 2). A block is given by
its four sides traversed COUNTERCLOCKWISE, i.e. as one closed loop around the block:

    bottom: c00 → c10,   right: c10 → c11,   top: c11 → c01,   left: c01 → c00.

The block is meshed by transfinite interpolation on a uniform (ξ, η) grid, nodes on the sides are
the exact curve values x(i/n), and the boundary parts are ordered along the loop, so every part
has the domain on its left as `Mesh` requires. Finer levels are generated directly (nx·2^L),
never by refining a coarse mesh, so boundary nodes lie on the curve at every resolution.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from . import jacobians
from .mesh import Mesh

Curve = Callable[[np.ndarray], np.ndarray]
SIDES = ("bottom", "right", "top", "left")


def segment(p: Sequence[float], q: Sequence[float]) -> Curve:
    """The straight segment from p to q, uniformly parametrised; exactly p at t = 0 and q at t = 1
    (bit for bit, so blocks glued at a corner share the same coordinates)."""
    p_, q_ = np.asarray(p, dtype=float), np.asarray(q, dtype=float)

    def curve(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)[:, None]
        return (1.0 - t) * p_ + t * q_  # (n, 2)

    return curve


def arc(center: Sequence[float], radius: float, theta0: float, theta1: float) -> Curve:
    """The circular arc from angle theta0 to theta1 (counterclockwise if theta1 > theta0).

    Parametrised by angle, so every node x(i/n) lies on the circle up to rounding.
    """
    c = np.asarray(center, dtype=float)

    def curve(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        th = (1 - t) * theta0 + t * theta1  # (n,) exactly theta0, theta1 at the ends
        return c + radius * np.stack([np.cos(th), np.sin(th)], axis=-1)  # (n, 2)

    return curve


def reparametrise(curve: Curve, knots: Sequence[float]) -> Curve:
    """`curve` composed with the piecewise linear map i/n ↦ knots[i] (knots increasing in [0, 1]).

    With n + 1 knots and n cells along the side, the nodes land at curve(knots[i]): a way to get
    non-uniform node spacing on a side.
    """
    k = np.asarray(knots, dtype=float)
    if k[0] != 0.0 or k[-1] != 1.0 or (np.diff(k) <= 0).any():
        raise ValueError("knots must increase strictly from 0 to 1")
    grid = np.linspace(0.0, 1.0, k.size)
    return lambda t: curve(np.interp(np.asarray(t, dtype=float), grid, k))


def _order_edges(edges: np.ndarray) -> np.ndarray:
    """Order directed edges (a, b) along their chain(s): each piece follows its successors."""
    nxt = {int(a): i for i, (a, _) in enumerate(edges)}
    has_prev = np.isin(edges[:, 0], edges[:, 1])  # (n_edges,)
    starts = list(np.flatnonzero(~has_prev)) or [0]
    order: list[int] = []
    seen = np.zeros(len(edges), dtype=bool)
    for s in [*starts, *range(len(edges))]:  # chains first, then any closed loops left
        i = int(s)
        while not seen[i]:
            seen[i] = True
            order.append(i)
            j = nxt.get(int(edges[i, 1]))
            if j is None:
                break
            i = j
    return edges[order]


def check_cells(points: np.ndarray, cells: np.ndarray, what: str = "mesh") -> None:
    """Raise ValueError naming `what` unless every cell is positively oriented and not
    degenerate (`fem.jacobians.check_cells`; for a bilinear quadrilateral: counterclockwise,
    convex)."""
    try:
        jacobians.check_cells(Mesh(points, cells))
    except ValueError as err:
        raise ValueError(f"{what}: {err}") from None


def coons_block(
    bottom: Curve,
    right: Curve,
    top: Curve,
    left: Curve,
    nx: int,
    ny: int,
    names: dict[str, str],
    tol: float = 1e-10,
) -> Mesh:
    """A structured Q1 mesh of the block bounded by four curves (counterclockwise loop).

    bottom: c00 → c10, right: c10 → c11, top: c11 → c01, left: c01 → c00 (see module docstring);
    nx cells along bottom/top, ny along right/left. `names` maps a side ("bottom", "right", "top",
    "left") to a boundary part name; sides mapped to the same name form one part ordered along the
    loop; sides not in `names` get no part (e.g. sides to be glued to another block).
    Node (i, j) has index j·(nx + 1) + i.
    """
    unknown = set(names) - set(SIDES)
    if unknown:
        raise ValueError(f"unknown side name(s) {sorted(unknown)}; sides are {SIDES}")
    if nx < 1 or ny < 1:
        raise ValueError(f"nx, ny must be >= 1, got {nx}, {ny}")
    xi, eta = np.linspace(0.0, 1.0, nx + 1), np.linspace(0.0, 1.0, ny + 1)
    B = bottom(xi)  # (nx+1, 2) from c00 to c10
    T = top(xi)[::-1]  # (nx+1, 2) from c01 to c11
    R = right(eta)  # (ny+1, 2) from c10 to c11
    L = left(eta)[::-1]  # (ny+1, 2) from c00 to c01
    for a, b, where in [
        (B[-1], R[0], "bottom/right"),
        (R[-1], T[-1], "right/top"),
        (T[0], L[-1], "top/left"),
        (L[0], B[0], "left/bottom"),
    ]:
        if np.linalg.norm(a - b) > tol:
            raise ValueError(f"coons_block: sides do not meet at the {where} corner: {a} vs {b}")
    c00, c10, c01, c11 = B[0], B[-1], T[0], T[-1]
    X, E = xi[None, :, None], eta[:, None, None]  # (1, nx+1, 1), (ny+1, 1, 1)
    P = (
        (1 - E) * B[None]
        + E * T[None]
        + (1 - X) * L[:, None]
        + X * R[:, None]
        - (1 - X) * (1 - E) * c00
        - X * (1 - E) * c10
        - (1 - X) * E * c01
        - X * E * c11
    )  # (ny+1, nx+1, 2)
    P[0], P[-1], P[:, 0], P[:, -1] = B, T, L, R  # exact curve values on the sides
    points = P.reshape(-1, 2)
    idx = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)  # node (i, j) at idx[j, i]
    cells = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(
        -1, 4
    )  # (nx·ny, 4) counterclockwise
    check_cells(points, cells, "coons_block")
    loop = {
        "bottom": np.stack([idx[0, :-1], idx[0, 1:]], axis=1),
        "right": np.stack([idx[:-1, -1], idx[1:, -1]], axis=1),
        "top": np.stack([idx[-1, 1:], idx[-1, :-1]], axis=1)[::-1],
        "left": np.stack([idx[1:, 0], idx[:-1, 0]], axis=1)[::-1],
    }  # each (n_side, 2), domain on the left
    parts: dict[str, list[np.ndarray]] = {}  # part → its sides' edges, in loop order
    for side in (s for s in SIDES if s in names):
        parts.setdefault(names[side], []).append(loop[side])
    return Mesh(points, cells, {k: _order_edges(np.vstack(v)) for k, v in parts.items()})


def glue(blocks: Sequence[Mesh], tol: float = 1e-10) -> Mesh:
    """Merge Q1 meshes along coincident nodes (distance <= tol).

    Boundary parts with the same name are merged and ordered along their chain(s); boundary edges
    shared by two cells after merging (interior edges) are dropped. Nodes are numbered by first
    occurrence. Raises ValueError if a merged cell is degenerate.
    """
    offsets = np.cumsum([0] + [b.n_nodes for b in blocks])
    pts = np.vstack([b.points for b in blocks])  # (N_all, 2)
    pairs = cKDTree(pts).query_pairs(tol, output_type="ndarray")  # (n_pairs, 2)
    n_all = pts.shape[0]
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n_all,) * 2)
    _, label = sp.csgraph.connected_components(graph, directed=False)  # (N_all,)
    _, first, inverse = np.unique(label, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))  # renumber components by first occurrence
    new_id = rank[inverse]  # (N_all,)
    points = np.empty((first.size, 2))
    points[rank] = pts[first]
    cells = np.vstack([new_id[b.cells + o] for b, o in zip(blocks, offsets[:-1], strict=True)])
    check_cells(points, cells, "glue")
    cell_edges = np.sort(np.stack([cells, np.roll(cells, -1, axis=1)], axis=-1), axis=-1)
    n = points.shape[0]
    keys, counts = np.unique(cell_edges[..., 0] * n + cell_edges[..., 1], return_counts=True)
    interior = keys[counts > 1]  # (n_interior,) codes a·n + b of sorted node pairs a < b
    parts: dict[str, list[np.ndarray]] = {}
    for b, o in zip(blocks, offsets[:-1], strict=True):
        for name, e in b.boundaries.items():
            parts.setdefault(name, []).append(new_id[e + o])
    boundaries = {}
    for name, pieces in parts.items():
        e = np.vstack(pieces)  # (n_edges, 2)
        es = np.sort(e, axis=1)  # (n_edges, 2)
        inner = np.isin(es[:, 0] * n + es[:, 1], interior)  # (n_edges,)
        if (~inner).any():
            boundaries[name] = _order_edges(e[~inner])
    return Mesh(points, cells, boundaries)
