"""`mixvi check` compares the contact states of its answers node by node (issue 29): a
touch/open or stick/slip contradiction fails the check with a line naming the node count and
the states; a node ambiguous in either answer is counted, never a disagreement; `--json`
records the comparison. The faults it must catch are injected into the answers' states, and
mutations of the comparison (states not compared, a label ignored, the ambiguity rule dropped)
must each let a case through or fail a good one."""

from __future__ import annotations

import json

import numpy as np
import pytest

from problems.commands import check
from problems.commands.main import main
from problems.plugins.contact import plane as pc
from vi_core import states as node_states

SCENE = "piezo_coulomb_strip"  # every base node slips (its closed form)


def _states_of_fixed_point(monkeypatch, new: str, count: int = 3) -> None:
    """The fault: the fixed point's answer reports `new` at its first `count` nodes."""
    real = pc.contact_state

    def faulty(model, sol):
        st = real(model, sol)
        if sol.method == "fixed_point":
            st["state"] = np.asarray(st["state"], dtype=object).copy()
            st["state"][:count] = new
        return st

    monkeypatch.setattr(pc, "contact_state", faulty)


def _check(tmp_path, capsys) -> tuple[int, dict, str]:
    out = tmp_path / "check.json"
    rc = main(["check", SCENE, "--level", "0", "--json", str(out)])
    return rc, json.loads(out.read_text())["records"][0], capsys.readouterr().out


def _caught(tmp_path, capsys, monkeypatch) -> tuple[bool, bool]:
    """(a stick/slip flip fails the check, an ambiguous node passes it)."""
    with monkeypatch.context() as m:
        _states_of_fixed_point(m, "stick")
        rc_flip, _, _ = _check(tmp_path, capsys)
    with monkeypatch.context() as m:
        _states_of_fixed_point(m, "ambiguous")
        rc_amb, _, _ = _check(tmp_path, capsys)
    return rc_flip == 1, rc_amb == 0


def test_agreeing_states_are_recorded(tmp_path, capsys):
    rc, rec, text = _check(tmp_path, capsys)
    assert rc == 0, text
    (pair,) = rec["pairs"]
    n = pair["states"]["nodes"]
    assert n > 0 and pair["states"] == {"nodes": n, "agree": n, "ambiguous": 0, "disagree": 0,
                                        "disagree_nodes": []}  # fmt: skip
    assert all(m["states"] == {"slip": n} for m in rec["methods"].values())
    assert f"states ssn / fixed_point: {n} nodes, agree {n}, ambiguous 0, disagree 0" in text


def test_a_stick_slip_contradiction_fails_the_check(tmp_path, capsys, monkeypatch):
    _states_of_fixed_point(monkeypatch, "stick")
    rc, rec, text = _check(tmp_path, capsys)
    assert rc == 1 and not rec["ok"]
    assert rec["pairs"][0]["states"]["disagree"] == 3
    assert rec["pairs"][0]["states"]["disagree_nodes"] == [0, 1, 2]
    line = (
        "ssn / fixed_point: contact states disagree at 3 node(s) (ssn slip / fixed_point stick at 3"
    )
    assert line in text and line in " ".join(rec["failures"])


def test_a_touch_open_contradiction_fails_the_check(tmp_path, capsys, monkeypatch):
    _states_of_fixed_point(monkeypatch, "open", count=1)
    rc, rec, text = _check(tmp_path, capsys)
    assert rc == 1 and "(ssn slip / fixed_point open at 1" in text


def test_an_ambiguous_node_is_counted_not_a_disagreement(tmp_path, capsys, monkeypatch):
    _states_of_fixed_point(monkeypatch, "ambiguous")
    rc, rec, text = _check(tmp_path, capsys)
    assert rc == 0, text
    assert rec["pairs"][0]["states"]["ambiguous"] == 3
    assert rec["pairs"][0]["states"]["disagree"] == 0


# ------------------------------------------------------------------ mutations of the comparison
def _only_u_lam(plugin, model, sol):
    return None  # states never compared: u and λ only


def _ignore_stick(a, b):
    a, b = (np.where(np.asarray(x, dtype=object) == "stick", "ambiguous", x) for x in (a, b))
    return REAL_COMPARE(a, b)


def _no_ambiguity_rule(a, b):
    a, b = np.asarray(a, dtype=object), np.asarray(b, dtype=object)
    bad = a != b
    nodes = [int(i) for i in np.flatnonzero(bad)]
    return {"nodes": int(a.size), "agree": int(np.sum(~bad)), "ambiguous": 0,
            "disagree": int(np.sum(bad)), "disagree_nodes": nodes}  # fmt: skip


REAL_COMPARE = node_states.compare


@pytest.mark.parametrize(
    "target,mutant",
    [("_states", _only_u_lam), ("compare", _ignore_stick), ("compare", _no_ambiguity_rule)],
)
def test_mutations_of_the_comparison_are_caught(tmp_path, capsys, monkeypatch, target, mutant):
    assert _caught(tmp_path, capsys, monkeypatch) == (True, True)  # the real comparison
    if target == "_states":
        monkeypatch.setattr(check, "_states", mutant)
    else:
        monkeypatch.setattr(node_states, "compare", mutant)
    assert _caught(tmp_path, capsys, monkeypatch) != (True, True)
