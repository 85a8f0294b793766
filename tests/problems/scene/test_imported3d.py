"""3D scenes on meshes from files: the built-in answer on an identical imported mesh (hexahedra
refined by the level, tetrahedra as read), refusals naming the field, and the shipped gmsh
bracket."""

import pytest

from fem.mesh_import import write_msh
from fem.meshing import box, rectangle
from problems.commands.main import main
from problems.errors import SceneError
from problems.plugins import contact3d
from problems.scene import load_scene
from vi_core import solve

from .test_imported import _compare, _imported

BLOCK = ((0.0, 1.0), (0.0, 1.0), (0.0, 0.5), (4, 4, 2))  # block3d's box


def _solve(scene, level):
    model = contact3d.build(scene, level)
    sol = solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged
    return model, sol


def test_a_refined_imported_hexahedral_block_gives_the_built_in_answer(tmp_path):
    """block3d (BaTiO3, friction discs): its level-0 box in a file, refined once by the level."""
    built = _solve(load_scene("block3d"), 1)
    imported = _solve(_imported("block3d", {"block": box(*BLOCK)}, tmp_path), 1)
    _compare(built, imported)


def test_an_imported_tetrahedral_block_gives_the_built_in_answer(tmp_path):
    tet = ["bodies.block.geometry.element=tetra"]
    built = _solve(load_scene("block3d", tet), 1)
    imported = _solve(_imported("block3d", {"block": box(*BLOCK, "tetra", 1)}, tmp_path), 0)
    _compare(built, imported)


def test_mutation_a_wrong_answer_is_caught(tmp_path):
    built = _solve(load_scene("block3d"), 0)
    scene = _imported("block3d", {"block": box(*BLOCK)}, tmp_path)
    scene.data["bodies"]["block"]["displacement"][0]["value"][2] = "-1.01e-4"
    with pytest.raises(AssertionError):
        _compare(built, _solve(scene, 0))


def _refused(tmp_path, change, level=0) -> SceneError:
    scene = _imported("block3d", {"block": box(*BLOCK)}, tmp_path)
    change(scene.data)
    with pytest.raises(SceneError) as err:
        contact3d.build(scene, level)
    return err.value


def test_a_misspelt_volume_group_lists_the_available_ones(tmp_path):
    err = _refused(tmp_path, lambda d: d["bodies"]["block"]["geometry"].update(body="blok"))
    assert err.key == "bodies.block.geometry.mesh"
    assert "did you mean 'block'" in str(err) and "dimension 3" in str(err)


def test_misspelt_parts_are_named_by_their_field_listing_the_file_s_surfaces(tmp_path):
    def part(d):
        d["bodies"]["block"]["displacement"][0]["boundary"] = "tpo"

    err = _refused(tmp_path, part)
    assert err.key == "bodies.block.displacement[0].boundary"
    assert "back, bottom, front, left, right, top" in str(err)
    err = _refused(tmp_path, lambda d: d["contact"].update(slave="block.botom"))
    assert err.key == "contact.slave" and "bottom" in str(err)


def test_a_2d_mesh_file_is_refused_naming_the_key(tmp_path):
    write_msh(tmp_path / "flat.msh", {"block": rectangle((0, 1), (0, 1), (2, 2), "quad")})
    err = _refused(tmp_path, lambda d: d["bodies"]["block"].update(geometry={"mesh": "flat.msh"}))
    assert err.key == "bodies.block.geometry.mesh"
    assert "a volume with tetrahedra or hexahedra" in str(err)


def test_too_many_nodes_after_refinement_are_refused(tmp_path, monkeypatch):
    from problems.scene import geometry

    monkeypatch.setattr(geometry, "MAX_NODES", 2600)  # level 2: 17 · 17 · 9 = 2601 nodes
    err = _refused(tmp_path, lambda d: None, level=2)
    assert err.key == "bodies.block.geometry.mesh" and "at most 2,600 nodes" in str(err)
    assert "would have 2,601 at level 2" in str(err)
    monkeypatch.setattr(geometry, "MAX_NODES", 2601)  # exactly the limit: accepted
    scene = _imported("block3d", {"block": box(*BLOCK)}, tmp_path)
    assert contact3d.build(scene, 2).vi.n > 0


def test_the_shipped_bracket_solves_with_stick_and_slip(tmp_path, capsys):
    assert main(["solve", "bracket3d", "--out", str(tmp_path / "b")]) == 0
    assert "converged in" in capsys.readouterr().out
    model, sol = _solve(load_scene("bracket3d"), 0)
    st = contact3d.contact_state(model, sol)
    assert 0 < st["slip"].sum() < st["has_t"].sum()
    assert st["lemma_4_2"] <= 1e-8
