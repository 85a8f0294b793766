"""The installed `mixvi`, run as a user would, refuses bad input cleanly: for every case the
exit status is 2, the message names the option or scene field, no traceback is printed, and
the case's folder (the user's scene file, a folder of the user's files, earlier output) is
byte-identical afterwards — nothing created, nothing lost.

Classes: scene values (by --set and in scene files), scene files themselves, command-line
options of every command, level ranges and the per-scene cap, hostile output paths (under a
file, a file, a virtual or read-only file system, a folder holding the user's files, a locked
folder, a folder given for a file, a device), and levels that do not fit in memory (a process
memory limit, RLIMIT_AS, makes the machine small).

Message wording is not tested (the scene model words them), only that the field is named.

    .venv/bin/pytest tests/problems/commands/test_bad_input.py
"""

from __future__ import annotations

import fcntl
import io
import os
import resource
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from problems.scene import SCENES_DIR

MIXVI = str(Path(sys.executable).with_name("mixvi"))
SMALL_MEMORY = 15 * 10**8  # RLIMIT_AS of the memory cases: paper_two_body level 6 needs ~2.3 GB


@dataclass
class Case:
    """One bad invocation: `argv` after `mixvi` ({d} = the case's folder), the word the
    message must contain, and an optional setup of the folder."""

    name: str
    argv: list[str]
    needle: str
    setup: object = None
    rlimit_as: int | None = None
    code: int = 2
    extra: list[str] = field(default_factory=list)


def S(name: str, override: str, needle: str) -> Case:
    """A scene value set by --set on the user's copy of rigid_foundation."""
    return Case(name, ["solve", "{d}/scene.toml", "--set", override, "--out", "{d}/o"], needle)


def F(name: str, text: str, needle: str) -> Case:
    """A scene file with `text` (a folder `bad.toml`)."""

    def setup(d: Path) -> None:
        (d / "bad.toml").write_bytes(text.encode() if isinstance(text, str) else text)

    return Case(name, ["solve", "{d}/bad.toml", "--out", "{d}/o"], needle, setup)


def user_folder(d: Path) -> None:
    (d / "mine").mkdir()
    (d / "mine" / "notes.txt").write_text("the user's notes\n")
    (d / "mine" / "data.csv").write_text("1,2,3\n")


def a_file(d: Path) -> None:
    (d / "afile").write_text("the user's file\n")


def locked(d: Path) -> None:
    (d / "busy").mkdir()


GOOD = (SCENES_DIR / "rigid_foundation.toml").read_text().replace("level = 1", "level = 0")
HEAD = "[scene]\nplugin = 'contact'\nlevel = 0\n"
GEOM = 'geometry = { kind = "rectangle", x = [0.0, 2.0], y = [0.0, 1.0], cells = [8, 4] }'

