"""`mixvi bench`: the bench.json contract and bad input."""

import json

import pytest

from problems.commands import bench
from problems.commands.main import main
from problems.plugins import registry
from problems.scene import load_scene

from .electrical import SCENE, drop_electrical, matches


def test_bench_writes_the_contract(tmp_path, capsys):
    out = tmp_path / "bench.json"
    assert (
        main(["bench", "--scenes", "rigid_foundation", "--levels", "0..1", "--out", str(out)]) == 0
    )
    data = json.loads(out.read_text())
    assert set(data) == {"written_by", "machine", "records", "memory", "fits"}
    (fit,) = data["fits"]  # one series: rigid_foundation with the default linear solver
    assert fit["unknowns"] == [r["unknowns"] for r in data["records"]]
    assert set(fit["exponent"]) == {"time_nonlinear", "time_linear", "peak_mem"}
    svg = (tmp_path / "bench.svg").read_text()
    assert svg.lstrip().startswith("<?xml") and "</svg>" in svg
    keys = {
        "scene",
        "level",
        "unknowns",
        "solver",
        "iterations",
        "time_nonlinear_s",
        "time_linear_s",
        "ratio",
        "cpu_nonlinear_s",
        "cpu_linear_s",
        "cpu_ratio",
        "peak_mem_mb",
        "bytes_per_unknown",
    }
    assert [r["level"] for r in data["records"]] == [0, 1]
    for r in data["records"]:
        assert keys <= set(r)
        assert r["converged"] and r["time_linear_s"] > 0 and r["peak_mem_mb"] > 0
        assert abs(r["ratio"] - r["time_nonlinear_s"] / r["time_linear_s"]) < 1e-12
        assert r["cpu_linear_s"] > 0 and r["cpu_nonlinear_s"] > 0
        assert abs(r["cpu_ratio"] - r["cpu_nonlinear_s"] / r["cpu_linear_s"]) < 1e-12
        assert abs(r["bytes_per_unknown"] * r["unknowns"] - r["peak_mem_mb"] * 2**20) < 1.0
    mem = data["memory"]
    assert [(m["scene"], m["level"]) for m in mem] == [
        ("rigid_foundation", 0),
        ("rigid_foundation", 1),
    ]
    for m, r in zip(mem, data["records"], strict=True):
        assert m["peak_mem_mb"] == r["peak_mem_mb"] and m["bytes_per_unknown"] > 1000
        assert abs(m["estimate_ratio"] - m["estimate_mem_mb"] / m["peak_mem_mb"]) < 1e-12
    out = capsys.readouterr().out
    assert (
        "ratio" in out
        and "cpu ratio" in out
        and "B/unknown" in out
        and "peak resident memory" in out
    )


def test_bench_bad_input_exits_2(tmp_path, capsys):
    assert main(["bench", "--levels", "3..1", "--out", str(tmp_path / "b.json")]) == 2
    assert "--levels" in capsys.readouterr().err
    assert main(["bench", "--solvers", "magic", "--out", str(tmp_path / "b.json")]) == 2
    assert main(["bench", "--scenes", "nope", "--out", str(tmp_path / "b.json")]) == 2
    assert not (tmp_path / "b.json").exists()


@pytest.mark.parametrize("fault", [False, True], ids=["coupled", "electrical dropped"])
def test_bench_times_the_electrical_contact_problem(fault, monkeypatch):
    """The timed nested solve is the scene's coupled problem (the closed form at the finest
    level), and the conic row solves it too; with the electrical condition dropped it is not."""
    if fault:
        drop_electrical(monkeypatch)
    scene = load_scene(SCENE)
    model, sol, _, _, iters = bench._nested_ssn(registry.for_scene(scene), scene, 1, 1e-10)
    assert sol.converged and len(iters) == 2
    assert matches(model, sol) != fault
    records = bench._record(SCENE, 0, ["ssn", "conic"], 1e-10)
    assert [r["solver"] for r in records] == ["ssn", "conic"]
    assert all(r["converged"] for r in records)
    assert records[1]["difference_to_ssn"] <= 1e-8
