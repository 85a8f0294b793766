"""`mixvi solve --solver fixed_point`: the Coulomb fixed point g ← F·λ_n through the one solve
pipeline (`problems.pipeline.solve_built`). Its answers are cross-checked against semismooth
Newton's on the same scenes (independent computations) for drawn F inside the range where both
converge (docs/coulomb.md); beyond it (coulomb_strip, level 1, F = 15) it must say "NOT
converged" and exit 1; a scene without contact blocks is refused naming --solver.

The methods are one list: `mixvi solve --solver`, a scene's `[solver] method` (and the JSON
Schema of scenes) and `vi_core.solve` accept the same names, and a method the scene's multiplier
set cannot take is refused (exit 2) naming where it came from (--solver or solver.method), the
value and the methods allowed, by `mixvi solve` and `mixvi validate` alike.

Mutation: a fixed point whose Tresca bound is g ← F·λ_n / 2 (a dropped factor) must fail the
cross-check and report itself not converged."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import problems.pipeline as pipeline
import vi_core
from problems.commands.main import main
from problems.commands.schema import scene_schema
from problems.scene.model import METHODS
from vi_core import tresca_fixed_point

AGREE = 1e-7  # relative: both solve to tol 1e-10; the problem's conditioning costs the rest


def answers(scene: str, F: float, level: int) -> tuple:
    """(fixed point, ssn) solutions of `scene` with contact.F = F at `level`."""
    loaded = pipeline.load(scene, [f"contact.F={F!r}"])
    fp = pipeline.solve(loaded, level, method="fixed_point").solution
    newton = pipeline.solve(loaded, level, method="ssn").solution
    return fp, newton


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


@settings(max_examples=5)
@given(F=st.floats(0.05, 5.0), scene=st.sampled_from(["coulomb_strip", "coulomb_slip"]))
def test_fixed_point_agrees_with_newton(F, scene):
    fp, newton = answers(scene, F, 0)
    assert fp.method == "fixed_point" and fp.converged and newton.converged
    assert fp.iterations >= 1 and 0.0 <= (fp.info["contraction"] or 0.0) < 1.0
    assert relative(fp.u, newton.u) < AGREE and relative(fp.lam, newton.lam) < AGREE


def test_the_cross_check_catches_a_wrong_bound(monkeypatch):
    bounds = tresca_fixed_point.TrescaSequence.bounds

    def halved(self, lam):
        return [0.5 * g for g in bounds(self, lam)]

    monkeypatch.setattr(tresca_fixed_point.TrescaSequence, "bounds", halved)
    fp, newton = answers("coulomb_strip", 0.5, 0)
    assert not fp.converged
    assert relative(fp.lam, newton.lam) > 1e-3


def test_cli_reports_iterations_and_contraction(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["solve", "coulomb_strip", "--level", "1", "--solver", "fixed_point"]
    assert main([*argv, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    info = summary["solver_info"]
    assert summary["solver"] == "fixed_point" and summary["converged"]
    assert summary["iterations"] == len(info["inner_iterations"]) >= 2
    assert 0.0 < info["contraction"] < 1.0
    text = capsys.readouterr().out
    assert f"converged in {summary['iterations']} fixed-point iterations" in text
    assert f"contraction {info['contraction']:.3g}" in text


def test_cli_says_not_converged_beyond_the_range(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["solve", "coulomb_strip", "--level", "1", "--solver", "fixed_point"]
    assert main([*argv, "--set", "contact.F=15", "--out", str(out)]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert not summary["converged"] and summary["residual"] > 1e-6
    assert "NOT converged in" in capsys.readouterr().out


@pytest.mark.parametrize("scene", ["shear_strip", "manufactured"])
def test_cli_refuses_a_scene_without_contact_blocks(scene, tmp_path, capsys):
    argv = ["solve", scene, "--level", "0", "--solver", "fixed_point"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--solver" in err and "fixed_point" in err and "has none" in err
    assert not (tmp_path / "o" / "summary.json").exists()


@pytest.mark.slow
def test_a_load_path_by_the_fixed_point(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["solve", "shear_strip_path", "--level", "0", "--solver", "fixed_point"]
    assert main([*argv, "--out", str(out)]) == 2  # bilateral Tresca: no contact blocks
    argv = ["solve", "block3d_liftoff", "--level", "0", "--solver", "fixed_point"]
    assert main([*argv, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert all(s["converged"] for s in summary["steps"])
    assert [s["warm"] for s in summary["steps"]] == [False, True]
    assert "fixed-point iterations in all" in capsys.readouterr().out


def test_one_list_of_methods(capsys):
    """--solver, [solver] method, the JSON Schema and vi_core.solve accept the same names."""
    assert pipeline.SOLVERS == METHODS
    assert set(METHODS) == set(vi_core.METHODS) | set(vi_core.CONTACT_METHODS)
    enum = scene_schema()["$defs"]["Solver"]["properties"]["method"]["anyOf"][0]["enum"]
    assert enum == list(METHODS)
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    helptext = " ".join(capsys.readouterr().out.split())
    assert all(m in helptext for m in METHODS)


def test_a_scene_may_choose_the_fixed_point(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["solve", "coulomb_strip", "--level", "0", "--set", 'solver={method="fixed_point"}']
    assert main([*argv, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["solver"] == "fixed_point" and summary["converged"]
    assert "fixed-point iterations" in capsys.readouterr().out


REFUSED = [  # scene, method, where it is given, the key the error names, the methods allowed
    ("shear_strip", "fixed_point", "scene", "solver.method", "auto, ssn, conic, homotopy"),
    ("coulomb_strip", "conic", "scene", "solver.method", "auto, ssn, fixed_point"),
    ("coulomb_strip", "homotopy", "cli", "--solver", "auto, ssn, fixed_point"),
    ("coulomb_strip", "newton", "scene", "solver.method", ", ".join(METHODS)),
]
CASES = [("solve", *c) for c in REFUSED] + [("validate", *c) for c in REFUSED if c[2] == "scene"]


@pytest.mark.parametrize(("command", "scene", "method", "given", "key", "allowed"), CASES)
def test_a_method_the_scene_cannot_take_is_refused_naming_its_source(
    command, scene, method, given, key, allowed, tmp_path, capsys
):
    argv = [command, scene]
    argv += ["--solver", method] if given == "cli" else ["--set", f'solver={{method="{method}"}}']
    if command == "solve":
        argv += ["--level", "0", "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{key} = {method!r}" in err and allowed in err and "internal error" not in err
    assert not (tmp_path / "o" / "summary.json").exists()
