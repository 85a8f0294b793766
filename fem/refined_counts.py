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

from collections.abc import Sequence
from functools import cache

import numpy as np

from .elements import EDGES, FACETS, reference_element
from .mesh import Mesh, find_rows, row_codes
from .refine import refine

_SIMPLEX = {"triangle", "tetra"}


def reference_vertices(cell_type: str) -> np.ndarray:
    """(k, d) the reference cell's vertices (`fem.elements.reference_element`) in its local
    order, cubes mapped from [−1, 1]^d to [0, 1]^d (so that every vertex coordinate is 0 or 1)."""
    V = reference_element(cell_type).vertices.astype(float)  # (k, d)
    return V if cell_type in _SIMPLEX else (V + 1.0) / 2.0


_CHUNK = 4096  # coarse cells per block of `Skeleton.sums` (hexahedra: 343 classes x 4096: 11 MB)


def _local_entities(cell_type: str) -> list[tuple[int, ...]]:
    """The reference cell's entities as sorted tuples of local vertices: vertices, edges,
    faces (3D), the cell."""
    ref = reference_element(cell_type)
    faces = FACETS[cell_type].tolist() if ref.dim == 3 else []
    edges_faces = [tuple(sorted(e)) for e in EDGES[cell_type].tolist() + faces]
    return [(i,) for i in range(ref.n_loc)] + edges_faces + [tuple(range(ref.n_loc))]


def _distinct(values: np.ndarray) -> np.ndarray:
    """(n_distinct,) the distinct values of the 1-D integer array `values`, sorted (as
    np.unique, which takes a hash table here: 28 ms against 0.6 ms on 32,768 codes, numpy 2.4)."""
    v = np.sort(values)  # (n,)
    return v[np.concatenate([[True], v[1:] != v[:-1]])] if len(v) else v


def _supports(x: np.ndarray, y: np.ndarray, cell_type: str) -> np.ndarray:
    """(n,) bit masks of the local vertices of the smallest reference entity holding both
    points x[i] and y[i] ((n, d) each; x = y: the entity a point lies inside)."""
    V = reference_vertices(cell_type)  # (k, d)
    tol = 1e-9
    if cell_type in _SIMPLEX:
        lam = lambda p: np.concatenate([1.0 - p.sum(axis=1, keepdims=True), p], axis=1)  # noqa: E731
        inside = (lam(x) > tol) | (lam(y) > tol)  # (n, k) barycentric supports, united
        return inside @ (1 << np.arange(len(V)))  # (n,)
    fixed = (np.abs(x - y) < tol) & ((np.abs(x) < tol) | (np.abs(x - 1.0) < tol))  # (n, d)
    state = np.where(fixed, np.rint(x).astype(np.int64), 2)  # (n, d): 0 or 1 held there, 2 free
    return _cube_masks(cell_type)[state @ 3 ** np.arange(V.shape[1])]  # (n,)


@cache
def _cube_masks(cell_type: str) -> np.ndarray:
    """(3^d,) the bit mask of a cube's vertices V (k, d) matching each state (s_0, …, s_{d−1})
    coded Σ s_i 3^i: s_i = 0 or 1 a coordinate held at that value, 2 free."""
    V = reference_vertices(cell_type).astype(np.int64)  # (k, d) entries 0 or 1
    d = V.shape[1]
    states = np.stack(np.meshgrid(*[np.arange(3)] * d, indexing="ij"), -1).reshape(-1, d)
    states = states[np.argsort(states @ 3 ** np.arange(d))]  # (3^d, d) in code order
    inside = ((states[:, None, :] == 2) | (V[None, :, :] == states[:, None, :])).all(axis=2)
    return inside @ (1 << np.arange(len(V)))  # (3^d,)


@cache
def _reference_mesh(cell_type: str, level: int) -> Mesh:
    """The reference cell refined `level` times (each level refined once from the one before)."""
    if level == 0:
        V = reference_vertices(cell_type)  # (k, d)
        return Mesh(V, np.arange(len(V))[None, :], {})
    return refine(_reference_mesh(cell_type, level - 1))


