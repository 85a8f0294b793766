"""`mixvi check`: raw answers, the independent checker, honest non-zero differences within
`allowed`, and the solver faults it must catch (README "What catches which fault")."""

from __future__ import annotations

import json

import numpy as np
import pytest

import vi_core
import vi_core.conic as conic
import vi_core.homotopy as homotopy
import vi_core.sets as sets_module
import vi_core.ssn as ssn
from problems.commands.main import main
from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from vi_core.kkt import Checker

from .electrical import SCENE, drop_electrical

STRONG = "bodies.block.material={name='BaTiO3', coupling_scale=4.0}"  # ρ ≈ 2.2: 4 levels


def _check(tmp_path, *args: str) -> tuple[int, list[dict]]:
    out = tmp_path / "check.json"
    rc = main(["check", *args, "--json", str(out)])
    return rc, json.loads(out.read_text())["records"]


def test_json_reports_raw_methods_and_pairs(tmp_path, capsys):
    rc, recs = _check(tmp_path, "rigid_foundation", "--levels", "0..0")
    assert rc == 0
    text = capsys.readouterr().out
    assert "conic raw" in text and "conic+polish (labelled, not compared)" in text
    for r in recs:
        assert set(r["methods"]) == {"ssn", "homotopy", "conic"}
        for m in r["methods"].values():
            assert {"residual", "iterations", "time_s", "converged"} <= set(m)
        # the checker agrees with each solver's own residual (two implementations)
        for m in r["methods"].values():
            assert m["residual"] == pytest.approx(m["solver_residual"], rel=1e-6, abs=1e-15)
        assert {(p["a"], p["b"]) for p in r["pairs"]} == {
            ("ssn", "homotopy"),
            ("ssn", "conic"),
            ("homotopy", "conic"),
        }
        for p in r["pairs"]:
            assert set(p) >= {"a", "b", "diff_u", "diff_lam", "allowed"}
            # honest: the raw answers differ (no polished copy), and within what is allowed
            assert 0 < p["diff_lam"] and 0 < p["diff_u"]
            assert max(p["diff_u"], p["diff_lam"]) <= p["allowed"]
        # today's keys are kept
        assert {"level", "unknowns", "structure", "max_difference", "rho", "t0_paper"} <= set(r)
        assert r["max_difference"] > 0


def test_symmetric_problems_compare_ssn_with_conic_only(tmp_path, capsys):
    rc, recs = _check(tmp_path, "obstacle", "--level", "1")
    assert rc == 0
    assert set(recs[0]["methods"]) == {"ssn", "conic"}
    assert "homotopy not run" in capsys.readouterr().out


def test_conic_scale_invariance_on_a_scene():
    """Loads and g × 1e-12 … × 1e12 on rigid_foundation: the raw conic answer has the same
    relative residual (measured 2.33e-11 … 2.35e-11 over the factors) and scales with the data."""
    base = None
    for f in (1e-12, 1e-6, 1.0, 1e6, 1e12):
        scene = load_scene(
            "rigid_foundation",
            [
                f"bodies.block.displacement=[{{boundary='top', value=[{2e-4 * f!r}, "
                f"{-1e-4 * f!r}]}}]",
                f"contact.g={9e6 * f!r}",
            ],
        )
        model = pc.build(scene, 1)
        sol = vi_core.solve(model.vi, "conic", polish=0)
        res = Checker.of(model.vi)(sol.u, sol.lam).relative
        assert sol.info["status"] == "optimal" and res <= 1e-8, f
        if base is None:
            base = (res, sol.lam / f)
        assert res == pytest.approx(base[0], rel=1e-2), f
        np.testing.assert_allclose(sol.lam / f, base[1], rtol=1e-6, atol=1e-9 * abs(base[1]).max())


# ------------------------------------------------------------------ solver faults → check
def _flip_complementarity_rhs(orig):
    def step(self, J, W, rhs_c, **kw):  # W λ⁺ − J B u⁺ = −(p − J y − J gap): a sign in the update
        return orig(self, J, W, -rhs_c, **kw)

    return step


def _wrong_homotopy_step(orig):
    def init(self, e, levels, inner, eta, options):
        orig(self, e, levels, inner, eta, options)
        self.C = 1.5 * self.C  # the update uses (s − τ)·1.5·C: a wrong step

    return init


