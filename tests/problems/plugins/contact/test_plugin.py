"""The one contact plug-in: `[scene] plugin = "contact"` picks the front of the geometry's
dimension, the former names stay accepted with a notice, and `count` is the built size in 2D
as in 3D."""

from __future__ import annotations

import pytest

from problems.errors import SceneError
from problems.plugins import contact, registry
from problems.plugins.contact import dimension, plane, scene_model, solid
from problems.scene import SCENES_DIR, load_scene
from problems.scene.model import validate

BOX = {"kind": "box", "x": [0.0, 1.0], "y": [0.0, 1.0], "z": [0.0, 1.0], "cells": [1, 1, 1]}
RECTANGLE = {"kind": "rectangle", "x": [0.0, 1.0], "y": [0.0, 1.0], "cells": [1, 1]}


@pytest.mark.parametrize(
    "name,front", [("shear_strip", plane), ("plate_with_hole", plane), ("block3d", solid)]
)
def test_the_scene_gets_the_front_of_its_dimension(name, front):
    """A kind, a 2D mesh file (plate_with_hole) and a 3D kind; mutation: `front` returning
    plane always fails on block3d."""
    scene = load_scene(name)
    assert scene.data["scene"]["plugin"] == "contact"
    assert registry.for_scene(scene) is front and front.NAME == "contact"
    assert isinstance(validate(contact.SCENE_MODEL, scene.data), front.SCENE_MODEL)


def test_a_3d_mesh_file_is_told_by_its_cells():
    data = load_scene("bracket3d").data
    assert "mesh" in next(iter(data["bodies"].values()))["geometry"]
    assert dimension.scene_dimension(data, str(SCENES_DIR / "bracket3d.toml")) == 3


def test_bodies_of_two_dimensions_are_refused():
    data = {
        "scene": {"plugin": "contact"},
        "bodies": {"a": {"geometry": RECTANGLE}, "b": {"geometry": BOX}},
    }
    with pytest.raises(SceneError, match="bodies.b.geometry.*body 'a' is 2D"):
        dimension.scene_dimension(data)


@pytest.mark.parametrize("old,front", [("piezo_contact", plane), ("contact3d", solid)])
def test_the_former_names_still_work_with_a_notice(old, front, tmp_path, capsys):
    """A user's scene with the old plug-in name solves as before (same plug-in, same front,
    the dimension fixed by the name) and stderr says what to write instead, in one line."""
    name = "rigid_foundation" if front is plane else "block3d"
    text = (SCENES_DIR / f"{name}.toml").read_text()
    assert 'plugin = "contact"' in text
    path = tmp_path / "old.toml"
    path.write_text(text.replace('plugin = "contact"', f'plugin = "{old}"'))
    scene = load_scene(str(path))
    assert registry.for_scene(scene) is front
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and old in err[0] and "'contact'" in err[0]
    assert scene.validated(front.SCENE_MODEL).scene.plugin == old
    assert registry.names().count("contact") == 1 and old not in registry.names()


def test_the_new_name_prints_no_notice(capsys):
    registry.for_scene(load_scene("rigid_foundation"))
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("name", ["rigid_foundation", "paper_two_body", "piezo_liftoff"])
def test_count_in_2d_is_the_built_size(name):
    """`count` of the 2D front (level-0 meshes only) equals the built model's sizes at levels
    0 and 1 (mutation: d − p rows replaced by one row per contact node fails)."""
    scene = load_scene(name)
    assert plane.DIMENSION == 2
    counted = plane.count(scene, [0, 1])
    for level, c in zip((0, 1), counted, strict=True):
        vi = plane.build(scene, level).vi
        assert c == (vi.n + vi.m, vi.A.nnz, vi.n)


def _refused(name: str, change) -> SceneError:
    scene = load_scene(name)
    change(scene.data)
    with pytest.raises(SceneError) as err:
        scene.validated(contact.SCENE_MODEL)
    return err.value


def _set(*path_value):
    *path, value = path_value

    def change(data):
        node = data
        for p in path[:-1]:
            node = node[p]
        node[path[-1]] = value

    return change


SIX = [[float(i == j) for j in range(6)] for i in range(6)]
R, B, M = "rigid_foundation", "block3d", "manufactured"


