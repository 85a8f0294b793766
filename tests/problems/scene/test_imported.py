"""Scenes on meshes from files: the built-in answer on an identical imported mesh, refusals,
and the shipped gmsh examples; in 3D (the second half) hexahedra refined by the level,
tetrahedra as read, refusals naming the field, and the shipped gmsh bracket."""

import copy

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from fem import shapes
from fem.bisection import prepared, refine_marked
from fem.meshing import box, rectangle
from problems.commands.main import main
from problems.errors import SceneError
from problems.plugins.contact import plane as pc
from problems.plugins.contact import separation
from problems.plugins.contact import solid as contact3d
from problems.plugins.contact.bodies import given_meshes
from problems.scene import load_scene
from tests import optional
from tests.gmsh_files import write_msh
from vi_core import solve


def _solve(scene, level):
    model = pc.build(scene, level)
    sol = solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged
    return model, sol


def _imported(name, meshes: dict, tmp_path, fmt="gmsh22"):
    """The shipped scene `name` with each body's geometry replaced by its mesh in a file."""
    scene = load_scene(name)
    scene = type(scene)(copy.deepcopy(scene.data), str(tmp_path / f"{name}.toml"), name)
    for body, mesh in meshes.items():
        write_msh(tmp_path / f"{body}.msh", {body: mesh}, fmt)
        scene.data["bodies"][body]["geometry"] = {"mesh": f"{body}.msh", "body": body}
    return scene


def _compare(built, imported):
    """Same unknowns (up to a node permutation found from the coordinates), same answer."""
    (mb, sb), (mi, si) = built, imported
    assert mb.dofs == mi.dofs
    xb, xi = mb.full(sb.u), mi.full(si.u)
    for bb, bi in zip(mb.bodies, mi.bodies, strict=True):
        where = {tuple(p): k for k, p in enumerate(np.round(bb.mesh.points, 12).tolist())}
        perm = np.array([where[tuple(p)] for p in np.round(bi.mesh.points, 12).tolist()])
        ub, _ = bb.split(xb[bb.offset : bb.offset + bb.size])
        ui, _ = bi.split(xi[bi.offset : bi.offset + bi.size])
        scale = np.abs(ub).max()
        np.testing.assert_allclose(ui, ub[perm], rtol=0, atol=1e-9 * scale)
    lam_scale = np.abs(sb.lam).max()
    np.testing.assert_allclose(np.sort(si.lam), np.sort(sb.lam), rtol=0, atol=1e-9 * lam_scale)


def test_the_paper_scene_on_its_own_mesh_from_a_file_gives_the_built_in_answer(tmp_path):
    """Level-1 half disc and cradle written as gmsh v2.2 files, read at level 0."""
    built = _solve(load_scene("paper_two_body"), 1)
    meshes = {"disc": shapes.half_disc(level=1), "cradle": shapes.cradle(level=1)}
    imported = _solve(_imported("paper_two_body", meshes, tmp_path), 0)
    _compare(built, imported)


def test_a_refined_imported_rectangle_gives_the_built_in_answer(tmp_path):
    """The rigid foundation block: level-0 mesh in a gmsh v4.1 file, refined once by --level."""
    built = _solve(load_scene("rigid_foundation"), 1)
    block = rectangle((0.0, 2.0), (0.0, 1.0), (8, 4), "quad")
    imported = _solve(_imported("rigid_foundation", {"block": block}, tmp_path, "gmsh"), 1)
    _compare(built, imported)


def test_mutation_a_wrong_answer_is_caught(tmp_path):
    """_compare fails when the imported scene differs (a moved load): the check can fail."""
    built = _solve(load_scene("rigid_foundation"), 1)
    block = rectangle((0.0, 2.0), (0.0, 1.0), (8, 4), "quad")
    scene = _imported("rigid_foundation", {"block": block}, tmp_path)
    scene.data["bodies"]["block"]["displacement"][0]["value"] = [2.0e-4, -1.01e-4]
    with pytest.raises(AssertionError):
        _compare(built, _solve(scene, 1))


def _bad(tmp_path, level=0, **geometry):
    block = rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")
    scene = _imported("rigid_foundation", {"block": block}, tmp_path)
    scene.data["bodies"]["block"]["geometry"].update(geometry)
    with pytest.raises(SceneError) as err:
        pc.build(scene, level)
    return str(err.value)


