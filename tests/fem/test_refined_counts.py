"""`fem.refined_counts`: the nodal and pair sums of a refined mesh, counted on the coarse mesh,
equal those of the mesh refined (triangles, quadrilaterals, hexahedra: exactly; tetrahedra:
the nodal sum exactly, the pair sum within `Skeleton.pair_bound`), on gmsh-made unstructured
meshes with holes and notches and on structured boxes, with weights drawn per boundary part.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from fem import refined_counts
from fem.mesh import Mesh, row_codes
from fem.mesh_import import body_mesh, read_mesh
from fem.meshing import box, rectangle
from fem.refine import refine
from fem.refined_counts import Skeleton
from tests import optional

DIM = 3  # unknowns a node may have (before its parts fix some): the weights are 0 … DIM


def _weights(mesh: Mesh, fixes: dict[str, int]) -> np.ndarray:
    """(n_nodes,) DIM minus the most any part holding the node fixes (as `dirichlet` does
    with components: a node keeps the unknowns no part fixes)."""
    fixed = np.zeros(mesh.n_nodes, dtype=int)
    for name, k in fixes.items():
        nodes = mesh.boundary_nodes(name)
        fixed[nodes] = np.maximum(fixed[nodes], k)
    return DIM - fixed


def _entity_weights(sk: Skeleton, mesh: Mesh, fixes: dict[str, int]) -> np.ndarray:
    fixed = np.zeros(sk.n_entities, dtype=int)
    for name, k in fixes.items():
        on = sk.closure(mesh.boundaries[name])
        fixed[on] = np.maximum(fixed[on], k)
    return DIM - fixed


def _built(mesh: Mesh, w: np.ndarray) -> tuple[int, int]:
    """(Σ w_i, Σ_{i~j} w_i w_j) on the mesh itself: the cell pattern, every pair once."""
    c, N = mesh.cells, mesh.n_nodes
    k = c.shape[1]
    P = sp.csr_matrix(
        (np.ones(c.size * k), (np.repeat(c, k, axis=1).ravel(), np.tile(c, (1, k)).ravel())),
        shape=(N, N),
    )
    P.data[:] = 1.0  # duplicates summed: one entry per pair
    w = w.astype(np.int64)
    return int(w.sum()), int(w @ (P @ w))


def _gmsh_mesh(build: Callable, name: str, dim: int) -> Mesh:
    """Body `name` of the mesh `build(gmsh)` sets up, generated in `dim` dimensions."""
    gmsh = optional.gmsh()
    gmsh.initialize(["-noenv"])
    gmsh.option.setNumber("General.Terminal", 0)
    with TemporaryDirectory() as tmp:
        try:
            build(gmsh)
            gmsh.model.mesh.generate(dim)
            path = Path(tmp) / f"{name}.msh"
            gmsh.write(str(path))
        finally:
            gmsh.finalize()
        return body_mesh(read_mesh(path, planar=dim == 2), name)


def _gmsh_2d(element: str) -> Mesh:
    """A plate with a hole and a V notch, gmsh-meshed in triangles or quadrilaterals; parts
    left, right, notch, hole, rest."""

    def build(gmsh) -> None:
        occ = gmsh.model.occ
        plate = occ.addRectangle(0, 0, 0, 2.0, 1.0)
        hole = occ.addDisk(1.3, 0.5, 0, 0.2, 0.2)
        cut = occ.addRectangle(0.6, -0.1, 0, 0.08, 0.5)
        occ.rotate([(2, cut)], 0.64, 0.0, 0, 0, 0, 1, 0.3)
        out, _ = occ.cut([(2, plate)], [(2, hole), (2, cut)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [t for _, t in out], name="plate")
        groups: dict[str, list[int]] = {k: [] for k in ("left", "right", "notch", "hole")}
        rest = []
        for _, t in gmsh.model.getEntities(1):
            x0, y0, _, x1, y1, _ = gmsh.model.getBoundingBox(1, t)
            if x1 < 1e-9:
                groups["left"].append(t)
            elif x0 > 2.0 - 1e-9:
                groups["right"].append(t)
            elif x0 > 1.05 and x1 < 1.55 and y0 > 0.25:
                groups["hole"].append(t)
            elif 0.4 < x0 and x1 < 0.9 and y1 < 0.6:
                groups["notch"].append(t)
            else:
                rest.append(t)
        for name, tags in {**groups, "rest": rest}.items():
            gmsh.model.addPhysicalGroup(1, tags, name=name)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", 0.3)
        if element == "quad":
            gmsh.option.setNumber("Mesh.RecombineAll", 1)
            gmsh.option.setNumber("Mesh.Algorithm", 8)
            gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 1)  # all quadrilaterals

    mesh = _gmsh_mesh(build, "plate", 2)
    assert mesh.cell_type == element
    return mesh


def _gmsh_3d() -> Mesh:
    """A block with a cylindrical hole and a notch, gmsh-meshed in tetrahedra; parts by the
    faces' positions."""

    def build(gmsh) -> None:
        occ = gmsh.model.occ
        block = occ.addBox(0, 0, 0, 2.0, 1.0, 0.6)
        hole = occ.addCylinder(1.3, 0.5, -0.1, 0, 0, 0.8, 0.2)
        notch = occ.addBox(0.5, -0.1, 0.3, 0.1, 1.2, 0.4)
        out, _ = occ.cut([(3, block)], [(3, hole), (3, notch)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [t for _, t in out], name="block")
        groups: dict[str, list[int]] = {k: [] for k in ("left", "bottom", "hole", "rest")}
        for _, t in gmsh.model.getEntities(2):
            x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, t)
            if x1 < 1e-9:
                groups["left"].append(t)
            elif z1 < 1e-9:
                groups["bottom"].append(t)
            elif x0 > 1.05 and x1 < 1.55 and y0 > 0.25 and y1 < 0.75:
                groups["hole"].append(t)
            else:
                groups["rest"].append(t)
        for name, tags in groups.items():
            gmsh.model.addPhysicalGroup(2, tags, name=name)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", 0.45)

    mesh = _gmsh_mesh(build, "block", 3)
    assert mesh.cell_type == "tetra"
    return mesh


