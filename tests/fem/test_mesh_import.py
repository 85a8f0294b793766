"""fem.mesh_import: gmsh files → 2D and 3D meshes with named bodies and boundaries; the
refusals. 3D: any box mesh written as gmsh v2.2 reads back as the same cells and outward parts,
mirrored cells are renumbered, and bad files are refused naming the group or cell; the shipped
bracket (gmsh v4.1) is read with meshio alone, and gmsh meshes (hexahedra and tetrahedra) are
generated only when gmsh is installed."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fem import mesh_import, shapes
from fem.facets import trace
from fem.jacobians import jacobian_determinants
from fem.mesh import Mesh
from fem.mesh_import import MeshImportError, body_mesh, read_mesh, require_curve
from fem.meshing import box, rectangle, transform
from fem.refine import refine
from problems.scene import SCENES_DIR
from tests import optional
from tests.gmsh_files import write_msh

FORMATS = ("gmsh22", "gmsh")  # meshio's names of gmsh v2.2 and v4.1


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


@pytest.mark.parametrize("element", ["quad", "triangle"])
def test_a_closed_part_does_not_depend_on_the_order_of_the_cells(tmp_path, element):
    """A closed loop has no first edge of its own: it starts at the lowest-numbered edge, so
    the same nodes with the cells listed in another order give the same part, edge by edge
    (a mutation ordering the loop as the cells come is caught here)."""
    mesh = rectangle((0, 2), (0, 1), (3, 2), element)
    loop = np.concatenate([mesh.boundaries[s] for s in ("bottom", "right", "top", "left")])
    parts = []
    for seed in (0, 1):
        order = np.random.default_rng(seed).permutation(mesh.n_cells)
        path = tmp_path / f"m{seed}.msh"
        write_msh(path, {"part": Mesh(mesh.points, mesh.cells[order], {"outer": loop})})
        parts.append(body_mesh(read_mesh(path), "part").boundaries["outer"])
    np.testing.assert_array_equal(parts[0], parts[1])
    assert sorted(map(tuple, parts[0].tolist())) == sorted(map(tuple, loop.tolist()))


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
    monkeypatch.setattr(mesh_import, "_counterclockwise", lambda path, where, points, cells: cells)
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


# ------------------------------------------------------------------ 3D
BRACKET = SCENES_DIR / "meshes" / "bracket3d.msh"


def _canon(mesh: Mesh, cells: np.ndarray) -> list[tuple]:
    """Cells as sorted tuples of their corner coordinates in local order (numbering-free)."""
    return sorted(tuple(np.round(mesh.points[c], 9).ravel()) for c in cells)


def _same(a: Mesh, b: Mesh) -> bool:
    """Same cells (local order included) and the same oriented parts, up to node numbering."""
    return (
        _canon(a, a.cells) == _canon(b, b.cells)
        and sorted(a.boundaries) == sorted(b.boundaries)
        and all(_canon(a, a.boundaries[k]) == _canon(b, b.boundaries[k]) for k in a.boundaries)
    )


def _roundtrip(tmp_path, mesh: Mesh, body: str | None = "blk") -> Mesh:
    path = tmp_path / "m.msh"
    write_msh(path, {"blk": mesh})
    return body_mesh(read_mesh(path, planar=False), body)


@settings(max_examples=12)
@given(
    element=st.sampled_from(["hexahedron", "tetra"]),
    cells=st.tuples(*[st.integers(1, 3)] * 3),
    seed=st.integers(0, 2**16),
)
def test_any_box_mesh_reads_back_as_the_same_cells_and_parts(
    tmp_path_factory, element, cells, seed
):
    rng = np.random.default_rng(seed)
    A = np.eye(3) + 0.3 * rng.uniform(-1, 1, (3, 3))  # det > 0 for ‖A − I‖ small
    A *= np.sign(np.linalg.det(A))
    mesh = transform(box((0, 1), (0, 2), (0, 0.5), cells, element), lambda p: p @ A.T + 1.0)
    back = _roundtrip(tmp_path_factory.mktemp("rt"), mesh)
    assert back.cell_type == element and _same(mesh, back)


@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_mirrored_cells_are_renumbered_to_positive_volume(tmp_path, element):
    mesh = box((0, 1), (0, 1), (0, 1), (2, 1, 1), element)
    flip = mesh.cells.copy()
    flip[::2] = flip[::2][:, mesh_import.MIRROR[element]]  # every other cell det J < 0
    back = _roundtrip(tmp_path, Mesh(mesh.points, flip, mesh.boundaries))
    assert (jacobian_determinants(back, np.full((1, 3), 0.25)) > 0).all()
    assert _canon(back, back.boundaries["top"]) == _canon(mesh, mesh.boundaries["top"])


def test_mutation_without_the_renumbering_mirrored_cells_are_refused(tmp_path, monkeypatch):
    """The renumbering is what makes mirrored cells usable: without it check_cells refuses."""
    mesh = box((0, 1), (0, 1), (0, 1), (2, 1, 1), "tetra")
    flip = mesh.cells[:, mesh_import.MIRROR["tetra"]]
    identity = {k: np.arange(len(v)) for k, v in mesh_import.MIRROR.items()}
    monkeypatch.setattr(mesh_import, "MIRROR", identity)
    with pytest.raises(MeshImportError, match="positive volume"):
        _roundtrip(tmp_path, Mesh(mesh.points, flip, mesh.boundaries))


def test_mutation_reversed_parts_are_told_apart(tmp_path):
    """_same compares oriented faces: a part turned inward is a different mesh."""
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "hexahedron")
    back = _roundtrip(tmp_path, mesh)
    inward = {**back.boundaries, "top": back.boundaries["top"][:, ::-1]}
    assert not _same(mesh, Mesh(back.points, back.cells, inward))


def _write_volume(path, points, cells, groups):
    """A gmsh v2.2 file of meshio cell blocks with physical groups {name: (dim, block index)}."""
    phys = [np.full(len(c[1]), 0) for c in cells]
    field = {}
    for tag, (name, (dim, i)) in enumerate(groups.items(), start=1):
        phys[i][:] = tag
        field[name] = np.array([tag, dim])
    m = meshio.Mesh(points, cells, cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys},
                    field_data=field)  # fmt: skip
    m.write(str(path), file_format="gmsh22", binary=False)
    return read_mesh(path, planar=False)


def test_an_unknown_body_lists_the_volume_groups(tmp_path):
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "tetra")
    with pytest.raises(MeshImportError, match="did you mean 'blk'.*available: 'blk'"):
        _roundtrip(tmp_path, mesh, body="bkl")


def test_unsupported_and_mixed_cells_are_refused_naming_them(tmp_path):
    hexa = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "hexahedron")
    wedge = np.array([[0, 1, 2, 4, 5, 6]])
    mf = _write_volume(tmp_path / "w.msh", hexa.points, [("wedge", wedge)], {"v": (3, 0)})
    with pytest.raises(MeshImportError, match="'wedge'.*linear tetrahedra"):
        body_mesh(mf, "v")
    tet = np.array([[0, 1, 3, 4]])
    cells = [("hexahedron", hexa.cells), ("tetra", tet)]
    mf = _write_volume(tmp_path / "x.msh", hexa.points, cells, {"v": (3, 0), "t": (3, 1)})
    with pytest.raises(MeshImportError, match="mixes cell types"):
        body_mesh(mf, None)


def test_a_surface_group_inside_the_body_or_of_the_wrong_type_is_refused(tmp_path):
    mesh = box((0, 2), (0, 1), (0, 1), (2, 1, 1), "hexahedron")
    inner = np.array([mesh.cells[0, [1, 2, 6, 5]]])  # the face shared by the two cells
    cells = [("hexahedron", mesh.cells), ("quad", inner)]
    mf = _write_volume(tmp_path / "i.msh", mesh.points, cells, {"v": (3, 0), "wall": (2, 1)})
    with pytest.raises(MeshImportError, match="'wall' has 1 face.* inside body 'v'"):
        body_mesh(mf, "v")
    tri = np.array([mesh.boundaries["top"][0, :3]])
    cells = [("hexahedron", mesh.cells), ("triangle", tri)]
    mf = _write_volume(tmp_path / "t.msh", mesh.points, cells, {"v": (3, 0), "top": (2, 1)})
    with pytest.raises(MeshImportError, match="'top'.*'triangle'.*'quad' faces"):
        body_mesh(mf, "v")


def test_a_flat_cell_is_refused_naming_it(tmp_path):
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "tetra")
    pts = mesh.points.copy()
    flat = np.array([[0, 1, 2, 3]])  # four nodes of the bottom face z = 0
    mf = _write_volume(tmp_path / "f.msh", pts, [("tetra", flat)], {"v": (3, 0)})
    with pytest.raises(MeshImportError, match="body 'v'.*positive volume"):
        body_mesh(mf, "v")


def test_the_shipped_bracket_reads_with_meshio_alone():
    mf = read_mesh(BRACKET, planar=False)
    mesh = body_mesh(mf, "bracket")
    assert mesh.cell_type == "tetra"
    assert sorted(mesh.boundaries) == ["back", "base", "bolt", "toe", "top"]
    vol = float(np.sum(jacobian_determinants(mesh, np.full((1, 3), 0.25)))) / 6
    exact = 0.6 * 0.4 * 0.08 + 0.08 * 0.4 * 0.42 - np.pi * 0.08**2 * 0.08
    assert abs(vol - exact) < 0.01 * exact  # the hole is a polygon of chords
    base = trace(mesh, "base", 4)
    assert np.allclose(base.normals, [0.0, 0.0, -1.0])  # outward on the flat foot
    assert abs(base.weights.sum() - (0.6 * 0.4 - np.pi * 0.08**2)) < 0.01 * 0.24


@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_a_gmsh_box_imports_with_its_volume_and_faces(tmp_path, element):
    gmsh = optional.gmsh()
    gmsh.initialize(["-noenv"])
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, 1.0, 0.5, 0.25)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], name="part")
        bottom = [
            t for _, t in gmsh.model.getEntities(2) if gmsh.model.getBoundingBox(2, t)[5] < 1e-6
        ]
        gmsh.model.addPhysicalGroup(2, bottom, name="bottom")  # fmt: skip
        if element == "hexahedron":
            for d in (1, 2, 3):
                for _, t in gmsh.model.getEntities(d):
                    if d == 1:
                        gmsh.model.mesh.setTransfiniteCurve(t, 4)
                    elif d == 2:
                        gmsh.model.mesh.setTransfiniteSurface(t)
                        gmsh.model.mesh.setRecombine(2, t)
                    else:
                        gmsh.model.mesh.setTransfiniteVolume(t)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", 0.2)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(tmp_path / "box.msh"))
    finally:
        gmsh.finalize()
    mesh = body_mesh(read_mesh(tmp_path / "box.msh", planar=False), "part")
    assert mesh.cell_type == element
    pt = np.zeros((1, 3)) + (0.25 if element == "tetra" else 0.0)
    det = jacobian_determinants(mesh, pt)
    vol = det.sum() / (6 if element == "tetra" else 1 / 8)
    assert abs(vol - 0.125) < 1e-12
    s = trace(mesh, "bottom", 4)
    assert abs(s.weights.sum() - 0.5) < 1e-12 and np.allclose(s.normals, [0, 0, -1])


@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_coincident_nodes_in_a_volume_are_refused_naming_them(tmp_path, element):
    """A mesh not made coherent (the nodes of a layer written twice, one copy per side) would
    read as a body cut along that layer: refused, naming the nodes and the point."""
    mesh = box((0, 1), (0, 1), (0, 2), (1, 1, 2), element)
    mid = np.flatnonzero(np.isclose(mesh.points[:, 2], 1.0))  # (4,) nodes of the middle layer
    copy = np.arange(mesh.n_nodes)
    copy[mid] = mesh.n_nodes + np.arange(mid.size)
    upper = mesh.points[mesh.cells].mean(axis=1)[:, 2] > 1.0  # (n_cells,)
    cells = np.where(upper[:, None], copy[mesh.cells], mesh.cells)
    points = np.vstack([mesh.points, mesh.points[mid]])
    with pytest.raises(MeshImportError, match=r"nodes \d+ and \d+ at the same point"):
        _roundtrip(tmp_path, Mesh(points, cells))
