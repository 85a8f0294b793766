"""The typed scene model: whole scenes validated before anything is built, errors naming the
field path (and the override that caused them), format migration, expression paths."""

from __future__ import annotations

import tomllib

import pytest

import vi_core
from problems.errors import SceneError
from problems.plugins import registry
from problems.plugins.contact import plane as pc
from problems.scene import SCENES_DIR, Scene, load_scene
from problems.scene.fields import Number
from problems.scene.materials import Isotropic
from problems.scene.model import METHODS, migrate, validate

SHIPPED = sorted(p.stem for p in SCENES_DIR.glob("*.toml"))


def _error(name: str, *overrides: str) -> SceneError:
    scene = load_scene(name, list(overrides))
    with pytest.raises(SceneError) as err:
        scene.validated(registry.for_scene(scene).SCENE_MODEL)
    return err.value


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_scene_is_format_2_and_valid(name):
    scene = load_scene(name)
    assert scene.notices == [] and scene.data["format"] == 2
    spec = scene.validated(registry.for_scene(scene).SCENE_MODEL)
    assert spec.scene.plugin == scene.data["scene"]["plugin"]


@pytest.mark.parametrize(
    ("name", "override", "key", "words"),
    [
        ("rigid_foundation", "contact.gg=1", "contact.gg", "did you mean 'g'"),
        ("rigid_foundation", "scene.levle=2", "scene.levle", "did you mean 'level'"),
        ("rigid_foundation", "contact.g=-1.0", "contact.g", "≥ 0"),
        ("rigid_foundation", "contact.g='sin(x, y)'", "contact.g", "takes 1 argument"),
        ("rigid_foundation", "contact.g=true", "contact.g", "a number"),
        ("rigid_foundation", "contact.slave='block.bottm'", "contact.slave", "bottom"),
        ("rigid_foundation", "contact.slave='moon.bottom'", "contact.slave", "block"),
        ("rigid_foundation", "contact.master='block.top'", "contact.master", "other than"),
        ("rigid_foundation", "contact.ends='both'", "contact.ends", "merge, keep"),
        (
            "rigid_foundation",
            "bodies.block.geometry.kind='sphere'",
            "bodies.block.geometry.kind",
            "rectangle",
        ),
        (
            "rigid_foundation",
            "bodies.block.geometry.x=[2.0, 0.0]",
            "bodies.block.geometry.x",
            "a < b",
        ),
        (
            "rigid_foundation",
            "bodies.block.geometry.cells=[0, 4]",
            "bodies.block.geometry.cells",
            "positive",
        ),
        (
            "rigid_foundation",
            "bodies.block.material={kind='isotropic', E=1e9, nu=0.5}",
            "bodies.block.material.nu",
            "< 0.5",
        ),
        (
            "rigid_foundation",
            "bodies.block.material='unobtainium'",
            "bodies.block.material.name",
            "BaTiO3",
        ),
        (
            "rigid_foundation",
            "bodies.block.displacement=[]",
            "bodies.block.displacement",
            "at least one",
        ),
        ("rigid_foundation", "solver={method='magic'}", "solver.method", "ssn"),
        ("rigid_foundation", "solver={tol=0}", "solver.tol", "> 0"),
        ("paper_two_body", "bodies.disc.geometry.angle=3.5", "bodies.disc.geometry.angle", "<"),
        (
            "paper_two_body",
            "output.potential_along='disc.top'",
            "output.potential_along",
            "piezoelectric",
        ),
        ("obstacle", "dirichlet=[{boundary='middle', value=0}]", "dirichlet[0].boundary", "bottom"),
        ("obstacle", "domain.obstacle='x +'", "domain.obstacle", "syntax"),
        ("antiplane", "friction.boundary='middle'", "friction.boundary", "bottom"),
        ("antiplane", "domain.shear_modulus=0", "domain.shear_modulus", "> 0"),
        ("signorini", "body.material='BaTiO3'", "body.material", "elastic"),
        ("signorini", "contact.gap=-1e-3", "contact.gap", "≥ 0"),
        ("shear_strip_two_body", "exact.phi='x'", "exact.phi", "grad_phi"),
    ],
)
def test_errors_name_the_field_the_value_and_the_override(name, override, key, words):
    err = _error(name, override)
    assert err.key == key, str(err)
    assert words in err.allowed, str(err)
    assert f"--set {override}" in err.allowed  # the override that caused it
    assert err.file.endswith(f"{name}.toml")