def test_a_missing_mesh_file_names_the_key_and_the_file(tmp_path):
    msg = _bad(tmp_path, mesh="nowhere.msh")
    assert "bodies.block.geometry.mesh" in msg and "nowhere.msh" in msg
    assert "relative to the scene file" in msg


def test_a_misspelt_body_group_lists_the_available_ones(tmp_path):
    msg = _bad(tmp_path, body="blok")
    assert "bodies.block.geometry.mesh" in msg and "did you mean 'block'" in msg
    assert "available: 'block'" in msg


def test_an_unknown_geometry_key_beside_mesh_is_refused(tmp_path):
    assert "unknown key" in _bad(tmp_path, kind="rectangle")


def test_a_misspelt_boundary_lists_the_file_s_curves(tmp_path):
    block = rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")
    scene = _imported("rigid_foundation", {"block": block}, tmp_path)
    scene.data["contact"]["slave"] = "block.botom"
    with pytest.raises(SceneError, match="bottom, left, right, top"):
        pc.build(scene, 0)


def test_a_misspelt_body_boundary_is_named_by_its_field_after_meshing(tmp_path):
    """A file's parts are known only once read (BOUNDARIES None): the check after meshing
    names the field; without it the KeyError of the assembly would be an internal error."""
    block = rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")
    scene = _imported("rigid_foundation", {"block": block}, tmp_path)
    scene.data["bodies"]["block"]["displacement"][0]["boundary"] = "tpo"
    with pytest.raises(SceneError, match="bottom, left, right, top") as err:
        pc.build(scene, 0)
    assert err.value.key == "bodies.block.displacement[0].boundary"


def test_mutation_without_the_check_after_meshing_the_name_reaches_the_assembly(
    tmp_path, monkeypatch
):
    from problems.plugins.contact import bodies

    monkeypatch.setattr(bodies, "check_meshed", lambda mesh, refs: None)
    block = rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")
    scene = _imported("rigid_foundation", {"block": block}, tmp_path)
    scene.data["bodies"]["block"]["displacement"][0]["boundary"] = "tpo"
    with pytest.raises(KeyError):
        pc.build(scene, 0)


def test_a_contact_boundary_of_two_pieces_is_refused(tmp_path):
    m = rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")
    parts = dict(m.boundaries)
    parts["sides"] = np.concatenate([parts["left"], parts["right"]])
    scene = _imported("rigid_foundation", {"block": type(m)(m.points, m.cells, parts)}, tmp_path)
    scene.data["contact"]["slave"] = "block.sides"
    with pytest.raises(SceneError, match="contact.slave.*one simple curve"):
        pc.build(scene, 0)


def test_too_many_nodes_after_refinement_are_refused(tmp_path, monkeypatch):
    from problems.scene import geometry

    monkeypatch.setattr(geometry, "MAX_NODES", 152)  # 4 × 2 quads, level 2: 17 · 9 = 153
    msg = _bad(tmp_path, level=2)
    assert "at most 152 nodes" in msg and "would have 153 at level 2" in msg


@pytest.mark.parametrize("name", ["wavy_two_body", "plate_with_hole"])
def test_the_shipped_gmsh_scenes_solve_with_one_command(tmp_path, name, capsys):
    assert main(["solve", name, "--level", "0", "--out", str(tmp_path / name)]) == 0
    out = capsys.readouterr().out
    assert "converged in" in out


def test_a_separately_meshed_interface_stays_accepted_under_refinement():
    """The punch and base polylines differ by the chords' sagitta, fixed by the file; relative
    to the level-3 mesh size it is 0.12 × h, within 0.1 × the level-0 size (docs/design.md)."""
    model = pc.build(load_scene("wavy_two_body"), 3)
    assert model.contact.patch_defect < 1e-12


def test_mutation_a_tolerance_on_the_refined_mesh_size_refuses_it(monkeypatch):
    real = separation.check_separation
    monkeypatch.setattr(separation, "check_separation", lambda *a: real(*a[:-1], 0))
    with pytest.raises(SceneError, match="overlap"):
        pc.build(load_scene("wavy_two_body"), 3)


