"""Unstructured meshes of any dimension with named boundary parts, and their local topology.

One `Mesh` serves 2D (triangles P1, quadrilaterals Q1) and 3D (tetrahedra P1, hexahedra Q1);
the dimension d is the number of point coordinates and the cell type follows from (d, nodes
per cell). Local node orders, edges (`EDGES`), outward facets (`FACETS`) and facet types
(`FACET_TYPE`) of every cell type are the reference elements' data in `fem.elements`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .elements import CELL_TYPE, EDGES, FACETS


@dataclass(frozen=True, eq=False)
class Mesh:
    """A mesh of dimension d = 2 or 3.

    points : (n_nodes, d) float coordinates.
    cells : (n_cells, k) node lists: triangles (k = 3) or quadrilaterals (4), counterclockwise,
        in 2D; tetrahedra (4) or hexahedra (8), positively oriented (det J > 0), in 3D.
    boundaries : name -> (n_facets, k_facet) node lists of the part's facets, oriented outward
        (`FACETS`): in 2D edges (a, b) with the domain on their left, the edges of one part
        ordered along it; in 3D triangles or quadrilaterals counterclockwise seen from outside.
    """

    points: np.ndarray
    cells: np.ndarray
    boundaries: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def dim(self) -> int:
        """The dimension d: the number of coordinates of a point."""
        return self.points.shape[1]

    @property
    def cell_type(self) -> str:
        """'triangle' or 'quad' (2D), 'tetra' or 'hexahedron' (3D): meshio's names."""
        key = (self.dim, self.cells.shape[1])
        if key not in CELL_TYPE:
            raise ValueError(
                f"no cell type with {key[1]} nodes in {key[0]}D: need points (n, 2) with cells "
                f"(n, 3) or (n, 4), or points (n, 3) with cells (n, 4) or (n, 8)"
            )
        return CELL_TYPE[key]

    @property
    def n_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def n_cells(self) -> int:
        return self.cells.shape[0]

    def boundary(self, name: str) -> np.ndarray:
        """The facets (n_facets, k_facet) of boundary part `name`; KeyError naming the parts
        this mesh has if it has no such part."""
        if name not in self.boundaries:
            raise KeyError(
                f"unknown boundary {name!r}; this mesh has: {', '.join(sorted(self.boundaries))}"
            )
        return self.boundaries[name]

    def boundary_nodes(self, name: str) -> np.ndarray:
        """Sorted unique node indices of the boundary part `name` (KeyError: `boundary`)."""
        return np.unique(self.boundary(name))

    @property
    def h(self) -> float:
        """Mesh size: the largest cell diameter."""
        P = self.points[self.cells]  # (n_cells, k, d)
        d = np.linalg.norm(P[:, :, None, :] - P[:, None, :, :], axis=-1)  # (n_cells, k, k)
        return float(d.max())

    def refined_nodes(self, times: int) -> int:
        """Nodes after `times` uniform refinements (`fem.refine.refine`), counted without
        refining: the counts (V, E[, F], C) of vertices, edges, (3D: faces) and cells change
        by one step of `REFINED_COUNTS`."""
        ctype = self.cell_type
        counts = [self.n_nodes, distinct(self.cells, EDGES[ctype])]
        if self.dim == 3:
            counts.append(distinct(self.cells, FACETS[ctype]))
        counts = np.array(counts + [self.n_cells], dtype=object)  # exact integers
        step = REFINED_COUNTS[ctype].astype(object)
        for _ in range(times):
            counts = step @ counts
        return int(counts[0])


# One uniform refinement (`fem.refine`) maps the entity counts (V, E, C) in 2D and
# (V, E, F, C) in 3D by these matrices: new nodes at edge midpoints (and at the centres of
# quadrilaterals and hexahedra); each edge into 2, each cell and face into 2^d and 4 with
# the new edges and faces inside them.
REFINED_COUNTS: dict[str, np.ndarray] = {
    "triangle": np.array([[1, 1, 0], [0, 2, 3], [0, 0, 4]]),
    "quad": np.array([[1, 1, 1], [0, 2, 4], [0, 0, 4]]),
    "tetra": np.array([[1, 1, 0, 0], [0, 2, 3, 1], [0, 0, 4, 8], [0, 0, 0, 8]]),
    "hexahedron": np.array([[1, 1, 1, 1], [0, 2, 4, 6], [0, 0, 4, 12], [0, 0, 0, 8]]),
}


def row_codes(rows: np.ndarray) -> np.ndarray:
    """(n,) integers equal exactly where the rows of `rows` (n, size) of node numbers (≥ 0)
    are, in the rows' lexicographic order: the columns in mixed radix (each column's max + 1),
    ranked by np.unique only where the next column would overflow 2^62."""
    code = rows[:, 0].astype(np.int64)
    top = int(code.max(initial=0)) + 1  # every code < top
    for col in rows[:, 1:].T.astype(np.int64):
        radix = int(col.max(initial=0)) + 1
        if top * radix > 2**62:
            _, code = np.unique(code, return_inverse=True)
            code = code.ravel()
            top = int(code.max(initial=0)) + 1
        code, top = code * radix + col, top * radix
    return code


def find_rows(table: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(n,) for each row of `rows` (n, k) of node numbers the index of the row of `table`
    (m ≥ 1, k) with the same nodes (each of table's rows sorted; the first such row), or −1."""
    code = row_codes(np.concatenate([table, np.sort(rows, axis=1)]))  # (m + n,)
    known, asked = code[: len(table)], code[len(table) :]
    order = np.argsort(known, kind="stable")
    pos = order[np.minimum(np.searchsorted(known, asked, sorter=order), len(table) - 1)]
    return np.where(known[pos] == asked, pos, -1)


def distinct(cells: np.ndarray, local: np.ndarray) -> int:
    """The number of distinct entities (edges, faces) with local node lists `local`
    (n_local, m) over the cells (n_cells, k)."""
    items = cells[:, local].reshape(-1, local.shape[1])  # (n_cells n_local, m)
    return len(np.unique(np.sort(items, axis=1), axis=0))


def exterior_facets(cells: np.ndarray, cell_type: str) -> np.ndarray:
    """The facets (n_facets, k_facet) that belong to one cell only, oriented outward (from
    positively oriented cells), in the order of the cells and of `FACETS`."""
    local = FACETS[cell_type]  # (n_f, m)
    facets = cells[:, local].reshape(-1, local.shape[1])  # (n_cells n_f, m)
    key = np.sort(facets, axis=1)  # (n_cells n_f, m)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return facets[count[inv.ravel()] == 1]
