"""One battery for every plug-in: each shipped scene converges with every applicable solver,
the solvers agree, the model's identities hold, errors shrink, and `mixvi solve` works.

A new plug-in is checked by adding its scene (and a small level) to SCENES.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import vi_core
from problems.commands import main as cli
from problems.plugins import registry
from problems.plugins.contract import conforms
from problems.scene import load_scene

SCENES = [  # (scene, level)
    ("obstacle", 1),
    ("antiplane", 1),
    ("signorini", 1),
    ("rigid_foundation", 0),
]
TOL = 1e-10
AGREE = 1e-6


def _solve_all(vi):
    methods = {"ssn": {}, "homotopy": {"report_constants": False}}
    if vi.structure != "general":
        methods["conic"] = {}
    return {m: vi_core.solve(vi, method=m, tol=TOL, **o) for m, o in methods.items()}


@pytest.fixture(scope="module", params=SCENES, ids=[s for s, _ in SCENES])
def solved(request):
    name, level = request.param
    scene = load_scene(name)
    plugin = registry.get(scene.data["scene"].get("plugin", "piezo_contact"))
    model = plugin.build(scene, level)
    return scene, plugin, model, _solve_all(model.vi)


def test_builtins_conform():
    for name, mod in registry.plugins().items():
        assert conforms(mod) == [], name
        assert mod.NAME == name


def test_model_contract(solved):
    _, _, model, _ = solved
    assert isinstance(model.vi, vi_core.MixedVI)
    assert isinstance(model.level, int) and isinstance(model.warnings, list)
    assert all(isinstance(v, int) for v in model.dofs.values())
    assert sum(model.dofs.values()) == model.vi.n + model.vi.m


def test_every_solver_converges(solved):
    _, _, model, sols = solved
    for meth, sol in sols.items():
        r = model.vi.residual(sol.u, sol.lam)
        assert sol.converged, meth
        assert sol.residual <= TOL and float(r.relative) <= TOL, meth


def test_solvers_agree(solved):
    _, _, _, sols = solved
    ref = sols["ssn"]
    for meth, sol in sols.items():
        assert np.linalg.norm(sol.u - ref.u) <= AGREE * np.linalg.norm(ref.u), meth
        assert np.linalg.norm(sol.lam - ref.lam) <= AGREE * np.linalg.norm(ref.lam), meth


def test_complementarity_identity(solved):
    _, _, model, sols = solved
    if not hasattr(model, "complementarity"):
        pytest.skip("model has no complementarity identity")
    for meth, sol in sols.items():
        assert model.complementarity(sol) <= 1e-8, meth


def test_refinement_reduces_error(solved):
    scene, plugin, model, sols = solved
    if not hasattr(model, "errors") or getattr(model, "exact", None) is None:
        pytest.skip("no exact solution")
    coarse = model.errors(sols["ssn"])
    fine_model = plugin.build(scene, model.level + 1)
    fine = fine_model.errors(vi_core.solve(fine_model.vi, method="ssn", tol=TOL))
    assert fine["h"] < coarse["h"]
    assert fine["h1"] < 0.75 * coarse["h1"]


def test_cli_solve(solved, tmp_path):
    scene, plugin, model, _ = solved
    out = tmp_path / "out"
    assert cli.main(["solve", scene.name, "--level", str(model.level), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] and summary["plugin"] == plugin.NAME
    assert any(f.endswith(".vtu") for f in summary["files"])
    assert any(f.endswith(".png") for f in summary["files"])
    for f in summary["files"]:
        assert (out / f).is_file(), f