CASES = [
    # ---------------------------------------------------------------- scene values (--set)
    S("g negative", "contact.g=-1.0", "contact.g"),
    S("g a word", "contact.g='lots'", "contact.g"),
    S("g nan", "contact.g=nan", "contact.g"),
    S("g inf", "contact.g=inf", "contact.g"),
    S("g overflow literal", "contact.g=1e400", "contact.g"),
    S("g a list", "contact.g=[1, 2]", "contact.g"),
    S("g huge", "contact.g=1e200", "contact.g"),
    S("g expression syntax", "contact.g='x +'", "contact.g"),
    S("g expression division by zero", "contact.g='1/(x-x)'", "contact.g"),
    S("g unknown function", "contact.g='gamma(x)'", "contact.g"),
    S("g boolean", "contact.g=true", "contact.g"),
    S("slave boundary typo", "contact.slave='block.bottm'", "contact.slave"),
    S("master unknown", "contact.master='moon'", "contact.master"),
    S("no displacement data", "bodies.block.displacement=[]", "bodies.block.displacement"),
    S("unknown material", "bodies.block.material='unobtainium'", "bodies.block.material"),
    S("negative E", "bodies.block.material={kind='isotropic', E=-1.0, nu=0.3}", "E"),
    S("nu one half", "bodies.block.material={kind='isotropic', E=1e9, nu=0.5}", "nu"),
    S("zero cells", "bodies.block.geometry.cells=[0, 4]", "bodies.block.geometry.cells"),
    S("reversed interval", "bodies.block.geometry.x=[2.0, 0.0]", "bodies.block.geometry.x"),
    S("geometry kind", "bodies.block.geometry.kind='sphere'", "bodies.block.geometry.kind"),
    S("too many cells", "bodies.block.geometry.cells=[100000, 100000]", "cells"),
    S("key typo", "scene.levle=2", "levle"),
    S("unknown key", "contact.nosuch=1", "contact.nosuch"),
    S("negative level", "scene.level=-1", "scene.level"),
    S("level a word", "scene.level='two'", "scene.level"),
    S("level above the cap", "scene.level=12", "scene.level"),
    S("unknown plug-in", "scene.plugin='nosuch'", "scene.plugin"),
    S("solver tol zero", "solver.tol=0", "solver"),
    S("--set without =", "contact.g", "--set"),
    S("--set into a missing table", "nosuch.key=1", "nosuch"),
    S("--set empty key part", "contact..g=1", "--set"),
    S("g wrong arity", "contact.g='sin(x, y)'", "contact.g"),
    S("g keyword argument", "contact.g='maximum(x, 0, out=y)'", "contact.g"),
    S("g nested too deep", "contact.g='" + "sin(" * 40 + "x" + ")" * 40 + "'", "contact.g"),
    S("g expression too long", "contact.g='" + "x+" * 1100 + "1'", "contact.g"),
    S("g overflows on the domain", "contact.g='exp(1000*(x + 1))'", "contact.g"),
    S("g constant division by zero", "contact.g='1/0'", "contact.g"),
    S("master is the slave", "contact.master='block.top'", "contact.master"),
    S("potential along no boundary", "output.potential_along='block.middle'", "potential_along"),
    S("body force of one component", "bodies.block.body_force=[1.0]", "bodies.block.body_force"),
    S("format 3", "format=3", "format"),
    Case(
        "validate a bad override",
        ["validate", "{d}/scene.toml", "--set", "contact.g='where(x, y)'"],
        "contact.g",
    ),
    Case(
        "validate an unknown key", ["validate", "{d}/scene.toml", "--set", "solver.x=1"], "solver.x"
    ),
    Case("validate a missing scene", ["validate", "{d}/nosuch.toml"], "scene"),
    # ---------------------------------------------------------------- scene files
    F("format 2 without plugin", "format = 2\n[scene]\nlevel = 0\n", "scene.plugin"),
    F("invalid TOML", "[scene\n", "bad.toml"),
    F("binary file", b"\x89PNG\x00\xff\xfe garbage", "bad.toml"),
    F("missing geometry", f"{HEAD}[bodies.b]\nmaterial = 'BaTiO3'\n", "bodies.b.geometry"),
    F("scene is a list", "scene = [1, 2]\n", "scene"),
    F("bodies is a number", f"{HEAD}bodies = 3\n", "bodies"),
    F("duplicate key", "[scene]\nlevel = 0\nlevel = 1\n", "bad.toml"),
    F("body without material", f"{HEAD}[bodies.b]\n{GEOM}\n", "bodies.b.material"),
    Case("scene does not exist", ["solve", "{d}/nosuch.toml", "--out", "{d}/o"], "scene"),
    Case("scene name unknown", ["solve", "paper_two_bdy", "--out", "{d}/o"], "scene"),
    Case("scene is a folder", ["solve", "{d}/mine", "--out", "{d}/o"], "scene", user_folder),
    # ---------------------------------------------------------------- options
    Case("--level negative", ["solve", "{d}/scene.toml", "--level", "-1"], "--level"),
    Case("--level 99", ["solve", "{d}/scene.toml", "--level", "99"], "--level"),
    Case("--level a word", ["solve", "{d}/scene.toml", "--level", "two"], "--level"),
    Case("--level above the cap", ["solve", "paper_two_body", "--level", "9"], "--level"),
    Case("--tol zero", ["solve", "{d}/scene.toml", "--tol", "0"], "--tol"),
    Case("--tol one", ["solve", "{d}/scene.toml", "--tol", "1"], "--tol"),
    Case("--tol negative", ["solve", "{d}/scene.toml", "--tol", "-1e-8"], "--tol"),
    Case("--solver unknown", ["solve", "{d}/scene.toml", "--solver", "magic"], "--solver"),
    Case("--accuracy unknown", ["solve", "--accuracy", "turbo"], "--accuracy"),
    Case("--accuracy number in 3D", ["solve", "block3d", "--accuracy", "0.1"], "2D only"),
    Case(
        "--accuracy number, no estimate",
        ["solve", "obstacle", "--accuracy", "0.1"],
        "gives none for this scene",
    ),
    Case("--contact-zone without a number", ["solve", "--contact-zone"], "--contact-zone"),
    Case(
        "--contact-zone with a preset",
        ["solve", "--contact-zone", "--accuracy", "fast"],
        "--contact-zone",
    ),
    Case("unknown option", ["solve", "--frobnicate"], "--frobnicate"),
    Case("unknown command", ["frobnicate"], "frobnicate"),
    Case("check --levels reversed", ["check", "{d}/scene.toml", "--levels", "2..1"], "--levels"),
    Case("check --levels words", ["check", "{d}/scene.toml", "--levels", "a..b"], "--levels"),
    Case("check --levels negative", ["check", "{d}/scene.toml", "--levels", "-1..2"], "--levels"),
    Case("check --levels 0..20", ["check", "paper_two_body", "--levels", "0..20"], "--levels"),
    Case("study --levels 0..20", ["study", "paper_two_body", "--levels", "0..20"], "--levels"),
    Case("study --levels -1..2", ["study", "paper_two_body", "--levels", "-1..2"], "--levels"),
    Case("study --solvers unknown", ["study", "manufactured", "--solvers", "ssn,x"], "--solvers"),
    Case("study --solvers empty", ["study", "manufactured", "--solvers", ""], "--solvers"),
    Case(
        "study --solvers repeated", ["study", "manufactured", "--solvers", "ssn,ssn"], "--solvers"
    ),
    Case("study --tols zero", ["study", "manufactured", "--tols", "0"], "--tols"),
    Case("study --tols empty", ["study", "manufactured", "--tols", ""], "--tols"),
    Case(
        "figures: the swept value is an expression",
        ["figures", "antiplane", "--set", "friction.g='8e5 + 0*x'", "--out", "{d}/f"],
        "friction.g",
    ),
    Case("bench --scenes empty", ["bench", "--scenes", "", "--out", "{d}/b.json"], "--scenes"),
    Case("bench --scenes comma", ["bench", "--scenes", ",", "--out", "{d}/b.json"], "--scenes"),
    Case("bench --scenes unknown", ["bench", "--scenes", "nosuch", "--out", "{d}/b.json"], "scene"),
    Case("bench --solvers unknown", ["bench", "--solvers", "magic"], "--solvers"),
    Case("bench --solvers empty", ["bench", "--solvers", ""], "--solvers"),
    Case("bench --levels reversed", ["bench", "--levels", "3..1"], "--levels"),
    Case("bench --levels 0..20", ["bench", "--levels", "0..20"], "--levels"),
    Case("bench --tol zero", ["bench", "--tol", "0"], "--tol"),
    Case("bench --timeout zero", ["bench", "--timeout", "0"], "--timeout"),
    Case("bench --timeout negative", ["bench", "--timeout", "-5"], "--timeout"),
    Case("bench --timeout nan", ["bench", "--timeout", "nan"], "--timeout"),
    Case("extremes --only nosuch", ["extremes", "--only", "nosuch"], "--only"),
    Case(
        "extremes --plugins unknown",
        ["extremes", "--plugins", "nosuch", "--out", "{d}/x"],
        "--plugins",
    ),
    Case("figures --level negative", ["figures", "--level", "-2"], "--level"),
    # ---------------------------------------------------------------- hostile output paths
    Case(
        "--out under a file", ["solve", "{d}/scene.toml", "--out", "{d}/afile/o"], "--out", a_file
    ),
    Case("--out is a file", ["solve", "{d}/scene.toml", "--out", "{d}/afile"], "--out", a_file),
    Case("--out in /proc", ["solve", "{d}/scene.toml", "--out", "/proc/mixvi-out"], "--out"),
    Case("--out name too long", ["solve", "{d}/scene.toml", "--out", "{d}/" + "a" * 300], "--out"),
    Case("scene name too long", ["solve", "{d}/" + "b" * 300 + ".toml"], "scene"),
    Case(
        "--json name too long", ["check", "{d}/scene.toml", "--json", "{d}/" + "c" * 300], "--json"
    ),
    Case("--json empty", ["check", "{d}/scene.toml", "--json", ""], "--json"),
    Case("--out in /sys", ["solve", "{d}/scene.toml", "--out", "/sys/mixvi-out"], "--out"),
    Case("--out /proc itself", ["solve", "{d}/scene.toml", "--out", "/proc"], "--out"),
    Case(
        "--out the user's folder",
        ["solve", "{d}/scene.toml", "--out", "{d}/mine"],
        "data.csv",
        user_folder,
    ),
    Case("--out . beside the scene", ["solve", "{d}/scene.toml", "--out", "."], "scene.toml"),
    Case(
        "--out a locked folder", ["solve", "{d}/scene.toml", "--out", "{d}/busy"], "locked", locked
    ),
    Case(
        "study --out the user's folder",
        ["study", "manufactured", "--levels", "0", "--out", "{d}/mine"],
        "--out",
        user_folder,
    ),
    Case(
        "figures --out the user's folder",
        ["figures", "--level", "0", "--out", "{d}/mine"],
        "--out",
        user_folder,
    ),
    Case(
        "extremes --out the user's folder",
        ["extremes", "--only", "BaTiO3", "--out", "{d}/mine"],
        "--out",
        user_folder,
    ),
    Case(
        "check --json a folder",
        ["check", "{d}/scene.toml", "--json", "{d}/mine"],
        "--json",
        user_folder,
    ),
    Case(
        "check --json under a file",
        ["check", "{d}/scene.toml", "--json", "{d}/afile/t.json"],
        "--json",
        a_file,
    ),
    Case("check --json in /proc", ["check", "{d}/scene.toml", "--json", "/proc/t.json"], "--json"),
    Case("check --json a device", ["check", "{d}/scene.toml", "--json", "/dev/null"], "--json"),
    Case(
        "bench --out a folder",
        ["bench", "--scenes", "rigid_foundation", "--levels", "0", "--out", "{d}/mine"],
        "--out",
        user_folder,
    ),
    Case(
        "bench --out in /sys",
        ["bench", "--scenes", "rigid_foundation", "--levels", "0", "--out", "/sys/b.json"],
        "--out",
    ),
    Case(
        "bench --out under a file",
        ["bench", "--scenes", "rigid_foundation", "--levels", "0", "--out", "{d}/afile/b.json"],
        "--out",
        a_file,
    ),
    # ---------------------------------------------------------------- memory
    Case(
        "level 6 in 1.5 GB",
        ["solve", "paper_two_body", "--level", "6", "--out", "{d}/o"],
        "--level",
        rlimit_as=SMALL_MEMORY,
    ),
    Case(
        "check level 6 in 1.5 GB",
        ["check", "paper_two_body", "--levels", "0..6"],
        "--levels",
        rlimit_as=SMALL_MEMORY,
    ),
    Case(
        "study level 6 in 1.5 GB",
        ["study", "paper_two_body", "--levels", "5..6"],
        "--levels",
        rlimit_as=SMALL_MEMORY,
    ),
    Case(
        "bench level 6 in 1.5 GB",
        ["bench", "--scenes", "paper_two_body", "--levels", "6", "--out", "{d}/b.json"],
        "--levels",
        rlimit_as=SMALL_MEMORY,
    ),
]


