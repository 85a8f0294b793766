"""`mixvi schema` (the JSON Schema of scenes) and `mixvi validate` (check without solving)."""

from __future__ import annotations

import contextlib
import copy
import io
import json
import tomllib

import pytest

from problems.commands.main import main
from problems.scene import SCENES_DIR

jsonschema = pytest.importorskip("jsonschema")
SHIPPED = sorted(SCENES_DIR.glob("*.toml"))


def _run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(list(argv))
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def validator():
    rc, text, _ = _run("schema")
    assert rc == 0
    schema = json.loads(text)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_every_shipped_scene_validates_against_the_schema(validator, path):
    data = tomllib.loads(path.read_text())
    errors = list(validator.iter_errors(data))
    assert errors == [], [e.message for e in errors][:3]


@pytest.mark.parametrize(
    ("where", "key", "value"),
    [
        (("contact",), "nosuch", 1),  # an unknown key in a section
        ((), "nosuch", 1),  # an unknown top-level table
        (("scene",), "level", "two"),  # a wrong type
        (("scene",), "level", -1),  # out of range
        (("scene",), "plugin", "nosuch"),  # an unknown plug-in
        (("bodies", "block", "geometry"), "kind", "sphere"),  # an unknown geometry kind
        (("bodies", "block", "geometry"), "cells", [1]),  # a pair of one
    ],
)
def test_a_scene_with_an_unknown_key_or_a_wrong_value_does_not(validator, where, key, value):
    data = tomllib.loads((SCENES_DIR / "rigid_foundation.toml").read_text())
    bad = copy.deepcopy(data)
    node = bad
    for k in where:
        node = node[k]
    node[key] = value
    assert validator.is_valid(data) and not validator.is_valid(bad)


def test_each_plugin_contributes_its_section(validator):
    defs = validator.schema["$defs"]
    for name in ("ContactScene", "ObstacleScene", "AntiplaneScene", "SignoriniScene"):
        assert {"$ref": f"#/$defs/{name}"} in validator.schema["oneOf"]
    for name in ("ContactScene", "ObstacleScene", "AntiplaneScene", "SignoriniScene"):
        assert defs[name]["additionalProperties"] is False
    assert "PlaneScene" not in defs and "SolidScene" not in defs  # one model for 2D and 3D
    kinds = defs["ContactScene"]  # the geometry union is told apart by kind
    assert "bodies" in kinds["properties"]


def test_validate_checks_without_solving(tmp_path):
    rc, out, err = _run("validate", "rigid_foundation")
    assert rc == 0 and "valid contact scene" in out and err == ""
    rc, out, err = _run("validate", "rigid_foundation", "--set", "contact.g='sin(x, y)'")
    assert rc == 2 and "contact.g" in err and "--set contact.g=" in err and out == ""
    assert list(tmp_path.iterdir()) == []


def test_validate_notes_a_format_1_scene_once(tmp_path):
    text = (SCENES_DIR / "obstacle.toml").read_text().replace("format = 2", "")
    p = tmp_path / "old.toml"
    p.write_text(text)
    rc, out, err = _run("validate", str(p))
    assert rc == 0 and err.count("\n") == 1 and "format-1" in err and "deprecated" in err


# ------------------------------------------------------------------ the scene reference
def _builtin_reference() -> str:
    import importlib

    from problems.commands.schema import scene_reference
    from problems.plugins.registry import BUILTIN
    from problems.scene.model import json_schema

    models = {n: importlib.import_module(m).SCENE_MODEL for n, m in BUILTIN.items()}
    return scene_reference(json_schema(models))


def test_docs_scene_reference_is_generated_from_the_current_schema():
    """docs/scenes.md is `mixvi schema --markdown` of the built-in plug-ins, not a stale copy
    (regenerate: `mixvi schema --markdown > docs/scenes.md`)."""
    doc = SCENES_DIR.parents[1] / "docs" / "scenes.md"
    assert doc.read_text() == _builtin_reference()


def test_the_reference_lists_every_key_of_the_shipped_scenes():
    """Every key used by a shipped scene (at any depth) has a row in the reference."""
    text = _builtin_reference()

    def keys(d):
        for k, v in d.items():
            yield k
            items = v if isinstance(v, list) else [v]
            for item in items:
                if isinstance(item, dict):
                    yield from keys(item)

    names = set()
    for path in SHIPPED:
        data = tomllib.loads(path.read_text())
        names |= {k for k in keys(data) if k not in data.get("bodies", {})}
    missing = sorted(k for k in names if f"| `{k}` |" not in text)
    assert not missing, missing


def test_mutation_a_dropped_row_is_caught(monkeypatch):
    """The key check above fails on a reference that leaves out one key's row."""
    from problems.commands import schema

    real = schema.scene_reference

    def without_n_contact(spec):
        rows = real(spec).splitlines()
        return "\n".join(r for r in rows if not r.startswith("| `n_contact` |"))

    monkeypatch.setattr(schema, "scene_reference", without_n_contact)
    with pytest.raises(AssertionError, match="n_contact"):
        test_the_reference_lists_every_key_of_the_shipped_scenes()


def test_each_example_is_toml_of_the_shipped_scenes_table():
    """Each section's example parses as TOML and holds the table of the shipped scene it
    names, at its path (mutation: a literal TOML cannot read, a table put at another path)."""
    import re
    import tomllib

    from problems.commands.schema import example_block, scene_schema, shipped_examples

    examples = shipped_examples(scene_schema())
    assert {"Isotropic", "DisplacementPart", "Rectangle"} <= set(examples)
    for name, (scene, path, table) in examples.items():
        block = "\n".join(example_block(scene, path, table))
        if not block:
            continue  # a whole scene's model: the scene file is its example
        toml = re.search(r"```toml\n(.*)\n```", block, re.S).group(1)
        data = tomllib.loads(toml)
        keys = [p for p in path if p != "[]"]
        for k in keys:
            data = data[k]
        if path[-1] == "[]":
            data = data[0]
        assert data == table, name
        scene_data = tomllib.loads((SCENES_DIR / f"{scene}.toml").read_text())
        for k in keys:
            scene_data = scene_data[k]
        tables = scene_data if path[-1] == "[]" else [scene_data]
        assert table in tables, name
