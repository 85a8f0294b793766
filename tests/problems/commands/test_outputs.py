"""Every output option of every command goes through one claim (problems.output.files): never
an input of the run, never a file mixvi did not write (unless --overwrite), never two outputs
on one path, never under a regular file, nothing partial on a signal; a killed run leaves
nothing that blocks the next; contradictory options are refused.

The matrix runs in-process (`problems.commands.main.main`, CI tier); the same cases as real
`mixvi` subprocesses are in the slow tier (each ~3 s of CPU for the imports); SIGINT during
writing and SIGKILL then a rerun are subprocess tests. After each refusal the case folder is
byte-identical (every file hashed before and after)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from problems.commands.main import main as cli
from problems.scene import SCENES_DIR

MIXVI = str(Path(sys.executable).with_name("mixvi"))
ENV = {**os.environ, "MPLBACKEND": "Agg"}
SCENE, MESH = "plate_with_hole.toml", "meshes/plate_with_hole.msh"

# command → (arguments before the output option, {output option: kind}); every writer
COMMANDS = {
    "solve": (["solve", SCENE, "--level", "0"], {"--out": "folder"}),
    "check": (["check", SCENE, "--level", "0"], {"--json": "file"}),
    "figures": (["figures", SCENE, "--level", "0"], {"--out": "folder"}),
    "study": (["study", SCENE, "--levels", "0..0", "--solvers", "ssn"], {"--out": "folder"}),
    "bench": (
        ["bench", "--scenes", SCENE, "--levels", "0..0"],
        {"--out": "file", "--figure": "file"},
    ),
    "extremes": (["extremes", "--only", "PZT-5H"], {"--out": "folder"}),
}
CASES = [(c, o) for c, (_, opts) in COMMANDS.items() for o in opts]


def case(tmp_path: Path) -> Path:
    """A user's case folder: a scene, its mesh file and a file of the user's."""
    d = tmp_path / "case"
    (d / "meshes").mkdir(parents=True)
    shutil.copy(SCENES_DIR / SCENE, d / SCENE)
    shutil.copy(SCENES_DIR / MESH, d / MESH)
    (d / "notes.json").write_text('{"mine": true}\n')
    return d


def hashes(root: Path) -> dict:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        if p.is_file()
        else None
        for p in sorted(root.rglob("*"))
    }


def argv(command: str, option: str, target: str) -> list[str]:
    head, opts = COMMANDS[command]
    extra = [f"{o}=other{o[2:]}" for o in opts if o != option]  # the run's other outputs
    return [*head, f"{option}={target}", *extra]


def run_inprocess(cwd: Path, args: list[str], capsys) -> tuple[int, str]:
    old = os.getcwd()
    os.chdir(cwd)
    try:
        rc = cli(args)
    finally:
        os.chdir(old)
    return rc, capsys.readouterr().err


def run_subprocess(cwd: Path, args: list[str], capsys=None) -> tuple[int, str]:
    r = subprocess.run([MIXVI, *args], cwd=cwd, env=ENV, capture_output=True, text=True)
    return r.returncode, r.stderr


@pytest.fixture(params=["inprocess", pytest.param("subprocess", marks=pytest.mark.slow)])
def mixvi(request, capsys):
    fn = run_inprocess if request.param == "inprocess" else run_subprocess
    return lambda cwd, args: fn(cwd, args, capsys)


TARGETS = {  # target → what the refusal says
    "scene": (SCENE, ("not an input", "this path is a file")),
    "mesh": (MESH, ("not an input", "this path is a file")),
    "user file": ("notes.json", ("mixvi did not write it", "this path is a file")),
    "under a file": ("notes.json/sub/x", ("is a file",)),
}


# extremes computes its table before it writes (~4 s of CPU a case): its "user file" and "under a
# file" cases (the two refusals) run in CI; "scene" and "mesh", the user-file refusal again, slow
SLOW = {("extremes", "scene"), ("extremes", "mesh")}


@pytest.mark.parametrize(
    ("command", "option", "target"),
    [
        pytest.param(c, o, t, marks=[pytest.mark.slow] * ((c, t) in SLOW), id=f"{t}-{c}-{o}")
        for c, o in CASES
        for t in TARGETS
    ],
)
def test_an_output_option_pointed_at_a_users_file_is_refused(
    tmp_path, mixvi, command, option, target
):
    d = case(tmp_path)
    path, says = TARGETS[target]
    before = hashes(tmp_path)
    rc, err = mixvi(d, argv(command, option, path))
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("mixvi: error: "), err
    assert option in lines[0] and any(s in lines[0] for s in says), lines[0]
    if command != "extremes" and target in ("scene", "mesh"):
        assert "not an input" in lines[0]  # the input check, before anything else
    if "mixvi did not write it" in lines[0]:
        assert "pass --overwrite to" in lines[0]  # the command line's word (the API's differs)
    assert hashes(tmp_path) == before


@pytest.mark.parametrize(
    "args, says",
    [
        (["--out=r.json", "--figure=r.json"], "the same path as --out"),
        (["--out=r.svg"], "the default --figure"),
        (["--out=d", "--figure=d/f.svg"], "inside --out"),
        (["--out=./x/../r.json", "--figure=r.json"], "the same path as --out"),
    ],
)
def test_two_outputs_of_one_run_on_one_path_are_refused(tmp_path, mixvi, args, says):
    d = case(tmp_path)
    (d / "x").mkdir()
    before = hashes(tmp_path)
    rc, err = mixvi(d, ["bench", "--scenes", SCENE, "--levels", "0..0", *args])
    assert rc == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert hashes(tmp_path) == before


def test_overwrite_replaces_a_users_file_and_a_mixvi_file_needs_no_flag(tmp_path, capsys):
    d = case(tmp_path)
    rc, err = run_inprocess(
        d, ["check", SCENE, "--level", "0", "--json", "notes.json", "--overwrite"], capsys
    )
    assert rc == 0, err
    assert json.loads((d / "notes.json").read_text())["written_by"].startswith("mixvi ")
    rc, err = run_inprocess(d, ["check", SCENE, "--level", "0", "--json", "notes.json"], capsys)
    assert rc == 0, err  # mixvi's own file now: replaced without --overwrite


class TestContradictions:
    def test_level_and_levels_together(self, tmp_path, mixvi):
        rc, err = mixvi(case(tmp_path), ["check", SCENE, "--level", "0", "--levels", "1..1"])
        assert rc == 2 and "--levels" in err and "not both" in err, err

    @pytest.mark.parametrize("scenes", [f"{SCENE},{SCENE}", f"{SCENE},./meshes/../{SCENE}"])
    def test_one_scene_twice_in_bench(self, tmp_path, mixvi, scenes):
        rc, err = mixvi(case(tmp_path), ["bench", "--scenes", scenes, "--levels", "0..0"])
        assert rc == 2 and "--scenes" in err and "one scene" in err, err

    @pytest.mark.parametrize("components", ["xy", "x", "y"])
    def test_one_boundary_prescribed_twice(self, tmp_path, mixvi, components):
        d = case(tmp_path)  # its [[bodies.plate.displacement]] prescribes x and y on "top"
        entry = "[[bodies.plate.displacement]]\n"
        extra = f'{entry}boundary = "top"\ncomponents = "{components}"\nvalue = [0.0, 0.0]\n\n'
        (d / SCENE).write_text((d / SCENE).read_text() + "\n" + extra)
        rc, err = mixvi(d, ["validate", SCENE])
        assert rc == 2 and "prescribed once" in err and "displacement[1].boundary" in err, err
        assert f"component {components[0]}" in err


SLOW_WRITE = """
import os, sys, time
from problems.output import single
class SlowOs:
    def __getattr__(self, name):
        return getattr(os, name)
    def fdopen(self, fd, mode):
        fh = os.fdopen(fd, mode)
        class Half:
            def __enter__(self):
                return self
            def __exit__(self, *exc):
                fh.close()
            def write(self, text):
                fh.write(text[: len(text) // 2]); fh.flush()
                print("WRITING", file=sys.stderr, flush=True)
                time.sleep(120)
                fh.write(text[len(text) // 2 :])
        return Half()
single.os = SlowOs()
from problems.commands.entry import run
sys.argv[0] = "mixvi"
sys.exit(run())
"""


def test_sigint_while_a_single_file_is_written_leaves_the_case_folder_byte_identical(tmp_path):
    """The staged file is half written when SIGINT comes (a test-side hook slows the write):
    exit 130, one line, the previous mixvi file and everything else as before."""
    d = case(tmp_path)
    rc, err = run_subprocess(d, ["check", SCENE, "--level", "0", "--json", "r.json"])
    assert rc == 0, err
    before = hashes(tmp_path)
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_WRITE, "check", SCENE, "--level", "0", "--json", "r.json"],
        cwd=d,
        env=ENV,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stderr.readline().strip() == "WRITING"
    assert any(p.name.startswith(".mixvi-tmp-") for p in d.iterdir())  # half a file staged
    proc.send_signal(signal.SIGINT)
    err = proc.stderr.read()
    assert proc.wait(60) == 130 and err.strip().splitlines() == ["mixvi: interrupted by SIGINT"]
    assert hashes(tmp_path) == before


def test_sigkill_then_a_rerun_to_the_same_out(tmp_path):
    """SIGKILL during a solve leaves a lock file and a staging folder; the rerun says so in one
    line, clears them (mixvi's own only) and succeeds; the user's files are untouched."""
    d = case(tmp_path)
    out = d / "o"
    rc, err = run_subprocess(d, ["solve", SCENE, "--level", "0", "--out", "o"])
    assert rc == 0, err
    (out / "mine.txt").write_text("the user's")
    before = hashes(out)
    proc = subprocess.Popen(
        [MIXVI, "solve", "paper_two_body", "--level", "3", "--out", "o", "--overwrite"],
        cwd=d,
        env=ENV,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while not any(p.name.startswith(".mixvi-tmp-") for p in out.iterdir()):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.01)
    time.sleep(0.5)  # inside the solve
    proc.kill()
    assert proc.wait(30) == -signal.SIGKILL
    assert (out / ".mixvi-lock").exists()
    left = {
        k: v for k, v in hashes(out).items() if not k.startswith((".mixvi-lock", ".mixvi-tmp-"))
    }
    assert left == before  # the killed run changed nothing of the previous run's or the user's
    rc, err = run_subprocess(d, ["solve", SCENE, "--level", "0", "--out", "o", "--overwrite"])
    lines = err.strip().splitlines()
    assert rc == 0 and len(lines) == 1, err
    assert "no longer running" in lines[0] and "lock" in lines[0] and "staged" in lines[0]
    assert (out / "mine.txt").read_text() == "the user's"
    assert sorted(p for p in os.listdir(out) if p.startswith(".mixvi-")) == [".mixvi-run.json"]
