"""Results as data: every file a contact solve writes, read back (meshio, csv, json, XML)."""

import csv
import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from problems.commands.main import main
from problems.output.results import STATES, VTK_ORDER, von_mises
from problems.plugins.contact import plane as pc
from problems.plugins.contact.body_output import body_fields
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
    assert files == ["block.vtu", "estimate_block.vtu", "contact.vtu"]  # estimate: error per cell
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
        "g",  # added with the one 2D/3D writer (the friction radius, 3D's column)
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
    def voigt(xx=0.0, yy=0.0, zz=0.0, yz=0.0, xz=0.0, xy=0.0):
        return np.array([[xx, yy, zz, yz, xz, xy]])

    assert von_mises(voigt(xx=1))[0] == pytest.approx(1.0)
    for shear in ("xy", "yz", "xz"):
        assert von_mises(voigt(**{shear: 1}))[0] == pytest.approx(np.sqrt(3.0))
    assert von_mises(voigt(1, 1, 1))[0] == pytest.approx(0.0)  # hydrostatic
    np.testing.assert_array_equal(voigt(1, 2, 3, 5, 6, 4)[:, VTK_ORDER], [[1, 2, 3, 4, 5, 6]])


# ------------------------------------------------------------------ antiplane's friction line
def _antiplane_balance(model, sol):
    """−(load + Dirichlet reactions) on the body: by equilibrium the force the foundation
    exerts, computed from the assembled system at every node (not from the multipliers)."""
    import problems.plugins.antiplane as ap
    from fem import assembly

    spec = model.scene.validated(ap.SCENE_MODEL)
    w = model.full(sol.u)
    F = assembly.volume_load(model.mesh, spec.domain.load, 1)
    for t in spec.traction:
        for part in t.boundary:
            F = F + assembly.boundary_load(model.mesh, part, t.value, 1)
    K = spec.domain.shear_modulus * assembly.stiffness_matrix(model.mesh)
    fixed = np.setdiff1d(np.arange(model.mesh.n_nodes), model.free)
    reaction = float((K @ w - F)[fixed].sum())  # support reaction at the prescribed nodes
    return -(float(F.sum()) + reaction)


@pytest.mark.parametrize("scene", ["antiplane", "antiplane_manufactured"])
def test_antiplane_writes_its_friction_line(tmp_path, scene):
    out = _solve_cli(tmp_path, scene)
    summary = json.loads((out / "summary.json").read_text())
    comments, rows = _csv(out / "contact.csv")
    assert list(rows[0])[:7] == [
        "x",
        "y",
        "normal_x",
        "normal_y",
        "tangent_x",
        "tangent_y",
        "tangent_z",
    ]
    assert list(rows[0])[7:] == ["lambda_t", "jump_t", "state"]  # no normal multiplier
    assert any("lambda_t [Pa]" in c and "e_z" in c for c in comments)
    assert all(float(r["tangent_z"]) == 1.0 for r in rows)
    c = summary["contact"]
    assert len(rows) == len(c["table"]) == c["nodes"] + c["counts"]["no_multiplier"]
    assert c["stick"] + c["slip"] == c["nodes"] and "open" not in c
    assert len(c["force_on_slave"]) == 3 and c["force_on_slave"][:2] == [0.0, 0.0]
    line = meshio.read(out / "contact.vtu")
    assert line.point_data["tangent"].shape == (len(rows), 3)
    assert "lambda_n" not in line.point_data
    files = [d.get("file") for d in ET.parse(out / "results.pvd").getroot().iter("DataSet")]
    assert files == ["antiplane.vtu", "contact.vtu"]


def _antiplane(level=1):
    import problems.plugins.antiplane as ap

    model = ap.build(load_scene("antiplane"), level)
    return ap, model, solve(model.vi, "ssn", tol=1e-12)


def test_antiplane_contact_force_is_the_load_and_reaction_balance():
    """−∫λ ds from the multipliers against equilibrium of the assembled system: two ways."""
    ap, model, sol = _antiplane()
    fz = ap.contact_table(model, sol).totals()["force_on_slave"][2]
    assert fz == pytest.approx(_antiplane_balance(model, sol), rel=1e-10)
    assert fz < 0  # the top is sheared along +z, the foundation holds it back


def test_mutation_antiplane_a_flipped_tangent_breaks_the_balance():
    ap, model, sol = _antiplane()
    table = ap.contact_table(model, sol)
    flipped = type(table)(**{**table.__dict__, "tangents": -table.tangents})
    assert flipped.totals()["force_on_slave"][2] != pytest.approx(
        _antiplane_balance(model, sol), rel=1e-6
    )


def test_mutation_antiplane_dropped_weights_break_the_balance():
    ap, model, sol = _antiplane()
    table = ap.contact_table(model, sol)
    unweighted = type(table)(**{**table.__dict__, "weights": np.ones_like(table.weights)})
    assert unweighted.totals()["force_on_slave"][2] != pytest.approx(
        _antiplane_balance(model, sol), rel=1e-6
    )


# ------------------------------------------------------------------ the .pvd of a nested solve
def test_write_levels_puts_every_level_in_the_collection(tmp_path):
    out = tmp_path / "nested"
    assert (
        main(["solve", "rigid_foundation", "--level", "2", "--write-levels", "--out", str(out)])
        == 0
    )
    steps = [
        (float(d.get("timestep")), d.get("file"))
        for d in ET.parse(out / "results.pvd").getroot().iter("DataSet")
    ]
    assert steps == [
        (0.0, "levels/0/block.vtu"),
        (0.0, "levels/0/contact.vtu"),
        (1.0, "levels/1/block.vtu"),
        (1.0, "levels/1/contact.vtu"),
        (2.0, "block.vtu"),
        (2.0, "estimate_block.vtu"),  # the solved level's error estimate per cell
        (2.0, "contact.vtu"),
    ]
    sizes = [len(meshio.read(out / f).points) for _, f in steps if f.endswith("/block.vtu")]
    sizes.append(len(meshio.read(out / "block.vtu").points))
    assert sizes[0] < sizes[1] < sizes[2]  # each level refines the one before
    # the coarse level written during the nested solve is the level-0 solve on its own
    alone = _solve_cli(tmp_path, "rigid_foundation")
    _, nested0 = _csv(out / "levels" / "0" / "contact.csv")
    _, direct0 = _csv(alone / "contact.csv")
    for a, b in zip(nested0, direct0, strict=True):
        assert a["state"] == b["state"]
        assert float(a["lambda_t"]) == pytest.approx(float(b["lambda_t"]), rel=1e-9, abs=1e-3)
    marker = json.loads((out / ".mixvi-run.json").read_text())
    assert "levels/1/contact.csv" in marker["files"]


def test_without_write_levels_the_collection_holds_the_solved_level(tmp_path):
    out = tmp_path / "plain"
    assert main(["solve", "rigid_foundation", "--level", "1", "--out", str(out)]) == 0
    steps = [d.get("timestep") for d in ET.parse(out / "results.pvd").getroot().iter("DataSet")]
    assert steps == ["1.0", "1.0", "1.0"] and not (out / "levels").exists()
