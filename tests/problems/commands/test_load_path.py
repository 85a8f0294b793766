"""`mixvi solve` of a scene with a [load_path]: steps/NNNN/ files, steps.pvd (time = t),
summary.json steps[], the per-step table, and an interrupt during the path that leaves the
previous run's folder as it was."""

from __future__ import annotations

import json
import signal
import xml.etree.ElementTree as ET

import pytest

from problems.commands.main import main

from .test_signals import check_clean_interrupt, previous_run, start, wait_for


def test_a_load_path_writes_every_step_and_the_collection(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["solve", "shear_strip_path", "--level", "0", "--set", "load_path.steps=4"]
    assert main([*argv, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    ts = [0.75, 1.5, 2.25, 3.0]
    assert [s["t"] for s in summary["steps"]] == ts and summary["load_path"]["t"] == ts
    assert summary["load_path"]["form"] == "incremental"
    assert all(s["converged"] for s in summary["steps"])
    assert [s["warm"] for s in summary["steps"]] == [False, True, True, True]
    assert {k for s in summary["steps"] for k in s["contact"]} == {"stick", "slip", "open"}
    rows = ET.parse(out / "steps.pvd").getroot().findall("./Collection/DataSet")
    assert [(float(r.get("timestep")), r.get("part")) for r in rows] == [
        (t, p) for t in ts for p in ("0", "1")
    ]
    for r in rows:
        assert (out / r.get("file")).is_file(), r.get("file")
    marker = json.loads((out / ".mixvi-run.json").read_text())
    assert "steps/0004/block.vtu" in marker["files"] and "steps.pvd" in marker["files"]
    text = capsys.readouterr().out
    assert "load path: 4 of 4 steps, incremental form" in text
    table = [line.split() for line in text.splitlines() if line.strip()[:1].isdigit()]
    assert [float(r[1]) for r in table if len(r) == 8] == ts


@pytest.mark.parametrize(
    ("solver", "start", "words"),
    [
        ("ssn", "previous step", "each warm-started from the previous step"),
        ("conic", "none", "each solved from zero (conic takes no warm start)"),
        ("homotopy", "none", "each solved from zero (homotopy takes no warm start)"),
    ],
)
def test_the_summary_says_what_each_solver_carries_between_steps(
    tmp_path, capsys, solver, start, words
):
    """ssn starts each step after the first from the one before; conic and homotopy from
    zero, and summary.json and the console say so (they said "previous step" for every
    solver). The incremental form carries the history either way."""
    out = tmp_path / "o"
    argv = ["solve", "shear_strip_path", "--level", "0", "--set", "load_path.steps=3"]
    assert main([*argv, "--solver", solver, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["load_path"]["warm_start"] == start
    assert summary["load_path"]["form"] == "incremental"
    assert [s["warm"] for s in summary["steps"]] == [False, *[start != "none"] * 2]
    assert words in " ".join(capsys.readouterr().out.split())


def test_a_scene_without_a_load_path_writes_no_steps(tmp_path):
    out = tmp_path / "o"
    assert main(["solve", "shear_strip", "--level", "0", "--out", str(out)]) == 0
    assert not (out / "steps").exists() and not (out / "steps.pvd").exists()
    assert "steps" not in json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize(
    "sig",
    [signal.SIGINT, pytest.param(signal.SIGTERM, marks=pytest.mark.slow)],
    ids=["SIGINT", "SIGTERM"],
)
def test_an_interrupt_during_a_load_path_leaves_nothing(tmp_path, sig):
    """(SIGTERM in the slow tier: the same path through the same handler, CI time.)"""
    # the signal arrives after some steps were written to the staging folder: they go, the
    # previous run's files stay byte-identical
    out = tmp_path / "o"
    before = previous_run(out)
    proc = start(
        ["solve", "shear_strip_path", "--level", "1", "--set", "load_path.steps=400"]
        + ["--out", str(out)]
    )

    def some_steps_written() -> bool:
        return any(out.glob(".mixvi-tmp-*/steps/0002"))

    wait_for(some_steps_written, proc)  # the handshake: no fixed pause after it
    proc.send_signal(sig)
    check_clean_interrupt(proc, sig, out, before)


def test_a_plugin_without_the_hook_solves_in_total_form_and_says_so(tmp_path):
    from problems.scene import SCENES_DIR

    scene = tmp_path / "obstacle_path.toml"
    scene.write_text((SCENES_DIR / "obstacle.toml").read_text() + "\n[load_path]\nsteps = 2\n")
    out = tmp_path / "o"
    assert main(["solve", str(scene), "--level", "0", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["load_path"]["form"] == "total" and len(summary["steps"]) == 2
    assert any("does not declare `incremental`" in w for w in summary["warnings"])
    rows = ET.parse(out / "steps.pvd").getroot().findall("./Collection/DataSet")
    assert sorted({float(r.get("timestep")) for r in rows}) == [0.5, 1.0]


def test_a_step_that_does_not_converge_stops_the_path(tmp_path, monkeypatch):
    """The second of four steps reported not converged: two steps written, exit status 1."""
    import problems.pipeline.load_path as lp

    real, calls = lp.vi_core.solve, []

    def solve(vi, *a, **kw):
        sol = real(vi, *a, **kw)
        calls.append(1)
        sol.converged = sol.converged and len(calls) != 2
        return sol

    monkeypatch.setattr(lp.vi_core, "solve", solve)
    out = tmp_path / "o"
    argv = ["solve", "shear_strip_path", "--level", "0", "--set", "load_path.steps=4"]
    assert main([*argv, "--out", str(out)]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert [s["converged"] for s in summary["steps"]] == [True, False]
    assert summary["load_path"]["steps_solved"] == 2
    assert any("did not converge" in w for w in summary["warnings"])
    assert sorted(p.name for p in (out / "steps").iterdir()) == ["0001", "0002"]


def test_a_load_path_with_a_patch_defect_exits_1_unless_allowed(tmp_path, monkeypatch, capsys):
    """Mutation: a dropped master entry (as for a single solve, test_crosspoints): the path
    converges, and the exit status follows the last step's mortar patch defect."""
    from problems.scene import SCENES_DIR
    from tests.problems.plugins.contact.test_fault_table import mortar_dropped_entry

    mortar_dropped_entry(monkeypatch)
    scene = tmp_path / "two_body_path.toml"
    text = (SCENES_DIR / "shear_strip_two_body.toml").read_text()
    scene.write_text(text + "\n[load_path]\nsteps = 2\n")
    for extra, rc in (([], 1), (["--allow-defect"], 0)):
        out = tmp_path / f"o{rc}"
        assert main(["solve", str(scene), "--level", "0", "--out", str(out), *extra]) == rc
        summary = json.loads((out / "summary.json").read_text())
        assert all(s["converged"] for s in summary["steps"])
        assert summary["contact"]["mortar_patch_defect"] > 1e-3
        assert ("--allow-defect to accept" in capsys.readouterr().out) == (rc == 1)
