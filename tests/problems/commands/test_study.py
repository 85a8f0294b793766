"""`mixvi study`: the study.json contract, rates, atomic output, bad input, level transfer."""

import json

import numpy as np
import pytest

from problems.commands import study
from problems.commands.main import main
from problems.plugins.contact import plane as pc
from problems.scene import load_scene

from .electrical import SCENE, drop_electrical, matches

RECORD_KEYS = {"level", "h", "unknowns", "solver", "tol", "time_s", "iterations", "err"}
ERR_KEYS = {"u_L2", "u_H1", "phi_H1", "phi_L2", "lam"}


@pytest.fixture(scope="module")
def manufactured_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("study") / "man"
    argv = ["manufactured", "--levels", "0..2", "--solvers", "ssn", "--tols", "1e-8,1e-10"]
    code = study.study_main([*argv, "--out", str(out), "--no-progress"])
    return code, out


def test_manufactured_study_writes_the_contract(manufactured_run):
    code, out = manufactured_run
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == [
        ".mixvi-run.json",
        "errors_vs_h.png",
        "errors_vs_time.png",
        "study.json",
    ]
    res = json.loads((out / "study.json").read_text())
    assert res["scene"] == "manufactured" and res["reference"] == "exact"
    assert len(res["records"]) == 3 * 2
    for r in res["records"]:
        assert RECORD_KEYS <= set(r) and set(r["err"]) == ERR_KEYS
        assert r["solver"] == "ssn" and r["tol"] in (1e-8, 1e-10) and r["iterations"] > 0
    assert set(res["rates"]) == {"ssn"} and set(res["rates"]["ssn"]) == ERR_KEYS


def test_rates_are_the_fit_of_the_records(manufactured_run):
    """The rates written are the least-squares slopes of log err against log h of the
    tightest-tolerance records (levels 0–2 here: pre-asymptotic; the README's rates, levels
    2–4, are asserted within 0.1 in test_plugin_conformance.py::test_refinement_rates)."""
    res = json.loads((manufactured_run[1] / "study.json").read_text())
    rates = res["rates"]["ssn"]
    tight = [r for r in res["records"] if r["tol"] == 1e-10]
    h = [r["h"] for r in tight]
    assert h == sorted(h, reverse=True) and h[0] / h[-1] == pytest.approx(4.0)
    for k, v in rates.items():
        e = [r["err"][k] for r in tight]
        assert v == pytest.approx(np.polyfit(np.log(h), np.log(e), 1)[0], rel=1e-12)


def test_reference_mode_measures_against_the_finest_level(tmp_path):
    out = tmp_path / "rf"
    argv = ["rigid_foundation", "--levels", "0..2", "--solvers", "ssn", "--tols", "1e-10"]
    assert study.study_main([*argv, "--out", str(out), "--no-progress"]) == 0
    res = json.loads((out / "study.json").read_text())
    assert res["reference"] == "level 2"
    e = [r["err"]["u_H1"] for r in sorted(res["records"], key=lambda r: r["level"])]
    assert e[0] > e[1] > 0 and e[2] == 0.0  # the finest level is the reference itself


