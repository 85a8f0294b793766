"""Contract v2: the version is checked at registration (a v1 plug-in is refused with what
changed), every built-in plug-in declares what each command needs, and a command refuses a
plug-in lacking its declaration with exit status 2 naming it."""

from __future__ import annotations

import types

import pytest

from problems.commands import main as cli
from problems.errors import SceneError
from problems.plugins import registry
from problems.plugins.contract import CONTRACT, Sweep, conforms
from problems.scene import SceneModel


def _plugin(**attrs) -> types.ModuleType:
    mod = types.ModuleType("fake")
    mod.NAME, mod.DESCRIPTION = "fake", "a fake plug-in"
    mod.build = mod.postprocess = lambda *a: None
    mod.SCENE_MODEL = SceneModel
    for k, v in attrs.items():
        setattr(mod, k, v)
    return mod


def test_every_builtin_declares_the_v2_contract():
    for name, whole in registry.plugins().items():
        assert conforms(whole) == [], name
        for plugin in registry.fronts(whole):  # contact: its 2D and 3D fronts
            assert conforms(plugin) == [] and plugin.NAME == name
            assert plugin.CONTRACT == CONTRACT == 2
            assert isinstance(plugin.SWEEP, Sweep) and plugin.NORMS and plugin.extremes()
            assert callable(plugin.mesh_size) and callable(plugin.reference_errors)


@pytest.mark.parametrize("version", [None, 1, 3])
def test_another_contract_version_is_refused_with_what_changed(version, monkeypatch):
    attrs = {} if version is None else {"CONTRACT": version}
    monkeypatch.setitem(registry.BUILTIN, "fake", "fake")
    monkeypatch.setattr(registry.importlib, "import_module", lambda name: _plugin(**attrs))
    with pytest.raises(SceneError) as err:
        registry.get("fake")
    text = str(err.value)
    assert "CONTRACT = 2" in text and "docs/plugins.md" in text
    assert f"contract version {1 if version is None else version}" in text


def test_a_v2_plugin_is_accepted(monkeypatch):
    monkeypatch.setitem(registry.BUILTIN, "fake", "fake")
    monkeypatch.setattr(registry.importlib, "import_module", lambda name: _plugin(CONTRACT=2))
    assert registry.get("fake").NAME == "fake"


def test_a_plugin_without_its_scene_model_is_refused():
    plugin = _plugin(CONTRACT=2)
    del plugin.SCENE_MODEL
    assert conforms(plugin) == ["SCENE_MODEL (a subclass of problems.scene.SceneModel; contract 2)"]
    assert conforms(_plugin(CONTRACT=2, SCENE_MODEL=dict)) != []


def test_a_malformed_declaration_is_refused():
    assert conforms(_plugin(CONTRACT=2, SWEEP=("contact.g", 1.0))) == [
        "SWEEP (a problems.plugins.contract.Sweep, when declared)"
    ]
    with pytest.raises(ValueError, match="exactly one"):
        Sweep("contact.g", "g [Pa]")


@pytest.mark.parametrize(
    ("drop", "argv"),
    [
        ("SWEEP", ["figures", "obstacle", "--level", "0"]),
        ("reference_errors", ["study", "obstacle", "--levels", "0..1"]),
    ],
)
def test_a_command_needing_an_undeclared_entry_exits_2(drop, argv, monkeypatch, tmp_path, capsys):
    """obstacle without SWEEP: `mixvi figures` names SWEEP; without reference_errors, study."""
    real = registry.for_scene

    def stripped(scene):
        fake = types.ModuleType("obstacle")
        fake.__dict__.update({k: v for k, v in vars(real(scene)).items() if k != drop})
        return fake

    monkeypatch.setattr(registry, "for_scene", stripped)
    assert cli.main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert drop in err and "obstacle" in err and "contract v2" in err
