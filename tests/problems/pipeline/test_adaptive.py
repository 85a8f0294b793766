"""The adaptive loop (problems.pipeline.adaptive.adapt) and `mixvi solve --accuracy NUMBER`."""

import json
from pathlib import Path

import numpy as np
import pytest

from problems.commands.main import main
from problems.pipeline import adaptive
from problems.plugins.contact import error_estimate as ce
from problems.plugins.contact import plane as pc
from problems.scene import load_scene

SCENES = Path(__file__).resolve().parents[3] / "problems" / "scenes"
OPTIONS = {"method": "ssn", "tol": 1e-10}


class Recording:
    """piezo_contact, with the efficiency index of each cycle's estimate recorded."""

    def __init__(self):
        self.index: list[float] = []

    def __getattr__(self, name):
        return getattr(pc, name)

    def estimate(self, model, sol):
        ind = pc.estimate(model, sol)
        eta = {k: v.eta for k, v in ind.items()}
        self.index.append(ce.efficiency(eta, ce.energy_errors(model, sol)))
        return ind


def _adapt(name: str, accuracy: float, **kw):
    plugin = Recording()
    out = adaptive.adapt(
        plugin, load_scene(SCENES / f"{name}.toml"), accuracy, solve_options=OPTIONS, **kw
    )
    return plugin, *out


def test_loop_reaches_accuracy_with_efficient_estimates():
    """manufactured to 0.5: the estimate falls every cycle, the meshes grow locally (less
    than 4× per cycle), the efficiency index stays in [0.5, 5], the last cycle meets it."""
    plugin, model, sol, cycles, why = _adapt("manufactured", 0.5)
    rel = [c["relative"] for c in cycles]
    assert rel[-1] <= 0.5 < min(rel[:-1]) and "≤ 0.5" in why
    assert np.all(np.diff(rel) < 0)
    n = np.array([c["unknowns"] for c in cycles])
    assert np.all(n[1:] > n[:-1]) and np.all(n[1:] < 4 * n[:-1])
    assert all(0.5 <= i <= 5.0 for i in plugin.index), plugin.index
    assert all(c["errors"]["u_H1"] > 0 for c in cycles)
    assert model.bodies[0].mesh.cell_type == "triangle"


def test_loop_stops_at_the_size_limit():
    _, model, _, cycles, why = _adapt("manufactured", 1e-6, max_unknowns=300)
    assert "300 unknowns" in why and 4 * cycles[-1]["unknowns"] > 300
    assert cycles[-1]["relative"] > 1e-6


@pytest.mark.slow
def test_efficiency_over_adaptive_cycles_curved():
    """curved_manufactured (quadrilaterals split into triangles): the index over 4 cycles."""
    plugin, *_ = _adapt("curved_manufactured", 1e-6, max_cycles=4)
    assert all(0.5 <= i <= 5.0 for i in plugin.index), plugin.index


@pytest.mark.slow
def test_cli_accuracy_number(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["solve", "manufactured", "--accuracy", "0.7", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["reached"] and s["cycles"][-1]["relative"] <= 0.7 and len(s["uniform"]) >= 2
    assert (out / "convergence.png").stat().st_size > 0 and (out / "estimate_block.vtu").exists()
    lines = capsys.readouterr().out.splitlines()
    assert sum(line.strip()[:1].isdigit() for line in lines) == len(s["cycles"])


@pytest.mark.parametrize("value", ["2", "0", "fastest"])
def test_cli_accuracy_refused(tmp_path, capsys, value):
    with pytest.raises(SystemExit) as exit_:
        main(["solve", "manufactured", "--accuracy", value, "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert "--accuracy" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