def _prepare(case: Case, d: Path) -> None:
    d.mkdir()
    (d / "scene.toml").write_text(GOOD)
    if case.setup is not None:
        case.setup(d)


def tree(root: Path) -> dict:
    """Relative path → bytes (None for folders) of everything under `root`."""
    out = {}
    for p in sorted(root.rglob("*")):
        out[str(p.relative_to(root))] = None if p.is_dir() else p.read_bytes()
    return out


SAMPLE = 10


def installed(i: int, case: Case) -> bool:
    """Whether case `i` runs the installed `mixvi` in a subprocess: those with a memory limit or
    a lock held by another process, the first case of each command and every SAMPLE-th case
    (so the command's own start-up and exit path is exercised in every class); the others call
    `main` in this process (the same code after start-up; ~0.1 s a case instead of ~2 s)."""
    first = next(j for j, c in enumerate(CASES) if c.argv[0] == case.argv[0])
    return bool(case.rlimit_as) or case.setup is locked or i % SAMPLE == 0 or i == first


def _run(case: Case, d: Path, subprocess_run: bool) -> tuple[int, str, dict, dict]:
    _prepare(case, d)
    lock_fd = None
    if case.setup is locked:  # another run holds the folder
        lock_fd = os.open(d / "busy" / ".mixvi-lock", os.O_RDWR | os.O_CREAT)
        fcntl.flock(lock_fd, fcntl.LOCK_EX)
    before = tree(d)

    def limit() -> None:
        if case.rlimit_as:
            resource.setrlimit(resource.RLIMIT_AS, (case.rlimit_as, case.rlimit_as))

    argv = [a.replace("{d}", str(d)) for a in case.argv]
    try:
        if subprocess_run:
            r = subprocess.run(
                [MIXVI, *argv],
                cwd=d,
                capture_output=True,
                text=True,
                timeout=180,
                preexec_fn=limit,
                env={**os.environ, "MPLBACKEND": "Agg"},
            )
            code, text = r.returncode, r.stderr + r.stdout
        else:
            code, text = _in_process(argv, d)
    finally:
        if lock_fd is not None:
            os.close(lock_fd)
    after = tree(d)
    return code, text, before, after


