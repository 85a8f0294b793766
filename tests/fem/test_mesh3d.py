"""3D boxes: counts, volumes, conformity, boundary faces by side, Jacobian checks."""

import numpy as np
import pytest

from fem.elements import FACETS as FACES
from fem.mesh3d import (
    EDGES,
    END_PARTS,
    SIDES,
    Mesh3D,
    box,
    check_cells,
    cofactors,
    exterior_faces,
    extrude,
    jacobian_determinants,
    refine,
    transform,
)

ELEMENTS = ["hexahedron", "tetra"]
BOUNDS = ((0.0, 2.0), (-0.5, 0.5), (0.0, 1.5))


def wavy(p: np.ndarray, amount: float = 0.06) -> np.ndarray:
    """A smooth distortion of the box BOUNDS that keeps its faces plane."""
    x, y, z = p.T
    bx = x * (2 - x)  # vanishes on x = 0, 2
    by = (y + 0.5) * (0.5 - y)
    bz = z * (1.5 - z)
    q = p.copy()
    q[:, 0] += amount * np.sin(3 * y + 2 * z) * bx
    q[:, 1] += amount * np.cos(2 * x - z) * by * 4
    q[:, 2] += amount * np.sin(x + 2 * y) * bz
    return q


def cell_volumes(mesh: Mesh3D) -> np.ndarray:
    from fem.assembly import cell_geometry

    return cell_geometry(mesh, order=2).w.sum(axis=1)


@pytest.mark.parametrize("element", ELEMENTS)
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


@pytest.mark.parametrize("element", ELEMENTS)
def test_box_is_conforming(element):
    """Every interior face is shared by exactly two cells with opposite orientation."""
    mesh = box(*BOUNDS, (2, 2, 2), element)
    local = FACES[element]
    faces = mesh.cells[:, local].reshape(-1, local.shape[1])  # (n_cells n_f, k)
    key = np.sort(faces, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    assert set(count.tolist()) <= {1, 2}
    n_ext = (count == 1).sum()
    per_side = {"hexahedron": 1, "tetra": 2}[element]
    assert n_ext == per_side * 2 * (4 + 4 + 4)  # 6 sides of 2×2 squares
    assert exterior_faces(mesh.cells, element).shape[0] == n_ext
    # paired faces have opposite outward normals
    P = mesh.points[faces]  # (n, k, 3)
    nrm = np.cross(P[:, 1] - P[:, 0], P[:, -1] - P[:, 0])  # (n, 3)
    inv = inv.ravel()
    for g in np.flatnonzero(count == 2)[:50]:
        a, b = np.flatnonzero(inv == g)
        assert np.allclose(nrm[a], -nrm[b])


@pytest.mark.parametrize("element", ELEMENTS)
def test_boundary_sides(element):
    mesh = transform(box(*BOUNDS, (2, 1, 3), element, level=1), wavy)
    assert tuple(mesh.boundaries) == SIDES
    all_faces = np.concatenate(list(mesh.boundaries.values()))
    assert all_faces.shape[0] == exterior_faces(mesh.cells, element).shape[0]
    from fem.assembly import facet_geometry as face_geometry

    lengths = np.ptp(np.array(BOUNDS), axis=1)  # (3,)
    for s, name in enumerate(SIDES):
        axis, end = divmod(s, 2)
        x, w, _, n = face_geometry(mesh, name)
        assert np.allclose(x[..., axis], BOUNDS[axis][end], rtol=0, atol=1e-14)
        expected = np.zeros(3)
        expected[axis] = 1.0 if end else -1.0
        assert np.allclose(n, expected, atol=1e-12)  # outward unit normals
        assert np.isclose(w.sum(), np.prod(np.delete(lengths, axis)), rtol=1e-12)
    with pytest.raises(KeyError, match="unknown boundary"):
        mesh.boundary_nodes("side")
    assert mesh.boundary_nodes("left").size == 3 * 7  # (ny + 1)(nz + 1) at level 1


@pytest.mark.parametrize("element", ELEMENTS)
def test_inverted_cell_is_refused(element):
    mesh = box(*BOUNDS, (2, 2, 2), element)
    cells = mesh.cells.copy()
    swap = [1, 3] if element == "hexahedron" else [1, 2]
    cells[5, swap] = cells[5, swap[::-1]]  # mirror the local order: det J < 0
    with pytest.raises(ValueError, match="cell 5"):
        check_cells(Mesh3D(mesh.points, cells, mesh.boundaries))
    with pytest.raises(ValueError, match="inverted"):
        transform(mesh, lambda p: p * np.array([1.0, 1.0, -1.0]))  # a reflection


def test_folded_hexahedron_is_refused():
    """Positive at all 8 corners but det J < 0 inside: the interior check is needed."""
    pts = np.array(
        [
            [0.5, 0.46, 0.42],
            [1.48, 0.1, -0.24],
            [-0.41, 0.43, 0.31],
            [1.12, 0.67, 0.47],
            [-0.6, 0.58, 0.51],
            [1.38, -0.58, 1.43],
            [0.37, 1.17, 0.6],
            [1.14, 0.76, 1.48],
        ]
    )  # a random perturbation of the unit cube, nodes in lexicographic order (found by search)
    folded = Mesh3D(pts, np.array([[0, 1, 3, 2, 4, 5, 7, 6]]))
    corners = np.array([[sx, sy, sz] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)])
    assert jacobian_determinants(folded, corners).min() > 0
    with pytest.raises(ValueError, match="cell 0"):
        check_cells(folded)


