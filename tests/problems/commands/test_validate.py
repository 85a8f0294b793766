"""`mixvi validate` opens the mesh files a scene names and refuses what a solve's build would:
missing or misspelt groups (listing the available ones), unsupported, inverted or degenerate
cells, a contact boundary that is not one simple curve — exit 2 with the field path, nothing
written."""

import os
from pathlib import Path

import meshio
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fem.meshing import rectangle
from problems.commands.main import main
from problems.scene import load_scene
from tests.gmsh_files import write_msh


def _scene(tmp_path, name):
    """The shipped scene `name` copied into tmp_path (mesh paths are relative to it)."""
    path = tmp_path / f"{name}.toml"
    path.write_text(Path(load_scene(name).path).read_text())
    return path


def _table(d: dict) -> str:
    return "{" + ", ".join(f"{k}={v!r}" for k, v in d.items()) + "}"


def _block_msh(tmp_path, mesh=None, file="block.msh"):
    write_msh(tmp_path / file, {"block": mesh or rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")})
    return {"mesh": file, "body": "block"}


def _raw_msh(tmp_path, points, cells, file="raw.msh"):
    """A gmsh file of one physical surface 'block' (no curves) with the given cells."""
    pts = np.concatenate([np.asarray(points, float), np.zeros((len(points), 1))], axis=1)
    m = meshio.Mesh(
        pts,
        cells,
        cell_data={
            "gmsh:physical": [np.ones(len(c[1]), int) for c in cells],
            "gmsh:geometrical": [np.ones(len(c[1]), int) for c in cells],
        },
        field_data={"block": np.array([1, 2])},
    )
    m.write(str(tmp_path / file), file_format="gmsh22", binary=False)
    return {"mesh": file, "body": "block"}


def _validate(path, capsys, *extra):
    folder = path.parent
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        rc = main(["validate", str(path), *extra])
    finally:
        os.chdir(cwd)
    after = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    assert after == before  # nothing written, nothing changed
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return rc, out, err


def _contact_of_two_pieces(tmp_path):
    m = rectangle((0.0, 2.0), (0.0, 1.0), (4, 2), "quad")
    parts = {**m.boundaries, "sides": np.concatenate([m.boundaries["left"], m.boundaries["right"]])}
    return _block_msh(tmp_path, type(m)(m.points, m.cells, parts))


SQUARE = [[0, 0], [1, 0], [1, 1], [0, 1], [2, 0.5], [2, 0.0]]
CASES = {
    # case: (scene, body key, geometry maker, scene edit, field path, words of the message)
    "misspelt body group": (
        "rigid_foundation",
        "bodies.block",
        lambda t: {**_block_msh(t), "body": "blok"},
        [],
        "bodies.block.geometry.mesh",
        ["did you mean 'block'", "available: 'block'"],
    ),
    "missing mesh file": (
        "rigid_foundation",
        "bodies.block",
        lambda t: {"mesh": "nowhere.msh", "body": "block"},
        [],
        "bodies.block.geometry.mesh",
        ["nowhere.msh", "relative to the scene file"],
    ),
    "misspelt boundary group": (
        "rigid_foundation",
        "bodies.block",
        _block_msh,
        ["bodies.block.displacement=[{boundary='tpo', value=[0.0, 0.0]}]"],
        "bodies.block.displacement[0].boundary",
        ["bottom, left, right, top"],
    ),
    "misspelt contact group": (
        "rigid_foundation",
        "bodies.block",
        _block_msh,
        ["contact.slave=block.botom"],
        "contact.slave",
        ["bottom, left, right, top"],
    ),
    "unsupported cells": (
        "rigid_foundation",
        "bodies.block",
        lambda t: _raw_msh(t, SQUARE, [("triangle6", np.array([[0, 1, 2, 0, 1, 2]]))]),
        [],
        "bodies.block.geometry.mesh",
        ["triangle6", "linear triangles"],
    ),
    "inverted cell": (
        "rigid_foundation",
        "bodies.block",
        lambda t: _raw_msh(t, SQUARE, [("triangle", np.array([[0, 1, 2], [1, 2, 4]]))]),
        [],
        "bodies.block.geometry.mesh",
        ["inverted"],
    ),
    "degenerate cell": (
        "rigid_foundation",
        "bodies.block",
        lambda t: _raw_msh(t, SQUARE, [("triangle", np.array([[0, 1, 2], [0, 1, 5]]))]),
        [],
        "bodies.block.geometry.mesh",
        ["degenerate"],
    ),
    "contact boundary of two pieces": (
        "rigid_foundation",
        "bodies.block",
        _contact_of_two_pieces,
        ["contact.slave=block.sides"],
        "contact.slave",
        ["one simple curve"],
    ),
    "antiplane friction boundary of two pieces": (
        "antiplane",
        "domain",
        _contact_of_two_pieces,
        ["friction.boundary=sides"],
        "friction.boundary",
        ["one simple curve"],
    ),
    "signorini contact boundary of two pieces": (
        "signorini",
        "body",
        _contact_of_two_pieces,
        ["contact.boundary=sides"],
        "contact.boundary",
        ["one simple curve"],
    ),
}


def _args(tmp_path, case):
    name, where, geometry, sets, field, words = CASES[case]
    path = _scene(tmp_path, name)
    args = ["--set", f"{where}.geometry={_table(geometry(tmp_path))}"]
    for s in sets:
        args += ["--set", s]
    return path, args, field, words


@pytest.mark.parametrize("case", list(CASES))
def test_validate_refuses_a_bad_mesh_as_a_solve_would(tmp_path, capsys, case):
    path, args, field, words = _args(tmp_path, case)
    rc, _, err = _validate(path, capsys, *args)
    assert rc == 2, err
    assert field in err, err
    for w in words:
        assert w in err, err
    # the solve refuses it with the same message, before writing anything
    out = tmp_path / "out"
    assert main(["solve", str(path), *args, "--level", "0", "--out", str(out)]) == 2
    assert capsys.readouterr().err == err
    assert not out.exists()


@pytest.mark.parametrize("name", ["wavy_two_body", "plate_with_hole", "antiplane"])
def test_the_shipped_scenes_validate(capsys, name):
    assert main(["validate", name]) == 0
    assert f"valid {load_scene(name).data['scene']['plugin']} scene" in capsys.readouterr().out


def test_mutation_validate_without_the_build_misses_a_misspelt_group(tmp_path, capsys, monkeypatch):
    """The scene model alone cannot see into the file: skipping the build lets it through."""
    from types import SimpleNamespace

    from problems.plugins.contact import plane as piezo_contact
    from vi_core import Free, product

    unchecked = SimpleNamespace(
        warnings=[], options={}, vi=SimpleNamespace(Lambda=product(Free(1)))
    )
    monkeypatch.setattr(piezo_contact, "build", lambda scene, level=None: unchecked)
    path, args, _, _ = _args(tmp_path, "misspelt boundary group")
    rc, _, _ = _validate(path, capsys, *args)
    assert rc == 0


@pytest.mark.parametrize(
    ("case", "module"),
    [
        ("antiplane friction boundary of two pieces", "antiplane"),
        ("signorini contact boundary of two pieces", "contact.curve_contact"),  # its preset
    ],
)
def test_mutation_without_the_curve_check_two_pieces_are_not_refused(
    tmp_path, capsys, monkeypatch, case, module
):
    import importlib

    plugin = importlib.import_module(f"problems.plugins.{module}")
    monkeypatch.setattr(plugin, "require_curve", lambda *a: None)
    path, args, _, _ = _args(tmp_path, case)
    rc, _, err = _validate(path, capsys, *args)
    assert rc != 2, err  # passed silently (or a ValueError of the trace): not refused


@given(st.integers(0, 2**32 - 1), st.integers(1, 300))
def test_a_long_value_keeps_both_ends_in_the_message(seed, depth):
    """A missing mesh under a long folder (a deep TMPDIR, found under TMPDIR='/tmp/a dir'):
    the message once cut the path after 77 characters, before its file name."""
    from problems.errors import SceneError

    rng = np.random.default_rng(seed)
    folder = "/" + "".join(rng.choice(list("abc d/"), size=depth))
    value = f"{folder}/nowhere_{seed}.msh"
    message = str(SceneError("bodies.block.geometry.mesh", value, "an existing mesh file"))
    shown = message.split(" = ", 1)[1].rsplit(": an existing", 1)[0]
    assert len(shown) <= 80
    assert shown.endswith(f"nowhere_{seed}.msh'") and shown.startswith(repr(value)[:10])
