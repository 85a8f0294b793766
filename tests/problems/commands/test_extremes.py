"""The `mixvi extremes` rows of every plug-in at level 0: residual, cross-method agreement,
λ ∈ Λ and the plug-ins' physical checks.

The conic answers are Clarabel's raw ones (no polishing). With loads and g scaled by 1e-12 the
conic method used to fail (absolute tolerances); it now normalises the data (vi_core.conic) and
agrees like the other rows (tests/problems/commands/test_check.py::
test_conic_scale_invariance_on_a_scene: the same relative residual from 1e-12 to 1e12).
The Lemma 4.2 gap is held to 1e-9, not the 1e-10 of the shipped scenes: g = 1e-6 σ_ref and the
10:1 mortar interface give 4.6e-10 (relative to ∫g|[u_τ]|, which is tiny there).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from problems.commands.extremes import (
    ADMISSIBLE_OK,
    AGREE_OK,
    RESIDUAL_OK,
    extremes_main,
    rows,
    run_row,
)
from problems.plugins import registry
from problems.plugins.contact import plane, solid

from .electrical import SCENE, drop_electrical

ROWS = [dataclasses.replace(r, level=0) for r in rows() if not r.huge]
# the 3D rows cost ~15 s each at level 0 (homotopy: 34 ssn solves): three in CI, all under slow;
# the unilateral ones (ssn and the fixed point, no homotopy) ~1 s: two in CI
CI_3D = (
    "3D: g = 1e-6 σ_ref (all slip)",
    "3D: loads, g × 1e-9",
    "3D: extruded 2D scene (discs + lines)",
    "3D unilateral: Coulomb F = 0.6",
    "3D unilateral: gap 1e-3 (apart, λ = 0)",
)
SOLID = {r.name for r in solid.extremes()}  # the 3D rows of `contact`
PLANE = {r.name for r in plane.extremes()}  # its 2D rows
ROWS_CI = [r for r in ROWS if r.name not in SOLID or r.name in CI_3D]
ROWS_3D_SLOW = [r for r in ROWS if r.name in SOLID and r.name not in CI_3D]


def test_every_builtin_plugin_has_rows():
    assert {r.plugin for r in ROWS} == set(registry.BUILTIN)


@pytest.mark.parametrize(
    "row",
    [*ROWS_CI, *(pytest.param(r, marks=pytest.mark.slow) for r in ROWS_3D_SLOW)],
    ids=[r.name for r in (*ROWS_CI, *ROWS_3D_SLOW)],
)
def test_extreme_row(row):
    rec = run_row(row)
    assert rec["converged"] and rec["residual"] <= RESIDUAL_OK, rec
    agree = dict(rec["agreement"])
    assert agree and max(agree.values()) <= AGREE_OK, rec
    assert rec["admissibility"] <= ADMISSIBLE_OK, rec
    assert rec["ok"], rec
    if row.plugin == "contact" and row.name in SOLID:
        assert rec["friction_excess"] <= 1e-9, rec
        if rec["lemma_4_2"] is not None and rec["slip"] > 0:
            assert rec["lemma_4_2"] <= 1e-9, rec
        if "homogeneity" in rec:
            assert rec["homogeneity"] <= 1e-6, rec
        return
    if row.plugin != "contact" or row.name not in PLANE:  # other plug-ins share row names
        return
    assert rec["friction_excess"] <= 1e-9, rec
    # with no slipping node (4.3) reads 0 = 0 and the ratio is rounding over a "tiny"
    # denominator (3e-9 with SuperLU on the all-stick 10:1 row): checked only where nodes slip
    if rec["lemma_4_2"] is not None and rec["slip"] > 0:
        assert rec["lemma_4_2"] <= 1e-9, rec
    if "homogeneity" in rec:
        assert rec["homogeneity"] <= 1e-6, rec
    if "locking_overestimate" in rec:  # locking: a coarse mesh is too stiff
        f = rec["normal_force_levels"]
        assert abs(f[0]) >= abs(f[1]) >= abs(f[2]) > 0, f
    if "coupling" in row.name:
        assert rec["rho"] > 2 and rec["homotopy_levels"] >= 3, rec


def test_thresholds_are_physical_checks():
    """g = 1e6 σ_ref ties every node; g = 0 lets every node slip."""
    by = {r.name: r for r in ROWS if r.plugin == "contact" and r.name in PLANE}
    tied, free = run_row(by["g = 1e6 σ_ref"]), run_row(by["g = 0 (frictionless)"])
    assert tied["slip"] == 0 and tied["stick"] > 0
    assert free["stick"] == 0 and free["slip"] > 0


def test_command_writes_json(tmp_path, capsys):
    rc = extremes_main(["--plugins", "contact", "--only", "gap = 0", "--out", str(tmp_path)])
    assert rc == 0
    assert "gap = 0" in capsys.readouterr().out
    assert (tmp_path / "extremes.json").read_text().count('"row"') == 1


def test_a_failed_plugin_check_fails_the_row():
    """The obstacle's 'no contact' row with the obstacle back in place: the count check says
    FAIL and the row is not ok (mutation: the check can fail)."""
    row = next(r for r in ROWS if r.name == "obstacle far below (no contact)")
    rec = run_row(dataclasses.replace(row, overrides=[]))
    assert not rec["ok"] and any(n.startswith("FAIL: contact =") for n in rec["notes"]), rec


def test_a_multiplier_outside_lambda_fails_the_row(monkeypatch):
    import vi_core

    real = vi_core.solve

    def outside(vi, method, **kw):  # ssn's answer pushed out of Λ (a wrong sign of λ)
        sol = real(vi, method, **kw)
        if method == "ssn":
            sol.lam = -sol.lam
        return sol

    monkeypatch.setattr(vi_core, "solve", outside)
    rec = run_row(next(r for r in ROWS if r.name == "load -1e3 (pressed onto the obstacle)"))
    assert rec["admissibility"] > ADMISSIBLE_OK and not rec["ok"], rec


def test_plugins_option_selects_and_refuses(tmp_path, capsys):
    assert extremes_main(["--plugins", "antiplane", "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "g × 1e6 (tied)" in out and "BaTiO3" not in out
    with pytest.raises(Exception, match="--plugins"):
        extremes_main(["--plugins", "nosuch", "--out", str(tmp_path / "b")])


@pytest.mark.parametrize("part", ["u", "lam"])
def test_a_disagreement_is_caught_where_ssn_answer_is_zero(part, monkeypatch):
    """The obstacle far below: ssn's λ is rounding zero. A conic answer off by 1e-3 (u scaled,
    or λ given a force of 1e-3 of the largest elastic one) still fails the row."""
    import numpy as np

    import vi_core

    real = vi_core.solve

    def off(vi, method, **kw):
        sol = real(vi, method, **kw)
        if method == "conic":
            if part == "u":
                sol.u = sol.u * (1 + 1e-3)
            else:
                sol.lam = sol.lam + 1e-3 * np.abs(vi.A @ sol.u).max()
        return sol

    monkeypatch.setattr(vi_core, "solve", off)
    rec = run_row(next(r for r in ROWS if r.name == "obstacle far below (no contact)"))
    assert rec["agreement"]["conic"] > AGREE_OK and not rec["ok"], rec


def test_a_broken_third_party_plugin_is_skipped_unless_named(tmp_path, capsys, monkeypatch):
    from importlib.metadata import EntryPoint

    from problems.errors import SceneError

    broken = EntryPoint("broken", "no_such_module_for_mixvi", registry.GROUP)
    monkeypatch.setattr(registry, "_third_party", lambda: {"broken": broken})
    assert extremes_main(["--only", "g × 1e6 (tied)", "--out", str(tmp_path / "a")]) == 0
    assert "skipping plug-in 'broken'" in capsys.readouterr().err
    with pytest.raises(SceneError, match="failed to load"):
        extremes_main(["--plugins", "broken", "--out", str(tmp_path / "b")])


def test_electrical_rows_fail_when_the_electrical_condition_is_dropped(monkeypatch):
    """The electrical rows hold the closed form; solved as the insulating VI (the fault) every
    row with a touching conductive or grounded foundation fails, while the pulled-apart row
    (k = 0) has nothing to drop and still passes."""
    drop_electrical(monkeypatch)
    for row in (r for r in ROWS if r.scene in (SCENE, "electrical_two_body")):
        rec = run_row(row)
        apart = "pulled apart" in row.name
        assert rec["ok"] == apart, rec
        if not apart:
            assert any("off the uniaxial closed form" in n for n in rec["notes"]), rec


def _displacement_off(monkeypatch, factor: float) -> None:
    """conic's answer with its displacement unknowns (only) scaled by `factor`."""
    import vi_core

    real = vi_core.solve

    def off(vi, method, **kw):
        sol = real(vi, method, **kw)
        if method == "conic":
            disp = vi.fields["displacement"]
            sol.u = sol.u.copy()
            sol.u[disp] *= factor
        return sol

    monkeypatch.setattr(vi_core, "solve", off)


