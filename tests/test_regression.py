"""The shipped scenes give the stored answers (tests/baselines, taken before the plug-in
contract v2 and the scene model), to the rounding tolerance derived in tests/regression.py;
and the comparison catches a perturbed answer."""

from __future__ import annotations

import json

import pytest

import vi_core
from tests import regression

CASES = [(name, level) for name in regression.scenes() for level in regression.levels(name)]


def test_every_shipped_scene_has_a_baseline():
    assert {p.stem for p in regression.BASELINES.glob("*.json")} == set(regression.scenes())


@pytest.mark.parametrize(("name", "level"), CASES)
def test_same_answers_as_the_baseline(name, level):
    base = regression.baseline(name)[str(level)]
    now = regression.run_case(name, level)
    assert regression.check_case(name, level, base, now) == []
    # the derived tolerance stays a rounding tolerance (κ and r as measured at baseline time)
    assert regression.tolerance(base, now) <= 1e-8


def _scaled_solve(factor):
    real = vi_core.solve

    def solve(vi, *args, **kw):
        sol = real(vi, *args, **kw)
        sol.lam = sol.lam * factor
        return sol

    return solve


@pytest.mark.parametrize(
    "name", ["rigid_foundation", "obstacle", "antiplane", "signorini", "electrical_block"]
)
def test_a_perturbed_multiplier_is_caught(name, monkeypatch):
    """λ scaled by 1 + 1e-6 (far above rounding, far below anything a plot would show)."""
    base = regression.baseline(name)["0"]
    monkeypatch.setattr(vi_core, "solve", _scaled_solve(1 + 1e-6))
    diffs = regression.check_case(name, 0, base, regression.run_case(name, 0))
    assert any(".norms.lambda" in d for d in diffs), diffs


def test_perturbed_data_are_caught():
    """The friction bound changed by one part in a million moves the answer beyond tolerance."""
    base = regression.baseline("rigid_foundation")["0"]
    now = regression.run_case("rigid_foundation", 0, ("contact.g=9000009.0",))
    diffs = regression.check_case("rigid_foundation", 0, base, now)
    assert any(".norms." in d for d in diffs), diffs


def test_a_changed_count_is_caught():
    base = regression.baseline("signorini")["0"]
    now = regression.run_case("signorini", 0)
    now["summary"]["contact"]["slip"] += 1
    assert regression.check_case("signorini", 0, base, now) == [
        "signorini level 0: .summary.contact.slip: 3 → 4"
    ]


def test_rounding_is_not_a_difference(monkeypatch):
    """λ moved by 10 ε: within tolerance (the check does not fail on rounding alone)."""
    base = regression.baseline("rigid_foundation")["0"]
    monkeypatch.setattr(vi_core, "solve", _scaled_solve(1 + 10 * regression.EPS))
    assert (
        regression.check_case(
            "rigid_foundation", 0, base, regression.run_case("rigid_foundation", 0)
        )
        == []
    )


def test_a_slack_beyond_rounding_is_caught():
    base = regression.baseline("curved_manufactured")["0"]
    now = regression.run_case("curved_manufactured", 0)
    assert regression.check_case("curved_manufactured", 0, base, now) == []
    bad = {**now, "norms": {**now["norms"], "slack": 1e-6 * now["slack_scale"]}}
    assert any("slack" in d for d in regression.check_case("curved_manufactured", 0, base, bad))


def test_floats_inside_lists_of_entries_are_compared_to_rounding_not_exactly():
    """A load path's steps (a list of dicts) once compared with ==: a last-bit change on another
    machine failed the suite there. Floats anywhere are compared to rtol; counts exactly."""
    base = {"steps": [{"t": 1.0, "norm": 7.180038696610759e-06, "open": 10}]}
    rounded = {"steps": [{"t": 1.0, "norm": 7.180038696610757e-06, "open": 10}]}
    assert regression.compare(base, rounded, 1e-12) == []
    moved = {"steps": [{"t": 1.0, "norm": 7.180045e-06, "open": 10}]}
    assert regression.compare(base, moved, 1e-12) == [
        ".steps[0].norm: 7.180038696610759e-06 → 7.180045e-06 (relative 8.8e-07 > 1e-12)"
    ]
    counted = {"steps": [{"t": 1.0, "norm": 7.180038696610759e-06, "open": 11}]}
    assert regression.compare(base, counted, 1e-12) == [".steps[0].open: 10 → 11"]
    assert regression.compare(base, {"steps": []}, 1e-12) == [".steps: 1 entries → 0"]


def test_the_flux_of_an_insulated_contact_is_a_residue_of_a_conducting_one_an_answer():
    """hertz_piezo (law "none": D·n = 0 on the contact) stored flux_max 7.6e-16 and measured
    6.1e-16 on another machine: rounding of a zero, not compared. electrical_block conducts:
    its flux_max moved by 1e-6 relative is a difference."""
    insulated = regression.baseline("hertz_piezo")["0"]
    moved = json.loads(json.dumps(insulated))
    assert insulated["summary"]["electrical"]["kind"] == "none"
    # a rerun's rounding of the zero (a baseline written since stores the summary stripped)
    moved["summary"]["electrical"]["flux_max"] = 6.1e-16
    moved["summary"] = regression._strip(moved["summary"])  # as run_case returns it
    assert regression.check_case("hertz_piezo", 0, insulated, moved) == []
    conducting = regression.baseline("electrical_block")["0"]
    assert conducting["summary"]["electrical"]["kind"] != "none"
    assert conducting["summary"]["electrical"]["flux_max"] > 0
    moved = json.loads(json.dumps(conducting))
    moved["summary"]["electrical"]["flux_max"] *= 1 + 1e-6
    moved["summary"] = regression._strip(moved["summary"])
    diffs = regression.check_case("electrical_block", 0, conducting, moved)
    assert any("flux_max" in d for d in diffs), diffs
