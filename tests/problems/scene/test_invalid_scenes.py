"""Bad scenes end with exit status 2 and one message naming file, key and value — never a traceback.

Hand-picked cases for each kind of error first, then a hypothesis property over random
mutations of the shipped scenes (each mutation invalid by construction): a deleted required
key, an unknown key, a wrong type / NaN / inf / huge magnitude / huge list, a non-positive-
definite C, an unknown boundary or material, broken TOML text. Every example must make
`mixvi solve FILE --level 0` return 2 with exactly one stderr line `mixvi: error: FILE: …`
and leave no output directory behind.
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import tempfile
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from problems.commands.main import main
from problems.commands.schema import toml_literal
from problems.scene import SCENES_DIR

SHIPPED = {
    n: tomllib.loads((SCENES_DIR / f"{n}.toml").read_text())
    for n in ("rigid_foundation", "paper_two_body")
}


def toml_text(data: dict) -> str:
    """A whole scene: each top-level key as an inline value."""
    return "".join(f"{json.dumps(k)} = {toml_literal(v)}\n" for k, v in data.items())


def run_invalid(text: str, needles: tuple[str, ...] = ()) -> str:
    """Write `text` as a scene, solve it at level 0, check the exit-2 contract; the message."""
    with tempfile.TemporaryDirectory() as d:
        scene, out = Path(d) / "bad.toml", Path(d) / "out"
        scene.write_text(text)
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = main(["solve", str(scene), "--level", "0", "--out", str(out)])
        msg = err.getvalue()
        assert rc == 2, (rc, msg, text)
        assert msg.startswith("mixvi: error: ") and msg.count("\n") == 1, msg
        assert "Traceback" not in msg
        assert str(scene) in msg, msg  # the file is named
        assert not out.exists() and [p.name for p in Path(d).iterdir()] == ["bad.toml"]
        for n in needles:
            assert n in msg, (n, msg)
        return msg


def mutated(name: str, path: tuple, value) -> str:
    data = copy.deepcopy(SHIPPED[name])
    node = data
    for p in path[:-1]:
        node = node[p]
    if value is DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return toml_text(data)


DELETE = object()
P, R = "paper_two_body", "rigid_foundation"
CASES = [
    # empty contact surface: a boundary name that is empty / a body with no such boundary
    (R, ("contact", "slave"), "block.", ("contact.slave",)),
    # surfaces that do not touch, and that overlap (cradle arc inside the disc)
    (P, ("bodies", "disc", "geometry", "center"), [0.0, 10.0], ("stand apart",)),
    (P, ("bodies", "cradle", "geometry", "radius"), 0.95, ("overlap", "contact.master")),
    (P, ("bodies", "cradle", "geometry", "radius"), 1.05, ("stand apart",)),
    # inverted / degenerate meshes
    (P, ("bodies", "cradle", "geometry", "p2"), [1.0, 0.0], ("bodies.cradle.geometry", "inverted")),
    (P, ("bodies", "cradle", "geometry", "p2"), [-1.0, 3.0], ("bodies.cradle.geometry",)),
    (P, ("bodies", "disc", "geometry", "angle"), -1.0, ("bodies.disc.geometry.angle",)),
    (P, ("bodies", "disc", "geometry", "angle"), math.pi, ("bodies.disc.geometry.angle",)),
    (P, ("bodies", "disc", "geometry", "radius"), 1e-300, ("bodies.disc.geometry",)),
    (R, ("bodies", "block", "geometry", "x"), [0.0, 1e-320], ("bodies.block.geometry",)),
    # too large to mesh (was a MemoryError)
    (R, ("bodies", "block", "geometry", "cells"), [100000, 100000], ("4,000,000",)),
    (P, ("bodies", "disc", "geometry", "n_contact"), 10**8, ("n_contact",)),
    # wrong units / types, wrong list lengths, extra material keys
    (P, ("bodies", "disc", "material", "E"), "1e10 Pa", ("bodies.disc.material.E",)),
    (P, ("bodies", "disc", "material", "label"), 3, ("label",)),
    (P, ("bodies", "disc", "material", "rho"), 7800.0, ("allowed keys",)),
    (R, ("bodies", "block", "material"), {"name": "BaTiO3", "E": 1.0}, ("allowed keys",)),
    (R, ("bodies", "block", "geometry", "x"), [0.0, 1.0, 2.0], ("bodies.block.geometry.x",)),
    (R, ("bodies", "block", "displacement", 0, "value"), [1.0], ("list of 2",)),
    (R, ("bodies", "block", "material"), {"kind": "anisotropic", "C": [[1, 0], [0, 1]]}, ("3×3",)),
    (
        R,
        ("bodies", "block", "material"),
        {"kind": "anisotropic", "C": [[True, 0, 0], [0, 1, 0], [0, 0, 1]]},
        ("bodies.block.material.C[0][0]", "a number"),
    ),
    # magnitudes that overflow in assembly or plotting (were tracebacks)
    (R, ("contact", "g"), 1e308, ("contact.g",)),
    (R, ("bodies", "block", "displacement", 0, "value"), [1e308, 0.0], ("value",)),
    (
        R,
        ("bodies", "block", "material"),
        {"name": "BaTiO3", "coupling_scale": 1e300},
        ("coupling",),
    ),
    (P, ("bodies", "disc", "geometry", "radius"), 1e300, ("radius",)),
    # an unknown solver named in the scene (was refused only as --solver, without the file)
    (R, ("solver",), {"method": "magic"}, ("solver.method", "one of auto, ssn")),
    # a required key deleted
    (P, ("bodies", "cradle", "potential"), DELETE, ("bodies.cradle.potential",)),
    (R, ("contact", "g"), DELETE, ("contact.g", "required")),
]


@pytest.mark.parametrize("name,path,value,needles", CASES)
def test_each_kind_of_bad_scene_exits_2_naming_file_and_key(name, path, value, needles):
    run_invalid(mutated(name, path, value), needles)


def test_unknown_plugin_names_the_file():
    msg = run_invalid(mutated(P, ("scene", "plugin"), "lots"), ("scene.plugin",))
    assert "bad.toml" in msg


def test_set_errors_name_the_file(tmp_path, capsys):
    assert main(["solve", R, "--set", "solver.tol=1", "--out", str(tmp_path / "o")]) == 2
    assert "rigid_foundation.toml: --set solver.tol" in capsys.readouterr().err


def test_set_into_a_missing_table_says_how_to_add_it(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["solve", R, "--set", 'contact.electrical.kind="grounded"', "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "'electrical' missing" in err and "--set 'contact.electrical={kind = ...}'" in err
    assert not out.exists()


# ------------------------------------------------------------------ property test
def _leaves(node, path=()):
    """(path, value) of every scalar leaf, descending into tables and arrays."""
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for k, v in items:
        if isinstance(v, dict | list) and not (isinstance(v, list) and _scalar_list(v)):
            yield from _leaves(v, (*path, k))
        else:
            yield (*path, k), v


def _scalar_list(v: list) -> bool:
    return not any(isinstance(x, dict | list) for x in v)


def _tables(node, path=()):
    """Paths of every table (dict) except [exact], which `build` does not read."""
    if isinstance(node, dict):
        yield path
        for k, v in node.items():
            if k != "exact":
                yield from _tables(v, (*path, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _tables(v, (*path, i))


FREE_TEXT = {"title", "description", "label"}  # any string is valid here
REQUIRED = {
    P: [
        ("scene",),
        ("bodies",),
        ("bodies", "disc", "geometry"),
        ("bodies", "cradle", "material"),
        ("bodies", "cradle", "geometry", "kind"),
        ("bodies", "disc", "displacement"),
        ("bodies", "disc", "displacement", 0, "boundary"),
        ("bodies", "cradle", "potential", 0, "value"),
        ("contact", "slave"),
        ("contact", "g"),
        ("bodies", "disc", "material", "E"),
    ],
    R: [
        ("bodies", "block", "geometry", "cells"),
        ("bodies", "block", "geometry", "x"),
        ("bodies", "block", "material"),
        ("bodies", "block", "potential"),
        ("bodies", "block", "displacement", 0, "value"),
        ("contact", "g"),
    ],
}
WRONG = [
    "lots",
    "1e10 Pa",
    "x +",
    True,
    {"a": 1},
    [1.0] * 5000,
    math.nan,
    math.inf,
    -math.inf,
    1e300,
]


@st.composite
def invalid_scene(draw) -> str:
    """The TOML text of a shipped scene with one mutation that makes it invalid."""
    name = draw(st.sampled_from([P, R]))
    data = SHIPPED[name]
    kind = draw(
        st.sampled_from(
            [
                "delete",
                "unknown_key",
                "wrong_value",
                "negative",
                "non_pd",
                "boundary",
                "material",
                "toml",
            ]
        )
    )
    if kind == "delete":
        return mutated(name, draw(st.sampled_from(REQUIRED[name])), DELETE)
    if kind == "unknown_key":
        table = draw(st.sampled_from(list(_tables(data))))
        key = draw(st.sampled_from(["zzz", "radus", "levle", "materal", "valeu", "Boundary"]))
        return mutated(name, (*table, key), 1.0)
    if kind == "wrong_value":
        leaves = [(p, v) for p, v in _leaves(data) if p[-1] not in FREE_TEXT]
        path, old = draw(st.sampled_from(leaves))
        wrong = list(WRONG)
        if (
            isinstance(old, str)
            and not isinstance(path[-1], int)
            and path[-1] not in ("value", "g")
        ):
            wrong += ["nonsense_name", 3]
        return mutated(name, path, draw(st.sampled_from(wrong)))
    if kind == "negative":
        positive = [
            ("contact", "g"),
            ("bodies", "disc", "material", "E") if name == P else ("contact", "g"),
            ("bodies", "disc", "geometry", "radius") if name == P else ("contact", "g"),
        ]
        path = draw(st.sampled_from(positive))
        return mutated(name, path, -draw(st.floats(1e-300, 1e100)))
    body = "disc" if name == P else "block"
    if kind == "non_pd":
        a = draw(st.floats(-1e11, 1e11))
        C = [[1e10, 2e10, 0.0], [2e10, 1e10, 0.0], [0.0, 0.0, a]]
        return mutated(name, ("bodies", body, "material"), {"kind": "anisotropic", "C": C})
    if kind == "boundary":
        where = ("bodies", body, "displacement", 0, "boundary")
        return mutated(name, where, draw(st.sampled_from(["nowhere", "Top", "", "contact "])))
    if kind == "material":
        return mutated(
            name, ("bodies", body, "material"), draw(st.sampled_from(["Steel", "batio3", "PZT5H"]))
        )
    text = toml_text(data)
    lines = text.splitlines(keepends=True)
    at = draw(st.integers(0, len(lines)))
    junk = draw(st.sampled_from(["]]] = =\n", 'x = "unterminated\n', "[bodies\n", "= 3\n"]))
    return "".join(lines[:at]) + junk + "".join(lines[at:])


@settings(max_examples=500)
@given(invalid_scene())
def test_random_invalid_scenes_exit_2_with_one_message(text):
    run_invalid(text)
