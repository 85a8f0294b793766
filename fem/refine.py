"""Uniform refinement of a `fem.mesh.Mesh` (2D or 3D), with the subdivision rules as data.

A cell of type t is refined on its *local nodes*: its vertices, then the midpoints of its
edges (`fem.elements.EDGES[t]`, in order), then the centres of its quadrilateral faces
(hexahedra: `fem.elements.FACETS`), then its centre (quadrilaterals, hexahedra). `CHILDREN[t]`
(n_rules, n_children, k) lists the children as local-node lists: one rule, except tetrahedra,
whose inner octahedron is split along one of its 3 diagonals (the shortest is chosen per
cell, which keeps repeated refinement from degrading the cells). A boundary facet is refined
by the rule of its own type (a line into 2, a triangle or quadrilateral into 4), so parts
keep their names, outward orientation and (2D) edge order.

Nested: the parent nodes keep their indices, then come the edge midpoints, the face centres
and the cell centres; so a parent nodal vector is the restriction of the child's to its first
n_nodes entries. Every child is positively oriented (det J > 0).
"""

from __future__ import annotations

import numpy as np

from .elements import EDGES, FACET_TYPE, FACETS, reference_element
from .jacobians import check_cells
from .mesh import Mesh, find_rows, row_codes

_CENTRED_FACES = ("hexahedron",)  # cell types whose faces get a centre node
_CENTRED = ("quad", "hexahedron")  # cell types that get a centre node


def _oriented(children: np.ndarray, ref_points: np.ndarray) -> np.ndarray:
    """Swap the 2nd and 3rd node of the tetrahedra (k, 4) that are negative on the reference."""
    P = ref_points[children]  # (k, 4, 3)
    neg = np.linalg.det(P[:, 1:] - P[:, :1]) < 0  # (k,)
    out = children.copy()
    out[neg, 1], out[neg, 2] = children[neg, 2], children[neg, 1]
    return out


# Tetrahedron [x0, x1, x2, x3] on its 10 local nodes (4 + e the midpoint of edge e): the four
# corner tetrahedra and the inner octahedron split into 4 along one of its diagonals.
_X01, _X02, _X03, _X12, _X13, _X23 = range(4, 10)
_DIAGONALS = np.array([(_X01, _X23), (_X02, _X13), (_X03, _X12)])


def _tetra_rules() -> np.ndarray:
    """(3, 8, 4) the children of a tetrahedron, one rule per octahedron diagonal."""
    corners = [[0, _X01, _X02, _X03], [_X01, 1, _X12, _X13], [_X02, _X12, 2, _X23]]
    corners.append([_X03, _X13, _X23, 3])
    vertices = reference_element("tetra").vertices
    ref10 = np.concatenate([vertices, vertices[EDGES["tetra"]].mean(axis=1)])  # (10, 3)
    rules = []
    for d in range(3):
        p, q = _DIAGONALS[d]
        (r1, r2), (s1, s2) = [_DIAGONALS[k] for k in range(3) if k != d]
        inner = [[p, q, r1, s1], [p, q, s1, r2], [p, q, r2, s2], [p, q, s2, r1]]
        rules.append(_oriented(np.array(corners + inner), ref10))
    return np.stack(rules)


