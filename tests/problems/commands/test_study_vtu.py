"""`mixvi study --vtu`: each level's results and one ParaView collection per solver."""

import csv
import xml.etree.ElementTree as ET

import meshio
import pytest

from problems.commands.main import main


def _rows(path):
    return list(csv.DictReader(ln for ln in path.read_text().splitlines() if ln[:1] != "#"))


def test_study_vtu_writes_a_collection_per_solver_over_the_levels(tmp_path):
    out = tmp_path / "study"
    argv = ["study", "rigid_foundation", "--levels", "0..1", "--solvers", "ssn"]
    argv += ["--tols", "1e-6,1e-10", "--vtu", "--no-progress", "--out", str(out)]
    assert main(argv) == 0
    steps = [
        (d.get("timestep"), d.get("part"), d.get("file"))
        for d in ET.parse(out / "ssn.pvd").getroot().iter("DataSet")
    ]
    assert steps == [
        ("0.0", "0", "ssn/level_0/block.vtu"),
        ("0.0", "1", "ssn/level_0/contact.vtu"),
        ("1.0", "0", "ssn/level_1/block.vtu"),
        ("1.0", "1", "ssn/level_1/contact.vtu"),
    ]
    for _, _, f in steps:
        assert len(meshio.read(out / f).points) > 0
    # the level-1 result is the tightest tolerance's: the same as a plain solve of level 1
    solo = tmp_path / "solo"
    assert main(["solve", "rigid_foundation", "--level", "1", "--cold", "--out", str(solo)]) == 0
    a, b = _rows(out / "ssn" / "level_1" / "contact.csv"), _rows(solo / "contact.csv")
    assert [r["state"] for r in a] == [r["state"] for r in b]
    for ra, rb in zip(a, b, strict=True):
        assert float(ra["lambda_t"]) == pytest.approx(float(rb["lambda_t"]), rel=1e-8, abs=1e-2)


def test_without_vtu_the_study_writes_no_results_per_level(tmp_path):
    out = tmp_path / "study"
    argv = ["study", "rigid_foundation", "--levels", "0..0", "--solvers", "ssn", "--tols", "1e-8"]
    assert main([*argv, "--no-progress", "--out", str(out)]) == 0
    assert not (out / "ssn.pvd").exists() and not (out / "ssn").exists()
