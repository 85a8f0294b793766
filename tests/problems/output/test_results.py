"""Results as data: every file a contact solve writes, read back (meshio, csv, json, XML)."""

import csv
import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from problems.commands.main import main
from problems.output.results import STATES, symmetric_tensor, von_mises
from problems.plugins import piezo_contact as pc
from problems.plugins.body_output import body_fields
from problems.scene import load_scene
from vi_core import solve


def _solve_cli(tmp_path, scene, *extra):
    out = tmp_path / scene
    assert main(["solve", scene, "--level", "0", "--out", str(out), *extra]) == 0
    return out


def _csv(path):
    lines = path.read_text().splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    rows = list(csv.DictReader(ln for ln in lines if not ln.startswith("#")))
    return comments, rows


@pytest.fixture(scope="module")
def rigid(tmp_path_factory):
    return _solve_cli(tmp_path_factory.mktemp("rf"), "rigid_foundation")


def test_every_written_file_reads_back(rigid):
    summary = json.loads((rigid / "summary.json").read_text())
    for fn in summary["files"]:
        assert (rigid / fn).is_file(), fn
    block = meshio.read(rigid / "block.vtu")
    n, nc = len(block.points), len(block.cells[0].data)
    assert block.point_data["displacement"].shape == (n, 3)
    assert block.point_data["electric_potential"].shape == (n,)
    cd = {k: v[0] for k, v in block.cell_data.items()}
    assert cd["stress"].shape == (nc, 6)  # XX YY ZZ XY YZ XZ
    assert np.isfinite(cd["stress"]).all() and not cd["stress"][:, 4:].any()
    assert cd["von_mises"].shape == (nc,)
    assert cd["electric_field"].shape == (nc, 3) and cd["electric_displacement"].shape == (nc, 3)
    line = meshio.read(rigid / "contact.vtu")
    assert line.cells[0].type == "line"
    k = len(line.points)
    assert k == summary["contact"]["nodes"]
    for name in ("lambda_n", "lambda_t", "jump_t", "state"):
        assert line.point_data[name].shape == (k,)
    root = ET.parse(rigid / "results.pvd").getroot()
    files = [d.get("file") for d in root.iter("DataSet")]
    assert files == ["block.vtu", "contact.vtu"]
    for f in files:
        meshio.read(rigid / f)


def test_contact_csv_matches_the_summary_and_the_vtu(rigid):
    summary = json.loads((rigid / "summary.json").read_text())
    comments, rows = _csv(rigid / "contact.csv")
    assert list(rows[0]) == [
        "x",
        "y",
        "normal_x",
        "normal_y",
        "lambda_n",
        "lambda_t",
        "jump_t",
        "state",
    ]
    assert any("lambda_n [Pa]" in c for c in comments) and any("x [m]" in c for c in comments)
    table = summary["contact"]["table"]
    assert len(rows) == len(table) == summary["contact"]["nodes"]
    for r, t in zip(rows, table, strict=True):
        assert r["state"] == t["state"] and r["state"] in STATES
        assert float(r["lambda_t"]) == t["lambda_t"]  # the csv keeps every digit
    line = meshio.read(rigid / "contact.vtu")
    np.testing.assert_array_equal(line.point_data["lambda_n"], [t["lambda_n"] for t in table])
    c = summary["contact"]
    assert c["stick"] == c["counts"]["stick"] and c["slip"] == c["counts"]["slip"]
    assert c["stick_length"] + c["slip_length"] == pytest.approx(2.0)  # the block's width


def test_the_total_contact_force_is_the_force_balance_s(rigid):
    """Σ_k W_k λ_k (nodal) against ∫λ_h ds by Gauss quadrature in piezo_balance: two ways."""
    summary = json.loads((rigid / "summary.json").read_text())
    total = np.array(summary["contact"]["force_on_slave"])
    balance = np.array(summary["force_balance"]["bodies"]["block"]["contact"])
    np.testing.assert_allclose(total, balance, rtol=1e-12)
    assert total[1] > 0  # the foundation pushes the block up


