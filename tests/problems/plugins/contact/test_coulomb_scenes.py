"""Coulomb friction and unilateral contact on the shipped scenes (issue 17): the strip's closed
form, Coulomb → Tresca at a known pressure, F → 0 and F → ∞, Newton against the fixed point on
Tresca problems, the stick zone growing with F, lift-off with the voltage, convergence under
refinement — each with a fault that makes it fail."""

from __future__ import annotations

import numpy as np
import pytest

import vi_core
from benchmarks import coulomb_range
from problems.plugins.contact import law as contact_law
from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from vi_core.coulomb import Coulomb

# coulomb_strip (its header): λ_n = (λ + 2μ) d/H, λ_t = F λ_n, u = (s + γ y, −d y/H)
P_N, F_STRIP, MU, DELTA, D = 7.0e5, 0.5, 1.0e9, 1.0e-3, 2.0e-4


def _solve(scene, level, method="ssn", **options):
    model = pc.build(scene, level)
    sol = vi_core.solve(model.vi, method, tol=1e-12, **options)
    assert sol.converged, (sol.history, sol.warnings)
    return model, sol


def _friction(name, friction, value, *overrides):
    """The shipped scene with its friction replaced (g and F cannot be swapped by --set)."""
    scene = load_scene(name, list(overrides))
    ct = scene.data["contact"]
    ct.pop("g", None)
    ct.pop("F", None)
    ct.update(friction=friction, **{"F" if friction == "coulomb" else "g": value})
    return scene


def _strip_errors(model, sol) -> dict[str, float]:
    """Largest relative deviation of λ_n, λ_t and u from the strip's closed form."""
    c = model.contact
    g = F_STRIP * P_N
    u = pc.fields(model, sol)["block.displacement"]  # (N, 2)
    y = model.bodies[0].mesh.points[:, 1]
    exact = np.column_stack([DELTA - g / MU + g / MU * y, -D * y])  # (N, 2)
    return {
        "lam_n": float(np.abs(c.normal(sol.lam) / P_N - 1).max()),
        "lam_t": float(np.abs(c.tangential(sol.lam) / g - 1).max()),
        "u": float(np.abs(u - exact).max() / DELTA),
    }


@pytest.mark.parametrize("level", [0, 1, 2])
def test_strip_matches_the_closed_form(level):
    errs = _strip_errors(*_solve(load_scene("coulomb_strip"), level))
    assert max(errs.values()) <= 1e-9, errs


def test_dropping_the_F_factor_breaks_the_strip(monkeypatch):
    # mutation: the Coulomb radius λ_n instead of F λ_n
    monkeypatch.setattr(contact_law, "Coulomb", lambda F, dim: Coulomb(np.ones_like(F), dim))
    errs = _strip_errors(*_solve(load_scene("coulomb_strip"), 1))
    assert errs["lam_t"] > 0.1


def test_coulomb_is_tresca_with_g_equal_F_lambda_n_when_the_pressure_is_known():
    m_c, s_c = _solve(load_scene("coulomb_strip"), 1)
    m_t, s_t = _solve(_friction("coulomb_strip", "tresca", F_STRIP * P_N), 1)
    np.testing.assert_allclose(s_c.u, s_t.u, rtol=0, atol=1e-12 * np.abs(s_t.u).max())
    np.testing.assert_allclose(s_c.lam, s_t.lam, rtol=0, atol=1e-9 * np.abs(s_t.lam).max())
    # the fixed point reaches the same answer (from the frictionless pressure, which is not
    # uniform: the pressure is uniform only with the friction of the answer)
    fp = vi_core.solve(m_c.vi, "fixed_point", tol=1e-12, inner="ssn")
    assert fp.converged and fp.info["contraction"] < 0.5, fp.info
    np.testing.assert_allclose(fp.lam, s_t.lam, rtol=0, atol=1e-9 * np.abs(s_t.lam).max())


