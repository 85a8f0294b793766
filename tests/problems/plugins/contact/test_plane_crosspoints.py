"""Contact boundaries that meet Dirichlet sides, coverage, and the mortar patch defect.

The exact solutions are the shipped shear-strip scenes (closed forms in their headers):
u = (s + γy, 0), λ = (λ·n, λ·τ) = (0, g), solved on every variant — clamped and roller corners,
rollers fixing the contact tangent or the normal, both end treatments, rigid foundation and
an elastic base (non-matching, matching, either body the slave).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import fem.mortar as fm
from problems.commands.main import main
from problems.errors import SceneError
from problems.plugins.contact import errors, reports
from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from problems.scene.exact import split_exact
from vi_core import solve

SCENES = Path(pc.__file__).parents[2] / "scenes"
G = 6.0e5  # the scenes' friction bound = the exact tangential multiplier


def _variant(name: str, ends: str, variant: str):
    """A shear-strip scene variant and its exact solution."""
    scene = load_scene(name, [f"contact.ends='{ends}'"])
    bodies = scene.data["bodies"]
    if variant == "roller-x":  # left sides: u_x prescribed (the contact tangent), t_y given
        for b in bodies.values():
            left = next(t for t in b["displacement"] if t["boundary"] == "left")
            left["components"] = "x"
            b["traction"] = [{"boundary": "left", "value": [0.0, -G]}]  # σn, n = (−1, 0)
    if variant == "matching":
        bodies["base"]["geometry"]["cells"] = [8, 2]
    if variant == "base-slave":
        scene.data["contact"].update(slave="base.top", master="block.bottom")
    return split_exact(scene)


def _nodal_error(model, sol, exact) -> float:
    """max |u_h − u| at the nodes / max |u| (each body evaluated on its own side of y = 0)."""
    x = model.full(sol.u)
    err, ref = 0.0, 0.0
    for b in model.bodies:
        u, _ = b.split(x[b.offset : b.offset + b.size])
        P = b.mesh.points
        side = 1.0 if P[:, 1].mean() > 0 else -1.0
        ue = exact.u(P[:, 0], P[:, 1] + side * 1e-300)  # (n, 2); y = ±0 picks the body's side
        err, ref = max(err, np.abs(u - ue).max()), max(ref, np.abs(ue).max())
    return err / ref


CASES = [("shear_strip", v) for v in ("shipped", "roller-x")] + [
    ("shear_strip_two_body", v) for v in ("shipped", "roller-x", "matching", "base-slave")
]
EXACT_CASES = [(*c, "merge") for c in CASES] + [(*c, "keep") for c in CASES if c[1] != "base-slave"]


@pytest.mark.parametrize("name, variant, ends", EXACT_CASES)
def test_shear_strip_is_exact_with_clamped_and_roller_corners(name, variant, ends):
    """Exact (to rounding) with merge everywhere; with keep wherever the master side's shape
    functions are linear over the slave's end segment (rigid base; master as coarse as the
    slave there). The other case is `test_keep_is_first_order_when_the_master_is_finer`."""
    for level in (0, 2):
        scene, exact = _variant(name, ends, variant)
        model = pc.build(scene, level)
        sol = solve(model.vi, "ssn", tol=1e-13)
        assert sol.converged and sol.info["condensed"], sol.history
        c = model.contact
        N = c.tr.size
        n_n, _, n_t = c.sizes
        # corners: clamped drops both, roller-y drops the normal, roller-x the tangential one
        expected = {"shipped": (N - 2, N - 1), "roller-x": (N - 1, N - 1)}
        assert (n_n, n_t) == expected.get(variant, (N - 2, N - 1))
        assert _nodal_error(model, sol, exact) <= 1e-12
        lam_n, lam_t = sol.lam[:n_n], sol.lam[n_n:]
        assert np.abs(lam_n).max() <= 1e-12 * G
        np.testing.assert_allclose(lam_t, G, rtol=1e-12)
        st = pc.contact_state(model, sol)
        assert st["slip"].all() and st["lemma_4_2"] <= 1e-10
        assert c.patch_defect <= 1e-12


def test_keep_is_first_order_when_the_master_is_finer():
    """Slave = the base (5 segments), master = the block (8): with keep, the clamped end's
    dropped dual function leaves Σψ ≠ 1 on the slave's end segment, where the finer master's
    shape functions are not linear — wrong forces on the master, an O(h) error (1.1 % of u at
    level 0, halving per level). Merge is exact (previous test)."""
    errs = []
    for level in (0, 1, 2, 3):
        scene, exact = _variant("shear_strip_two_body", "keep", "base-slave")
        model = pc.build(scene, level)
        sol = solve(model.vi, "ssn", tol=1e-13)
        assert sol.converged and sol.info["condensed"]
        errs.append(_nodal_error(model, sol, exact))
    rate = -np.polyfit(np.arange(4), np.log2(errs), 1)[0]
    assert errs[0] > 1e-3 and 0.98 < rate < 1.02, errs


@pytest.mark.parametrize("name", ["shear_strip", "shear_strip_two_body"])
def test_merge_keeps_the_multiplier_exact_at_a_clamped_end_and_keep_does_not(name):
    """λ as a function of the multiplier basis: merge reproduces λ·τ = g up to the clamped end
    (rounding), keep has λ_h = g ψ_1 ≠ g on the end segment: an O(h) error in the h-weighted
    L² norm of `errors` (the displacements are exact either way)."""
    errs = {}
    for ends in ("merge", "keep"):
        errs[ends] = []
        for level in (0, 1, 2):
            scene, exact = _variant(name, ends, "shipped")
            model = pc.build(scene, level)
            sol = solve(model.vi, "ssn", tol=1e-13)
            e = errors.against(model, sol, exact, pc.contact_state)
            assert e["u_H1"] <= 1e-15  # absolute: ‖u‖_H1 ≈ 1e-3
            errs[ends].append(e["lam"])
    assert max(errs["merge"]) <= 1e-12 * G
    rate = -np.polyfit(np.arange(3), np.log2(errs["keep"]), 1)[0]
    assert min(errs["keep"]) > 1e-3 * G and 0.95 < rate < 1.05, errs["keep"]


def test_keep_and_merge_give_the_same_problem_for_a_zero_clamp_on_a_rigid_base():
    """A clamped corner with u = 0 on a rigid base: the merged neighbour row only adds the
    clamped node's (zero) value, so both treatments solve the same discrete problem."""
    sols = []
    for ends in ("merge", "keep"):
        scene = load_scene("rigid_foundation", [f"contact.ends='{ends}'"])
        scene.data["bodies"]["block"]["displacement"].append(
            {"boundary": "left", "value": [0.0, 0.0]}
        )
        model = pc.build(scene, 1)
        sol = solve(model.vi, "ssn", tol=1e-12)
        assert sol.converged and sol.info["condensed"]
        assert pc.contact_state(model, sol)["lemma_4_2"] <= 1e-10
        sols.append(model.full(sol.u))
    assert np.abs(sols[0] - sols[1]).max() <= 1e-10 * np.abs(sols[0]).max()


