"""Local refinement of triangle meshes by newest-vertex bisection (NVB) with red refinement of
fully marked cells, with the P1 prolongation.

Labelling: the node order of a cell carries its bisection data. Cell (v0, v1, v2) (counter-
clockwise, as every `Mesh` cell) has *newest vertex* v0 and *refinement edge* (v1, v2), the edge
opposite it. Bisecting it at the midpoint m of (v1, v2) gives the children (m, v0, v1) and
(m, v2, v0): again counterclockwise, m their newest vertex, the parent's other two edges their
refinement edges. A mesh made by `refine_marked` is labelled so; a mesh from elsewhere is
labelled once by `prepared` (the longest edge of each triangle as its refinement edge;
quadrilaterals split into two triangles along their shorter diagonal, the diagonal the
refinement edge of both halves). With any initial labelling, repeated NVB produces at most
finitely many similarity classes of triangles (4 per initial triangle: Sewell 1972, Mitchell
1991), so the angles stay bounded below over any number of cycles.

One call (`refine_marked`) works on edges: the three edges of every marked cell are marked,
then the closure marks the refinement edge of every cell with a marked edge until no cell
has a marked edge without its refinement edge marked (finitely many steps: marks only get
added). Each cell is then split by its marked edges into 2 (refinement edge only: green), 3
(and one other edge: blue, two bisections) or 4 (all three: red, the regular split into four
similar triangles at the edge midpoints, as `fem.refine.refine`): a marked cell is always
split into 4. Red children are labelled as images of their parent under the homothety that
maps one onto the other (refinement edge parallel to the parent's), so red keeps a labelled
similarity class and the bound on the angles holds as for NVB. Red rather than two
bisections ("bisec3") because bisec3 turns a structured mesh into a criss-cross one, whose
boundary nodes alternate between 2 and 4 cells: there a contact pressure oscillates node to
node by O(h) (±4 % at the top centre of the Hertz block after 3 uniform steps, ±0.05 % with
red; docs/benchmarks.md). Every new node is the midpoint of an edge of the old mesh, shared
by both cells on it: the mesh stays conforming. Refining every cell once puts new nodes at
exactly the edge midpoints of one uniform refinement (`fem.refine.refine`), so node counts
follow `Mesh.refined_nodes`.

Boundary parts: a bisected boundary edge (a, b) becomes (a, m), (m, b) at its place in the
part, so parts keep their names, outward orientation (domain on the left) and order along
the part. Curved boundaries: the mesh knows only its polyline; the geometry knows the curve.
As in `fem.refine` a new boundary node stays at the polyline's midpoint unless the caller
passes `project` (part name → a map of points (k, 2) onto the true curve, e.g. `onto_circle`
for the built-in arcs): the new nodes of that part are moved there, and their prolongation
rows become the barycentric coordinates of the moved point in the parent cell, so the
prolongation still reproduces linear functions exactly.

Several bodies: each body has its own `Mesh` and is refined on its own (its own marks). A
contact interface's mortar coupling (`fem.mortar`, the dual multiplier basis) is not carried
over: it is rebuilt when the model is built on the new meshes, as on any other mesh; a
multiplier vector of the old interface has no prolongation here (warm-start the primal fields
with P and let the solver recompute the multiplier, or start it from zero).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
import scipy.sparse as sp

from .jacobians import check_cells
from .mesh import Mesh

Projection = Callable[[np.ndarray], np.ndarray]  # points (k, 2) -> points (k, 2) on the curve


def onto_circle(center: tuple[float, float] | np.ndarray, radius: float) -> Projection:
    """The nearest-point projection onto the circle |x − center| = radius (for the arcs of the
    built-in geometries: `fem.mapped.arc`, `fem.shapes`)."""
    c = np.asarray(center, dtype=float)

    def project(p: np.ndarray) -> np.ndarray:
        d = p - c  # (k, 2)
        return c + radius * d / np.linalg.norm(d, axis=1, keepdims=True)

    return project


def split_quads(mesh: Mesh) -> Mesh:
    """A quadrilateral mesh's cells each split into two triangles along the shorter diagonal
    (the same nodes, so nodal vectors carry over unchanged; boundary parts unchanged), labelled
    for `refine_marked` with the diagonal as the refinement edge of both halves."""
    if mesh.cells.shape[1] != 4 or mesh.dim != 2:
        raise ValueError(f"split_quads needs a 2D quadrilateral mesh, got a {mesh.cell_type} mesh")
    a, b, c, d = mesh.cells.T  # (n_cells,) each, counterclockwise
    P = mesh.points
    ac = np.linalg.norm(P[c] - P[a], axis=1) <= np.linalg.norm(P[d] - P[b], axis=1)  # (n_cells,)
    # diagonal a–c: (b, c, a), (d, a, c); diagonal b–d: (a, b, d), (c, d, b); newest vertex first
    first = np.where(ac[:, None], np.stack([b, c, a], 1), np.stack([a, b, d], 1))  # (n_cells, 3)
    second = np.where(ac[:, None], np.stack([d, a, c], 1), np.stack([c, d, b], 1))
    cells = np.stack([first, second], axis=1).reshape(-1, 3)  # (2 n_cells, 3)
    return Mesh(mesh.points, cells, dict(mesh.boundaries))


def longest_edge_labelled(mesh: Mesh) -> Mesh:
    """The triangle mesh with each cell's nodes rotated (orientation kept) so that its longest
    edge is its refinement edge: the usual initial labelling for `refine_marked`."""
    _require_triangles(mesh, "longest_edge_labelled")
    T = mesh.cells  # (n_cells, 3)
    P = mesh.points[T]  # (n_cells, 3, 2)
    opposite = np.linalg.norm(np.roll(P, -1, axis=1) - np.roll(P, -2, axis=1), axis=2)
    k = np.argmax(opposite, axis=1)  # (n_cells,) the node opposite the longest edge
    rot = (k[:, None] + np.arange(3)[None, :]) % 3  # (n_cells, 3)
    return Mesh(mesh.points, np.take_along_axis(T, rot, axis=1), dict(mesh.boundaries))


def prepared(mesh: Mesh) -> Mesh:
    """A 2D mesh made ready for adaptive refinement, once, before the first `refine_marked`:
    quadrilaterals split (`split_quads`), triangles labelled by their longest edge
    (`longest_edge_labelled`). Nodes and boundary parts are unchanged."""
    if mesh.dim == 2 and mesh.cells.shape[1] == 4:
        return split_quads(mesh)
    return longest_edge_labelled(mesh)


def _require_triangles(mesh: Mesh, who: str) -> None:
    if mesh.dim != 2 or mesh.cells.shape[1] != 3:
        raise ValueError(
            f"{who} needs a 2D triangle mesh (points (n, 2), cells (n, 3)), got points "
            f"{mesh.points.shape} and cells {mesh.cells.shape}; split quadrilaterals first "
            f"(fem.bisection.prepared)"
        )


def _marked_cells(marked: np.ndarray, n_cells: int) -> np.ndarray:
    """(n_cells,) bool from a bool mask or an array of cell indices."""
    m = np.asarray(marked)
    if m.dtype == bool:
        if m.shape != (n_cells,):
            raise ValueError(f"marked: a bool mask must have shape ({n_cells},), got {m.shape}")
        return m
    if m.size and not np.issubdtype(m.dtype, np.integer):
        raise ValueError(f"marked: bool (n_cells,) or integer cell indices, got dtype {m.dtype}")
    idx = m.ravel().astype(np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= n_cells):
        raise ValueError(
            f"marked: cell indices must lie in [0, {n_cells}), got {idx.min()}..{idx.max()}"
        )
    out = np.zeros(n_cells, dtype=bool)
    out[idx] = True
    return out


def _edges(cells: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Edges of the labelled triangles: (codes (n_edges,) sorted, a·n + b for a < b;
    cell_edges (n_cells, 3): local edge 0 the refinement edge (v1, v2), 1 (v2, v0), 2 (v0, v1))."""
    a = cells[:, [1, 2, 0]]  # (n_cells, 3)
    b = cells[:, [2, 0, 1]]
    n = np.int64(n_nodes)
    code = np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)  # (n_cells, 3)
    codes, inv = np.unique(code.ravel(), return_inverse=True)
    return codes, inv.reshape(cells.shape)