def test_fault_ssn_update_sign_is_caught_by_check(tmp_path, monkeypatch):
    monkeypatch.setattr(ssn._Stepper, "step", _flip_complementarity_rhs(ssn._Stepper.step))
    rc, recs = _check(tmp_path, "obstacle", "--level", "1")  # symmetric: ssn and conic only
    assert rc == 1
    assert any(f.startswith("ssn") for f in recs[0]["failures"])


def test_fault_homotopy_step_is_caught_by_check(tmp_path, monkeypatch):
    monkeypatch.setattr(
        homotopy._Homotopy, "__init__", _wrong_homotopy_step(homotopy._Homotopy.__init__)
    )
    rc, recs = _check(tmp_path, "rigid_foundation", "--level", "0")
    assert rc == 1
    assert any(f.startswith("homotopy") for f in recs[0]["failures"])


def test_fault_homotopy_rho_is_caught_by_check(tmp_path, monkeypatch):
    """ρ under-estimated 4×: one level where four are needed, the fixed point diverges."""
    orig = homotopy.skew_ratio
    monkeypatch.setattr(homotopy, "skew_ratio", lambda A0, C: orig(A0, C) / 4)
    rc, recs = _check(tmp_path, "rigid_foundation", "--level", "0", "--set", STRONG)
    assert rc == 1
    assert any(f.startswith("homotopy") for f in recs[0]["failures"])


def test_without_the_rho_fault_the_strong_coupling_scene_passes(tmp_path):
    rc, recs = _check(tmp_path, "rigid_foundation", "--level", "0", "--set", STRONG)
    assert rc == 0 and recs[0]["rho"] > 2


def test_fault_conic_dual_sign_is_caught_by_check(tmp_path, monkeypatch):
    monkeypatch.setattr(conic, "_DUAL_SIGN", -1.0)
    rc, recs = _check(tmp_path, "rigid_foundation", "--level", "0")
    assert rc == 1
    assert any(f.startswith("conic") for f in recs[0]["failures"])
    pair = next(p for p in recs[0]["pairs"] if p["b"] == "conic" and p["a"] == "ssn")
    assert pair["diff_lam"] > 1.0


def test_polishing_would_hide_the_conic_dual_sign(monkeypatch):
    """Why the raw answer is compared: Newton steps from the wrong-signed conic answer reach
    the ssn solution, so a polished conic answer agrees with ssn whatever the conic path did."""
    model = pc.build(load_scene("rigid_foundation"), 0)
    ref = vi_core.solve(model.vi, "ssn")
    monkeypatch.setattr(conic, "_DUAL_SIGN", -1.0)
    raw = vi_core.solve(model.vi, "conic", polish=0)
    polished = vi_core.solve(model.vi, "conic", polish=10)
    assert np.linalg.norm(raw.lam - ref.lam) > np.linalg.norm(ref.lam)
    assert polished.converged
    assert np.linalg.norm(polished.lam - ref.lam) <= 1e-8 * np.linalg.norm(ref.lam)


def test_fault_in_the_sets_projection_is_caught_by_the_independent_checker(tmp_path, monkeypatch):
    """Box.project clips at 2g: ssn and its residual share the fault and report convergence;
    only the independent checker (and the conic path, which uses the support function) see it."""

    def faulty(self, y):
        return np.clip(np.asarray(y, float), self.lo, 2.0 * self.hi)

    monkeypatch.setattr(sets_module.Box, "project", faulty)
    rc, recs = _check(tmp_path, "rigid_foundation", "--level", "0")
    assert rc == 1
    ssn_rec = recs[0]["methods"]["ssn"]
    assert ssn_rec["converged"] and ssn_rec["solver_residual"] <= 1e-10  # fooled …
    assert ssn_rec["residual"] > 1e-6  # … the checker is not


@pytest.mark.parametrize("fault", [False, True], ids=["coupled", "electrical dropped"])
def test_check_solves_and_judges_the_electrical_contact_problem(fault, tmp_path, monkeypatch):
    """Every method runs inside the electrical fixed point and is judged against the VI frozen
    at its own answer's conductances; a method that solves the insulating VI instead fails the
    independent residual (exit 1)."""
    if fault:
        drop_electrical(monkeypatch)
    rc, (rec,) = _check(tmp_path, SCENE, "--level", "0")
    if fault:
        assert rc == 1 and any("independent residual" in f for f in rec["failures"]), rec
        return
    assert rc == 0, rec["failures"]
    assert set(rec["methods"]) == {"ssn", "homotopy", "conic"}
    for m in rec["methods"].values():
        assert m["outer_iterations"] > 2 and m["residual"] <= 1e-9
