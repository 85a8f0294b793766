"""Uniform refinement of 2D and 3D meshes (`fem.refine`): nested, conforming, same geometry."""

import numpy as np
import pytest

from fem import refine as refine_module
from fem.mesh import Mesh, exterior_facets
from fem.meshing import SIDES, box, rectangle, transform
from fem.refine import refine

from .mesh_checks import (
    BOUNDS,
    cell_volumes,
    check_mesh,
    part_length,
    signed_areas,
    tet_quality,
    wavy,
)

ELEMENTS = ["quad", "triangle"]
SOLIDS = ["hexahedron", "tetra"]


@pytest.mark.parametrize("element", ELEMENTS)
def test_refine(element):
    rng = np.random.default_rng(0)
    coarse = rectangle((0.0, 2.0), (-1.0, 0.5), (3, 2), element)
    # a distorted coarse mesh: refinement must preserve areas of arbitrary convex cells
    pts = coarse.points.copy()
    interior = np.setdiff1d(
        np.arange(coarse.n_nodes), np.unique(np.concatenate(list(coarse.boundaries.values())))
    )
    pts[interior] += rng.uniform(-0.15, 0.15, (interior.size, 2))
    coarse = Mesh(pts, coarse.cells, coarse.boundaries)
    mesh = coarse
    for level in range(1, 4):
        fine = refine(mesh)
        assert fine.n_cells == 4 * mesh.n_cells == 4**level * coarse.n_cells
        assert fine.cell_type == element
        assert np.isclose(signed_areas(fine).sum(), 3.0)
        assert list(fine.boundaries) == list(coarse.boundaries)
        for name in coarse.boundaries:
            assert len(fine.boundaries[name]) == 2 * len(mesh.boundaries[name])
            assert np.isclose(part_length(fine, name), part_length(coarse, name))
            # same endpoints in the same order
            assert fine.boundaries[name][0, 0] == coarse.boundaries[name][0, 0]
            assert fine.boundaries[name][-1, 1] == coarse.boundaries[name][-1, 1]
        check_mesh(fine)
        # nested: parent nodes keep their indices; no duplicate nodes
        assert np.array_equal(fine.points[: mesh.n_nodes], mesh.points)
        assert np.unique(fine.points.round(12), axis=0).shape[0] == fine.n_nodes
        mesh = fine
    assert np.isclose(mesh.h, coarse.h / 8, rtol=0.3)


@pytest.mark.parametrize("element", ELEMENTS)
def test_refine_matches_structured_mesh(element):
    """Refining an nx×ny quad rectangle gives the 2nx×2ny node set (and node count)."""
    fine = refine(rectangle((0, 1), (0, 2), (2, 3), element), times=2)
    direct = rectangle((0, 1), (0, 2), (8, 12), element)
    assert fine.n_nodes == direct.n_nodes
    a = fine.points[np.lexsort(fine.points.T)]
    b = direct.points[np.lexsort(direct.points.T)]
    assert np.allclose(a, b)


def test_refine_times():
    mesh = rectangle((0, 1), (0, 1), (1, 1))
    assert refine(mesh, 0) is mesh
    with pytest.raises(ValueError):
        refine(mesh, -1)


@pytest.mark.parametrize("element", SOLIDS)
def test_refine_matches_the_box_of_the_next_levels(element):
    coarse = box(*BOUNDS, (2, 1, 3), element)
    for times in (1, 2):
        fine, ref = refine(coarse, times), box(*BOUNDS, (2, 1, 3), element, level=times)
        assert (fine.n_nodes, fine.n_cells) == (ref.n_nodes, ref.n_cells)
        key = lambda p: np.lexsort(p.round(12).T)  # noqa: E731
        assert np.array_equal(fine.points[key(fine.points)], ref.points[key(ref.points)])
        assert np.isclose(cell_volumes(fine).sum(), 3.0, rtol=1e-13)
        assert np.isclose(fine.h, ref.h)  # the shortest octahedron diagonal keeps Kuhn's cells
        for name in SIDES:
            assert fine.boundaries[name].shape == ref.boundaries[name].shape
        all_faces = np.concatenate(list(fine.boundaries.values()))
        assert np.array_equal(
            np.unique(np.sort(all_faces, axis=1), axis=0),
            np.unique(np.sort(exterior_facets(fine.cells, element), axis=1), axis=0),
        )  # the refined parts are exactly the exterior faces: conforming, nothing lost


@pytest.mark.parametrize("element", SOLIDS)
def test_refine_is_nested_and_keeps_the_geometry(element):
    """Parent nodes first; new nodes on the parent's (trilinear) map: a linear function's
    nodal values on the fine mesh are its parent interpolant's values; outward faces."""
    coarse = transform(box(*BOUNDS, (2, 1, 2), element), wavy)
    fine = refine(coarse)
    assert np.array_equal(fine.points[: coarse.n_nodes], coarse.points)
    assert np.isclose(cell_volumes(fine).sum(), cell_volumes(coarse).sum(), rtol=1e-12)
    from fem.assembly import facet_geometry

    for name in ("left", "top"):
        _, w_c, _, _ = facet_geometry(coarse, name)
        _, w_f, _, n_f = facet_geometry(fine, name)
        assert np.isclose(w_f.sum(), w_c.sum(), rtol=1e-12)  # plane faces: same area
        axis, end = divmod(SIDES.index(name), 2)
        assert np.allclose(n_f[..., axis], 1.0 if end else -1.0)
    if element == "tetra":  # shape regularity does not decay under repeated refinement
        q = [tet_quality(refine(coarse, t)) for t in range(4)]
        assert min(q) > 0.95 * q[0], q


def test_refine_a_single_tetrahedron_keeps_its_quality():
    p = np.array([[0, 0, 0], [1, 0, 0], [0.3, 0.9, 0], [0.2, 0.3, 0.8]], dtype=float)
    tet = Mesh(
        p, np.array([[0, 1, 2, 3]]), {"all": np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])}
    )
    q = [tet_quality(refine(tet, t)) for t in range(5)]
    # the first split loses some quality (0.63 -> 0.42 here); after it, none is lost
    assert q[1] > 0.5 * q[0] and min(q[1:]) > 0.99 * q[1], q
    fine = refine(tet, 2)
    assert fine.n_cells == 64 and fine.boundaries["all"].shape == (64, 3)
    with pytest.raises(ValueError, match="times"):
        refine(tet, -1)


def test_refine_check_catches_a_fixed_octahedron_diagonal(monkeypatch):
    """Fault: the octahedron always split along x02–x13: Kuhn's cells get long edges."""
    fixed = refine_module.CHILDREN["tetra"][[1, 1, 1]]  # (3, 8, 4) one rule for every choice
    monkeypatch.setitem(refine_module.CHILDREN, "tetra", fixed)
    fine = refine(box(*BOUNDS, (2, 1, 3), "tetra"))
    assert fine.h > 1.5 * box(*BOUNDS, (2, 1, 3), "tetra", level=1).h