@cache
def reference_tables(cell_type: str, level: int) -> tuple[np.ndarray, np.ndarray]:
    """(N (n_e,) fine nodes inside each local entity, T (n_classes, 4) rows (a, b, t, count))
    of the reference cell refined `level` times (module docstring)."""
    k = reference_element(cell_type).n_loc
    fine = _reference_mesh(cell_type, level)
    index = {sum(1 << v for v in e): j for j, e in enumerate(_local_entities(cell_type))}
    table = np.full(1 << k, -1)  # (2^k,) bit mask of local vertices → local entity
    table[list(index)] = list(index.values())

    def lookup(masks: np.ndarray) -> np.ndarray:  # (n,) bit masks → (n,) local entities
        found = table[masks]
        if (found < 0).any():
            raise AssertionError(f"{cell_type}: a support {masks[found < 0][0]} is no entity")
        return found

    P = fine.points  # (n_fine, d)
    parent = lookup(_supports(P, P, cell_type))  # (n_fine,)
    N = np.bincount(parent, minlength=len(index))  # (n_e,)
    c = fine.cells  # (n_fine_cells, k)
    n_fine, n_e = len(P), len(index)
    # ordered pairs (i, j), i = j included, as one integer i·n_fine + j each (lexicographic)
    code = _distinct(np.repeat(c, k, axis=1).ravel() * n_fine + np.tile(c, (1, k)).ravel())
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
            code = row_codes(tuples.reshape(-1, size))  # (C n_j,)
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
        pos = find_rows(self._keys[tuples.shape[1]], tuples)  # keys: sorted rows, in id order
        if (pos < 0).any():
            raise ValueError("a boundary facet is not an entity of the mesh's cells")
        return self._offset[tuples.shape[1]] + pos

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

    def sums(
        self, w: np.ndarray, levels: Sequence[int], pairs: bool = True
    ) -> list[tuple[int, int]]:
        """(Σ_i w_i, Σ_{i~j} w_i w_j) over the nodes of the mesh refined L times, for each L of
        `levels`, with w (n_entities,) integer weights per parent entity (module docstring);
        `pairs` False: the pair sums are not computed (0). The cells' moments
        Σ_c w(G(c, e)) / k(G(c, e)) and, for each class (a, b, t) of the levels' tables,
        Σ_c w(G(c, a)) w(G(c, b)) / k(G(c, t)) are taken once, whatever the levels; each level
        then weighs them by its table's counts."""
        tables = [reference_tables(self.cell_type, level) for level in levels]
        n_e = self.entities.shape[1]
        codes = [(T[:, 0] * n_e + T[:, 1]) * n_e + T[:, 2] for _, T in tables]  # (n_cl,) each
        classes = _distinct(np.concatenate(codes)) if pairs else np.zeros(0, np.int64)
        a, b, t = classes // (n_e * n_e), classes // n_e % n_e, classes % n_e  # (n_all,) each
        node_moment = np.zeros(n_e)  # (n_e,)
        pair_moment = np.zeros(len(classes))  # (n_all,)
        for start in range(0, len(self.entities), _CHUNK):
            G = self.entities[start : start + _CHUNK]  # (c, n_e)
            G = G[w[G].any(axis=1)].T  # (n_e, c'): cells where w vanishes add nothing
            x, y = w[G].astype(float), 1.0 / self.holders[G]  # (n_e, c') each, rows gathered
            node_moment += (x * y).sum(axis=1)
            pair_moment += (x[a] * x[b] * y[t]).sum(axis=1)  # (n_all,)
        out = []
        for (N, T), code in zip(tables, codes, strict=True):
            nodes = float(node_moment @ N)
            pair = float(pair_moment[np.searchsorted(classes, code)] @ T[:, 3]) if pairs else 0.0
            out.append((int(round(nodes)), int(round(pair))))
        return out

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