@cache
def _mesh(kind: str) -> Mesh:
    """The test meshes, made once per process (read-only afterwards)."""
    if kind in ("triangle", "quad"):
        return _gmsh_2d(kind)
    if kind == "tetra":
        return _gmsh_3d()
    if kind == "hexahedron":  # a skewed box: gmsh's hexahedra are transfinite boxes anyway
        return box((0.0, 2.0), (0.0, 1.0), (0.0, 0.5), (3, 2, 2), "hexahedron")
    return rectangle((0.0, 1.0), (0.0, 1.0), (3, 2), "triangle")  # "structured"


@settings(max_examples=16, deadline=None)
@given(
    kind=st.sampled_from(["triangle", "quad", "tetra", "hexahedron", "structured"]),
    level=st.integers(0, 3),
    seed=st.integers(0, 2**16),
)
def test_the_counts_on_the_coarse_mesh_are_the_refined_meshs(kind, level, seed):
    """Each part fixes a random number of the DIM unknowns of its nodes: Σ w and Σ w_i w_j
    counted on the coarse mesh equal the refined mesh's (tetrahedra's pair sum within its
    bound; measured on the gmsh block: 1.6–2.3 % below at level 1, 0.4–0.7 % at level 2,
    the bound 12–50 %: docs/benchmarks.md)."""
    coarse = _mesh(kind)
    if kind == "tetra" and level == 3:
        level = 2  # level 3 of the gmsh block: 0.4M tetrahedra to compare against; 2 suffices
    rng = np.random.default_rng(seed)
    fixes = {name: int(rng.integers(0, DIM + 1)) for name in coarse.boundaries}
    sk = Skeleton(coarse)
    w = _entity_weights(sk, coarse, fixes)
    fine = refine(coarse, level)
    nodes, pairs = _built(fine, _weights(fine, fixes))
    got_nodes, got_pairs = sk.sums(w, [level])[0]
    assert got_nodes == nodes
    bound = sk.pair_bound(w, level)
    assert abs(got_pairs - pairs) <= bound
    assert bound == 0 or kind == "tetra"


