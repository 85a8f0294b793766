"""Structured meshes: rectangles (graded), boxes, moved nodes, extrusions."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fem import meshing
from fem.elements import FACETS
from fem.jacobians import jacobian_determinants
from fem.mesh import Mesh, exterior_facets
from fem.meshing import END_PARTS, SIDES, box, extrude, rectangle, transform

from .mesh_checks import BOUNDS, cell_volumes, check_mesh, part_length, signed_areas, wavy

ELEMENTS = ["quad", "triangle"]
SOLIDS = ["hexahedron", "tetra"]
RECTANGLE_SIDES = ["bottom", "right", "top", "left"]


@pytest.mark.parametrize("element", ELEMENTS)
def test_rectangle(element):
    mesh = rectangle((-1.0, 2.0), (0.5, 1.5), (3, 2), element)
    k = 4 if element == "quad" else 3
    assert mesh.cell_type == element
    assert mesh.cells.shape == (6 * (1 if k == 4 else 2), k)
    assert mesh.n_nodes == 12
    assert np.isclose(signed_areas(mesh).sum(), 3.0)
    assert set(mesh.boundaries) == set(RECTANGLE_SIDES)
    check_mesh(mesh)
    for name, length, n_edges in [("bottom", 3, 3), ("right", 1, 2), ("top", 3, 3), ("left", 1, 2)]:
        assert np.isclose(part_length(mesh, name), length)
        assert len(mesh.boundaries[name]) == n_edges
    assert np.allclose(mesh.points[mesh.boundaries["bottom"][0, 0]], [-1.0, 0.5])
    assert np.allclose(mesh.points[mesh.boundaries["right"][0, 0]], [2.0, 0.5])
    assert np.allclose(mesh.points[mesh.boundaries["top"][0, 0]], [2.0, 1.5])
    assert np.allclose(mesh.points[mesh.boundaries["left"][0, 0]], [-1.0, 1.5])


@pytest.mark.parametrize(
    "args",
    [
        ((0, 1), (0, 1), (0, 2), "quad"),
        ((0, 1), (0, 1), (2, -1), "quad"),
        ((0, 1), (0, 1), (1.5, 2), "quad"),
        ((1, 1), (0, 1), (2, 2), "quad"),
        ((0, 1), (2, 1), (2, 2), "triangle"),
        ((0, 1), (0, 1), (2, 2), "hexagon"),
    ],
)
def test_rectangle_bad_input(args):
    with pytest.raises(ValueError):
        rectangle(*args)


@given(
    c=st.floats(0.0, 1.0),
    p=st.floats(1.0, 4.0),
    n=st.integers(2, 40),
)
def test_graded_keeps_ends_and_focus_and_is_monotone(c, p, n):
    t = np.linspace(0.0, 1.0, n + 1)
    x = meshing.graded(t, 0.0, 1.0, c, p)
    assert x[0] == 0.0 and x[-1] == pytest.approx(1.0, abs=1e-15)
    assert (np.diff(x) > 0).all()
    assert meshing.graded(np.array([c]), 0.0, 1.0, c, p)[0] == c
    assert np.array_equal(meshing.graded(t, 0.0, 1.0, c, 1.0), t)


def test_graded_rectangle_levels_are_nested_and_finer_at_the_focus():
    coarse = meshing.rectangle((-1, 1), (0, 1), (8, 4), focus=(0.0, 1.0), grading=(2.0, 1.5))
    fine = meshing.rectangle((-1, 1), (0, 1), (16, 8), focus=(0.0, 1.0), grading=(2.0, 1.5))
    fine_set = {tuple(np.round(p, 14)) for p in fine.points}
    assert all(tuple(np.round(p, 14)) in fine_set for p in coarse.points)
    x = np.unique(coarse.points[:, 0])
    dx = np.diff(x)
    assert dx[len(dx) // 2] < dx[0] / 4  # cells at x = 0 much narrower than at the ends
    with pytest.raises(ValueError, match="focus"):
        meshing.rectangle((0, 1), (0, 1), (2, 2), focus=(2.0, 0.5), grading=(2.0, 2.0))


@pytest.mark.parametrize("element", SOLIDS)
@pytest.mark.parametrize("level", [0, 1])
def test_box_counts_and_volume(element, level):
    mesh = box(*BOUNDS, (2, 1, 3), element, level=level)
    k = 2**level
    assert mesh.n_nodes == (2 * k + 1) * (k + 1) * (3 * k + 1)
    per_hex = 1 if element == "hexahedron" else 6
    assert mesh.n_cells == per_hex * 6 * k**3
    assert mesh.cell_type == element
    vol = cell_volumes(mesh)
    assert (vol > 0).all()
    assert np.isclose(vol.sum(), 2.0 * 1.0 * 1.5, rtol=1e-13)
    assert np.isclose(mesh.h, np.sqrt(1 + 1 + 0.25) / k, rtol=1e-13)


@pytest.mark.parametrize("element", SOLIDS)
def test_box_is_conforming(element):
    """Every interior face is shared by exactly two cells with opposite orientation."""
    mesh = box(*BOUNDS, (2, 2, 2), element)
    local = FACETS[element]
    faces = mesh.cells[:, local].reshape(-1, local.shape[1])  # (n_cells n_f, k)
    key = np.sort(faces, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    assert set(count.tolist()) <= {1, 2}
    n_ext = (count == 1).sum()
    per_side = {"hexahedron": 1, "tetra": 2}[element]
    assert n_ext == per_side * 2 * (4 + 4 + 4)  # 6 sides of 2×2 squares
    assert exterior_facets(mesh.cells, element).shape[0] == n_ext
    # paired faces have opposite outward normals
    P = mesh.points[faces]  # (n, k, 3)
    nrm = np.cross(P[:, 1] - P[:, 0], P[:, -1] - P[:, 0])  # (n, 3)
    inv = inv.ravel()
    for g in np.flatnonzero(count == 2)[:50]:
        a, b = np.flatnonzero(inv == g)
        assert np.allclose(nrm[a], -nrm[b])


@pytest.mark.parametrize("element", SOLIDS)
def test_boundary_sides(element):
    mesh = transform(box(*BOUNDS, (2, 1, 3), element, level=1), wavy)
    assert tuple(mesh.boundaries) == SIDES
    all_faces = np.concatenate(list(mesh.boundaries.values()))
    assert all_faces.shape[0] == exterior_facets(mesh.cells, element).shape[0]
    from fem.assembly import facet_geometry

    lengths = np.ptp(np.array(BOUNDS), axis=1)  # (3,)
    for s, name in enumerate(SIDES):
        axis, end = divmod(s, 2)
        x, w, _, n = facet_geometry(mesh, name)
        assert np.allclose(x[..., axis], BOUNDS[axis][end], rtol=0, atol=1e-14)
        expected = np.zeros(3)
        expected[axis] = 1.0 if end else -1.0
        assert np.allclose(n, expected, atol=1e-12)  # outward unit normals
        assert np.isclose(w.sum(), np.prod(np.delete(lengths, axis)), rtol=1e-12)
    with pytest.raises(KeyError, match="unknown boundary"):
        mesh.boundary_nodes("side")
    assert mesh.boundary_nodes("left").size == 3 * 7  # (ny + 1)(nz + 1) at level 1


def test_tetrahedra_are_positive_and_kuhn_consistent():
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "tetra")
    det = jacobian_determinants(mesh, np.zeros((1, 3)))
    assert np.allclose(det, 1.0)  # 6 tetrahedra of volume 1/6 each
    # all six share the main diagonal (node 0 → node 7 of the 2×2×2 grid)
    assert all({0, 7} <= set(t) for t in mesh.cells.tolist())


def test_box_and_transform_bad_arguments():
    with pytest.raises(ValueError, match="unknown element"):
        box(*BOUNDS, (1, 1, 1), "prism")
    with pytest.raises(ValueError, match="level"):
        box(*BOUNDS, (1, 1, 1), level=-1)
    with pytest.raises(ValueError, match="cell counts"):
        box(*BOUNDS, (1, 0, 1))
    with pytest.raises(ValueError, match="x0 < x1"):
        box((1, 0), (0, 1), (0, 1), (1, 1, 1))
    with pytest.raises(ValueError, match="shape"):
        transform(box(*BOUNDS, (1, 1, 1)), lambda p: p[:, :2])


@pytest.mark.parametrize("layers", [1, 3])
def test_extrude_a_2d_mesh(layers):
    """The paper's cradle extruded: volume = area × thickness, every exterior face in exactly
    one part and outward (same orientation as the cells' own exterior faces)."""
    from fem.shapes import cradle

    m2 = cradle(level=1)
    mesh = extrude(m2, (-0.1, 0.2), layers)
    X = m2.points[m2.cells]  # (n_c, 4, 2) counterclockwise quadrilaterals
    area = 0.5 * np.sum(
        X[:, :, 0] * np.roll(X[:, :, 1], -1, 1) - np.roll(X[:, :, 0], -1, 1) * X[:, :, 1]
    )
    np.testing.assert_allclose(cell_volumes(mesh).sum(), 0.3 * area, rtol=1e-13)
    ext = exterior_facets(mesh.cells, "hexahedron")
    parts = np.concatenate(list(mesh.boundaries.values()))
    assert parts.shape[0] == ext.shape[0] == len({tuple(sorted(f)) for f in parts})
    own = {tuple(sorted(f)): list(f) for f in ext}
    for f in parts:  # the same cyclic order as the cell's outward face
        g = own[tuple(sorted(f))]
        assert list(np.roll(g, -g.index(f[0]))) == list(f)
    assert set(mesh.boundaries) == set(m2.boundaries) | set(END_PARTS)


def test_extrude_refuses_bad_input():
    from fem.shapes import cradle

    tri = Mesh(np.array([[0.0, 0], [1, 0], [0, 1]]), np.array([[0, 1, 2]]), {})
    with pytest.raises(ValueError, match="quadrilateral"):
        extrude(tri, (0.0, 1.0))
    with pytest.raises(ValueError, match="layers"):
        extrude(cradle(), (0.0, 1.0), 0)
    with pytest.raises(ValueError, match="z0 < z1"):
        extrude(cradle(), (1.0, 1.0))


@pytest.mark.parametrize("element", ELEMENTS)
def test_transform_a_rectangle(element):
    """2D as 3D: the nodes moved, cells and parts kept; a reflection is refused."""
    mesh = rectangle((0, 2), (0, 1), (4, 2), element)
    x, y = mesh.points.T
    bump = np.stack([x * (2 - x) * np.sin(3 * y), y * (1 - y) * np.sin(2 * x)], axis=1)
    moved = transform(mesh, lambda p: p + 0.1 * bump)  # each side slides along its own line
    assert moved.cells is mesh.cells and moved.boundaries is mesh.boundaries
    assert not np.allclose(moved.points, mesh.points)
    assert np.isclose(signed_areas(moved).sum(), 2.0, rtol=1e-12)
    with pytest.raises(ValueError, match="inverted"):
        transform(mesh, lambda p: p * np.array([-1.0, 1.0]))
