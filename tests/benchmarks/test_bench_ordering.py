"""`python benchmarks/bench_ordering.py`: the JSON contract on a small level."""

import json

from benchmarks.bench_ordering import main


def test_bench_ordering_writes_each_variant_and_solve(tmp_path, capsys):
    out = tmp_path / "o.json"
    variants = "MMD_AT_PLUS_A sym 0.1,COLAMD"
    assert main(["rigid_foundation@1", "--variants", variants, "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    (case,) = data["cases"]
    assert case["level"] == 1 and case["n"] > 0 and case["nnz"] > case["n"]
    assert [r["variant"] for r in case["factorisations"]] == variants.split(",")
    for r in case["factorisations"]:
        assert r["fill"] >= 1.0 and r["residual"] < 1e-10
    solves = {r["linear_solver"]: r for r in case["solves"]}
    assert set(solves) == {"auto", "splu", "amg"}
    assert solves["auto"]["chosen"] == "splu" and solves["auto"]["converged"]
    assert solves["splu"]["factor_fill"] and solves["amg"]["chosen"] == "amg"
    assert "fill" in capsys.readouterr().out
