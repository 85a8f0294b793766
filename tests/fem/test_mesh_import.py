"""fem.mesh_import: gmsh files → meshes with named bodies and boundaries; the refusals."""

import meshio
import numpy as np
import pytest

from fem import mesh_import, shapes
from fem.facets import trace
from fem.mesh import Mesh
from fem.mesh_import import MeshImportError, body_mesh, read_mesh, require_curve, write_msh
from fem.meshing import rectangle, refine

FORMATS = ("gmsh22", "gmsh")  # meshio's names of gmsh v2.2 and v4.1


def _edge_set(edges: np.ndarray) -> set[tuple[int, int]]:
    return {(int(a), int(b)) for a, b in edges}


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize(
    "mesh",
    [
        rectangle((0, 2), (0, 1), (4, 3), "quad"),
        rectangle((0, 2), (0, 1), (4, 3), "triangle"),
        shapes.half_disc(),
        shapes.cradle(),
    ],
    ids=["quad", "triangle", "half_disc", "cradle"],
)
def test_a_written_mesh_reads_back_identical(tmp_path, fmt, mesh):
    """Same nodes, cells and boundary parts (edge direction and order along the part); v2.2
    keeps the node numbering, v4.1 (meshio groups nodes by entity) may permute it."""
    path = tmp_path / "m.msh"
    write_msh(path, {"part": mesh}, fmt)
    got = body_mesh(read_mesh(path), "part")
    where = {tuple(p): i for i, p in enumerate(mesh.points.tolist())}
    perm = np.array([where[tuple(p)] for p in got.points.tolist()])  # got node → mesh node
    if fmt == "gmsh22":
        np.testing.assert_array_equal(perm, np.arange(mesh.n_nodes))
    np.testing.assert_array_equal(perm[got.cells], mesh.cells)
    assert set(got.boundaries) == set(mesh.boundaries)
    for name, edges in mesh.boundaries.items():
        np.testing.assert_array_equal(perm[got.boundaries[name]], edges)


def test_two_bodies_in_one_file_are_cut_apart(tmp_path):
    a = rectangle((0, 1), (0, 1), (2, 2))
    b = rectangle((0, 1), (1, 2), (3, 3), "triangle")
    write_msh(tmp_path / "two.msh", {"lower": a, "upper": b})
    mf = read_mesh(tmp_path / "two.msh")
    assert mf.names(2) == ["lower", "upper"]
    lo, up = body_mesh(mf, "lower"), body_mesh(mf, "upper")
    assert (lo.n_nodes, lo.cell_type) == (9, "quad")
    assert (up.n_nodes, up.cell_type) == (16, "triangle")
    assert "lower_top" in lo.boundaries and "lower_top" not in up.boundaries
    np.testing.assert_array_equal(up.boundaries["upper_bottom"], b.boundaries["bottom"])


def test_clockwise_cells_are_flipped_and_boundary_keeps_the_body_on_the_left(tmp_path):
    m = rectangle((0, 1), (0, 1), (2, 2), "triangle")
    cw = type(m)(m.points, m.cells[:, ::-1].copy(), {})
    pts3 = np.c_[m.points, np.zeros(m.n_nodes)]
    bottom = m.boundaries["bottom"][:, ::-1]  # the file's curve runs the other way
    meshio.Mesh(
        pts3,
        [("triangle", cw.cells), ("line", bottom)],
        cell_data={"gmsh:physical": [np.full(m.n_cells, 1), np.full(2, 2)]},
        field_data={"plate": np.array([1, 2]), "base": np.array([2, 1])},
    ).write(str(tmp_path / "cw.msh"), file_format="gmsh22", binary=False)
    got = body_mesh(read_mesh(tmp_path / "cw.msh"), "plate")
    P = got.points[got.cells]
    d1, d2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    area = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    assert (area > 0).all()
    np.testing.assert_array_equal(got.boundaries["base"], m.boundaries["bottom"])
    assert (trace(got, "base").normals[:, 1] < 0).all()  # outward = −y on the bottom


def test_refinement_of_an_imported_mesh_keeps_names(tmp_path):
    write_msh(tmp_path / "d.msh", {"disc": shapes.half_disc()})
    m = refine(body_mesh(read_mesh(tmp_path / "d.msh"), "disc"), 2)
    ref = refine(shapes.half_disc(), 2)
    np.testing.assert_allclose(m.points, ref.points)
    assert set(m.boundaries) == set(ref.boundaries)


# ------------------------------------------------------------------ refusals
def _write(tmp_path, cells, groups, points=None, name="bad.msh"):
    """A gmsh v2.2 file with the given cell blocks [(type, data, tag)] and groups."""
    pts = points if points is not None else np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    pts3 = np.c_[pts, np.zeros(len(pts))] if pts.shape[1] == 2 else pts
    meshio.Mesh(
        pts3,
        [(t, np.asarray(d)) for t, d, _ in cells],
        cell_data={"gmsh:physical": [np.full(len(d), g) for _, d, g in cells]},
        field_data={k: np.array(v) for k, v in groups.items()},
    ).write(str(tmp_path / name), file_format="gmsh22", binary=False)
    return tmp_path / name


def test_misspelt_group_lists_the_available_ones(tmp_path):
    write_msh(tmp_path / "m.msh", {"plate": rectangle((0, 1), (0, 1), (1, 1))})
    with pytest.raises(MeshImportError) as err:
        body_mesh(read_mesh(tmp_path / "m.msh"), "plat")
    msg = str(err.value)
    assert "m.msh" in msg and "'plat'" in msg and "did you mean 'plate'" in msg
    assert "available: 'plate'" in msg


