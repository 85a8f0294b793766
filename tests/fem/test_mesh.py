"""fem.mesh: one Mesh for 2D and 3D (dimension and cell type from the data), its local
topology tables, node counts after refinement, exterior facets."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fem import mesh as mesh_module
from fem.elements import EDGES, FACET_TYPE, FACETS
from fem.mesh import Mesh, exterior_facets
from fem.meshing import box, rectangle
from fem.refine import refine

MESHES = {
    "triangle": lambda: rectangle((0, 2), (0, 1), (3, 2), "triangle"),
    "quad": lambda: rectangle((0, 2), (0, 1), (3, 2), "quad"),
    "tetra": lambda: box((0, 1), (0, 1), (0, 1), (2, 1, 1), "tetra"),
    "hexahedron": lambda: box((0, 1), (0, 1), (0, 1), (2, 1, 1), "hexahedron"),
}


@pytest.mark.parametrize("cell_type", MESHES)
def test_dimension_and_cell_type_come_from_the_data(cell_type):
    mesh = MESHES[cell_type]()
    assert mesh.cell_type == cell_type
    assert mesh.dim == (2 if cell_type in ("triangle", "quad") else 3)
    for facets in mesh.boundaries.values():
        assert facets.shape[1] == FACETS[cell_type].shape[1]


def test_points_and_cells_of_no_cell_type_are_refused():
    with pytest.raises(ValueError, match="no cell type with 8 nodes in 2D"):
        _ = Mesh(np.zeros((8, 2)), np.arange(8)[None, :]).cell_type
    with pytest.raises(ValueError, match="in 1D"):
        _ = Mesh(np.zeros((2, 1)), np.arange(2)[None, :]).cell_type


def test_unknown_boundary_lists_the_parts():
    with pytest.raises(KeyError, match="unknown boundary 'side'.*bottom, left, right, top"):
        MESHES["quad"]().boundary_nodes("side")


@pytest.mark.parametrize("cell_type", MESHES)
def test_local_facets_are_outward_and_cover_every_edge(cell_type):
    """Each local facet's edges are local edges of the cell; the facets of a positive
    reference cell point away from its centroid."""
    from fem.elements import reference_element

    ref = reference_element(cell_type)
    edges = {tuple(sorted(e)) for e in EDGES[cell_type].tolist()}
    ftype = FACET_TYPE[cell_type]
    for f in FACETS[cell_type]:
        assert {tuple(sorted(f[e])) for e in EDGES[ftype].tolist()} <= edges
        P = ref.vertices[f]  # (k_f, d)
        if ref.vertices.shape[1] == 2:
            t = P[1] - P[0]
            normal = np.array([t[1], -t[0]])  # the right of a side with the cell on its left
        else:
            normal = np.cross(P[1] - P[0], P[-1] - P[0])
        assert normal @ (P.mean(axis=0) - ref.centroid) > 0
    facets_of_edges = {tuple(sorted(e)) for f in FACETS[cell_type] for e in f[EDGES[ftype]]}
    assert facets_of_edges == edges


@given(seed=st.integers(0, 2**32 - 1), times=st.integers(0, 3))
def test_refined_nodes_counts_without_refining(seed, times):
    """The count of `REFINED_COUNTS` equals the refined mesh's nodes, also on meshes with
    holes (a random subset of a box's cells) where V − E + F − C is not that of a ball."""
    rng = np.random.default_rng(seed)
    cell_type = list(MESHES)[rng.integers(4)]
    mesh = MESHES[cell_type]()
    keep = rng.random(mesh.n_cells) < 0.7
    keep[0] = True
    used, cells = np.unique(mesh.cells[keep], return_inverse=True)
    sub = Mesh(mesh.points[used], cells.reshape(-1, mesh.cells.shape[1]))
    assert sub.refined_nodes(times) == refine(sub, times).n_nodes


def test_mutation_a_wrong_count_step_is_caught(monkeypatch):
    wrong = {**mesh_module.REFINED_COUNTS}
    wrong["hexahedron"] = wrong["hexahedron"].copy()
    wrong["hexahedron"][0, 2] = 0  # forget the face centres
    monkeypatch.setattr(mesh_module, "REFINED_COUNTS", wrong)
    mesh = MESHES["hexahedron"]()
    assert mesh.refined_nodes(1) != refine(mesh, 1).n_nodes


@pytest.mark.parametrize("cell_type", MESHES)
def test_exterior_facets_are_the_boundary_parts(cell_type):
    """The facets of one cell only are exactly the structured mesh's parts, same orientation."""
    mesh = MESHES[cell_type]()
    ext = exterior_facets(mesh.cells, cell_type)
    parts = np.concatenate(list(mesh.boundaries.values()))

    def cyclic(f):  # a facet up to the cyclic start of its node list (an edge as it is)
        i = int(np.argmin(f)) if len(f) > 2 else 0
        return tuple(np.roll(f, -i).tolist())

    assert sorted(map(cyclic, ext)) == sorted(map(cyclic, parts))
    inner = mesh.cells[:, FACETS[cell_type]].reshape(-1, ext.shape[1])  # every local facet
    assert len(ext) < len(inner)  # the shared ones are left out
