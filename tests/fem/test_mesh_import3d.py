"""3D meshes from files (`fem.mesh_import3d`): any box mesh written as gmsh v2.2 reads back as
the same cells and outward parts, mirrored cells are renumbered, and bad files are
refused naming the group or cell; the shipped bracket (gmsh v4.1) is read with meshio alone,
and gmsh meshes (hexahedra and tetrahedra) are generated only when gmsh is installed."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fem import mesh_import3d
from fem.facets import trace
from fem.mesh3d import Mesh3D, box, jacobian_determinants, transform
from fem.mesh_import import MeshImportError, read_mesh, write_msh
from fem.mesh_import3d import body_mesh3d
from problems.scene import SCENES_DIR

BRACKET = SCENES_DIR / "meshes" / "bracket3d.msh"


def _canon(mesh: Mesh3D, cells: np.ndarray) -> list[tuple]:
    """Cells as sorted tuples of their corner coordinates in local order (numbering-free)."""
    return sorted(tuple(np.round(mesh.points[c], 9).ravel()) for c in cells)


def _same(a: Mesh3D, b: Mesh3D) -> bool:
    """Same cells (local order included) and the same oriented parts, up to node numbering."""
    return (
        _canon(a, a.cells) == _canon(b, b.cells)
        and sorted(a.boundaries) == sorted(b.boundaries)
        and all(_canon(a, a.boundaries[k]) == _canon(b, b.boundaries[k]) for k in a.boundaries)
    )


def _roundtrip(tmp_path, mesh: Mesh3D, body: str | None = "blk") -> Mesh3D:
    path = tmp_path / "m.msh"
    write_msh(path, {"blk": mesh})
    return body_mesh3d(read_mesh(path, planar=False), body)


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
    flip[::2] = flip[::2][:, mesh_import3d.MIRROR[element]]  # every other cell det J < 0
    back = _roundtrip(tmp_path, Mesh3D(mesh.points, flip, mesh.boundaries))
    assert (jacobian_determinants(back, np.full((1, 3), 0.25)) > 0).all()
    assert _canon(back, back.boundaries["top"]) == _canon(mesh, mesh.boundaries["top"])


def test_mutation_without_the_renumbering_mirrored_cells_are_refused(tmp_path, monkeypatch):
    """The renumbering is what makes mirrored cells usable: without it check_cells refuses."""
    mesh = box((0, 1), (0, 1), (0, 1), (2, 1, 1), "tetra")
    flip = mesh.cells[:, mesh_import3d.MIRROR["tetra"]]
    identity = {k: np.arange(len(v)) for k, v in mesh_import3d.MIRROR.items()}
    monkeypatch.setattr(mesh_import3d, "MIRROR", identity)
    with pytest.raises(MeshImportError, match="positive volume"):
        _roundtrip(tmp_path, Mesh3D(mesh.points, flip, mesh.boundaries))


def test_mutation_reversed_parts_are_told_apart(tmp_path):
    """_same compares oriented faces: a part turned inward is a different mesh."""
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "hexahedron")
    back = _roundtrip(tmp_path, mesh)
    inward = {**back.boundaries, "top": back.boundaries["top"][:, ::-1]}
    assert not _same(mesh, Mesh3D(back.points, back.cells, inward))


def _write(path, points, cells, groups):
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
    mf = _write(tmp_path / "w.msh", hexa.points, [("wedge", wedge)], {"v": (3, 0)})
    with pytest.raises(MeshImportError, match="'wedge'.*linear tetrahedra"):
        body_mesh3d(mf, "v")
    tet = np.array([[0, 1, 3, 4]])
    cells = [("hexahedron", hexa.cells), ("tetra", tet)]
    mf = _write(tmp_path / "x.msh", hexa.points, cells, {"v": (3, 0), "t": (3, 1)})
    with pytest.raises(MeshImportError, match="mixes cell types"):
        body_mesh3d(mf, None)


def test_a_surface_group_inside_the_body_or_of_the_wrong_type_is_refused(tmp_path):
    mesh = box((0, 2), (0, 1), (0, 1), (2, 1, 1), "hexahedron")
    inner = np.array([mesh.cells[0, [1, 2, 6, 5]]])  # the face shared by the two cells
    cells = [("hexahedron", mesh.cells), ("quad", inner)]
    mf = _write(tmp_path / "i.msh", mesh.points, cells, {"v": (3, 0), "wall": (2, 1)})
    with pytest.raises(MeshImportError, match="'wall' has 1 face.* inside body 'v'"):
        body_mesh3d(mf, "v")
    tri = np.array([mesh.boundaries["top"][0, :3]])
    cells = [("hexahedron", mesh.cells), ("triangle", tri)]
    mf = _write(tmp_path / "t.msh", mesh.points, cells, {"v": (3, 0), "top": (2, 1)})
    with pytest.raises(MeshImportError, match="'top'.*'triangle'.*'quad' faces"):
        body_mesh3d(mf, "v")


def test_a_flat_cell_is_refused_naming_it(tmp_path):
    mesh = box((0, 1), (0, 1), (0, 1), (1, 1, 1), "tetra")
    pts = mesh.points.copy()
    flat = np.array([[0, 1, 2, 3]])  # four nodes of the bottom face z = 0
    mf = _write(tmp_path / "f.msh", pts, [("tetra", flat)], {"v": (3, 0)})
    with pytest.raises(MeshImportError, match="body 'v'.*positive volume"):
        body_mesh3d(mf, "v")


def test_the_shipped_bracket_reads_with_meshio_alone():
    mf = read_mesh(BRACKET, planar=False)
    mesh = body_mesh3d(mf, "bracket")
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
    gmsh = pytest.importorskip("gmsh")
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
    mesh = body_mesh3d(read_mesh(tmp_path / "box.msh", planar=False), "part")
    assert mesh.cell_type == element
    pt = np.zeros((1, 3)) + (0.25 if element == "tetra" else 0.0)
    det = jacobian_determinants(mesh, pt)
    vol = det.sum() / (6 if element == "tetra" else 1 / 8)
    assert abs(vol - 0.125) < 1e-12
    s = trace(mesh, "bottom", 4)
    assert abs(s.weights.sum() - 0.5) < 1e-12 and np.allclose(s.normals, [0, 0, -1])


@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_coincident_nodes_are_refused_naming_them(tmp_path, element):
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
        _roundtrip(tmp_path, Mesh3D(points, cells))