def test_errors_without_override_do_not_blame_one():
    scene = load_scene("rigid_foundation", ["contact.g=5e6"])
    scene.data["bodies"]["block"]["geometry"]["cells"] = [0, 1]
    with pytest.raises(SceneError) as err:
        scene.validated(pc.SCENE_MODEL)
    assert err.value.key == "bodies.block.geometry.cells" and "--set" not in err.value.allowed


def test_a_dropped_range_check_is_caught():
    """Mutation: the same data pass a material model whose ν range was dropped, so the test
    above (ν = 0.5 refused) can fail."""
    data = {"kind": "isotropic", "E": 1e9, "nu": 0.5}
    with pytest.raises(SceneError):
        validate(Isotropic, data)

    class Mutant(Isotropic):
        nu: Number  # no range

    validate(Mutant, data)


def test_nothing_is_built_while_validating(monkeypatch):
    """Validation touches no mesh: with meshing broken, a scene still validates (and a bad one
    is still refused by name)."""
    from problems.scene import geometry

    def boom(*a, **k):
        raise AssertionError("meshed during validation")

    for kind in (geometry.Rectangle, geometry.HalfDisc, geometry.Cradle):
        monkeypatch.setattr(kind, "mesh", boom)
    for name in SHIPPED:
        scene = load_scene(name)
        scene.validated(registry.for_scene(scene).SCENE_MODEL)
    assert _error("paper_two_body", "contact.slave='disc.nosuch'").key == "contact.slave"


def test_expressions_know_their_field_path():
    spec = load_scene("paper_two_body").validated(pc.SCENE_MODEL)
    assert spec.contact.g.path == "contact.g"
    assert (
        spec.bodies["disc"].displacement[0].value[1].path == "bodies.disc.displacement[0].value[1]"
    )
    assert spec.bodies["disc"].geometry.key("radius") == "bodies.disc.geometry.radius"


def test_validation_is_cached_until_the_data_change():
    scene = load_scene("rigid_foundation")
    a = scene.validated(pc.SCENE_MODEL)
    assert scene.validated(pc.SCENE_MODEL) is a
    scene.data["contact"]["g"] = -1.0
    with pytest.raises(SceneError, match="contact.g"):
        scene.validated(pc.SCENE_MODEL)


def test_format_1_is_migrated_with_one_notice(tmp_path):
    text = (SCENES_DIR / "rigid_foundation.toml").read_text()
    old = text.replace("format = 2  # the scene format (mixvi schema)\n", "").replace(
        'plugin = "contact"\n', ""
    )
    assert "format" not in tomllib.loads(old) and "plugin" not in tomllib.loads(old)["scene"]
    p = tmp_path / "old.toml"
    p.write_text(old)
    scene = load_scene(str(p))
    assert len(scene.notices) == 1 and "format-1" in scene.notices[0]
    assert scene.data["format"] == 2 and scene.data["scene"]["plugin"] == "contact"
    new = load_scene("rigid_foundation")
    assert scene.validated(pc.SCENE_MODEL) == new.validated(pc.SCENE_MODEL)


@pytest.mark.parametrize("fmt", [3, 0, "2", True])
def test_unknown_formats_are_refused(fmt):
    with pytest.raises(SceneError, match="format"):
        migrate({"format": fmt, "scene": {}}, "x.toml")


def test_format_2_requires_the_plugin():
    data = load_scene("rigid_foundation").data
    del data["scene"]["plugin"]
    with pytest.raises(SceneError, match="scene.plugin"):
        validate(pc.SCENE_MODEL, data)


def test_solver_methods_are_vi_cores():
    assert set(METHODS) == set(vi_core.METHODS) | set(vi_core.CONTACT_METHODS)


def test_a_scene_from_a_model_round_trips():
    spec = load_scene("paper_two_body").validated(pc.SCENE_MODEL)
    scene = Scene.from_model(spec, "copy")
    assert scene.validated(pc.SCENE_MODEL) == spec
