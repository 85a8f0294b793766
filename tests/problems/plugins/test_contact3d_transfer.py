"""contact3d_transfer: a coarse P1/Q1 field at the nodes of a finer mesh."""

from __future__ import annotations

import numpy as np
import pytest

from fem import mesh3d
from problems.plugins import contact3d, contact3d_transfer
from problems.scene import load_scene


@pytest.mark.parametrize("element", ["tetra", "hexahedron"])
def test_nested_nodes_get_the_coarse_values_and_edge_midpoints_their_mean(element):
    """On nested meshes the transfer is the prolongation: a fine node on a coarse node takes
    its value, a fine node at the midpoint of a coarse edge the mean of the edge's two values
    (P1 and Q1 are linear along edges) — for any nodal values, so a wrong cell or wrong
    reference coordinates show."""
    coarse = mesh3d.box((0.0, 1.0), (0.0, 2.0), (0.0, 0.5), (2, 3, 1), element, 0)
    fine = mesh3d.box((0.0, 1.0), (0.0, 2.0), (0.0, 0.5), (2, 3, 1), element, 1)
    rng = np.random.default_rng(7)
    nodal = rng.standard_normal((coarse.n_nodes, 2))  # (N_c, 2) two components
    vals, outside = contact3d_transfer.evaluate(coarse, nodal, fine.points)
    assert outside == 0
    expect = np.full((fine.n_nodes, 2), np.nan)
    for i, p in enumerate(coarse.points):
        expect[np.flatnonzero(np.abs(fine.points - p).max(axis=1) < 1e-12)] = nodal[i]
    cells = coarse.cells  # (n_cells, n_loc): the edges of the cell types
    pairs = {tuple(sorted((a, b))) for c in cells for a in c for b in c if a != b}
    for a, b in pairs:
        mid = 0.5 * (coarse.points[a] + coarse.points[b])
        at = np.flatnonzero(np.abs(fine.points - mid).max(axis=1) < 1e-12)
        if element == "tetra" or np.count_nonzero(coarse.points[a] != coarse.points[b]) == 1:
            expect[at] = 0.5 * (nodal[a] + nodal[b])  # an edge (hexahedra: axis-parallel)
    known = ~np.isnan(expect[:, 0])
    assert known.sum() > coarse.n_nodes  # coarse nodes and edge midpoints were checked
    np.testing.assert_allclose(vals[known], expect[known], rtol=0, atol=1e-12)


def test_a_fine_node_outside_the_coarse_mesh_is_counted_and_extrapolated():
    coarse = mesh3d.box((0.0, 1.0), (0.0, 1.0), (0.0, 1.0), (1, 1, 1), "hexahedron", 0)
    pts = np.array([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]])  # (2, 3) inside, outside
    nodal = coarse.points @ np.array([1.0, 2.0, -3.0])  # (N,) an affine field: Q1 exact
    vals, outside = contact3d_transfer.evaluate(coarse, nodal[:, None], pts)
    assert outside == 1
    np.testing.assert_allclose(vals[:, 0], pts @ np.array([1.0, 2.0, -3.0]), atol=1e-12)


def test_prolongate_keeps_the_fine_prescribed_values():
    """The fixed entries of the fine full vector are the fine level's Dirichlet values, the
    free ones the coarse field: an affine coarse displacement (P1 exact) on the bracket."""
    scene = load_scene("bracket3d")
    coarse, fine = contact3d.build(scene, 0), contact3d.build(scene, 1)
    x = np.zeros(coarse.values.size)
    for b in coarse.bodies:
        d = b.u_dofs(np.arange(b.n_nodes))  # (N, 3)
        x[d] = b.mesh.points @ np.array([[1.0, 0.0, 2.0], [0.0, -1.0, 0.0], [0.5, 0.0, 1.0]])
    out, outside = contact3d_transfer.prolongate(coarse, x, fine)
    assert outside == 0
    fixed = np.ones(out.size, dtype=bool)
    fixed[fine.free] = False
    np.testing.assert_array_equal(out[fixed], fine.values[fixed])
    for b in fine.bodies:
        d = b.u_dofs(np.arange(b.n_nodes))  # (N, 3)
        want = b.mesh.points @ np.array([[1.0, 0.0, 2.0], [0.0, -1.0, 0.0], [0.5, 0.0, 1.0]])
        free = ~fixed[d]
        np.testing.assert_allclose(out[d][free], want[free], rtol=0, atol=1e-12)