FRICTIONLESS = "g = 0 (frictionless)"  # piezo_contact, manufactured: ‖φ‖ ~ 1e4 V, ‖u‖ ~ 1e-4 m


def test_a_displacement_off_is_caught_beside_large_potentials(monkeypatch):
    """Metres and volts are compared apart: conic's displacements off by 1e-4 (its potentials
    exact) fail the row, though they are lost in ‖(u, φ)‖ where φ is 1e8 times larger."""
    _displacement_off(monkeypatch, 1 + 1e-4)
    rec = run_row(next(r for r in ROWS if r.name == FRICTIONLESS))
    assert rec["agreement"]["conic"] > AGREE_OK and not rec["ok"], rec


def test_mutation_one_mixed_field_misses_the_displacement(monkeypatch):
    """Mutation: displacement and potential measured as one vector (the former measure): the
    same 1e-4 in the displacements passes as agreement."""
    from problems.plugins.contact.model import BodiesModel

    def one_field(self):
        return {"u": np.ones(self.values.size, dtype=bool)}

    monkeypatch.setattr(BodiesModel, "full_fields", one_field)
    _displacement_off(monkeypatch, 1 + 1e-4)
    rec = run_row(next(r for r in ROWS if r.name == FRICTIONLESS))
    assert rec["agreement"]["conic"] < AGREE_OK, rec