def _hexahedron_rule() -> np.ndarray:
    """(1, 8, 8) the octants of a hexahedron on its 27 local nodes."""
    V = reference_element("hexahedron").vertices.astype(int)  # (8, 3) in {−1, 1}
    grid = np.empty((3, 3, 3), dtype=int)  # local node at reference point − 1
    grid[tuple((V + 1).T)] = np.arange(8)
    grid[tuple(((V[EDGES["hexahedron"]].sum(axis=1)) // 2 + 1).T)] = 8 + np.arange(12)
    grid[tuple((V[FACETS["hexahedron"]].sum(axis=1) // 4 + 1).T)] = 20 + np.arange(6)
    grid[1, 1, 1] = 26
    idx = (V + 1)[:, None, :] // 2 + (V[None, :, :] + 1) // 2  # (8 children, 8 nodes, 3)
    return grid[idx[..., 0], idx[..., 1], idx[..., 2]][None]


# Local nodes of a triangle: 0–2, then 3, 4, 5 the midpoints of sides 01, 12, 20; of a
# quadrilateral: 0–3, then 4–7 the midpoints of sides 01, 12, 23, 30, then 8 its centre.
CHILDREN: dict[str, np.ndarray] = {
    "line": np.array([[[0, 2], [2, 1]]]),
    "triangle": np.array([[[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]]]),
    "quad": np.array([[[0, 4, 8, 7], [4, 1, 5, 8], [8, 5, 2, 6], [7, 8, 6, 3]]]),
    "tetra": _tetra_rules(),
    "hexahedron": _hexahedron_rule(),
}


def _sorted_keys(items: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of the sorted node tuples `items` (n, k): (unique (m, k), inverse (n,)),
    in lexicographic order (through one integer code per row: a 1D sort, much faster)."""
    s = np.sort(items, axis=1)  # (n, k)
    _, first, inv = np.unique(row_codes(s), return_index=True, return_inverse=True)
    return s[first], inv.ravel()


def _find(keys: np.ndarray, items: np.ndarray, name: str) -> np.ndarray:
    """Row index in the unique `keys` (m, k) of each sorted row of `items` (n, k)."""
    pos = find_rows(keys, items)
    if (pos < 0).any():
        raise ValueError(f"boundary part {name!r} has a facet that is not a facet of a cell")
    return pos


def _refine_once(mesh: Mesh) -> Mesh:
    n, ctype, cells = mesh.n_nodes, mesh.cell_type, mesh.cells  # cells (n_cells, k)
    ekeys, einv = _sorted_keys(cells[:, EDGES[ctype]].reshape(-1, 2))  # (n_edges, 2)
    local = [cells, n + einv.reshape(len(cells), -1)]  # vertices, edge midpoints
    points = [mesh.points, mesh.points[ekeys].mean(axis=1)]  # (n, d), (n_edges, d)
    start = n + len(ekeys)  # index of the next new node
    fkeys = np.zeros((0, 4), dtype=cells.dtype)  # centred faces (hexahedra)
    if ctype in _CENTRED_FACES:
        fkeys, finv = _sorted_keys(cells[:, FACETS[ctype]].reshape(-1, 4))  # (n_faces, 4)
        local.append(start + finv.reshape(len(cells), -1))
        points.append(mesh.points[fkeys].mean(axis=1))
        start += len(fkeys)
    if ctype in _CENTRED:
        local.append(start + np.arange(len(cells))[:, None])
        points.append(mesh.points[cells].mean(axis=1))
    nodes = np.concatenate(local, axis=1)  # (n_cells, n_local)
    rules = CHILDREN[ctype]  # (n_rules, n_children, k)
    choice = np.zeros(len(cells), dtype=int)  # (n_cells,) the rule of each cell
    if len(rules) > 1:  # tetrahedra: the shortest octahedron diagonal
        P = np.concatenate(points)[nodes[:, _DIAGONALS]]  # (n_cells, 3, 2, d)
        choice = np.argmin(np.linalg.norm(P[:, :, 0] - P[:, :, 1], axis=2), axis=1)
    children = nodes[np.arange(len(cells))[:, None, None], rules[choice]]  # (n_c, n_ch, k)
    boundaries = {}
    for name, facets in mesh.boundaries.items():
        ftype = FACET_TYPE[ctype]
        fe = facets[:, EDGES[ftype]].reshape(-1, 2)  # (n_b n_fe, 2) the facets' edges
        parts = [facets, n + _find(ekeys, fe, name).reshape(len(facets), -1)]
        if ftype == "quad":
            parts.append(n + len(ekeys) + _find(fkeys, facets, name)[:, None])
        fnodes = np.concatenate(parts, axis=1)  # (n_b, n_local of the facet)
        sub = fnodes[:, CHILDREN[ftype][0]]  # (n_b, n_sub, k_facet)
        boundaries[name] = sub.reshape(-1, facets.shape[1])
    return Mesh(np.concatenate(points), children.reshape(-1, cells.shape[1]), boundaries)


def refine(mesh: Mesh, times: int = 1) -> Mesh:
    """Uniform refinement, `times` times: each cell into 2^d, each boundary facet into
    2^(d−1), by the rules `CHILDREN`; ValueError (`fem.jacobians.check_cells`) for a mesh
    with an inverted or degenerate cell."""
    if int(times) != times or times < 0:
        raise ValueError(f"times must be a non-negative integer, got {times!r}")
    for _ in range(int(times)):
        mesh = _refine_once(mesh)
        check_cells(mesh)
    return mesh
