"""python benchmarks/hertz_table.py: the table, its JSON and its refusals."""

import json

import pytest

from benchmarks import hertz_table


def test_table_and_json(tmp_path, capsys):
    out = tmp_path / "h.json"
    assert hertz_table.main(["--levels", "0..1", "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert [r["level"] for r in rows] == [0, 1]
    assert rows[1]["rates"]["a"] is not None
    assert abs(rows[1]["errors"]["p0"]) < abs(rows[0]["errors"]["p0"])
    assert "a/a_ref-1" in capsys.readouterr().out


@pytest.mark.parametrize("args", [["--levels", "x..2"], ["--levels", "3..1"], ["--radius", "0"]])
def test_bad_input_exits_2(args, capsys):
    with pytest.raises(SystemExit) as err:
        hertz_table.main(args)
    assert err.value.code == 2
    assert "expected" in capsys.readouterr().err
