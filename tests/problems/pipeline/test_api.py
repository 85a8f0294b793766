"""The Python API and the pipeline it shares with `mixvi solve`: the same numbers as the
command line, objects instead of files, overrides validated like --set."""

from __future__ import annotations

import json

import numpy as np
import pytest

import problems
from problems.commands.main import main
from problems.errors import SceneError
from problems.pipeline import load, solve


def test_solve_scene_gives_what_mixvi_solve_writes(tmp_path, capsys):
    assert main(["solve", "rigid_foundation", "--level", "1", "--out", str(tmp_path / "o")]) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    res = problems.solve_scene("rigid_foundation", level=1)
    for key in ("level", "solver", "tol", "dofs", "converged", "iterations", "residual"):
        assert res.info[key] == summary[key], key
    assert res.info["nested"] == [
        {k: v for k, v in r.items() if k != "time_s"} | {"time_s": res.info["nested"][i]["time_s"]}
        for i, r in enumerate(summary["nested"])
    ]
    n = summary["contact"]["nodes"]
    slip = res.contact["state"] == "slip"
    assert slip.size == n and int(slip.sum()) == summary["contact"]["slip"]
    assert res.contact["lemma_4_2"] == pytest.approx(summary["lemma_4_2"], rel=1e-9, abs=1e-15)
    u = res.fields["block.displacement"]
    assert u.shape == (res.model.bodies[0].n_nodes, 2) and np.isfinite(u).all()
    assert not list(tmp_path.glob("*.png"))  # the API wrote nothing


@pytest.mark.parametrize(
    ("name", "field"),
    [("obstacle", "u"), ("antiplane", "w"), ("signorini", "displacement")],
)
def test_every_plugin_returns_fields(name, field):
    res = problems.solve_scene(name, level=0)
    assert res.info["converged"] and field in res.fields
    assert res.info["complementarity"] < 1e-8


def test_a_model_and_keyword_overrides():
    spec = problems.load_scene("rigid_foundation")
    a = problems.solve_scene(spec, level=0, contact__g=5e6)
    b = problems.solve_scene("rigid_foundation", level=0, contact__g=5e6)
    c = problems.solve_scene("rigid_foundation", level=0)
    np.testing.assert_array_equal(a.solution.u, b.solution.u)
    assert not np.array_equal(a.solution.u, c.solution.u)  # the override took effect
    with pytest.raises(SceneError, match="contact.g"):
        problems.solve_scene(spec, level=0, contact__g=-1.0)
    with pytest.raises(SceneError, match="contact.gg"):
        problems.solve_scene("rigid_foundation", level=0, contact__gg=1.0)


def test_solver_and_tol_reach_the_solve():
    run = solve(load("obstacle"), level=0, method="conic", tol=1e-8)
    assert run.method == "conic" and run.tol == 1e-8 and run.model.level == 0
    with pytest.raises(SceneError, match="--solver"):
        solve(load("signorini"), level=0, method="magic")