def test_output_is_replaced_atomically_and_never_half_written(tmp_path, monkeypatch):
    out = tmp_path / "o"
    argv = ["manufactured", "--levels", "0", "--solvers", "ssn", "--tols", "1e-8"]
    assert study.study_main([*argv, "--out", str(out), "--no-progress"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def boom(result, path):
        raise RuntimeError("figure failed")

    monkeypatch.setattr("problems.output.study_plots.plot_errors_vs_time", boom)
    with pytest.raises(RuntimeError):
        study.study_main([*argv, "--out", str(out), "--no-progress"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]  # no temporary left behind
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # old output untouched


@pytest.mark.parametrize(
    "args, word",
    [
        (["--levels", "3..1"], "--levels"),
        (["--levels", "a..b"], "--levels"),
        (["--solvers", "ssn,newton"], "--solvers"),
        (["--tols", "0"], "--tols"),
        (["--set", "contact.g=-1"], "contact.g"),
    ],
)
def test_bad_input_exits_2_with_one_message(args, word, tmp_path, capsys):
    out = tmp_path / "never"
    code = main(["study", "manufactured", *args, "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("mixvi: error: ") and word in err[0]
    assert not out.exists()


def test_rates_against_the_finest_level_leave_the_reference_out():
    from problems.commands.study import fit_rates

    recs = [
        {
            "level": k,
            "h": 2.0**-k,
            "solver": "ssn",
            "tol": 1e-10,
            "err": {"u_H1": e, "phi_H1": e, "lam": e},
        }
        for k, e in enumerate([1.0, 0.5, 0.25, 1e-16])  # level 3 is the reference itself
    ]
    assert abs(fit_rates(recs, below=3)["ssn"]["u_H1"] - 1.0) < 1e-12
    assert fit_rates(recs)["ssn"]["u_H1"] > 10  # what the reference level would do to the fit


@pytest.mark.parametrize("fault", [False, True], ids=["coupled", "electrical dropped"])
def test_study_solves_the_electrical_contact_problem(fault, monkeypatch):
    """Each study solve is the scene's coupled problem (the closed form on every level and
    solver); with the electrical condition dropped the answers miss it."""
    if fault:
        drop_electrical(monkeypatch)
    sols = {}
    scene = load_scene(SCENE)
    res = study.run_study(scene, [0, 1], ["ssn", "conic"], [1e-10], progress=False, solutions=sols)
    assert all(r["converged"] for r in res["records"])
    for (level, _, _), sol in sols.items():
        assert matches(pc.build(scene, level), sol) != fault


def test_applicable_solvers_follow_the_multiplier_set():
    from problems.plugins import registry

    for name, want in (("coulomb_strip", ["ssn", "fixed_point"]),
                       ("rigid_foundation", ["ssn", "conic", "homotopy"])):  # fmt: skip
        scene = load_scene(name)
        assert study.applicable(registry.for_scene(scene).build(scene, 0))[0] == want, name


@pytest.mark.slow
def test_a_coulomb_scene_gets_the_solvers_that_can_run_it(tmp_path, capsys):
    """Default: ssn and fixed_point on a Coulomb scene (conic/homotopy rows all failed, exit 1);
    conic asked is refused before anything is solved (exit 2)."""
    out = tmp_path / "c"
    argv = ["coulomb_strip", "--levels", "0", "--tols", "1e-8", "--no-progress"]
    assert study.study_main([*argv, "--out", str(out)]) == 0
    res = json.loads((out / "study.json").read_text())
    assert [r["solver"] for r in res["records"]] == ["ssn", "fixed_point"]
    assert all(r["converged"] for r in res["records"])
    code = main(["study", *argv, "--solvers", "ssn,conic", "--out", str(tmp_path / "n")])
    assert code == 2 and "--solvers = 'conic': one of ssn, fixed_point" in capsys.readouterr().err


def _reference_shown(result: dict) -> list[str]:
    """Where the reference level's records still show: a rate in the table, a point in the
    figures' series."""
    from problems.output.study_plots import _series

    finest = max(r["level"] for r in result["records"])
    found = []
    for line in study.table(result).splitlines():
        cells = line.split()
        if cells[:1] == [str(finest)] and "ref" not in cells:
            found.append(f"table row {line!r}")
    for r in _series(result, "ssn", 1e-10):
        if r["level"] == finest:
            found.append("figure point")
    return found


def test_the_reference_level_is_left_out_of_table_rates_and_figures(tmp_path):
    out = tmp_path / "rf"
    argv = ["rigid_foundation", "--levels", "0..1", "--solvers", "ssn", "--tols", "1e-10"]
    assert study.study_main([*argv, "--out", str(out), "--no-progress"]) == 0
    res = json.loads((out / "study.json").read_text())
    assert [r.get("reference", False) for r in res["records"]] == [False, True]
    assert _reference_shown(res) == []
    for r in res["records"]:  # mutation: the flag dropped shows the reference again
        r.pop("reference", None)
    assert len(_reference_shown(res)) == 2