@pytest.mark.parametrize(
    "name,change,key,words",
    [
        (R, _set("bodies", "block", "displacement", 0, "value", [0, 0, 0]),
         "bodies.block.displacement[0].value", "a list of 2 entries [x, y]: the body is 2D"),
        (B, _set("bodies", "block", "displacement", 0, "value", [0, 0]),
         "bodies.block.displacement[0].value", "a list of 3 entries [x, y, z]: the body is 3D"),
        (R, _set("bodies", "block", "body_force", [0, 0, 1]),
         "bodies.block.body_force", "a list of 2 entries"),
        (R, _set("bodies", "block", "displacement", 0, "components", "xz"),
         "bodies.block.displacement[0].components", "one of x, y, xy: the body is 2D"),
        (R, _set("bodies", "block", "material", {"kind": "anisotropic", "C": SIX}),
         "bodies.block.material.C", "a 3×3 matrix of numbers (the body is 2D)"),
        (R, _set("bodies", "block", "potential", 0, "value", "z"),
         "bodies.block.potential[0].value", "z is a coordinate of 3D scenes"),
        (R, _set("contact", "g", "1e6*(1 + z)"), "contact.g", "z is a coordinate of 3D scenes"),
        (R, lambda d: _set("scene", "plugin", "contact3d")(d) or d.pop("output"),
         "bodies.block.geometry.kind", "kind = box | extruded, or a 3D mesh file"),
        (B, _set("scene", "plugin", "piezo_contact"),
         "bodies.block.geometry.kind", "kind = rectangle | half_disc | cradle"),
        (M, _set("exact", "u", ["x", "y", "z"]), "exact.u", "2 entries: the scene is 2D"),
        (M, _set("exact", "grad_u", 0, ["x", "y", "x"]), "exact.grad_u[0]", "2 entries"),
        (M, _set("exact", "lam", ["x", "y", "x"]), "exact.lam", "2 entries, as u"),
    ],
)  # fmt: skip
def test_values_are_checked_against_the_geometry_s_dimension(name, change, key, words):
    """One body table for 2D and 3D: its geometry decides d, and a vector, a component, a
    matrix, an expression of z or an [exact] field that does not fit d is refused naming the
    field and what d allows."""
    err = _refused(name, change)
    assert err.key == key and words in str(err), str(err)


def test_the_default_components_are_every_axis_of_the_body():
    """A [[displacement]] without components holds all d of them (xy in 2D, xyz in 3D)."""
    for name, axes in ((R, "xy"), (B, "xyz")):
        scene = load_scene(name)
        assert "components" not in scene.data["bodies"]["block"]["displacement"][0]
        spec = scene.validated(contact.SCENE_MODEL)
        assert spec.bodies["block"].displacement[0].components == axes


@pytest.mark.parametrize(
    "front,old,new",
    [
        (plane, "PlaneScene", "ContactScene"),
        (solid, "SolidScene", "ContactScene"),
        (plane, "ContactSection", "ContactSection"),
        (solid, "ContactSection", "ContactSection"),
    ],
)
def test_the_former_scene_model_names_still_work_with_a_deprecation_warning(front, old, new):
    """One scene model for 2D and 3D (`scene_model`); the fronts' former names return it for
    one release and say where it is now (mutation: a name returned silently fails)."""
    with pytest.warns(DeprecationWarning, match=f"scene_model.{new}"):
        assert getattr(front, old) is getattr(scene_model, new)
    with pytest.raises(AttributeError):
        front.NoSuchName  # noqa: B018


@pytest.mark.parametrize("name", ["block3d", "rigid_foundation"])
def test_one_scene_model_knows_its_dimension(name):
    """The scene model tells the dimension from the geometries (block3d 3, rigid_foundation 2)
    and refuses the 2D-only electrical contact in 3D."""
    scene = load_scene(name)
    spec = validate(contact.SCENE_MODEL, scene.data)
    assert spec.dimension == (3 if name == "block3d" else 2)
    for where, value, key in (
        (("contact", "electrical"), {"kind": "insulating"}, "contact.electrical"),
        (("output",), {"potential_along": "block.top"}, "output.potential_along"),
    ):
        if name == "block3d":  # 2D only; mutation: the dimension check removed fails
            err = _refused(name, _set(*where, value))
            assert err.key == key and "absent in a 3D scene" in str(err)