def _plate_geometry(kind: str, level: int):
    """Area error and largest distance of the hole's nodes from the circle, plate mesh from
    the shipped .msh (refined on its polylines) or the shipped .geo (refined by gmsh)."""
    from pathlib import Path

    from problems.scene.imported import geo_mesh, imported_mesh

    path = Path(__file__).parents[3] / "problems" / "scenes" / "meshes" / f"plate_with_hole.{kind}"
    make = geo_mesh if kind == "geo" else imported_mesh
    m = make(path, "plate", level, "bodies.plate.geometry." + kind)
    P = m.points[m.cells]  # (n_cells, 4, 2)
    x, y = P[..., 0], P[..., 1]
    area = 0.5 * np.sum(x * np.roll(y, -1, 1) - np.roll(x, -1, 1) * y)
    hole = np.unique(m.boundaries["hole"])
    r = np.hypot(*(m.points[hole] - [1.0, 0.5]).T)
    return abs(area - (2.0 - np.pi / 16)), float(np.abs(r - 0.25).max())


def test_a_geo_file_refined_by_gmsh_keeps_the_hole_round():
    """From the .geo the area error falls ~4× per level and the hole's nodes stay on the
    circle; from the .msh the error stalls at the level-0 polygon's (the README's caveat)."""
    optional.gmsh()
    geo = [_plate_geometry("geo", lv) for lv in range(3)]
    msh = [_plate_geometry("msh", lv) for lv in range(3)]
    assert geo[0][0] == pytest.approx(msh[0][0], rel=1e-12)  # the same level-0 mesh
    for lv in (1, 2):
        assert 3.5 < geo[lv - 1][0] / geo[lv][0] < 4.5
        assert geo[lv][1] < 1e-12
        assert msh[lv][0] == pytest.approx(msh[0][0], rel=1e-9)  # stalls
        assert msh[lv][1] > 1e-4  # new hole nodes on the chords


@pytest.mark.parametrize(
    "gmsh_state, says",
    [("missing", "pip install gmsh"), ("no OpenGL", "libGLU.so.1.*apt-get install")],
)
def test_a_geo_file_without_a_working_gmsh_is_refused_with_what_to_do(
    tmp_path, monkeypatch, gmsh_state, says
):
    """gmsh not installed (ImportError), or installed without the system's OpenGL/X11
    libraries (ctypes raises OSError inside `import gmsh`): either way the .geo is refused with
    what to install."""
    import builtins
    import sys

    from problems.scene import imported

    if gmsh_state == "missing":
        monkeypatch.setitem(sys.modules, "gmsh", None)  # import gmsh raises ImportError
    else:
        real = builtins.__import__

        def no_glu(name, *args, **kwargs):
            if name == "gmsh":
                raise OSError("libGLU.so.1: cannot open shared object file")
            return real(name, *args, **kwargs)

        monkeypatch.delitem(sys.modules, "gmsh", raising=False)
        monkeypatch.setattr(builtins, "__import__", no_glu)
    imported._geo.cache_clear()
    block = rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")
    scene = _imported("rigid_foundation", {"block": block}, tmp_path)
    (tmp_path / "block.geo").write_text("// a geometry\n")
    scene.data["bodies"]["block"]["geometry"] = {"geo": "block.geo", "body": "block"}
    with pytest.raises(SceneError, match=f"geometry.geo.*{says}"):
        pc.build(scene, 0)


def test_mesh_and_geo_together_are_refused(tmp_path):
    msg = _bad(tmp_path, geo="block.geo")
    assert "either mesh" in msg and "not both" in msg


def test_mutation_gmsh_not_refining_is_caught(monkeypatch):
    gmsh = optional.gmsh()
    from problems.scene import imported

    imported._geo.cache_clear()
    monkeypatch.setattr(gmsh.model.mesh, "refine", lambda: None)
    with pytest.raises(AssertionError):
        test_a_geo_file_refined_by_gmsh_keeps_the_hole_round()
    imported._geo.cache_clear()


# ------------------------------------------------------------------ separately meshed bodies
def _strip_with_gap(tmp_path, gap: float, level: int = 0):
    """shear_strip_two_body from two gmsh files, the block (slave) lifted by `gap` (negative:
    pushed into the base); its level-0 mesh size on the interface is h0 = 0.4 (the base's
    segments, longer than the block's 0.25)."""
    return pc.build(_imported("shear_strip_two_body", _strip_meshes(gap), tmp_path), level)


def _strip_meshes(gap: float) -> dict:
    return {
        "block": rectangle((0.0, 2.0), (gap, 1.0 + gap), (8, 4), "quad"),
        "base": rectangle((0.0, 2.0), (-0.5, 0.0), (5, 2), "quad"),
    }