@pytest.mark.parametrize("ends", ["merge", "keep"])
def test_clamped_end_on_the_curved_paper_interface(ends):
    """The disc's free arcs clamped: the contact arc's end nodes are crosspoints on a curved
    two-body interface; ssn still condenses (the master nodes next to the crosspoints couple
    to one slave node only: `Condensation.detect` picks among the extra columns), the patch
    defect stays at rounding."""
    scene = load_scene("paper_two_body", [f"contact.ends='{ends}'", "contact.g=2e7"])
    disp = scene.data["bodies"]["disc"]["displacement"]
    disp += [{"boundary": p, "value": [0.0, 0.0]} for p in ("free_left", "free_right")]
    model = pc.build(scene, 1)
    c = model.contact
    assert c.sizes == (c.tr.size - 2, 0, c.tr.size - 2)
    sol = solve(model.vi, "ssn", tol=1e-11)
    assert sol.converged and sol.info["condensed"]
    assert c.patch_defect <= 1e-12
    st = pc.contact_state(model, sol)
    assert st["slip"].sum() > 4 and st["lemma_4_2"] <= 1e-10  # g lowered: some nodes slip
    summary = reports.interface_summary(c)
    assert summary["crosspoint_nodes"] == c.tr.nodes[[0, -1]].tolist()


def _scene_file(tmp_path: Path, name: str, extra: str = "", replace=()) -> str:
    text = (SCENES / f"{name}.toml").read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / f"{name}_variant.toml"
    path.write_text(text + extra)
    return str(path)