def test_mutation_a_flipped_tangent_in_the_totals_is_caught(monkeypatch):
    model = pc.build(load_scene("rigid_foundation"), 0)
    sol = solve(model.vi, "ssn", tol=1e-12)
    table = pc.contact_table(model, sol)
    good = np.array(table.totals()["force_on_slave"])
    flipped = type(table)(**{**table.__dict__, "lambda_t": -table.lambda_t})
    assert not np.allclose(np.array(flipped.totals()["force_on_slave"]), good, rtol=1e-6)


def test_sigma_zz_of_an_isotropic_body_is_nu_times_the_in_plane_trace():
    """Plane strain, isotropic: σ_zz = ν(σ_xx + σ_yy), independent of how C_zz is stored."""
    model = pc.build(load_scene("paper_two_body"), 0)
    sol = solve(model.vi, "ssn", tol=1e-12)
    disc = model.bodies[0]
    x = model.full(sol.u)[disc.offset : disc.offset + disc.size]
    _, cell, note = body_fields(disc, x)
    s = cell["stress"]
    assert note is None
    np.testing.assert_allclose(s[:, 2], 0.3 * (s[:, 0] + s[:, 1]), rtol=1e-10, atol=1e-6)


def test_mutation_a_wrong_sigma_zz_row_is_caught(monkeypatch):
    model = pc.build(load_scene("paper_two_body"), 0)
    sol = solve(model.vi, "ssn", tol=1e-12)
    disc = model.bodies[0]
    m = disc.material
    monkeypatch.setattr(disc, "material", type(m)(m.name, m.C, C_zz=m.C[0]))  # c11, not λ
    x = model.full(sol.u)[disc.offset : disc.offset + disc.size]
    s = body_fields(disc, x)[1]["stress"]
    assert not np.allclose(s[:, 2], 0.3 * (s[:, 0] + s[:, 1]), rtol=1e-10, atol=1e-6)


def test_a_material_without_full_constants_omits_sigma_zz_and_says_why(tmp_path):
    C = [[1.5e11, 6.6e10, 0.0], [6.6e10, 1.46e11, 0.0], [0.0, 0.0, 4.4e10]]
    e = [[0.0, 0.0, 11.4], [-4.35, 17.5, 0.0]]
    kappa = [[9.87e-9, 0.0], [0.0, 1.116e-8]]
    mat = f"bodies.block.material={{kind='piezoelectric', C={C}, e={e}, kappa={kappa}}}"
    out = tmp_path / "user"
    args = ["--set", mat]
    assert main(["solve", "rigid_foundation", "--level", "0", "--out", str(out), *args]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert any("sigma_zz" in n and "in-plane" in n for n in summary["notes"])
    cd = {k: v[0] for k, v in meshio.read(out / "block.vtu").cell_data.items()}
    assert np.isnan(cd["stress"][:, 2]).all() and np.isfinite(cd["stress"][:, [0, 1, 3]]).all()
    assert "von_mises" not in cd


def test_unilateral_contact_writes_the_gap_and_open_nodes(tmp_path):
    out = _solve_cli(tmp_path, "signorini")
    _, rows = _csv(out / "contact.csv")
    assert "gap" in rows[0]
    states = {r["state"] for r in rows}
    assert "open" in states and states <= {"stick", "slip", "open"}
    for r in rows:
        assert (float(r["gap"]) > 0) == (r["state"] == "open")
    line = meshio.read(out / "contact.vtu")
    assert line.point_data["gap"].shape == (len(rows),)


def test_von_mises_of_uniaxial_tension_and_pure_shear():
    one, zero = np.ones(1), np.zeros(1)
    assert von_mises(one, zero, zero, zero)[0] == pytest.approx(1.0)
    assert von_mises(zero, zero, zero, one)[0] == pytest.approx(np.sqrt(3.0))
    assert von_mises(one, one, one, zero)[0] == pytest.approx(0.0)  # hydrostatic
    t = symmetric_tensor(np.array([1.0]), np.array([2.0]), np.array([3.0]), np.array([4.0]))
    np.testing.assert_array_equal(t, [[1, 2, 3, 4, 0, 0]])