def test_mutation_a_formula_off_by_one_entity_kind_is_caught(monkeypatch):
    """The face entities' holders counted as 1 (a face shared by two cells counted twice):
    the pair sum of a refined quad mesh is no longer the built one; the same with an edge's
    nodes dropped from a part's closure."""
    coarse = _mesh("structured")
    fixes = {"left": 2, "bottom": 1}
    sk = Skeleton(coarse)
    w = _entity_weights(sk, coarse, fixes)
    fine = refine(coarse, 2)
    want = _built(fine, _weights(fine, fixes))
    assert sk.sums(w, [2])[0] == want
    edges = sk.of_size(2)
    bad = sk.holders.copy()
    bad[edges] = 1  # edges held by one cell each
    monkeypatch.setattr(sk, "holders", bad)
    assert sk.sums(w, [2])[0] != want
    monkeypatch.undo()
    w_bad = w.copy()
    w_bad[edges] = DIM  # the parts' edges forgotten: only their vertices fixed
    assert sk.sums(w_bad, [2])[0][0] != want[0]


def test_the_reference_tables_count_every_fine_node_and_pair():
    """N sums to the refined reference cell's nodes and T to its pattern's entries, for every
    cell type (a dropped class or a node without a parent fails)."""
    for cell_type in ("triangle", "quad", "tetra", "hexahedron"):
        V = refined_counts.reference_vertices(cell_type)  # (k, d)
        k = len(V)
        one = Mesh(V.copy(), np.arange(k)[None, :], {})
        fine = refine(one, 2)
        N, T = refined_counts.reference_tables(cell_type, 2)
        assert N.sum() == fine.n_nodes
        assert T[:, 3].sum() == _built(fine, np.ones(fine.n_nodes))[1]


def test_several_levels_at_once_are_each_level_alone():
    """`sums` over levels [2, 0, 1] in one call gives each level's own sums in that order;
    `pairs=False` the same nodal sums and no pair sums (a moment taken per level, or the
    tables of the wrong level, fails)."""
    coarse = _mesh("structured")
    sk = Skeleton(coarse)
    w = _entity_weights(sk, coarse, {"left": 2, "bottom": 1})
    alone = [sk.sums(w, [level])[0] for level in (2, 0, 1)]
    assert sk.sums(w, [2, 0, 1]) == alone
    assert len(set(alone)) == 3
    assert sk.sums(w, [2, 0, 1], pairs=False) == [(n, 0) for n, _ in alone]


@pytest.mark.parametrize("high", [50, 10**6])
def test_codes_are_equal_exactly_where_rows_are_and_keep_their_order(high):
    """`fem.mesh.row_codes` of (n, 8) rows of node numbers below `high` (10^6: eight columns
    overflow 2^62, so it ranks part-way): equal codes ⇔ equal rows, ordered as the rows
    lexicographically (mutation: the overflow guard removed wraps around and fails)."""
    rng = np.random.default_rng(high)
    rows = rng.integers(0, high, (400, 8))
    rows = np.concatenate([rows, rows[rng.integers(0, 400, 100)]])  # (500, 8) with repeats
    code = row_codes(rows)  # (500,)
    _, rank = np.unique(rows, axis=0, return_inverse=True)  # lexicographic ranks of the rows
    _, code_rank = np.unique(code, return_inverse=True)
    assert np.array_equal(code_rank.ravel(), rank.ravel())