def test_roller_at_an_angle_to_the_contact_is_refused_per_node(tmp_path, capsys):
    """u_x prescribed on the disc's free arcs: at the contact arc's ends that direction is
    neither the contact normal nor the tangent — exit 2, each node named, what to do said."""
    extra = "".join(
        f'\n[[bodies.disc.displacement]]\nboundary = "{p}"\ncomponents = "x"\nvalue = [0.0, 0.0]\n'
        for p in ("free_left", "free_right")
    )
    path = _scene_file(tmp_path, "paper_two_body", extra)
    assert main(["solve", path, "--level", "0", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("only u_x is prescribed") == 2 and "50.6° off the contact normal" in err
    assert "clamp these nodes" in err and "contact.slave" in err
    assert not (tmp_path / "o").exists()


def test_fully_clamped_contact_boundary_is_refused():
    scene = load_scene("shear_strip")
    scene.data["bodies"]["block"]["displacement"].append({"boundary": "bottom", "value": [0, 0]})
    with pytest.raises(SceneError, match="every node of this one is clamped"):
        pc.build(scene, 0)


def test_bad_end_treatment_is_refused(capsys):
    assert main(["solve", "shear_strip", "--set", "contact.ends='drop'"]) == 2
    assert "contact.ends" in capsys.readouterr().err


def test_uncovered_slave_nodes_are_left_free_and_reported(tmp_path, capsys):
    """A base covering only x ∈ [0.5, 2] under the block (8 segments of 0.25): the nodes at
    x = 0.25 and 0.5 lack a master behind their whole support (x = 0 is a crosspoint)."""
    path = _scene_file(
        tmp_path,
        "shear_strip_two_body",
        replace=[
            (
                "x = [0.0, 2.0], y = [-0.5, 0.0], cells = [5, 2]",
                "x = [0.5, 2.0], y = [-0.5, 0.0], cells = [5, 2]",
            )
        ],
    )
    out = tmp_path / "o"
    assert main(["solve", path, "--level", "0", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    model = pc.build(load_scene(path), 0)
    P = model.contact.slave.mesh.points
    xs = P[s["contact"]["uncovered_nodes"], 0]
    np.testing.assert_allclose(np.sort(xs), [0.25, 0.5])
    assert P[s["contact"]["crosspoint_nodes"], 0].tolist() == [0.0, 2.0]
    assert s["contact"]["mortar_patch_defect"] <= 1e-12
    assert "no master behind their whole support" in capsys.readouterr().out


def test_nothing_covered_is_refused_naming_the_nodes(tmp_path, capsys):
    """A master part facing the same way as the slave covers nothing: exit 2."""
    path = _scene_file(
        tmp_path,
        "shear_strip_two_body",
        replace=[
            ("y = [-0.5, 0.0], cells = [5, 2]", "y = [0.0, 0.5], cells = [5, 2]"),
            ('master = "base.top"', 'master = "base.bottom"'),
            ('boundary = "bottom"\nvalue = [0.0, 0.0]', 'boundary = "top"\nvalue = [0.0, 0.0]'),
        ],
    )
    assert main(["solve", path, "--level", "0", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "no slave node has the master behind its support" in err and "nodes [" in err


@pytest.mark.parametrize("angle", [0.6, 2.0, 2.8])
def test_paper_scene_at_wide_arcs_through_mixvi_solve(angle, tmp_path):
    out = tmp_path / "o"
    sets = [f"bodies.{b}.geometry.angle={angle}" for b in ("disc", "cradle")]
    args = ["solve", "paper_two_body", "--level", "1", "--out", str(out)]
    assert main(args + sum((["--set", s] for s in sets), [])) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] and s["solver_info"]["condensed"]
    assert s["contact"]["mortar_patch_defect"] <= 1e-12
    assert s["contact"]["uncovered_nodes"] == [] and s["lemma_4_2"] <= 1e-10


def test_patch_defect_above_the_limit_exits_1_unless_allowed(monkeypatch, tmp_path, capsys):
    """Mutation: a dropped master entry. The solve converges, but the defect is reported in
    summary.json and the console, and the exit status is 1 unless --allow-defect."""
    real = fm.mortar_coupling

    def dropped_entry(*args, **kw):
        mo = real(*args, **kw)
        M = mo.M.tolil()
        r, c = mo.M.nonzero()
        M[r[5], c[5]] = 0.0
        return dataclasses.replace(mo, M=M.tocsr())

    monkeypatch.setattr(fm, "mortar_coupling", dropped_entry)
    for extra, rc in (([], 1), (["--allow-defect"], 0)):
        out = tmp_path / f"o{rc}"
        assert main(["solve", "paper_two_body", "--level", "0", "--out", str(out)] + extra) == rc
        s = json.loads((out / "summary.json").read_text())
        assert s["converged"] and s["contact"]["mortar_patch_defect"] > 1e-3
        text = capsys.readouterr().out
        assert "mortar patch defect" in text and "not transferred" in text
        assert ("--allow-defect to accept" in text) == (rc == 1)
