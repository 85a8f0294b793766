"""Sizes of a uniformly refined mesh, counted on the coarse mesh without refining it.

Uniform refinement (`fem.refine.refine`) puts every fine node in the
interior of exactly one entity of the coarse mesh (a vertex, an edge, a face or a cell: its
*parent*), and the fine nodes of a coarse entity are the same whichever cell is refined.
So a per-node quantity w that depends only on the parent entity (free unknowns of a node:
which boundary parts hold it; whether it lies on the contact surface) sums to

    Σ_i w_i         = Σ_cells Σ_e N_L[e] w(G(c, e)) / k(G(c, e))
    Σ_{i~j} w_i w_j = Σ_cells Σ_(a,b,t) T_L[a,b,t] w(G(c, a)) w(G(c, b)) / k(G(c, t))

over the coarse cells c: e, a, b, t local entities of the reference cell, G(c, e) the global
entity, k(G) the number of coarse cells holding G, N_L[e] the fine nodes inside local entity e
after L refinements, and T_L[a,b,t] the ordered pairs of fine nodes (i = j included) that share
a fine cell, with parents a and b, whose smallest common entity (their *carrier*) is t. A pair
on a face or edge shared by k cells is adjacent in each of them (conforming refinement), hence
the division by k. N_L and T_L are read off the reference cell refined L times by the same code
that refines meshes. The pair sum is the stored entries of an operator assembled in full
blocks on the cell pattern (w = unknowns per node).

Exact for triangles, quadrilaterals and hexahedra, whose refinement is fixed. Tetrahedra split
their inner octahedron along its shortest diagonal, a choice that depends on each cell's shape:
the nodal sums stay exact (the nodes do not depend on it), the pair sum counts every cell with
the reference tetrahedron's choices. The fine edges on a coarse cell's faces are fixed (each
face splits into 4 at its midpoints), so only the pairs inside the coarse cell may differ, by
at most w_max² − w_min² each over that cell's closure: `Skeleton.pair_bound`, none where w is
the same on all nodes of a cell's closure (tests/fem/test_refined_counts.py compares it with
the error seen on gmsh meshes).
"""

from __future__ import annotations

from functools import cache

import numpy as np

from .elements import EDGES, FACETS, reference_element
from .mesh import Mesh
from .refine import refine

# reference vertices in [0, 1]^d (cubes) or the unit simplex, in each cell type's local order
_REFERENCE = {
    "triangle": np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
    "quad": np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
    "tetra": reference_element("tetra").vertices.astype(float),
    "hexahedron": (reference_element("hexahedron").vertices.astype(float) + 1.0) / 2.0,
}
_SIMPLEX = {"triangle", "tetra"}
_CHUNK = 4096  # coarse cells per block of `Skeleton.sums` (4096 hexahedra: 24 MB)


def _local_entities(cell_type: str) -> list[tuple[int, ...]]:
    """The reference cell's entities as sorted tuples of local vertices: vertices, edges,
    faces (3D), the cell."""
    k = len(_REFERENCE[cell_type])
    edges = [tuple(sorted(e)) for e in EDGES[cell_type].tolist()]
    faces = (
        [tuple(sorted(f)) for f in FACETS[cell_type].tolist()]
        if reference_element(cell_type).dim == 3
        else []
    )
    return [(i,) for i in range(k)] + edges + faces + [tuple(range(k))]


def _codes(rows: np.ndarray) -> np.ndarray:
    """(n,) integers equal exactly where the rows of `rows` (n, size) of node numbers are."""
    code = rows[:, 0].astype(np.int64)
    for col in rows[:, 1:].T.astype(np.int64):
        _, code = np.unique(code * (int(col.max(initial=0)) + 1) + col, return_inverse=True)
        code = code.ravel()
    return code


def _supports(x: np.ndarray, y: np.ndarray, cell_type: str) -> np.ndarray:
    """(n,) bit masks of the local vertices of the smallest reference entity holding both
    points x[i] and y[i] ((n, d) each; x = y: the entity a point lies inside)."""
    V = _REFERENCE[cell_type]  # (k, d)
    tol = 1e-9
    if cell_type in _SIMPLEX:
        lam = lambda p: np.concatenate([1.0 - p.sum(axis=1, keepdims=True), p], axis=1)  # noqa: E731
        inside = (lam(x) > tol) | (lam(y) > tol)  # (n, k) barycentric supports, united
    else:
        fixed = (np.abs(x - y) < tol) & ((np.abs(x) < tol) | (np.abs(x - 1.0) < tol))  # (n, d)
        match = np.abs(V[None, :, :] - x[:, None, :]) < tol  # (n, k, d)
        inside = (match | ~fixed[:, None, :]).all(axis=2)  # (n, k)
    return inside @ (1 << np.arange(len(V)))  # (n,)


