"""`mixvi figures`: every panel of the sweep is a solve of the scene's real problem."""

from __future__ import annotations

import pytest

from problems.commands.main import main
from problems.output import plots

from .electrical import SCENE, drop_electrical, matches


@pytest.mark.parametrize("fault", [False, True], ids=["coupled", "electrical dropped"])
def test_figures_panels_solve_the_electrical_contact_problem(fault, tmp_path, monkeypatch):
    """electrical_block swept over g: each panel's answer is the coupled one (the closed form;
    g does not act on the uniaxial state); with the electrical condition dropped it is not."""
    if fault:
        drop_electrical(monkeypatch)
    panels = []
    original = plots.sweep_figure

    def keep(found, *args, **kwargs):
        panels.extend(found)
        return original(found, *args, **kwargs)

    monkeypatch.setattr(plots, "sweep_figure", keep)
    assert main(["figures", SCENE, "--level", "0", "--out", str(tmp_path / "f")]) == 0
    assert len(panels) == 3 and (tmp_path / "f" / "fig_5_4.png").exists()
    for _, model, sol in panels:
        assert matches(model, sol) != fault


@pytest.mark.parametrize("scene", ["coulomb_strip", "coulomb_strip3d"])
def test_a_coulomb_scene_sweeps_its_friction_coefficient(scene, tmp_path, capsys):
    """A Coulomb scene has no bound g (issue 29: figures told the user to set g): the sweep is
    over its coefficient F, one panel per value of F × (1.5, 1, 0.6)."""
    out = tmp_path / "f"
    assert main(["figures", scene, "--level", "0", "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    panels = [ln for ln in lines if ln.startswith("friction coefficient F = ")]
    assert [ln.split(":")[0] for ln in panels] == [
        f"friction coefficient F = {v}" for v in ("0.75", "0.5", "0.3")
    ]
    assert sorted(p.name for p in out.glob("*.png")) == [
        "F_sweep.png" if scene == "coulomb_strip" else "F_sweep3d.png"
    ]


def test_a_coulomb_scene_with_a_field_f_is_told_about_f_not_g(tmp_path, capsys):
    out = tmp_path / "f"
    argv = ["figures", "coulomb_strip", "--level", "0", "--set", 'contact.F="0.3*(1+x)"']
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "contact.F = '0.3*(1+x)': a number" in err[0], err
    assert "--set contact.F=VALUE" in err[0] and "contact.g" not in err[0], err
    assert not out.exists()