def _edge_cells(cell_edges: np.ndarray, n_edges: int) -> np.ndarray:
    """(n_edges, 2) the (one or two) cells on each edge, −1 where there is none."""
    flat = cell_edges.ravel()  # (3 n_cells,)
    order = np.argsort(flat, kind="stable")
    count = np.bincount(flat, minlength=n_edges)  # (n_edges,)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])  # (n_edges,)
    out = np.full((n_edges, 2), -1, dtype=np.int64)
    out[:, 0] = order[start] // 3
    two = count == 2
    out[two, 1] = order[start[two] + 1] // 3
    if (count > 2).any():
        e = int(np.flatnonzero(count > 2)[0])
        raise ValueError(f"not a valid 2D mesh: edge {e} lies in {count[e]} cells")
    return out


def _closure(cell_edges: np.ndarray, edge_cells: np.ndarray, marked: np.ndarray) -> np.ndarray:
    """Mark the refinement edge of every cell that has a marked edge, until none is missing.
    marked (n_edges,) bool, updated and returned."""
    front = np.flatnonzero(marked)  # edges marked since the last pass
    while front.size:
        cells = edge_cells[front].ravel()  # (2 k,)
        cells = cells[cells >= 0]
        ref = cell_edges[cells, 0]  # (k',) their refinement edges
        front = np.unique(ref[~marked[ref]])
        marked[front] = True
    return marked


