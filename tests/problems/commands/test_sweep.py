"""`mixvi sweep`: the grid, bad options (exit 2 naming the option, its value and what is
allowed), the output folder's rules (a refused or failed sweep leaves it as it was) and the
contact3d plug-in (the other plug-ins: test_every_command.py)."""

from __future__ import annotations

import json
import re

import pytest

from problems.commands import sweep
from problems.commands.main import main
from problems.scene.reader import SCENES_DIR


def test_ranges_lists_and_the_grid():
    assert sweep.parse_range("contact.F=0.1:1:10")[1] == pytest.approx(
        [0.1 + 0.1 * i for i in range(10)]
    )
    assert sweep.parse_range("a.b=2:5:1") == ("a.b", [2.0])
    assert sweep.parse_list("electric.V=700, 784") == ("electric.V", [700, 784])
    params = {"a": ("--set-range", "", [1, 2]), "b": ("--set-list", "", ["x", "y", "z"])}
    cases = sweep.grid(params)
    assert len(cases) == 6 and cases[:2] == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}]
    assert sweep.override("a.b", "x") == 'a.b="x"' and sweep.override("a", 0.5) == "a=0.5"


TWO_LOADS = ["sweep", "obstacle", "--level", "0", "--set-list", "domain.load=0,-2"]
BAD = [
    (["--set-range", "contact.Fx=0.1:1:3"], "--set-range contact.Fx", "unknown key"),
    (["--set-range", "contact.g=a:1:3"], "--set-range", "START:STOP:N"),
    (["--set-range", "contact.g=1:2:0"], "--set-range", "N ≥ 1"),
    (["--set-range", "contact.g=1:2"], "--set-range", "START:STOP:N"),
    (["--set-range", "contact.g=-1:1:3"], "--set-range contact.g", "≥ 0"),
    (["--set-list", "contact.g=1e6,-5"], "--set-list contact.g", "≥ 0"),
    (["--set-list", "contact.g="], "--set-list", "at least one value"),
    (["--set-range", "contact.g=1:2:2", "--set", "contact.g=3"], "--set-range", "--set"),
    (["--set-range", "contact.g=1:2:2", "--set-list", "contact.g=3"], "--set-list", "swept"),
    ([], "--set-range", "at least one"),
]


@pytest.mark.parametrize("args, option, allowed", BAD, ids=[" ".join(b[0]) for b in BAD])
def test_bad_options_exit_2_naming_option_value_and_what_is_allowed(
    args, option, allowed, tmp_path, capsys
):
    out = tmp_path / "never"
    code = main(["sweep", "rigid_foundation", "--level", "0", *args, "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert f"{option} = " in err[0] and allowed in err[0], err[0]
    if args:
        assert repr(args[1]) in err[0] or args[1] in err[0]
    assert not out.exists()


def test_a_refused_value_is_named_by_its_case_not_by_set(tmp_path, monkeypatch, capsys):
    """Mutation: without the sweep's own naming (`load_case` re-raising), the error names
    --set, an option the user did not give."""
    argv = ["sweep", "rigid_foundation", "--set-range", "contact.g=-1:1:3", "--out", "x"]
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert "--set-range contact.g" in capsys.readouterr().err
    import problems.pipeline as pipeline

    monkeypatch.setattr(sweep, "load_case", lambda scene, fixed, case, params: pipeline.load(
        scene, [*fixed, *(sweep.override(k, v) for k, v in case.items())]))  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--set-range contact.g" not in err and "--set contact.g" in err


def test_a_bad_plot_key_after_the_first_case_leaves_the_folder_as_it_was(tmp_path, capsys):
    out = tmp_path / "o"
    argv = [*TWO_LOADS, "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert {"sweep.json", "sweep.csv", "case_0/summary.json", "case_1/summary.json"} <= {
        str(p) for p in before
    }
    code = main([*argv, "--set-list", "domain.other=1", "--no-progress"])
    assert code == 2  # a key the scene refuses: nothing solved
    code = main([*argv, "--plot", "no.such.output", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "--plot = 'no.such.output'" in err and "iterations" in err
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before  # no case of the refused run replaced an earlier one
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]  # nothing staged left


def test_a_folder_with_the_users_files_is_refused(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    argv = ["sweep", "obstacle", "--level", "0", "--set-list", "domain.load=0", "--out", str(out)]
    assert main(argv) == 2
    assert "notes.txt" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_a_failed_case_is_a_row_and_exit_1(tmp_path, monkeypatch, capsys):
    real = sweep.solve_case

    def failing(scene, level, solver, keep_model=True):
        if scene.data["domain"]["load"] == -2:
            return "RuntimeError: the mesh generator crashed"
        return real(scene, level, solver, keep_model)

    monkeypatch.setattr(sweep, "solve_case", failing)
    out = tmp_path / "o"
    argv = [*TWO_LOADS, "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 1
    res = json.loads((out / "sweep.json").read_text())
    assert [c["converged"] for c in res["cases"]] == [True, False]
    assert res["cases"][1]["error"].startswith("RuntimeError") and not (out / "case_1").exists()
    assert "failed: RuntimeError" in capsys.readouterr().out


@pytest.mark.slow
def test_contact3d(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["block3d", "--level", "0", "--set-range", "contact.g=1e6:2e6:2", "--plot", "iterations"]
    assert sweep.sweep_main([*argv, "--no-progress", "--out", str(out)]) == 0
    res = json.loads((out / "sweep.json").read_text())
    assert res["plugin"] == "contact" and all(c["converged"] for c in res["cases"])


@pytest.mark.parametrize("option", ["--set-range", "--set-list"])
def test_the_help_examples_are_accepted_by_a_shipped_scene(option, capsys):
    """Each example of the two options' help, with its values, validates on a shipped scene
    (an example no scene accepts, such as the former electric.V=700,784, fails here)."""
    action = next(a for a in sweep.parser()._actions if option in a.option_strings)
    example = re.search(r"e\.g\. (\S+)", action.help).group(1)
    key, values = (sweep.parse_range if option == "--set-range" else sweep.parse_list)(example)
    accepted = next(
        (
            name
            for name in sorted(p.stem for p in SCENES_DIR.glob("*.toml"))
            if all(main(["validate", name, "--set", f"{key}={v!r}"]) == 0 for v in values)
        ),
        None,
    )
    capsys.readouterr()
    assert accepted, f"no shipped scene accepts the example {example}"