def test_F_to_zero_is_frictionless():
    m0, s0 = _solve(_friction("coulomb_slip", "coulomb", 0.0), 1)
    assert not m0.contact.tangential(s0.lam).any()
    m1, s1 = _solve(_friction("coulomb_slip", "coulomb", 1e-10), 1)
    mt, st = _solve(_friction("coulomb_slip", "tresca", 0.0), 1)
    np.testing.assert_allclose(s0.u, st.u, rtol=0, atol=1e-12 * np.abs(st.u).max())
    assert np.abs(s1.u - s0.u).max() <= 1e-6 * np.abs(s0.u).max()


def test_F_to_infinity_sticks_like_tied_contact():
    m, s = _solve(_friction("coulomb_slip", "coulomb", 1e6), 1)
    st = pc.contact_state(m, s)
    assert st["touch"].all() and not st["slip"].any()
    tied = _friction("coulomb_slip", "tresca", 1e15)
    tied.data["contact"]["law"] = "bilateral"
    mb, sb = _solve(tied, 1)
    assert (mb.contact.normal(sb.lam) > 0).all()  # the premise: pressed everywhere
    np.testing.assert_allclose(s.u, sb.u, rtol=0, atol=1e-10 * np.abs(sb.u).max())


def test_the_stick_zone_grows_with_F():
    counts = []
    for F in (0.05, 0.2, 0.3, 0.4, 0.6):
        m, s = _solve(_friction("coulomb_slip", "coulomb", F), 1)
        st = pc.contact_state(m, s)
        counts.append(int((st["touch_t"] & ~st["slip"]).sum()))
    assert counts == sorted(counts) and counts[0] == 0 and counts[-1] == len(st["slip"]), counts
    assert len(set(counts)) >= 3, counts  # partial stick in between


@pytest.mark.parametrize(
    "scene,F,overrides",
    [
        ("coulomb_slip", 0.1, ()),
        ("coulomb_slip", 0.3, ()),
        ("coulomb_slip", 1.0, ()),
        ("coulomb_strip", 0.5, ()),
        ("piezo_liftoff", 0.3, ()),
        (
            "piezo_liftoff",
            0.3,
            (
                "bodies.block.potential=[{boundary='top', value=700.0}, "
                "{boundary='bottom', value=0.0}]",
            ),
        ),
    ],
)
def test_newton_and_the_fixed_point_agree(scene, F, overrides):
    row = coulomb_range.measure(scene, F, 1, "conic", overrides)
    assert row["verdict"] == "agree", row


def test_a_fixed_point_without_lambda_n_disagrees(monkeypatch):
    # mutation in one path only: the fixed point's Tresca bound F instead of F λ_n
    monkeypatch.setattr(Coulomb, "tresca_bound", lambda self, lam_n: self.F * (lam_n > 0))
    row = coulomb_range.measure("coulomb_slip", 0.3, 1, "ssn")
    assert row["verdict"] != "agree", row


def test_the_voltage_opens_and_closes_contact():
    opened = []
    for v in (-500.0, 0.0, 700.0, 1000.0):
        pot = (
            f"bodies.block.potential=[{{boundary='top', value={v}}}, "
            "{boundary='bottom', value=0.0}]"
        )
        m, s = _solve(load_scene("piezo_liftoff", [pot]), 1)
        opened.append(int((~pc.contact_state(m, s)["touch"]).sum()))
    n = m.contact.rows_n.size
    assert opened[0] == 0 and opened[1] == 0 and 0 < opened[2] < n and opened[3] == n, opened


@pytest.mark.slow
def test_coulomb_slip_converges_under_refinement():
    # ‖u_h − u_ref‖_H¹ against level 4 on levels 0..2: decreasing, fitted rate ≥ 0.7
    scene = load_scene("coulomb_slip")
    ref_m, ref_s = _solve(scene, 4)
    errs, hs = [], []
    for level in (0, 1, 2):
        m, s = _solve(scene, level)
        errs.append(pc.reference_errors(m, s, ref_m, ref_s)["u_H1"])
        hs.append(pc.mesh_size(m))
    rate = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert errs == sorted(errs, reverse=True) and rate >= 0.7, (errs, rate)


