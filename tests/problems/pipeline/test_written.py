"""`Results.write` writes what `mixvi solve` writes (the same names, the same contents but the
times), under the same rules (a user's file is never replaced or removed)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import problems
from problems.commands.main import main
from problems.errors import SceneError
from problems.output.paths import MARKER

# (scene, level): the 2D contact front with its potential plot and estimate, the 3D front,
# antiplane friction, an obstacle problem
CASES = [
    ("rigid_foundation", 1),
    ("block3d", 0),
    pytest.param("antiplane", 0, marks=pytest.mark.slow),
    pytest.param("obstacle", 0, marks=pytest.mark.slow),
]
TIMES = ("time", "time_s", "solve_time", "factor_time", "build_time")


def timeless(x):
    """`x` without the entries that hold times (they differ between two runs)."""
    if isinstance(x, dict):
        return {k: timeless(v) for k, v in x.items() if k not in TIMES and "time" not in k}
    if isinstance(x, list):
        return [timeless(v) for v in x]
    return x


def files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != MARKER
    }


def same_as_solve(cli: Path, api: Path) -> None:
    """The two folders hold the same files; every file but summary.json byte for byte,
    summary.json equal but its times."""
    a, b = files(cli), files(api)
    assert sorted(a) == sorted(b)
    for name in a:
        if name == "summary.json":
            sa, sb = json.loads(a[name]), json.loads(b[name])
            assert timeless(sa) == timeless(sb)
            assert list(sa) == list(sb)  # the same entries in the same order
        else:
            assert a[name] == b[name], name


@pytest.mark.parametrize(("scene", "level"), CASES)
def test_results_write_the_files_of_mixvi_solve(tmp_path, capsys, scene, level):
    cli, api = tmp_path / "cli", tmp_path / "api"
    assert main(["solve", scene, "--level", str(level), "--out", str(cli)]) in (0, 1)
    names = problems.solve_scene(scene, level=level).write(api)
    assert names[0] == "summary.json" and sorted(names) == sorted(files(api))
    same_as_solve(cli, api)


@pytest.mark.slow
def test_a_load_paths_results_write_its_last_state(tmp_path, capsys):
    cli, api = tmp_path / "cli", tmp_path / "api"
    assert main(["solve", "shear_strip_path", "--level", "0", "--out", str(cli)]) == 0
    problems.solve_scene("shear_strip_path", level=0).write(api)
    s_cli = json.loads((cli / "summary.json").read_text())
    s_api = json.loads((api / "summary.json").read_text())
    # the command adds each step's contact counts as it writes the step's files
    cli_steps = [{k: v for k, v in s.items() if k != "contact"} for s in s_cli["steps"]]
    assert timeless(s_api["steps"]) == timeless(cli_steps)
    assert timeless(s_api["contact"]) == timeless(s_cli["contact"])
    for f in ("contact.csv", "strip.vtu"):  # the last step's state, as mixvi solve's top level
        if (cli / f).exists():
            assert (api / f).read_bytes() == (cli / f).read_bytes(), f


def test_results_write_never_replaces_a_users_file(tmp_path):
    res = problems.solve_scene("rigid_foundation", level=0)
    out = tmp_path / "o"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(SceneError, match=r"notes.txt.*pass overwrite=True to"):  # the API's word
        res.write(out)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]  # nothing written
    (out / "summary.json").write_text("my own summary")
    res.write(out, overwrite=True)  # beside the user's files; only mixvi's names replaced
    assert (out / "notes.txt").read_text() == "mine"
    assert json.loads((out / "summary.json").read_text())["scene"] == "rigid_foundation"
    with pytest.raises(SceneError, match="notes.txt"):  # the user's file is still there
        res.write(out)
    assert (out / "notes.txt").read_text() == "mine"


def test_mutation_a_dropped_file_is_caught(tmp_path, capsys, monkeypatch):
    """Mutation: Results.write without the collection; the comparison sees it."""
    from problems.pipeline import written

    cli, api = tmp_path / "cli", tmp_path / "api"
    assert main(["solve", "block3d", "--level", "0", "--out", str(cli)]) in (0, 1)
    monkeypatch.setattr(written, "collection", lambda folder, datasets, name: [])
    problems.solve_scene("block3d", level=0).write(api)
    with pytest.raises(AssertionError):
        same_as_solve(cli, api)