def test_tetrahedra_are_positive_and_kuhn_consistent():
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "tetra")
    det = jacobian_determinants(mesh, np.zeros((1, 3)))
    assert np.allclose(det, 1.0)  # 6 tetrahedra of volume 1/6 each
    # all six share the main diagonal (node 0 → node 7 of the 2×2×2 grid)
    assert all({0, 7} <= set(t) for t in mesh.cells.tolist())


def test_bad_arguments():
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


def test_cofactors_and_determinants_against_numpy():
    J = np.random.default_rng(0).normal(size=(4, 5, 3, 3))
    cof = cofactors(J)
    det = np.linalg.det(J)
    assert np.allclose(cof, det[..., None, None] * np.linalg.inv(J).transpose(0, 1, 3, 2))
    mesh = transform(box(*BOUNDS, (1, 1, 1)), wavy)
    pts = np.random.default_rng(1).uniform(-1, 1, (6, 3))
    from fem.elements import reference_element as reference_element3d

    G = reference_element3d("hexahedron").gradients(pts)  # (6, 8, 3)
    Jm = np.einsum("cai,qaj->cqij", mesh.points[mesh.cells], G)
    assert np.allclose(jacobian_determinants(mesh, pts), np.linalg.det(Jm), rtol=1e-13)


def tet_quality(mesh: Mesh3D) -> float:
    """min over cells of 6√2 V / L_max³ (1 for the regular tetrahedron)."""
    P = mesh.points[mesh.cells]  # (n_cells, 4, 3)
    V = np.abs(np.linalg.det(P[:, 1:] - P[:, :1])) / 6
    L = np.max([np.linalg.norm(P[:, a] - P[:, b], axis=1) for a, b in EDGES["tetra"]], axis=0)
    return float((6 * np.sqrt(2) * V / L**3).min())


@pytest.mark.parametrize("element", ELEMENTS)
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
            np.unique(np.sort(exterior_faces(fine.cells, element), axis=1), axis=0),
        )  # the refined parts are exactly the exterior faces: conforming, nothing lost


@pytest.mark.parametrize("element", ELEMENTS)
def test_refine_is_nested_and_keeps_the_geometry(element):
    """Parent nodes first; new nodes on the parent's (trilinear) map: a linear function's
    nodal values on the fine mesh are its parent interpolant's values; outward faces."""
    coarse = transform(box(*BOUNDS, (2, 1, 2), element), wavy)
    fine = refine(coarse)
    assert np.array_equal(fine.points[: coarse.n_nodes], coarse.points)
    assert np.isclose(cell_volumes(fine).sum(), cell_volumes(coarse).sum(), rtol=1e-12)
    from fem.assembly import facet_geometry as face_geometry

    for name in ("left", "top"):
        _, w_c, _, _ = face_geometry(coarse, name)
        _, w_f, _, n_f = face_geometry(fine, name)
        assert np.isclose(w_f.sum(), w_c.sum(), rtol=1e-12)  # plane faces: same area
        axis, end = divmod(SIDES.index(name), 2)
        assert np.allclose(n_f[..., axis], 1.0 if end else -1.0)
    if element == "tetra":  # shape regularity does not decay under repeated refinement
        q = [tet_quality(refine(coarse, t)) for t in range(4)]
        assert min(q) > 0.95 * q[0], q


def test_refine_a_single_tetrahedron_keeps_its_quality():
    p = np.array([[0, 0, 0], [1, 0, 0], [0.3, 0.9, 0], [0.2, 0.3, 0.8]], dtype=float)
    tet = Mesh3D(
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
    import fem.mesh3d as mesh3d

    good = mesh3d._octahedron
    monkeypatch.setattr(mesh3d, "_octahedron", lambda d: good(1))
    fine = refine(box(*BOUNDS, (2, 1, 3), "tetra"))
    assert fine.h > 1.5 * box(*BOUNDS, (2, 1, 3), "tetra", level=1).h


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
    ext = exterior_faces(mesh.cells, "hexahedron")
    parts = np.concatenate(list(mesh.boundaries.values()))
    assert parts.shape[0] == ext.shape[0] == len({tuple(sorted(f)) for f in parts})
    own = {tuple(sorted(f)): list(f) for f in ext}
    for f in parts:  # the same cyclic order as the cell's outward face
        g = own[tuple(sorted(f))]
        assert list(np.roll(g, -g.index(f[0]))) == list(f)
    assert set(mesh.boundaries) == set(m2.boundaries) | set(END_PARTS)


def test_extrude_refuses_bad_input():
    from fem.mesh import Mesh
    from fem.shapes import cradle

    tri = Mesh(np.array([[0.0, 0], [1, 0], [0, 1]]), np.array([[0, 1, 2]]), {})
    with pytest.raises(ValueError, match="quadrilateral"):
        extrude(tri, (0.0, 1.0))
    with pytest.raises(ValueError, match="layers"):
        extrude(cradle(), (0.0, 1.0), 0)
    with pytest.raises(ValueError, match="z0 < z1"):
        extrude(cradle(), (1.0, 1.0))