# ------------------------------------------------------------------ beyond the range of F
def test_beyond_the_range_each_path_says_not_converged():
    """coulomb_strip at level 1 (docs/coulomb.md, "The upper end of the range"): at F = 30 the
    fixed point stalls (its step ratio stays at 1) while Newton converges; at F = 1e6 Newton
    cycles too. Each path says converged False with its reason — never an answer — and the
    range tool's verdict names the path."""
    row = coulomb_range.measure("coulomb_strip", 30.0, 1, "conic")
    assert row["newton_converged"] and row["verdict"] == "not converged: fixed point", row
    model = pc.build(coulomb_range._scene("coulomb_strip", [], 1e6), 1)
    fp = vi_core.solve(model.vi, "fixed_point", tol=1e-10, inner="conic")
    assert not fp.converged and any("did not shrink" in w for w in fp.warnings), fp.warnings
    newton = vi_core.solve(model.vi, "ssn", tol=1e-10)
    assert not newton.converged and any("did not reach tol" in w for w in newton.warnings)


def test_a_path_claiming_convergence_beyond_the_range_is_caught(monkeypatch):
    """The fault: a solver that calls its last iterate converged. The range tool judges each
    answer by the independent checker, so F = 30 on the strip is still "not converged"."""
    solve = vi_core.solve

    def lying(vi, method="auto", **kw):
        out = solve(vi, method, **kw)
        out.converged = True
        return out

    monkeypatch.setattr(vi_core, "solve", lying)
    row = coulomb_range.measure("coulomb_strip", 30.0, 1, "conic")
    assert row["verdict"] == "not converged: fixed point" and row["fp_residual"] > 1e-3, row


def test_mixvi_says_not_converged_beyond_the_range(tmp_path, capsys):
    """`mixvi solve --cold` at F = 1e6 (Newton cycles) exits 1 with converged false in
    summary.json; `mixvi check` at F = 30 (the fixed point stalls) exits 1."""
    import json

    from problems.commands.main import main

    out = tmp_path / "s"
    rc = main(["solve", "coulomb_strip", "--level", "1", "--cold", "--set", "contact.F=1e6",
               "--out", str(out)])  # fmt: skip
    assert rc == 1 and json.loads((out / "summary.json").read_text())["converged"] is False
    assert "NOT converged" in capsys.readouterr().out
    assert main(["check", "coulomb_strip", "--level", "1", "--set", "contact.F=30.0"]) == 1
    assert "fixed_point failed its own test" in capsys.readouterr().out


@pytest.mark.parametrize("friction", [0.2, 0.9])
def test_fixed_point_states_exact_at_default_tol(tmp_path, friction):
    """Issue 29: the whole base slides (F·λ_n < μδ/H) and the fixed point, at the default
    tolerance, labels every node slip (main's margin-only 1e-9 rule labelled 7 of 15 stick at
    F = 0.2). Mutation: that old rule applied to the same answer mislabels a node."""
    import json

    import numpy as np

    from problems.commands.main import main

    out = tmp_path / "s"
    rc = main(["solve", "coulomb_strip", "--level", "1", "--solver", "fixed_point",
               "--set", f"contact.F={friction}", "--out", str(out)])  # fmt: skip
    assert rc == 0
    c = json.loads((out / "summary.json").read_text())["contact"]
    assert (c["stick"], c["slip"], c["ambiguous"]) == (0, 15, 0)
    rows = [r for r in c["table"] if r["state"] != "no_multiplier"]
    lam_n = np.array([r["lambda_n"] for r in rows])
    lam_t = np.array([r["lambda_t"] for r in rows])
    rho = friction * lam_n
    old_slip = np.abs(lam_t) >= rho - 1e-9 * rho.max()
    assert not old_slip.all()