def test_a_curve_group_is_not_a_body(tmp_path):
    write_msh(tmp_path / "m.msh", {"plate": rectangle((0, 1), (0, 1), (1, 1))})
    with pytest.raises(MeshImportError, match="dimension 2"):
        body_mesh(read_mesh(tmp_path / "m.msh"), "top")


def test_unsupported_cells_are_refused(tmp_path):
    path = _write(
        tmp_path,
        [("triangle6", [[0, 1, 2, 0, 1, 2]], 1)],
        {"plate": [1, 2]},
    )
    with pytest.raises(MeshImportError, match="triangle6.*linear triangles"):
        body_mesh(read_mesh(path), "plate")


def test_mixed_cell_types_are_refused(tmp_path):
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 0.5]])
    path = _write(
        tmp_path, [("quad", [[0, 1, 2, 3]], 1), ("triangle", [[1, 4, 2]], 1)], {"p": [1, 2]}, pts
    )
    with pytest.raises(MeshImportError, match="mixes cell types"):
        body_mesh(read_mesh(path), "p")


def test_a_fold_is_refused(tmp_path):
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 0.5]])
    # second triangle clockwise while the first is counterclockwise
    path = _write(tmp_path, [("triangle", [[0, 1, 2], [1, 2, 4]], 1)], {"p": [1, 2]}, pts)
    with pytest.raises(MeshImportError, match="inverted"):
        body_mesh(read_mesh(path), "p")


def test_a_degenerate_cell_is_refused(tmp_path):
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 0.0]])
    path = _write(tmp_path, [("triangle", [[0, 1, 2], [0, 1, 4]], 1)], {"p": [1, 2]}, pts)
    with pytest.raises(MeshImportError, match="degenerate"):
        body_mesh(read_mesh(path), "p")


def test_a_nonconvex_quad_is_refused(tmp_path):
    pts = np.array([[0, 0], [2, 0], [0.3, 0.3], [0, 2.0]])  # a dart: corner 2 is reflex
    path = _write(tmp_path, [("quad", [[0, 1, 2, 3]], 1)], {"p": [1, 2]}, pts)
    with pytest.raises(MeshImportError, match="convex"):
        body_mesh(read_mesh(path), "p")


def test_a_curve_inside_a_body_is_refused(tmp_path):
    m = rectangle((0, 2), (0, 1), (2, 1), "quad")  # middle edge 1–4 is interior
    path = _write(
        tmp_path,
        [("quad", m.cells, 1), ("line", [[1, 4]], 2)],
        {"p": [1, 2], "cut": [2, 1]},
        m.points,
    )
    with pytest.raises(MeshImportError, match="'cut'.*inside"):
        body_mesh(read_mesh(path), "p")


def test_a_non_planar_mesh_is_refused(tmp_path):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.5]])
    path = _write(tmp_path, [("triangle", [[0, 1, 2]], 1)], {"p": [1, 2]}, pts)
    with pytest.raises(MeshImportError, match="z = 0"):
        read_mesh(path)


def test_an_unreadable_file_is_refused(tmp_path):
    (tmp_path / "x.msh").write_text("not a mesh\n")
    with pytest.raises(MeshImportError, match="x.msh: unreadable"):
        read_mesh(tmp_path / "x.msh")


def test_a_contact_part_of_two_pieces_is_not_a_curve(tmp_path):
    m = rectangle((0, 1), (0, 1), (2, 2))
    two = {"sides": np.concatenate([m.boundaries["left"], m.boundaries["right"]])}
    path = tmp_path / "m.msh"
    write_msh(path, {"p": type(m)(m.points, m.cells, two)})
    got = body_mesh(read_mesh(path), "p")
    assert got.boundary_nodes("sides").size == 6  # fine for Dirichlet data
    with pytest.raises(ValueError, match="disconnected"):
        require_curve(got, "sides")


def test_mutation_dropping_the_flip_is_caught(tmp_path, monkeypatch):
    """Without the flip of clockwise bodies the orientation test above fails."""
    monkeypatch.setattr(mesh_import, "_oriented", lambda path, where, points, cells: cells)
    with pytest.raises(AssertionError):
        test_clockwise_cells_are_flipped_and_boundary_keeps_the_body_on_the_left(tmp_path)


def test_mutation_a_misdirected_boundary_is_caught(tmp_path, monkeypatch):
    """Boundary edges taken in the file's direction instead of the body's: caught."""
    monkeypatch.setattr(mesh_import, "_order_edges", lambda e: e[::-1, ::-1])
    with pytest.raises(AssertionError):
        test_a_written_mesh_reads_back_identical(tmp_path, "gmsh22", shapes.cradle())


def test_coincident_nodes_are_refused_naming_them(tmp_path):
    """A mesh not made coherent (a node line written twice, one copy per side) would read as a
    body cut along it: refused, naming the nodes and the point."""
    m = rectangle((0, 2), (0, 1), (2, 1), "quad")
    mid = np.flatnonzero(np.isclose(m.points[:, 0], 1.0))  # (2,) nodes of the middle line
    copy = np.arange(m.n_nodes)
    copy[mid] = m.n_nodes + np.arange(mid.size)
    right = m.points[m.cells].mean(axis=1)[:, 0] > 1.0  # (n_cells,)
    cells = np.where(right[:, None], copy[m.cells], m.cells)
    write_msh(tmp_path / "cut.msh", {"part": Mesh(np.vstack([m.points, m.points[mid]]), cells)})
    with pytest.raises(MeshImportError, match=r"nodes \d+ and \d+ at the same point"):
        body_mesh(read_mesh(tmp_path / "cut.msh"), "part")