@settings(max_examples=8)
@given(frac=st.floats(-0.095, 0.095), level=st.integers(0, 1))
def test_a_gap_or_overlap_within_the_tolerance_is_accepted(tmp_path_factory, frac, level):
    """|gap| ≤ SEPARATION_TOL · h0 (0.1 × the local level-0 mesh size, docs/design.md §6): the
    two files are one interface, at every level."""
    model = _strip_with_gap(tmp_path_factory.mktemp("gap"), frac * 0.4, level)
    sol = solve(model.vi, "ssn", tol=1e-10)
    assert sol.converged and model.contact.patch_defect < 1e-12


@settings(max_examples=8)
@given(frac=st.floats(0.105, 0.5), sign=st.sampled_from([-1.0, 1.0]))
def test_a_gap_or_overlap_beyond_the_tolerance_is_refused(tmp_path_factory, frac, sign):
    with pytest.raises(SceneError, match="overlap the slave" if sign < 0 else "stand apart") as e:
        _strip_with_gap(tmp_path_factory.mktemp("gap"), sign * frac * 0.4)
    assert e.value.key == "contact.master" and "× the local level-0 mesh size 0.4" in str(e.value)


def _locally_refined(gap: float, depth: int):
    """The strip's level-0 meshes (`_strip_meshes`), and both bodies' cells at the left half of
    the interface refined `depth` times by newest-vertex bisection, as the adaptive loop refines:
    those segments 2^depth shorter than at level 0."""
    level0 = _strip_meshes(gap)
    meshes = {}
    for name, mesh in level0.items():
        mesh = prepared(mesh)
        for _ in range(depth):
            x, y = mesh.points[mesh.cells].transpose(2, 0, 1)  # (n_cells, 3) each
            on = np.abs(y - (gap if name == "block" else 0.0)) < 1e-9
            mesh = refine_marked(mesh, (on & (x < 1.0)).any(axis=1))[0]
        meshes[name] = mesh
    return level0, meshes


@settings(max_examples=6)
@given(frac=st.floats(-0.095, 0.095), depth=st.integers(1, 3))
@example(frac=-0.09, depth=3).via("an overlap the old measure refuses")
@example(frac=0.09, depth=1).via("a gap the old measure refuses")
def test_a_locally_refined_interface_is_measured_against_its_level_0_size(
    tmp_path_factory, frac, depth
):
    """A gap or overlap accepted at level 0 stays accepted on a locally refined slave, whose
    segments are 2^depth shorter (no uniform level says so): the tolerance is measured on the
    level-0 meshes given with it. Without them (the adaptive loop before: `mixvi solve
    wavy_two_body --accuracy 0.02` refused its own refined cycle 6 as "overlap"), an overlap of
    more than 0.1 / 2^depth of h0 is refused."""
    scene = _imported(
        "shear_strip_two_body", _strip_meshes(frac * 0.4), tmp_path_factory.mktemp("g")
    )
    level0, meshes = _locally_refined(frac * 0.4, depth)
    with given_meshes(meshes, level0):
        model = pc.build(scene, 0)
    h = model.contact.tr.measures
    assert np.isclose(h.min(), 0.25 / 2**depth) and np.isclose(h.max(), 0.25)  # locally refined
    sol = solve(model.vi, "ssn", tol=1e-10)
    assert sol.converged and model.contact.patch_defect < 1e-12
    if abs(frac) > 0.1 / 2**depth:  # the mutation: no level-0 meshes given
        with given_meshes(meshes), pytest.raises(SceneError, match="overlap|stand apart"):
            pc.build(scene, 0)


@settings(max_examples=4)
@given(frac=st.floats(0.105, 0.5), sign=st.sampled_from([-1.0, 1.0]), depth=st.integers(1, 3))
def test_a_locally_refined_interface_beyond_the_tolerance_is_still_refused(
    tmp_path_factory, frac, sign, depth
):
    scene = _imported(
        "shear_strip_two_body", _strip_meshes(sign * frac * 0.4), tmp_path_factory.mktemp("g")
    )
    level0, meshes = _locally_refined(sign * frac * 0.4, depth)
    with given_meshes(meshes, level0), pytest.raises(SceneError) as e:
        pc.build(scene, 0)
    assert "× the local level-0 mesh size 0.4" in str(e.value)