@cache
def reference_tables(cell_type: str, level: int) -> tuple[np.ndarray, np.ndarray]:
    """(N (n_e,) fine nodes inside each local entity, T (n_classes, 4) rows (a, b, t, count))
    of the reference cell refined `level` times (module docstring)."""
    V = _REFERENCE[cell_type]
    k = len(V)
    cells = np.arange(k)[None, :]
    fine = refine(Mesh(V.copy(), cells, {}), level)
    index = {sum(1 << v for v in e): j for j, e in enumerate(_local_entities(cell_type))}
    lookup = np.vectorize(index.__getitem__, otypes=[int])
    P = fine.points  # (n_fine, d)
    parent = lookup(_supports(P, P, cell_type))  # (n_fine,)
    N = np.bincount(parent, minlength=len(index))  # (n_e,)
    c = fine.cells  # (n_fine_cells, k)
    n_fine, n_e = len(P), len(index)
    # ordered pairs (i, j), i = j included, as one integer i·n_fine + j each (lexicographic)
    code = np.unique(np.repeat(c, k, axis=1).ravel() * n_fine + np.tile(c, (1, k)).ravel())
    i, j = np.divmod(code, n_fine)  # (n_pairs,) each
    carrier = lookup(_supports(P[i], P[j], cell_type))  # (n_pairs,)
    key, count = np.unique((parent[i] * n_e + parent[j]) * n_e + carrier, return_counts=True)
    classes = np.stack([key // (n_e * n_e), key // n_e % n_e, key % n_e], axis=1)  # (n_cl, 3)
    return N, np.concatenate([classes, count[:, None]], axis=1)


class Skeleton:
    """The entities of a coarse mesh (vertices, edges, faces in 3D, cells), numbered in that
    order, with each cell's local entities mapped to them and the cells holding each."""

    def __init__(self, mesh: Mesh):
        self.cell_type = mesh.cell_type
        local = _local_entities(self.cell_type)
        cells = mesh.cells  # (C, k)
        self._keys: dict[int, np.ndarray] = {}  # size of the vertex tuple → sorted unique keys
        self._offset: dict[int, int] = {}
        G = np.empty((len(cells), len(local)), dtype=np.int64)  # (C, n_e) global entity ids
        offset = 0
        sizes = sorted({len(e) for e in local})
        for size in sizes:
            cols = [j for j, e in enumerate(local) if len(e) == size]
            tuples = np.sort(cells[:, [list(local[j]) for j in cols]], axis=2)  # (C, n_j, size)
            code = _codes(tuples.reshape(-1, size))  # (C n_j,)
            keys, first, inv = np.unique(code, return_index=True, return_inverse=True)
            G[:, cols] = offset + inv.reshape(len(cells), len(cols))
            self._keys[size], self._offset[size] = tuples.reshape(-1, size)[first], offset
            offset += len(keys)
        self.n_entities = offset
        self.entities = G
        self.holders = np.bincount(G.ravel(), minlength=offset)  # (n_entities,) k(G)

    def of_size(self, size: int) -> slice:
        """The ids of the entities of `size` vertices (1: vertices, 2: edges, …)."""
        start = self._offset[size]
        return slice(start, start + len(self._keys[size]))

    def _find(self, tuples: np.ndarray) -> np.ndarray:
        """Global ids of entities given as (n, size) vertex tuples (any order)."""
        size = tuples.shape[1]
        keys = self._keys[size]  # (n_size, size) sorted rows, in id order
        code = _codes(np.concatenate([keys, np.sort(tuples, axis=1)]))  # (n_size + n,)
        known, asked = code[: len(keys)], code[len(keys) :]
        order = np.argsort(known)
        pos = order[np.minimum(np.searchsorted(known, asked, sorter=order), len(keys) - 1)]
        if (known[pos] != asked).any():
            raise ValueError("a boundary facet is not an entity of the mesh's cells")
        return self._offset[size] + pos

    def closure(self, facets: np.ndarray) -> np.ndarray:
        """(n_entities,) bool: the entities in the closure of boundary `facets` (n_b, k_f)
        (edges in 2D, faces in 3D): the facets, their edges and their vertices."""
        mask = np.zeros(self.n_entities, dtype=bool)
        if len(facets) == 0:
            return mask
        kf = facets.shape[1]
        mask[self._find(facets)] = True
        mask[self._find(facets.reshape(-1, 1))] = True  # their vertices
        if kf > 2:  # 3D: the facets' edges
            edges = np.stack([facets, np.roll(facets, -1, axis=1)], axis=2).reshape(-1, 2)
            mask[self._find(edges)] = True
        return mask

    def sums(self, w: np.ndarray, level: int) -> tuple[int, int]:
        """(Σ_i w_i, Σ_{i~j} w_i w_j) over the nodes of the mesh refined `level` times, with
        w (n_entities,) integer weights per parent entity (module docstring)."""
        N, T = reference_tables(self.cell_type, level)
        n_e = len(N)
        M = np.zeros((n_e, n_e, n_e))  # M[a, b, t]: the pairs of class (a, b, t)
        M[T[:, 0], T[:, 1], T[:, 2]] = T[:, 3]
        M = M.reshape(n_e * n_e, n_e)
        nodes = pairs = 0.0
        for start in range(0, len(self.entities), _CHUNK):
            G = self.entities[start : start + _CHUNK]  # (c, n_e)
            x, y = w[G].astype(float), 1.0 / self.holders[G]  # (c, n_e) each
            nodes += float(((x * y) @ N).sum())
            xx = (x[:, :, None] * x[:, None, :]).reshape(len(G), -1)  # (c, n_e²)
            pairs += float(((xx @ M) * y).sum())
        return int(round(nodes)), int(round(pairs))

    def pair_bound(self, w: np.ndarray, level: int) -> int:
        """How far `sums`' pair sum may be from the refined mesh's: 0 but for tetrahedra,
        2 E (w_max² − w_min²) per coarse cell, E the fine edges inside a coarse tetrahedron
        (module docstring: their nodes depend on the inner diagonals chosen)."""
        if self.cell_type != "tetra":
            return 0
        N, T = reference_tables(self.cell_type, level)
        inner = len(N) - 1  # the cell itself, last local entity
        edges = int(T[T[:, 2] == inner, 3].sum() - N[inner])  # ordered pairs i ≠ j inside
        x = w[self.entities]  # (C, n_e)
        spread = x.max(axis=1).astype(np.int64) ** 2 - x.min(axis=1).astype(np.int64) ** 2
        return int(edges * spread.sum())
