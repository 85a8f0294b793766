"""Unilateral contact in piezo_contact (law = "unilateral"): a piezoelectric block on a rigid
foundation at an initial gap, with contact-only Tresca or Coulomb friction.

The checks read the solution through the nodal fields and the scene's own data (the gap field,
the bottom face y = 0 with outward normal (0, −1)), not through the constraint rows: with
ends = "keep" the dual mortar rows of a rigid foundation are nodal (D diagonal), so each node of
Γ3 must satisfy u_y ≥ −gap(x), λ_n ≥ 0, λ_n (u_y + gap) = 0 and |λ_t| ≤ its friction radius.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from problems.errors import SceneError
from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from vi_core import solve

TOL = 1e-9  # relative defect of a condition (rows solved to 1e-12)


def _model(overrides, level=0):
    base = ["contact.law='unilateral'", "contact.ends='keep'"]
    return pc.build(load_scene("rigid_foundation", base + list(overrides)), level)


def _solve(model, method="ssn", **options):
    sol = solve(model.vi, method, tol=1e-12, **options)
    assert sol.converged, (sol.history, sol.warnings)
    return sol


def _defects(model, sol, gap_fun, radius):
    """Relative defects of the unilateral conditions at the nodes of Γ3 (module docstring);
    `radius(lam_n)` is the friction radius the law allows."""
    c = model.contact
    u = pc.fields(model, sol)["block.displacement"][c.tr.nodes]  # (N, 2)
    x, y = model.bodies[0].mesh.points[c.tr.nodes].T
    lam_n = np.zeros(c.tr.size)
    lam_n[c.rows_n] = c.normal(sol.lam)
    lam_t = np.zeros(c.tr.size)
    lam_t[c.rows_t] = c.tangential(sol.lam)
    free = np.zeros(c.tr.size, dtype=bool)
    free[c.rows_n] = True
    room = u[:, 1] + gap_fun(x, y)  # (N,) remaining gap (foundation at y = −gap)
    d = max(float(np.abs(u).max()), float(np.abs(gap_fun(x, y)).max()), 1e-300)
    # pressure scale: the largest λ_n, or the stress of the largest displacement over the
    # block's height 1 m (when nothing touches λ_n is rounding of that size)
    p = max(float(np.abs(lam_n).max()), float(model.bodies[0].material.C[0, 0]) * d, 1e-300)
    return {
        "penetration": float(max(-room[free].min(), 0.0)) / d,
        "sign": float(max(-lam_n.min(), 0.0)) / p,
        "complementarity": float(np.abs(lam_n * room)[free].max()) / max(p * d, 1e-300),
        "friction": float(max((np.abs(lam_t) - radius(lam_n))[free].max(), 0.0)) / p,
    }


def _const(v):
    return lambda x, y: np.full_like(x, v)


LOADS = st.tuples(st.floats(-3e-4, 3e-4), st.floats(-3e-4, 1e-4))


@settings(max_examples=8)
@given(load=LOADS, gap_exp=st.integers(-7, -2), g=st.sampled_from([0.0, 3e6, 9e6, 1e9]))
def test_unilateral_tresca_conditions_hold_node_by_node(load, gap_exp, g):
    gap = 10.0**gap_exp
    disp = f"bodies.block.displacement=[{{boundary='top', value=[{load[0]!r}, {load[1]!r}]}}]"
    model = _model([disp, f"contact.gap={gap!r}", f"contact.g={g!r}"])
    sol = _solve(model)
    tresca = lambda lam_n: g * (lam_n > 1e-9 * max(lam_n.max(), 1e-300))  # noqa: E731
    bad = {k: v for k, v in _defects(model, sol, _const(gap), tresca).items() if v > TOL}
    assert not bad, bad


@settings(max_examples=6)
@given(load=LOADS, F=st.sampled_from([0.0, 0.1, 0.3, 1.0]))
def test_unilateral_coulomb_conditions_hold_node_by_node(load, F):
    disp = f"bodies.block.displacement=[{{boundary='top', value=[{load[0]!r}, {load[1]!r}]}}]"
    scene = load_scene("rigid_foundation", [disp, "contact.ends='keep'"])
    ct = scene.data["contact"]
    del ct["g"]
    ct.update(law="unilateral", friction="coulomb", F=F)
    model = pc.build(scene, 0)
    sol = _solve(model)
    bad = {k: v for k, v in _defects(model, sol, _const(0.0), lambda ln: F * ln).items() if v > TOL}
    assert not bad, bad


def test_a_flipped_gap_sign_is_caught():
    # mutation: the rows get −gap (the foundation above the face): pressure where apart
    model = _model(["contact.gap=1e-5"])
    c = model.contact
    model.vi.gap[c.idx_n] -= 2 * c.gap0
    sol = _solve(model)
    tresca = lambda lam_n: 9e6 * (lam_n > 0)  # noqa: E731
    assert _defects(model, sol, _const(1e-5), tresca)["complementarity"] > 1e-3


def test_dropping_the_unilateral_sign_is_caught():
    # mutation: bilateral rows with the unilateral data: λ_n < 0 where the block lifts off
    model = pc.build(load_scene("rigid_foundation", ["contact.ends='keep'"]), 0)
    sol = _solve(model)
    d = _defects(model, sol, _const(0.0), lambda ln: 9e6 + 0 * ln)
    assert d["sign"] > 1e-3


def test_far_foundation_leaves_the_block_free():
    # gap far beyond the displacements: no node touches, λ = 0, u as without contact
    model = _model(["contact.gap=1.0"])
    sol = _solve(model)
    stress = float(model.bodies[0].material.C[0, 0]) * 2e-4  # of the prescribed displacement
    assert np.abs(sol.lam).max() <= 1e-12 * stress  # rounding
    free_scene = load_scene("rigid_foundation")
    del free_scene.data["contact"]
    free = pc.build(free_scene, 0)
    ref = _solve(free)
    a = pc.fields(model, sol)["block.displacement"]
    b = pc.fields(free, ref)["block.displacement"]
    assert np.linalg.norm(a - b) <= 1e-10 * np.linalg.norm(b)
    st_ = pc.contact_state(model, sol)
    assert not st_["touch"].any()


@settings(max_examples=6)
@given(load=st.tuples(st.floats(-2e-4, 2e-4), st.floats(-3e-3, -1e-3)))
def test_pressed_hard_unilateral_equals_bilateral(load):
    # every node in compression in the bilateral answer ⇒ the unilateral answer is the same
    disp = f"bodies.block.displacement=[{{boundary='top', value=[{load[0]!r}, {load[1]!r}]}}]"
    bi = pc.build(load_scene("rigid_foundation", [disp]), 0)
    s_bi = _solve(bi)
    assert (bi.contact.normal(s_bi.lam) > 0).all()  # the premise
    uni = pc.build(load_scene("rigid_foundation", [disp, "contact.law='unilateral'"]), 0)
    s_uni = _solve(uni)
    a, b = pc.fields(uni, s_uni)["block.displacement"], pc.fields(bi, s_bi)["block.displacement"]
    assert np.linalg.norm(a - b) <= 1e-9 * np.linalg.norm(b)


def test_lemma_4_2_holds_for_unilateral_laws():
    model = _model(["contact.gap='1e-5*(x-1)**2'"], level=1)
    sol = _solve(model)
    st_ = pc.contact_state(model, sol)
    assert st_["lemma_4_2"] < 1e-10 and (~st_["touch"]).any() and st_["touch"].any()


@pytest.mark.parametrize(
    "edit,field",
    [
        ({"friction": "coulomb", "F": 0.3}, "contact.g"),  # g and F together
        ({"friction": "coulomb", "F": 0.3, "g": None}, "contact.friction"),  # bilateral Coulomb
        ({"gap": 1e-3}, "contact.gap"),  # a gap with bilateral contact
        ({"law": "unilateral", "gap": -1.0}, "contact.gap"),
        ({"law": "unilateral", "friction": "coulomb", "g": None}, "contact.F"),
    ],
)
def test_contact_law_options_are_checked(edit, field):
    scene = load_scene("rigid_foundation")
    ct = scene.data["contact"]
    for k, v in edit.items():
        if v is None:
            del ct[k]
        else:
            ct[k] = v
    with pytest.raises(SceneError, match=field.replace(".", r"\.")):
        pc.build(scene, 0)


GAP2 = 1e-4  # two bodies: the block starts this far above the base


def _two_bodies(push: float, friction_g: float = 1e5, lift: float = GAP2):
    """shear_strip_two_body made unilateral: matching meshes (8 cells on both sides of the
    interface, so the mortar rows are nodal), the block lifted by `lift`, its top pushed down by
    `push` and sideways by push/4, the base clamped at its bottom, no side conditions."""
    from problems.scene.exact import split_exact

    scene, _ = split_exact(load_scene("shear_strip_two_body"))
    d = scene.data
    block, base = d["bodies"]["block"], d["bodies"]["base"]
    block["geometry"]["y"] = [lift, 1.0 + lift]
    base["geometry"]["cells"] = [8, 2]
    block["displacement"] = [{"boundary": "top", "value": [push / 4, -push]}]
    base["displacement"] = [{"boundary": "bottom", "value": [0.0, 0.0]}]
    d["contact"].update(law="unilateral", g=friction_g, ends="keep")
    return pc.build(scene, 0)


@pytest.mark.parametrize("push", [0.5 * GAP2, 0.99 * GAP2, 3 * GAP2, 20 * GAP2])
def test_two_bodies_start_apart_and_close(push):
    model = _two_bodies(push)
    c = model.contact
    np.testing.assert_allclose(c.gap0 / c.W_n[c.rows_n], GAP2, rtol=1e-12)  # the geometry's gap
    sol = _solve(model)
    f = pc.fields(model, sol)
    us = f["block.displacement"][c.tr.nodes]  # (N, 2) slave trace
    mesh_m = model.bodies[1].mesh
    top = np.flatnonzero(np.isclose(mesh_m.points[:, 1], 0.0))
    xs = model.bodies[0].mesh.points[c.tr.nodes, 0]
    um = np.interp(xs, mesh_m.points[top, 0], f["base.displacement"][top, 1])  # (N,)
    room = GAP2 + us[:, 1] - um  # remaining gap at each slave node
    lam_n = np.zeros(c.tr.size)
    lam_n[c.rows_n] = c.normal(sol.lam)
    p = max(float(lam_n.max()), 2.6e9 * push)  # or the stress of the push (E = 2.6e9 Pa)
    carrying = np.zeros(c.tr.size, dtype=bool)
    carrying[c.rows_n] = True
    assert room[carrying].min() >= -1e-10 * push
    assert (lam_n >= -1e-10 * p).all()
    assert np.abs(lam_n * room)[carrying].max() <= 1e-9 * p * push
    touching = pc.contact_state(model, sol)["touch"]
    if push < GAP2:  # never reaches the base
        assert not touching.any() and room.min() > 0
    else:
        assert touching.all()


def test_two_bodies_that_overlap_are_refused():
    with pytest.raises(SceneError, match="overlap"):
        _two_bodies(GAP2, lift=-0.2)


def test_a_roller_across_a_unilateral_contact_is_refused():
    scene = load_scene("shear_strip_two_body", ["contact.law='unilateral'"])
    with pytest.raises(SceneError, match="contact.law.*roller across"):
        pc.build(scene, 0)
