"""`python -m problems.commands.bench_ordering`: the JSON contract on a small level."""

import json

from problems.commands.bench_ordering import main


def test_bench_ordering_writes_the_three_orderings(tmp_path, capsys):
    out = tmp_path / "o.json"
    assert main(["paper_two_body", "--level", "1", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["level"] == 1 and data["n"] > 0 and data["nnz"] > data["n"]
    names = [r["ordering"] for r in data["orderings"]]
    assert names == ["COLAMD", "MMD_AT_PLUS_A", "nested dissection"]
    for r in data["orderings"]:
        assert r["fill"] >= 1.0 and r["residual"] < 1e-10
    assert "fill" in capsys.readouterr().out
