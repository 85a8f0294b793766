"""benchmarks/adaptive_solvers.py: the JSON contract on a few small cycles of hertz."""

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def bench(monkeypatch):
    """The benchmark module, importable by name (its spawned children import it by name)."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import adaptive_solvers

    return adaptive_solvers


def test_every_cycle_of_every_solver_is_measured(bench, tmp_path, capsys):
    out = tmp_path / "o.json"
    argv = ["hertz@0.3", "--max-unknowns", "2000", "--out", str(out)]
    assert bench.main(argv) == 0
    data = json.loads(out.read_text())
    (case,) = data["cases"]
    assert data["max_unknowns"] == 2000 and case["accuracy"] == 0.3
    runs = case["runs"]
    assert list(runs) == ["auto", "splu", "amg"]
    for name, r in runs.items():
        cycles = r["cycles"]
        assert len(cycles) == 3 and "2000 unknowns" in r["stopped"], name
        assert [c["unknowns"] for c in cycles] == [306, 370, 542], name
        for c in cycles:
            assert c["converged"] and c["newton_steps"] >= 1 and c["nnz_A"] > c["unknowns"]
            assert c["solve_cpu_s"] > 0 and c["peak_mib"] > 50
            direct = name != "amg"
            assert c["ran"] == ("splu" if direct else "amg"), name
            assert (c["fill"] is not None and c["fill"] >= 1.0) is direct, name
            assert (c["krylov_iterations"] >= c["newton_steps"]) is not direct, name
    ratio = case["auto_over_best"]
    assert ratio["ratio"] >= 1.0 and ratio["best"] in runs and ratio["cycles"] == 3
    assert "auto / best" in capsys.readouterr().out