# ------------------------------------------------------------------ 3D scenes on mesh files
BLOCK = ((0.0, 1.0), (0.0, 1.0), (0.0, 0.5), (4, 4, 2))  # block3d's box


def _solve3(scene, level):
    model = contact3d.build(scene, level)
    sol = solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged
    return model, sol


def test_a_refined_imported_hexahedral_block_gives_the_built_in_answer(tmp_path):
    """block3d (BaTiO3, friction discs): its level-0 box in a file, refined once by the level."""
    built = _solve3(load_scene("block3d"), 1)
    imported = _solve3(_imported("block3d", {"block": box(*BLOCK)}, tmp_path), 1)
    _compare(built, imported)


def test_an_imported_tetrahedral_block_gives_the_built_in_answer(tmp_path):
    tet = ["bodies.block.geometry.element=tetra"]
    built = _solve3(load_scene("block3d", tet), 1)
    imported = _solve3(_imported("block3d", {"block": box(*BLOCK, "tetra", 1)}, tmp_path), 0)
    _compare(built, imported)


def test_mutation_a_wrong_answer_is_caught_3d(tmp_path):
    built = _solve3(load_scene("block3d"), 0)
    scene = _imported("block3d", {"block": box(*BLOCK)}, tmp_path)
    scene.data["bodies"]["block"]["displacement"][0]["value"][2] = "-1.01e-4"
    with pytest.raises(AssertionError):
        _compare(built, _solve3(scene, 0))


def _refused3(tmp_path, change, level=0) -> SceneError:
    scene = _imported("block3d", {"block": box(*BLOCK)}, tmp_path)
    change(scene.data)
    with pytest.raises(SceneError) as err:
        contact3d.build(scene, level)
    return err.value


def test_a_misspelt_volume_group_lists_the_available_ones(tmp_path):
    err = _refused3(tmp_path, lambda d: d["bodies"]["block"]["geometry"].update(body="blok"))
    assert err.key == "bodies.block.geometry.mesh"
    assert "did you mean 'block'" in str(err) and "dimension 3" in str(err)


def test_misspelt_parts_are_named_by_their_field_listing_the_file_s_surfaces(tmp_path):
    def part(d):
        d["bodies"]["block"]["displacement"][0]["boundary"] = "tpo"

    err = _refused3(tmp_path, part)
    assert err.key == "bodies.block.displacement[0].boundary"
    assert "back, bottom, front, left, right, top" in str(err)
    err = _refused3(tmp_path, lambda d: d["contact"].update(slave="block.botom"))
    assert err.key == "contact.slave" and "bottom" in str(err)


def test_a_2d_mesh_file_is_refused_naming_the_key(tmp_path):
    write_msh(tmp_path / "flat.msh", {"block": rectangle((0, 1), (0, 1), (2, 2), "quad")})
    err = _refused3(tmp_path, lambda d: d["bodies"]["block"].update(geometry={"mesh": "flat.msh"}))
    assert err.key == "bodies.block.geometry.mesh"
    assert "a volume with tetrahedra or hexahedra" in str(err)


def test_too_many_nodes_after_refinement_are_refused_3d(tmp_path, monkeypatch):
    from problems.scene import geometry

    monkeypatch.setattr(geometry, "MAX_NODES", 2600)  # level 2: 17 · 17 · 9 = 2601 nodes
    err = _refused3(tmp_path, lambda d: None, level=2)
    assert err.key == "bodies.block.geometry.mesh" and "at most 2,600 nodes" in str(err)
    assert "would have 2,601 at level 2" in str(err)
    monkeypatch.setattr(geometry, "MAX_NODES", 2601)  # exactly the limit: accepted
    scene = _imported("block3d", {"block": box(*BLOCK)}, tmp_path)
    assert contact3d.build(scene, 2).vi.n > 0


def test_the_shipped_bracket_solves_with_stick_and_slip(tmp_path, capsys):
    assert main(["solve", "bracket3d", "--out", str(tmp_path / "b")]) == 0
    assert "converged in" in capsys.readouterr().out
    model, sol = _solve3(load_scene("bracket3d"), 0)
    st = contact3d.contact_state(model, sol)
    assert 0 < st["slip"].sum() < st["has_t"].sum()
    assert st["lemma_4_2"] <= 1e-8
