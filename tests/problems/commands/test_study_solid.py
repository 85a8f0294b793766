"""`mixvi study manufactured3d`: the exact errors of the 3D manufactured solution per level
(u and φ in L² and H¹, λ in the discrete norm: `contact3d.EXACT_NORMS`, computed by
`problems.plugins.contact.errors`) with fitted rates, through the same study command as
2D's `manufactured`.

Cross-checks: every record's errors are those of an independent build, solve and
`contact3d.exact_errors` of that level; the rates written are the fit of the records
and pass the slopes of `test_manufactured.py` (MIN_SLOPE). Mutation: the exact displacement
gradient transposed (a wrong reference) must fail the slopes."""

from __future__ import annotations

import json

import numpy as np
import pytest

import vi_core
from problems.commands import study
from problems.plugins.contact import solid as contact3d
from problems.scene import load_scene
from problems.scene.exact import Exact, ExactSection

from ..plugins.contact.test_manufactured import slope_failures

ARGS = ["manufactured3d", "--levels", "0..2", "--solvers", "ssn", "--tols", "1e-10"]


def run(tmp_path) -> dict:
    out = tmp_path / "study3d"
    assert study.study_main([*ARGS, "--out", str(out), "--no-progress"]) == 0
    return json.loads((out / "study.json").read_text())


def test_study_reports_the_exact_errors_and_rates(tmp_path, capsys):
    res = run(tmp_path)
    assert res["reference"] == "exact" and res["norms"] == list(contact3d.EXACT_NORMS)
    records = sorted(res["records"], key=lambda r: r["level"])
    assert [r["level"] for r in records] == [0, 1, 2]
    scene = load_scene("manufactured3d")
    for r in records:
        assert set(r["err"]) == set(contact3d.EXACT_NORMS) and r["converged"]
        model = contact3d.build(scene, r["level"])
        sol = vi_core.solve(model.vi, "ssn", tol=1e-10)
        direct = contact3d.exact_errors(model, sol)
        for k, v in direct.items():
            assert r["err"][k] == pytest.approx(v, rel=1e-6), (r["level"], k)
    rates = res["rates"]["ssn"]
    h = [r["h"] for r in records]
    for k, v in rates.items():
        e = [r["err"][k] for r in records]
        assert v == pytest.approx(np.polyfit(np.log(h), np.log(e), 1)[0], rel=1e-12)
    assert slope_failures(rates) == []
    text = capsys.readouterr().out
    assert "errors against: exact" in text and "u_L2" in text and "lam" in text


def test_a_wrong_exact_solution_fails_the_rates(tmp_path, monkeypatch):
    compiled = ExactSection.compiled

    def rest(e: Exact) -> tuple:
        return e.phi, e.grad_phi, e.lam

    def off(self) -> Exact:
        e = compiled(self)
        return Exact(e.u, lambda *p: np.swapaxes(e.grad_u(*p), -1, -2), *rest(e))

    monkeypatch.setattr(ExactSection, "compiled", off)
    assert slope_failures(run(tmp_path)["rates"]["ssn"])
