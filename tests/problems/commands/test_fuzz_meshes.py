"""Hypothesis-fuzzed mesh files through `mixvi validate`: whatever a scene's mesh file holds,
the command ends with exit status 0 or 2 — never 3, never a traceback, never a hang, never
the machine's memory — and with 2 exactly one line naming the scene's mesh key; the folder
(scene and mesh file) is byte-identical afterwards.

Each example writes a two-part mesh (a quadrilateral or triangle body with its boundary
curves) as gmsh v2.2 or v4.1, ASCII or binary (other formats meshio reads carry no
physical groups, so a scene cannot name their boundaries), then damages it: a number
replaced by a hostile one (a huge tag or count, 0, −1, 1e300, nan, inf, another node's tag),
a line deleted or repeated, the file cut short, or random bytes spliced in.

    CI tier (40 examples, in-process):           .venv/bin/pytest tests/problems/commands/test_fuzz_meshes.py
    fuzz tier (150, each in a child process under RLIMIT_AS and a timeout):
                                                 .venv/bin/pytest -m fuzz tests/problems/commands/test_fuzz_meshes.py
"""  # noqa: E501

from __future__ import annotations

import contextlib
import io
import os
import re
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fem.meshing import rectangle
from problems.commands.main import main
from tests.gmsh_files import write_msh

MIXVI = str(Path(sys.executable).with_name("mixvi"))
CHILD_MEMORY = 3 * 2**30  # RLIMIT_AS of a fuzz-tier child: a blow-up fails there, not here
SCENE = """format = 2
[scene]
plugin = "contact"
level = 0
[bodies.part]
material = "BaTiO3"
geometry = {{ mesh = "{mesh}", body = "part" }}
[[bodies.part.displacement]]
boundary = "top"
value = [2.0e-4, -1.0e-4]
[[bodies.part.potential]]
boundary = "top"
value = 0.0
[contact]
slave = "part.bottom"
master = "rigid"
g = 9.0e6
"""
FORMATS = ["gmsh22", "gmsh", "gmsh22-binary", "gmsh-binary"]
HOSTILE = [b"1000000000", b"4294967297", b"99999999999999999999", b"0", b"-1", b"1e300",
           b"nan", b"inf", b"-inf", b"2", b"7", b"1.5", b"x"]  # fmt: skip
NUMBER = re.compile(rb"-?\d+(\.\d+)?(e[-+]?\d+)?")


def mesh_bytes(fmt: str, element: str, cells: tuple[int, int]) -> tuple[str, bytes]:
    """A valid mesh file of one body 'part' (boundary curves bottom/right/top/left)."""
    m = rectangle((0.0, 2.0), (0.0, 1.0), cells, element)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "m.msh"
        write_msh(p, {"part": m}, fmt.split("-")[0], binary=fmt.endswith("binary"))
        return "m.msh", p.read_bytes()


@st.composite
def damaged_meshes(draw) -> tuple[str, bytes, bytes]:
    fmt = draw(st.sampled_from(FORMATS))
    element = draw(st.sampled_from(["quad", "triangle"]))
    name, data = mesh_bytes(fmt, element, (draw(st.integers(1, 4)), draw(st.integers(1, 3))))
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.integers(0, 4))
        numbers = list(NUMBER.finditer(data))
        if kind == 0 and numbers:  # a number replaced by a hostile one
            m = draw(st.sampled_from(numbers))
            data = data[: m.start()] + draw(st.sampled_from(HOSTILE)) + data[m.end() :]
        elif kind in (1, 2):  # a line deleted or repeated
            lines = data.split(b"\n")
            i = draw(st.integers(0, len(lines) - 1))
            lines[i : i + 1] = [] if kind == 1 else [lines[i], lines[i]]
            data = b"\n".join(lines)
        elif kind == 3:  # cut short
            data = data[: draw(st.integers(0, len(data)))]
        else:  # random bytes spliced in
            i = draw(st.integers(0, len(data)))
            data = data[:i] + draw(st.binary(min_size=1, max_size=8)) + data[i:]
    return name, data, SCENE.format(mesh=name).encode()


def _tree(root: Path) -> dict:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))}


def _check(code: int, msg: str, before: dict, after: dict) -> None:
    assert code in (0, 2), msg
    assert "Traceback" not in msg, msg
    assert after == before, "the folder changed"
    if code == 2:
        assert msg.startswith("mixvi: error: ") and msg.count("\n") == 1, msg
        assert "bodies.part.geometry.mesh" in msg or "contact" in msg or "bodies.part" in msg, msg


def run_in_process(name: str, data: bytes, scene: bytes) -> None:
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / name).write_bytes(data)
        (root / "scene.toml").write_bytes(scene)
        before = _tree(root)
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["validate", str(root / "scene.toml")])
        _check(code, err.getvalue(), before, _tree(root))


def _limit() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (CHILD_MEMORY, CHILD_MEMORY))


def run_in_child(name: str, data: bytes, scene: bytes) -> None:
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / name).write_bytes(data)
        (root / "scene.toml").write_bytes(scene)
        before = _tree(root)
        r = subprocess.run(
            [MIXVI, "validate", str(root / "scene.toml")],
            capture_output=True, text=True, timeout=120, preexec_fn=_limit, cwd=root,
            env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
        )  # fmt: skip
        _check(r.returncode, r.stderr, before, _tree(root))


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_undamaged_format_is_valid(tmp_path, fmt):
    """The fuzzer's starting points are accepted: a refusal below is the damage's doing."""
    name, data = mesh_bytes(fmt, "quad", (2, 2))
    (tmp_path / name).write_bytes(data)
    (tmp_path / "scene.toml").write_text(SCENE.format(mesh=name))
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        assert main(["validate", str(tmp_path / "scene.toml")]) == 0, err.getvalue()


@settings(max_examples=40, suppress_health_check=[HealthCheck.too_slow])
@given(damaged_meshes())
def test_fuzzed_mesh_files(case):
    run_in_process(*case)


@pytest.mark.slow
@pytest.mark.fuzz
@settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])
@given(damaged_meshes())
def test_fuzzed_mesh_files_150_in_children(case):
    run_in_child(*case)
