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
