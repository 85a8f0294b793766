"""The paper's two-body example: mortar contact on a curved non-matching interface."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.commands.main import main
from problems.plugins.contact import balance as piezo_balance
from problems.plugins.contact import plane as pc
from problems.plugins.contract import nested_start
from problems.scene import load_scene
from vi_core import solve


def _run(overrides=(), level=1):
    model = pc.build(load_scene("paper_two_body", list(overrides)), level)
    sol = solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged, sol.history
    return model, sol


def _linear(model, rows):
    """Reference: the linear saddle-point problem with equality constraints B[rows] u = gap,
    solved directly (full KKT system, SuperLU) in equilibrated variables — unscaled, entries
    1e11 beside 1e-8 would cost SuperLU about 8 digits."""
    e, s = model.vi.equilibrated, model.vi.scaling
    B = e.B[rows]
    K = sp.bmat([[e.A, B.T], [B, None]], format="csc")
    x = spla.spsolve(K, np.concatenate([e.f, e.gap[rows]]))
    return x[: e.n] * s.s_u


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_paper_scene_stick_in_the_middle_slip_at_the_ends():
    model, sol = _run(level=2)
    st = pc.contact_state(model, sol)
    assert sol.residual <= 1e-10
    slip = st["slip"]
    n = slip.size
    assert slip[0] and slip[-1] and not slip[n // 2]
    # both bodies in equilibrium, computed without the mortar matrices (piezo_balance)
    assert piezo_balance.force_balance(model, sol)["imbalance"] <= 1e-10
    # only the master (cradle) is piezoelectric: the disc has no potential unknowns
    disc, cradle = model.bodies
    assert not disc.has_potential and cradle.has_potential
    assert model.vi.structure == "skew-coupled"


def test_g_zero_is_frictionless_sliding_and_huge_g_is_tied():
    m0, s0 = _run(["contact.g=0.0"])
    N = m0.contact.tr.size
    assert _rel(s0.u, _linear(m0, np.arange(N))) <= 1e-10
    mt, st = _run(["contact.g=1e12"])
    assert pc.contact_state(mt, st)["slip"].sum() == 0
    assert _rel(st.u, _linear(mt, np.arange(2 * N))) <= 1e-10


def test_stick_zone_grows_with_g():
    sticks = []
    for g in (0.6e8, 1.0e8, 1.5e8):
        model, sol = _run([f"contact.g={g}"])
        sticks.append(int((~pc.contact_state(model, sol)["slip"]).sum()))
    assert sticks[0] < sticks[1] < sticks[2]


@pytest.mark.parametrize("level", [0, 1])
def test_check_command_agrees(level, capsys):
    assert main(["check", "--level", str(level)]) == 0
    assert "agree" in capsys.readouterr().out


def test_figures_command(tmp_path):
    assert main(["figures", "--level", "0", "--out", str(tmp_path / "f")]) == 0
    assert (tmp_path / "f" / "fig_5_4.png").stat().st_size > 0


def test_check_over_levels_reports_rho_t0_and_contraction(tmp_path, capsys):
    import json

    out = tmp_path / "check.json"
    assert main(["check", "rigid_foundation", "--levels", "0..1", "--json", str(out)]) == 0
    recs = json.loads(out.read_text())["records"]
    assert [r["level"] for r in recs] == [0, 1]
    for r in recs:
        assert 0 < r["t0_paper"] < 1e-20 < r["rho"] < 1  # (3.11) is very pessimistic here
        # the homotopy contracts at the rate its step was chosen for (within a factor 1.5)
        assert r["contraction_bound"] / 1.5 <= r["contraction_observed"] <= r["contraction_bound"]
    assert "contraction" in capsys.readouterr().out


def test_nested_iteration_keeps_newton_steps_bounded():
    """Warm-starting each level from the coarser one (the CLI's default for ssn): at most
    2 Newton steps per level, and the same solution as a cold start."""
    scene = load_scene("paper_two_body")
    prev = None
    for level in range(4):
        model = pc.build(scene, level)
        kw = nested_start(pc, *prev, model)[0] if prev else {}
        sol = solve(model.vi, "ssn", tol=1e-12, **kw)
        assert sol.converged
        if level > 0:
            assert sol.iterations <= 2, (level, sol.history)
        prev = (model, sol)
    cold = solve(model.vi, "ssn", tol=1e-12)
    assert cold.iterations > 2  # the cold start does need more: the test is not vacuous
    assert _rel(sol.u, cold.u) <= 1e-10 and _rel(sol.lam, cold.lam) <= 1e-10