def _in_process(argv: list[str], d: Path) -> tuple[int, str]:
    """`main(argv)` run in folder `d`: its exit status (argparse's SystemExit included) and
    what it printed, stderr first."""
    from problems.commands.main import main

    out, err, cwd = io.StringIO(), io.StringIO(), os.getcwd()
    os.chdir(d)
    try:
        with redirect_stdout(out), redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as e:
                code = e.code if isinstance(e.code, int) else 2
    finally:
        os.chdir(cwd)
    return code, err.getvalue() + out.getvalue()


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Every case run once: the installed command's cases concurrently (each in its own
    folder), then the in-process ones in turn."""
    root = tmp_path_factory.mktemp("bad")
    sub = [i for i, c in enumerate(CASES) if installed(i, c)]
    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
        futures = {CASES[i].name: pool.submit(_run, CASES[i], root / f"case{i}", True) for i in sub}
        out = {
            c.name: _run(c, root / f"case{i}", False) for i, c in enumerate(CASES) if i not in sub
        }
        out |= {name: f.result() for name, f in futures.items()}
    yield out
    shutil.rmtree(root, ignore_errors=True)


def test_both_ways_of_running_cover_every_command():
    """Each command of the cases runs at least once as the installed `mixvi`, and most cases
    in process."""
    sub = [c for i, c in enumerate(CASES) if installed(i, c)]
    assert {c.argv[0] for c in sub} == {c.argv[0] for c in CASES}
    assert len(sub) < len(CASES) / 3


def test_there_are_at_least_60_cases_in_every_class():
    assert len(CASES) >= 60 and len({c.name for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_refused_cleanly(case, results):
    code, text, before, after = results[case.name]
    assert code == case.code, text
    assert "Traceback" not in text, text
    assert case.needle in text, text
    lines = text.strip().splitlines()  # one line, or argparse's usage and one error line
    assert "error" in lines[-1] and (len(lines) == 1 or lines[0].startswith("usage:")), text
    assert after == before, "the case's folder changed"
