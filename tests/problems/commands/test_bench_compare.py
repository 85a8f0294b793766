"""`mixvi bench --baseline`: a slower, fatter or differently iterating case is flagged and
the run exits 1; an equal run passes; a bad baseline is refused before anything runs."""

from __future__ import annotations

import copy
import json

import pytest

from problems.commands import bench_compare
from problems.commands.main import main

MACHINE = {"platform": "Linux-x", "cpus": 2}


def record(**kw) -> dict:
    """One bench record (the keys `bench_compare` reads), times in CPU seconds."""
    r = {
        "scene": "paper_two_body",
        "level": 3,
        "solver": "ssn",
        "linear_solver": "splu",
        "unknowns": 6000,
        "iterations": 5,
        "converged": True,
        "cpu_nonlinear_s": 4.0,
        "cpu_linear_s": 1.0,
        "cpu_ratio": 4.0,
        "peak_mem_mb": 200.0,
    }
    return r | kw


def run(**kw) -> dict:
    return {"machine": dict(MACHINE), "records": [record(**kw)]}


def verdict(old: dict, new: dict) -> list[str]:
    (row,) = bench_compare.compare(old, new)
    return row["reasons"]


def test_an_equal_run_passes():
    assert verdict(run(), run()) == []


@pytest.mark.parametrize(
    "change, reason",
    [
        ({"cpu_linear_s": 19.0, "cpu_nonlinear_s": 76.0}, "cpu_linear_s x19.00"),  # the 19x
        ({"cpu_nonlinear_s": 10.0, "cpu_ratio": 10.0}, "cpu_nonlinear_s x2.50"),
        ({"peak_mem_mb": 300.0}, "peak_mem_mb x1.50"),
        ({"iterations": 6}, "iterations 5 -> 6"),
        ({"unknowns": 6001}, "unknowns 6000 -> 6001"),
        ({"converged": False}, "fails now"),
    ],
)
def test_a_regression_is_named(change, reason):
    assert any(reason in r for r in verdict(run(), run(**change)))


def test_within_the_limits_and_faster_pass():
    assert verdict(run(), run(cpu_nonlinear_s=5.6, cpu_ratio=5.6, peak_mem_mb=240.0)) == []
    assert verdict(run(), run(cpu_nonlinear_s=7.6, cpu_linear_s=1.9, peak_mem_mb=240.0)) == []
    assert verdict(run(), run(cpu_nonlinear_s=1.0, cpu_linear_s=0.5, cpu_ratio=2.0)) == []


def test_short_times_are_not_compared():
    old = run(cpu_nonlinear_s=0.04, cpu_linear_s=0.01, cpu_ratio=4.0)
    new = run(cpu_nonlinear_s=0.2, cpu_linear_s=0.02, cpu_ratio=10.0)
    (row,) = bench_compare.compare(old, new)
    assert row["reasons"] == [] and row["factors"]["cpu_nonlinear_s"] is None


def test_another_machine_compares_only_the_dimensionless_ratio():
    other = run(cpu_nonlinear_s=40.0, cpu_linear_s=10.0, peak_mem_mb=900.0)
    other["machine"]["cpus"] = 64
    assert verdict(run(), other) == []
    slower_nonlinear = copy.deepcopy(other)
    slower_nonlinear["records"][0].update(cpu_nonlinear_s=80.0, cpu_ratio=8.0)
    assert any("cpu_ratio x2.00" in r for r in verdict(run(), slower_nonlinear))


def test_cases_are_matched_by_scene_level_and_solvers():
    old = {"machine": MACHINE, "records": [record(linear_solver="amg", iterations=9)]}
    assert bench_compare.compare(old, run()) == []  # splu was not in the baseline
    lines = bench_compare.table([], True)
    assert "no case of this run is in the baseline" in lines[-1]


@pytest.mark.parametrize(
    "content, says",
    [
        (None, "an existing bench JSON file"),
        ("not json", "a bench JSON file written by mixvi bench"),
        ('{"records": 3}', "no 'records' list"),
    ],
)
def test_a_bad_baseline_is_refused_before_anything_runs(tmp_path, capsys, content, says):
    base = tmp_path / "old.json"
    if content is not None:
        base.write_text(content)
    out = tmp_path / "b.json"
    argv = ["bench", "--scenes", "rigid_foundation", "--levels", "0..0", "--out", str(out)]
    assert main([*argv, "--baseline", str(base)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--baseline" in err[0] and says in err[0], err
    assert not out.exists()


def test_a_run_against_a_doctored_baseline(tmp_path, capsys):
    """Level 0, then again against the first run with its iterations changed: the case is
    named, exit 1. The baseline is an input of the run: --out on it is refused (exit 2) and it
    stays as it was. (An unchanged run passes: `test_an_equal_run_passes`.)"""
    old, new = tmp_path / "old.json", tmp_path / "new.json"
    argv = ["bench", "--scenes", "rigid_foundation", "--levels", "0..0"]
    assert main([*argv, "--out", str(old)]) == 0
    doctored = json.loads(old.read_text())
    doctored["records"][0]["iterations"] += 1
    old.write_text(json.dumps(doctored))
    assert main([*argv, "--out", str(new), "--baseline", str(old)]) == 1
    out = capsys.readouterr().out
    assert "REGRESSED: iterations" in out and "1 case(s) regressed" in out
    (case,) = json.loads(new.read_text())["baseline"]["cases"]
    assert case["regressed"] and case["iterations"][1] == doctored["records"][0]["iterations"] - 1
    before = old.read_bytes()
    assert main([*argv, "--out", str(old), "--baseline", str(old), "--overwrite"]) == 2
    assert "--out" in capsys.readouterr().err and old.read_bytes() == before
