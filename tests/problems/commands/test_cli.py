"""The `mixvi` command line: outputs of solve, and bad input refused with exit status 2."""

import json

import pytest

from problems.commands.main import main


def test_solve_writes_summary_fields_and_plots(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["solve", "rigid_foundation", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    for key in (
        "scene",
        "level",
        "solver",
        "dofs",
        "converged",
        "iterations",
        "residual",
        "contact",
        "lemma_4_2",
        "lemma_4_2_quadrature",
        "force_balance",
        "time_s",
    ):
        assert key in s, key
    assert set(s["dofs"]) == {"displacement", "potential", "multiplier"}
    assert set(s["contact"]) == {
        "nodes",
        "stick",
        "slip",
        "ambiguous",
        "ambiguous_length",
        "master",
        "mortar_patch_defect",
        "ends",
        "multipliers",
        "crosspoint_nodes",
        "uncovered_nodes",
        "force_on_slave",
        "force_units",
        "stick_length",
        "slip_length",
        "open_length",
        "no_multiplier_length",
        "normal_only_length",
        "counts",
        "table",
    }
    # the rigid foundation has no master side: the patch defect is 0 by construction
    assert s["contact"]["mortar_patch_defect"] == 0.0 and s["contact"]["master"] == "rigid"
    assert s["contact"]["uncovered_nodes"] == s["contact"]["crosspoint_nodes"] == []
    assert set(s["time_s"]) == {"build", "solve", "total"}
    assert s["converged"] and s["residual"] <= 1e-10
    # independent of the contact assembly (problems/plugins/contact/balance.py)
    assert s["lemma_4_2_quadrature"]["gap"] <= 1e-10 and s["force_balance"]["imbalance"] <= 1e-10
    assert s["contact"]["stick"] > 0 and s["contact"]["slip"] > 0
    for f in ("block.vtu", "contact_multiplier.png", "contact_displacement.png", "potential.png"):
        assert (out / f).stat().st_size > 0, f
    assert "  converged in " in capsys.readouterr().out


def test_set_overrides_a_value(tmp_path):
    out = tmp_path / "run"
    assert main(["solve", "rigid_foundation", "--set", "contact.g=1e12", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["contact"]["slip"] == 0


def test_scenes_lists_the_shipped_scenes(capsys):
    assert main(["scenes"]) == 0
    assert "rigid_foundation" in capsys.readouterr().out


BAD = [
    (["--set", "contact.g=-1.0"], "contact.g"),
    (["--set", "contact.g='lots'"], "contact.g"),
    (["--set", "contact.slave='block.bottm'"], "contact.slave"),
    (["--set", "bodies.block.displacement=[]"], "bodies.block.displacement"),
    (["--set", "bodies.block.material={kind='anisotropic', C=[[1,2,0],[2,1,0],[0,0,1]]}"], "C"),
    (
        [
            "--set",
            "bodies.block.material={kind='piezoelectric', C=[[2,1,0],[1,2,0],[0,0,1]], "
            "e=[[0,0,1],[1,1,0]], kappa=[[1,0],[0,-1]]}",
        ],
        "kappa",
    ),
    (["--set", "scene.levle=2"], "did you mean 'level'"),
    (["--set", "contact.g=[1,2]"], "contact.g"),
    (["--solver", "magic"], "--solver"),
]


@pytest.mark.parametrize("extra,needle", BAD)
def test_bad_input_exits_2_with_one_message_and_no_output(tmp_path, capsys, extra, needle):
    out = tmp_path / "run"
    assert main(["solve", "rigid_foundation", "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mixvi: error: ") and err.count("\n") == 1, err
    assert needle in err
    assert "Traceback" not in err
    assert not out.exists()
    assert not any(tmp_path.iterdir())


def test_missing_required_key(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text("[scene]\nplugin = 'contact'\n[bodies.b]\nmaterial = 'BaTiO3'\n")
    assert main(["solve", str(scene), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "bodies.b.geometry" in err and "required" in err


def test_malformed_toml(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text("[scene\n")
    assert main(["solve", str(scene), "--out", str(tmp_path / "o")]) == 2
    assert "valid TOML" in capsys.readouterr().err


@pytest.mark.parametrize(
    "args",
    [
        ["solve", "--level", "-1"],
        ["solve", "--level", "40"],
        ["solve", "--tol", "0"],
        ["solve", "--tol", "-1"],
        ["check", "--levels", "2..1"],
        ["check", "--levels", "0..99"],
        ["figures", "--level", "-2"],
    ],
)
def test_bad_levels_and_tolerances_exit_2(tmp_path, capsys, args):
    with pytest.raises(SystemExit) as exc:  # argparse's own usage errors
        rc = main([*args, "--out", str(tmp_path / "o")] if args[0] != "check" else args)
        raise SystemExit(rc)
    assert exc.value.code == 2
    assert "Traceback" not in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_summary_reports_scales_condition_and_trust_warnings(tmp_path):
    out = tmp_path / "tied"
    assert main(["solve", "rigid_foundation", "--set", "contact.g=1e12", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["scaling"]["s_displacement"] > 0 and s["scaling"]["s_potential"] > 0
    assert s["condition_estimate"] > 1
    assert any("tied" in w for w in s["warnings"])


def test_nearly_incompressible_body_warns_of_locking(tmp_path):
    scene = tmp_path / "nu.toml"
    scene.write_text(
        "[bodies.b]\nmaterial = { kind = 'isotropic', E = 1e10, nu = 0.49 }\n"
        "geometry = { kind = 'rectangle', x = [0.0, 1.0], y = [0.0, 1.0], cells = [4, 4] }\n"
        "[[bodies.b.displacement]]\nboundary = 'top'\nvalue = [1e-4, -1e-4]\n"
        "[contact]\nslave = 'b.bottom'\ng = 1e6\n[scene]\nlevel = 0\n"
    )
    out = tmp_path / "o"
    assert main(["solve", str(scene), "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert any("lock" in w for w in s["warnings"])


def test_accuracy_presets_set_level_and_tolerance(tmp_path):
    out = tmp_path / "fast"
    assert main(["solve", "--accuracy", "fast", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["level"] == 1 and s["tol"] == 1e-6 and s["converged"]
    out2 = tmp_path / "explicit"  # an explicit --level wins over the preset
    assert main(["solve", "--accuracy", "fast", "--level", "0", "--out", str(out2)]) == 0
    assert json.loads((out2 / "summary.json").read_text())["level"] == 0


def test_solve_with_the_amg_linear_solver_reports_it(tmp_path, capsys):
    out = tmp_path / "amg"
    assert (
        main(
            [
                "solve",
                "rigid_foundation",
                "--level",
                "1",
                "--linear-solver",
                "amg",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    s = json.loads((out / "summary.json").read_text())
    assert s["linear_solver"] == "amg" and s["solver_info"]["linear_solver"] == "amg"
    info = s["solver_info"]
    assert len(info["krylov_iterations"]) == s["iterations"] and info["fallback"] == []
    assert "OMP_NUM_THREADS" in info["threads"]
    assert "Krylov iterations per Newton step" in capsys.readouterr().out


def test_unknown_linear_solver_exits_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as err:
        main(["solve", "rigid_foundation", "--linear-solver", "cg", "--out", str(tmp_path)])
    assert err.value.code == 2
    assert "--linear-solver" in capsys.readouterr().err