def _bisect(tri: np.ndarray, mid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Children (k, 3) and (k, 3) of labelled triangles tri (k, 3) at the midpoints mid (k,) of
    their refinement edges: (m, v0, v1) and (m, v2, v0)."""
    return np.stack([mid, tri[:, 0], tri[:, 1]], 1), np.stack([mid, tri[:, 2], tri[:, 0]], 1)


def _red(tri: np.ndarray, mid: np.ndarray) -> tuple[np.ndarray, ...]:
    """The four children (k, 3) each of labelled triangles tri (k, 3) with the midpoints mid
    (k, 3) of their edges (local edge i opposite v_i): the three corner children and the middle
    one, each labelled as the image of its parent under the homothety that maps one to the
    other (ratio ½ about a corner, −½ about the centroid), so it is similar to its parent with
    its refinement edge parallel to the parent's."""
    v0, v1, v2 = tri.T  # (k,) each
    m0, m1, m2 = mid.T
    return (
        np.stack([v0, m2, m1], 1),
        np.stack([m2, v1, m0], 1),
        np.stack([m1, m0, v2], 1),
        np.stack([m0, m1, m2], 1),
    )


def refine_marked(
    mesh: Mesh,
    marked: np.ndarray,
    project: Mapping[str, Projection] | None = None,
    bisect: np.ndarray | None = None,
) -> tuple[Mesh, sp.csr_matrix]:
    """Newest-vertex bisection of the labelled triangle mesh `mesh` (module docstring):
    every marked cell is split into 4, every `bisect` cell at least into 2 (its refinement
    edge bisected: one bisection, its area halved), others as conformity requires.

    marked : (n_cells,) bool, or integer indices of the cells to refine.
    bisect : optional, the same form: cells to bisect once (more if the closure asks).
    project : optional boundary part name → projection of points (k, 2) onto the true
        boundary curve; the new nodes on that part are moved onto it.
    Returns (new mesh, P): the new mesh's points begin with the old points (same indices),
    then one node per bisected edge; P (n_new_nodes, n_old_nodes) maps P1 nodal values on the
    old mesh to the new one (the interpolant; exact for linear functions; rows sum to 1).
    ValueError for a mesh that is not a 2D triangle mesh, bad marks, an unknown part in
    `project`, or a projection that inverts a cell.
    """
    _require_triangles(mesh, "refine_marked")
    cells, n = mesh.cells, mesh.n_nodes  # (n_cells, 3)
    cell_marked = _marked_cells(marked, mesh.n_cells)  # (n_cells,)
    unknown = set(project or {}) - set(mesh.boundaries)
    if unknown:
        raise ValueError(
            f"project: unknown boundary part(s) {sorted(unknown)}; this mesh has "
            f"{sorted(mesh.boundaries)}"
        )
    codes, cell_edges = _edges(cells, n)  # (n_edges,), (n_cells, 3)
    edge_cells = _edge_cells(cell_edges, len(codes))  # (n_edges, 2)
    edge_marked = np.zeros(len(codes), dtype=bool)
    edge_marked[cell_edges[cell_marked].ravel()] = True
    if bisect is not None:
        edge_marked[cell_edges[_marked_cells(bisect, mesh.n_cells), 0]] = True
    edge_marked = _closure(cell_edges, edge_cells, edge_marked)

    bisected = np.flatnonzero(edge_marked)  # (n_bis,) the edges that get a midpoint
    node_of = np.full(len(codes), -1, dtype=np.int64)  # (n_edges,) new node of a bisected edge
    node_of[bisected] = n + np.arange(bisected.size)
    ends = np.stack([codes[bisected] // n, codes[bisected] % n], axis=1)  # (n_bis, 2)
    points = np.concatenate([mesh.points, mesh.points[ends].mean(axis=1)])  # (n_new, 2)
    rows = np.concatenate([np.arange(n), np.repeat(node_of[bisected], 2)])
    cols = np.concatenate([np.arange(n), ends.ravel()])
    vals = np.concatenate([np.ones(n), np.full(2 * bisected.size, 0.5)])

    # the children: split by the refinement edge, then each child by its own, where marked
    mid = node_of[cell_edges]  # (n_cells, 3) new node on each local edge, −1 if none
    red = (mid >= 0).all(axis=1)  # (n_cells,) all three edges: the red split
    split = (mid[:, 0] >= 0) & ~red  # (n_cells,) bisected (green, or blue with one more edge)
    c1, c2 = _bisect(cells[split], mid[split, 0])  # (k, 3) each
    m2, m1 = mid[split, 2], mid[split, 1]  # c1's refinement edge is (v0, v1), c2's (v2, v0)
    b1, b2 = m2 >= 0, m1 >= 0
    c11, c12 = _bisect(c1[b1], m2[b1])
    c21, c22 = _bisect(c2[b2], m1[b2])
    parent = np.flatnonzero(split)
    keep = ~split & ~red
    reds = np.flatnonzero(red)
    pieces = [
        (np.flatnonzero(keep), cells[keep]),
        *((reds, c) for c in _red(cells[red], mid[red])),
        (parent[~b1], c1[~b1]),
        (parent[b1], c11),
        (parent[b1], c12),
        (parent[~b2], c2[~b2]),
        (parent[b2], c21),
        (parent[b2], c22),
    ]
    owner = np.concatenate([p for p, _ in pieces])  # (n_new_cells,) parent cell of each child
    order = np.argsort(owner, kind="stable")  # children at their parent's place
    new_cells = np.concatenate([c for _, c in pieces])[order]  # (n_new_cells, 3)

    boundaries = {}
    for name, facets in mesh.boundaries.items():  # facets (n_f, 2), domain on the left
        e = _find_edges(codes, facets, n, name)  # (n_f,)
        m = node_of[e]  # (n_f,)
        cut = m >= 0
        boundaries[name] = _split_facets(facets, m)
        if project and name in project and cut.any():
            new = m[cut]  # (k,)
            points[new] = _projected(project[name], points[new], name)
            cell = edge_cells[e[cut], 0]  # (k,) the one cell on a boundary edge
            lam = _barycentric(mesh.points[cells[cell]], points[new])  # (k, 3)
            keep = ~np.isin(rows, new)
            rows = np.concatenate([rows[keep], np.repeat(new, 3)])
            cols = np.concatenate([cols[keep], cells[cell].ravel()])
            vals = np.concatenate([vals[keep], lam.ravel()])

    new = Mesh(points, new_cells, boundaries)
    if project:
        try:
            check_cells(new)
        except ValueError as err:
            raise ValueError(f"refine_marked: projecting the new boundary nodes: {err}") from None
    P = sp.csr_matrix((vals, (rows, cols)), shape=(len(points), n))
    return new, P


def _split_facets(facets: np.ndarray, mid: np.ndarray) -> np.ndarray:
    """Boundary facets (n_f, 2) with each (a, b) whose new node mid (n_f,) is ≥ 0 replaced by
    (a, m), (m, b) at its place: (n_f + n_cut, 2), orientation and order along the part kept."""
    cut = mid >= 0  # (n_f,)
    out = np.repeat(facets, 1 + cut, axis=0)  # (n_f + n_cut, 2)
    pos = np.cumsum(1 + cut) - 1 - cut  # (n_f,) first output row of each facet
    out[pos[cut], 1] = mid[cut]
    out[pos[cut] + 1, 0] = mid[cut]
    return out


def _find_edges(codes: np.ndarray, facets: np.ndarray, n: int, name: str) -> np.ndarray:
    """Indices (n_f,) in the sorted edge codes of the boundary facets (n_f, 2)."""
    code = np.minimum(facets[:, 0], facets[:, 1]).astype(np.int64) * n + facets.max(axis=1)
    pos = np.minimum(np.searchsorted(codes, code), len(codes) - 1)  # (n_f,)
    if (codes[pos] != code).any():
        raise ValueError(f"boundary part {name!r} has a facet that is not an edge of a cell")
    return pos


def _projected(f: Projection, p: np.ndarray, name: str) -> np.ndarray:
    q = np.asarray(f(p.copy()), dtype=float)
    if q.shape != p.shape or not np.isfinite(q).all():
        raise ValueError(
            f"project[{name!r}] must map points {p.shape} to finite points of the same shape, "
            f"got {q.shape}"
        )
    return q


def _barycentric(tri: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (k, 3) of points x (k, 2) in triangles tri (k, 3, 2)."""
    J = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]], axis=2)  # (k, 2, 2)
    s = np.linalg.solve(J, (x - tri[:, 0])[..., None])[..., 0]  # (k, 2)
    return np.column_stack([1 - s.sum(axis=1), s])
