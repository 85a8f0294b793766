"""benchmarks/user_mesh_solvers.py: the JSON contract on a small level, the ratio, the output
rules (a file it did not write is never replaced) and a run killed at its time limit."""

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def bench(monkeypatch):
    """The benchmark module, importable by name (its spawned children import it by name)."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import user_mesh_solvers

    return user_mesh_solvers


def test_every_solver_is_measured_at_level_1(bench, tmp_path, capsys):
    out = tmp_path / "o.json"
    argv = ["actuator_tri", "--levels", "1", "--solvers", "auto,splu-colamd,amg"]
    assert bench.main([*argv, "--out", str(out)]) == 0
    (case,) = json.loads(out.read_text())["cases"]
    assert case["level"] == 1 and case["unknowns"] == 5_222 and case["nnz_A"] > case["unknowns"]
    runs = case["runs"]
    assert list(runs) == ["auto", "splu-colamd", "amg"]
    for name, r in runs.items():
        assert r["converged"] and r["residual"] <= 1e-10, name
        assert len(r["newton_steps"]) == 2 and r["newton_steps"][-1] >= 1, name
        assert r["cpu_s"] > 0 and r["wall_s"] > 0 and r["peak_mib"] > 50, name
    assert runs["auto"]["chosen"] == "splu" and runs["amg"]["chosen"] == "amg"
    assert runs["auto"]["orderings"] == ["MMD_AT_PLUS_A"]  # splu with the shipped ordering
    assert runs["splu-colamd"]["orderings"] == ["COLAMD"]
    for name in ("auto", "splu-colamd"):  # the fine level's: one per Newton step
        assert runs[name]["factorisations"] == runs[name]["newton_steps"][-1], name
        assert runs[name]["factor_n"] > 0 and runs[name]["fill"] >= 1.0, name
        assert runs[name]["krylov_iterations"] == 0, name
    assert runs["amg"]["factorisations"] == 0
    assert runs["amg"]["krylov_iterations"] >= runs["amg"]["newton_steps"][-1]
    ratio = case["auto_over_best"]
    assert ratio["cpu_s"]["ratio"] >= 1.0 and ratio["cpu_s"]["best"] in runs
    assert "auto / best" in capsys.readouterr().out


def test_krylov_iterations_count_every_solve_of_the_electrical_fixed_point(bench, tmp_path):
    """punch_graded's fine level is several ssn solves (its electrical contact fixed point):
    every Newton step on the iterative path takes at least one GMRES iteration."""
    out = tmp_path / "o.json"
    argv = ["punch_graded", "--levels", "0", "--solvers", "amg", "--out", str(out)]
    assert bench.main(argv) == 0
    r = json.loads(out.read_text())["cases"][0]["runs"]["amg"]
    assert r["converged"] and r["newton_steps"][-1] > 1
    assert r["krylov_iterations"] >= r["newton_steps"][-1]


def test_the_ratio_is_auto_over_the_best_converged_run(bench):
    def run(cpu, wall, converged=True):
        return {"cpu_s": cpu, "wall_s": wall, "converged": converged}

    runs = {
        "auto": run(3.0, 9.0),
        "splu": run(1.0, 1.0, converged=False),  # faster, but did not converge
        "amg": run(1.5, 10.0),
        "splu-colamd": {"error": "timed out after 300 s (wall)"},
    }
    r = bench.ratios(runs)
    assert r["cpu_s"] == {"ratio": 2.0, "best": "amg"}
    assert r["wall_s"] == {"ratio": 1.0, "best": "auto"}
    assert bench.ratios({"auto": run(1.0, 1.0, converged=False), "amg": run(1.0, 1.0)}) is None


def test_a_file_it_did_not_write_is_not_replaced(bench, tmp_path, capsys):
    out = tmp_path / "mine.json"
    out.write_text('{"my": "data"}')
    assert bench.main(["actuator_tri", "--levels", "0", "--solvers", "amg", "--out", str(out)]) == 2
    assert out.read_text() == '{"my": "data"}'
    assert "--out" in capsys.readouterr().err


def test_a_run_over_its_time_limit_is_killed_and_recorded(bench, tmp_path):
    out = tmp_path / "o.json"
    argv = ["actuator_tri", "--levels", "0", "--solvers", "splu", "--timeout", "0.5"]
    assert bench.main([*argv, "--out", str(out)]) == 0
    (case,) = json.loads(out.read_text())["cases"]
    assert case["runs"]["splu"]["error"].startswith("timed out after")
    assert case["auto_over_best"] is None


def test_bad_options_exit_2(bench, capsys):
    for argv in (["--solvers", "superlu"], ["--levels", "two"], ["--levels", "-1"]):
        with pytest.raises(SystemExit) as exc:
            bench.main(argv)
        assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--solvers: superlu" in err and "--levels: 'two'" in err and "levels are ≥ 0" in err
