"""The Coulomb benchmark command (benchmarks/bench_coulomb.py): its records, its refusals."""

import json

from benchmarks.bench_coulomb import PROBLEMS, main, run


def test_records_and_range():
    result = run({"general-2d": PROBLEMS["general-2d"]}, seeds=1, Fs=(0.0, 0.3))
    assert [(r["F"], r["seed"]) for r in result["records"]] == [(0.0, 0), (0.3, 0)]
    for r in result["records"]:
        assert r["agree"] and r["newton"]["converged"] and r["fixed_point"]["converged"]
        assert r["newton"]["checker_residual"] <= 1e-9
        assert r["fixed_point"]["checker_residual"] <= 1e-9
    assert result["summary"] == [{"problem": "general-2d", "both_converge_and_agree_up_to_F": 0.3}]


def test_writes_json_once_and_never_over_a_file(tmp_path, capsys):
    path = tmp_path / "coulomb.json"
    argv = ["--problems", "decoupled-2d", "--seeds", "1", "--F", "0,0.5", "--json", str(path)]
    assert main(argv) == 0
    data = json.loads(path.read_text())
    assert len(data["records"]) == 2 and data["F"] == [0.0, 0.5] and data["peak_mem_mb"] > 0
    assert "both paths converge and agree on every seed for F ≤ 0.5" in capsys.readouterr().out
    before = path.read_text()
    assert main(argv) == 2
    assert path.read_text() == before
    assert "the file exists" in capsys.readouterr().err


def test_bad_options_exit_2(capsys):
    assert main(["--F", "x"]) == 2
    assert main(["--F", "-1"]) == 2
    assert main(["--problems", "nope"]) == 2
    assert "allowed: symmetric-2d" in capsys.readouterr().err
