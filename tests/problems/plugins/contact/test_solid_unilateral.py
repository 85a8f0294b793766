"""contact3d with law = "unilateral": Coulomb and contact-only Tresca friction discs on a rigid
foundation and between two bodies that start apart (issue 17 in 3D; docs/coulomb.md).

- coulomb_strip3d: the closed form (uniform λ_n = 7e5 Pa, the whole base slides along the
  diagonal ê with |λ_t| = F λ_n = 3.5e5 Pa), by Newton and by the fixed point on Tresca
  problems; Coulomb equals Tresca with g = F λ_n (a separate solve of the Tresca scene).
- block3d_liftoff: open, stick and slip zones at once; Newton and the fixed point agree; the
  a posteriori separation checks (contact3d_checks.separation) hold; Tresca acts only where the
  block touches.
- Fault injection: a wrong sign of the gap, a dropped complementarity row and a wrong scaling
  of F are each reported by the separation check.
"""

from __future__ import annotations

import numpy as np
import pytest

import vi_core
from problems.errors import SceneError
from problems.plugins.contact import checks as contact3d_checks
from problems.plugins.contact import rows, surface_contact
from problems.plugins.contact import solid as contact3d
from problems.scene import SCENES_DIR, load_scene

E_HAT = np.array([0.8, 0.6, 0.0])
LAM_N, LAM_T = 7.0e5, 3.5e5  # coulomb_strip3d's closed form (scene comment)
TOL = 1e-13  # Newton converges quadratically: ask for rounding


def _model(name: str, level: int = 0, *overrides: str):
    return contact3d.build(load_scene(name, list(overrides)), level)


def _tresca(tmp_path, name: str, g: str, level: int = 0):
    """The scene `name` with friction = "tresca" and bound g instead of Coulomb's F."""
    text = (SCENES_DIR / f"{name}.toml").read_text()
    assert 'friction = "coulomb"' in text
    text = text.replace('friction = "coulomb"', 'friction = "tresca"')
    text = "\n".join(f"g = {g}" if ln.startswith("F = ") else ln for ln in text.splitlines())
    path = tmp_path / f"{name}_tresca.toml"
    path.write_text(text)
    return contact3d.build(load_scene(str(path)), level)


def _exact_u(points: np.ndarray) -> np.ndarray:
    z = points[:, 2:3]
    return (6.5e-4 + 3.5e-4 * z) * E_HAT + np.array([0.0, 0.0, -2.0e-4]) * z  # (N, 3)


@pytest.mark.parametrize("method", ["ssn", "fixed_point"])
def test_coulomb_strip3d_has_the_closed_form(method):
    model = _model("coulomb_strip3d")
    opts = {"inner": "ssn"} if method == "fixed_point" else {}
    sol = vi_core.solve(model.vi, method, tol=TOL, **opts)
    assert sol.converged
    st = contact3d.contact_state(model, sol)
    has = st["has_t"]
    assert has.sum() >= 3
    u = contact3d.fields(model, sol)["block.displacement"]
    exact = _exact_u(model.bodies[0].mesh.points)
    assert np.abs(u - exact).max() <= 1e-10 * np.abs(exact).max()
    assert np.abs(st["lam_n"][has] - LAM_N).max() <= 1e-10 * LAM_N
    assert np.abs(st["lam_t_vec"][has] - LAM_T * E_HAT).max() <= 1e-10 * LAM_T
    # the slip points along λ_t (the VI's convention) and is the closed form's 6.5e-4 ê
    assert np.abs(st["jump_t_vec"][has] - 6.5e-4 * E_HAT).max() <= 1e-10 * 6.5e-4
    assert st["slip"][has].all()


def test_coulomb_is_tresca_with_g_equal_F_lambda_n(tmp_path):
    """With a uniform pressure Coulomb reduces to unilateral Tresca with g = F λ_n: two
    separate builds and solves give the same answer."""
    c = _model("coulomb_strip3d")
    t = _tresca(tmp_path, "coulomb_strip3d", "3.5e5")
    assert t.contact.friction == "tresca" and c.contact.friction == "coulomb"
    sc = vi_core.solve(c.vi, "ssn", tol=TOL)
    st = vi_core.solve(t.vi, "ssn", tol=TOL)
    assert sc.converged and st.converged
    assert np.abs(sc.u - st.u).max() <= 1e-10 * np.abs(st.u).max()
    assert np.abs(sc.lam - st.lam).max() <= 1e-10 * np.abs(st.lam).max()


@pytest.fixture(scope="module")
def liftoff():
    model = _model("block3d_liftoff")
    sol = vi_core.solve(model.vi, "ssn", tol=TOL)
    assert sol.converged
    return model, sol


def test_liftoff_has_open_stick_and_slip_zones_and_passes_the_separation_checks(liftoff):
    model, sol = liftoff
    st = contact3d.contact_state(model, sol)
    counts = {s: int((st["state"] == s).sum()) for s in ("open", "stick", "slip")}
    assert min(counts.values()) > 0, counts
    sep = contact3d_checks.separation(model, sol)
    assert max(sep.values()) <= 1e-10, sep
    # Coulomb: no tangential force where the block is apart, |λ_t| ≤ F λ_n where it touches
    open_ = st["state"] == "open"
    assert np.abs(st["lam_t_vec"][open_]).max() <= 1e-10 * np.nanmax(st["lam_n"])
    assert st["lemma_4_2"] <= 1e-12


def test_liftoff_newton_and_fixed_point_agree(liftoff):
    model, sol = liftoff
    fp = vi_core.solve(model.vi, "fixed_point", inner="ssn", tol=1e-12)
    assert fp.converged and fp.info["contraction"] < 1.0
    scale = np.abs(sol.lam).max()
    assert np.abs(fp.lam - sol.lam).max() <= 1e-8 * scale


def test_unilateral_tresca_acts_only_where_the_block_touches(tmp_path):
    model = _tresca(tmp_path, "block3d_liftoff", "2e4")
    sol = vi_core.solve(model.vi, "ssn", tol=TOL)
    assert sol.converged
    st = contact3d.contact_state(model, sol)
    open_ = st["state"] == "open"
    assert open_.any() and (~open_ & st["has_t"]).any()
    assert np.abs(st["lam_t_vec"][open_]).max() <= 1e-12 * 2e4
    touching = st["has_t"] & ~open_
    mag = np.linalg.norm(st["lam_t_vec"][touching], axis=1)
    assert mag.max() <= 2e4 * (1 + 1e-12)
    assert max(contact3d_checks.separation(model, sol).values()) <= 1e-10


def test_a_rigid_gap_opens_the_contact():
    """A foundation 1e-5 m below the base (more than the 1e-6 m press) leaves the block apart:
    λ = 0, every node open, and the remaining gap is the field minus u_n."""
    model = _model("block3d_liftoff", 0, "contact.gap=1e-5")
    sol = vi_core.solve(model.vi, "ssn", tol=TOL)
    st = contact3d.contact_state(model, sol)
    assert sol.converged and np.abs(sol.lam).max() <= 1e-12 * st["pressure"]
    assert (st["state"][st["has_t"]] == "open").all()
    assert np.nanmin(st["gap"]) > 0


# ------------------------------------------------------------------ fault injection
def _solve(model):
    sol = vi_core.solve(model.vi, "ssn", tol=TOL)
    assert sol.converged
    return sol


def test_separation_check_sees_a_wrong_sign_of_the_gap(monkeypatch):
    over = ("contact.gap='2e-7*(1 + x)'",)
    model = _model("block3d_liftoff", 0, *over)
    assert max(contact3d_checks.separation(model, _solve(model)).values()) <= 1e-10
    real = rows.rigid_gap
    monkeypatch.setattr(rows, "rigid_gap", lambda *a: -real(*a))
    bad = _model("block3d_liftoff", 0, *over)
    sep = contact3d_checks.separation(bad, _solve(bad))
    # the block now stops short of the foundation and presses on nothing
    assert sep["open_pressure"] > 0.5 and sep["complementarity"] > 1e-2, sep


def test_separation_check_sees_a_dropped_complementarity_row(monkeypatch):
    real = rows.contact_rows

    def dropped(*args, **kwargs):  # the normal row of the first (pressed) node is lost
        B = real(*args, **kwargs).tolil()
        B[0, :] = 0.0
        return B.tocsr()

    monkeypatch.setattr(rows, "contact_rows", dropped)
    bad = _model("block3d_liftoff", 0)
    sep = contact3d_checks.separation(bad, _solve(bad))
    assert sep["penetration"] > 1e-3, sep


def test_separation_check_sees_a_wrong_scaling_of_F(monkeypatch):
    real = surface_contact.facet_integrals
    monkeypatch.setattr(  # F_k = ∫Fφ_k instead of ∫Fφ_k / W_k
        surface_contact,
        "facet_integrals",
        lambda mesh, surf, f, order: real(mesh, surf, f, order) ** 2,
    )
    bad = _model("coulomb_strip3d", 0)
    sep = contact3d_checks.separation(bad, _solve(bad))
    assert sep["friction"] > 1e-3, sep


# ------------------------------------------------------------------ refusals
def test_coulomb_needs_the_unilateral_law():
    with pytest.raises(SceneError, match="'tresca' with law = 'bilateral'"):
        _model("coulomb_strip3d", 0, "contact.law='bilateral'")


def test_a_roller_across_the_contact_surface_is_refused_for_unilateral_contact():
    roller = "{boundary='bottom', components='z', value=[0.0, 0.0, 0.0]}"
    top = "{boundary='top', value=[0.0, 0.0, -1e-6]}"
    with pytest.raises(SceneError, match="free to separate"):
        _model("block3d_liftoff", 0, f"bodies.block.displacement=[{top}, {roller}]")


# ------------------------------------------------------------------ two bodies that start apart
GAP = 1.0e-4
TWO = """format = 2
[scene]
title = "two blocks, 1e-4 m apart"
plugin = "contact"
level = 0
[bodies.top]
material = {{ kind = "isotropic", E = 2.6e9, nu = 0.3 }}
geometry = {{ kind = "box", x = [0.0, 1.0], y = [0.0, 1.0], z = [{z0}, 1.0], cells = [4, 4, 2] }}
[[bodies.top.displacement]]
boundary = "top"
value = [2.0e-5, 1.0e-5, "-2.5e-4 + 2.5e-4*x"]
[bodies.base]
material = {{ kind = "isotropic", E = 2.6e9, nu = 0.3 }}
geometry = {{ kind = "box", x = [-0.2, 1.2], y = [-0.2, 1.2], z = [0.0, 0.5], cells = [3, 3, 2] }}
[[bodies.base.displacement]]
boundary = "bottom"
value = [0.0, 0.0, 0.0]
[contact]
slave = "top.bottom"
master = "base.top"
law = "unilateral"
friction = "coulomb"
F = 0.3
"""


def _two_bodies(tmp_path, z0: float = 0.5 + GAP):
    path = tmp_path / "two.toml"
    path.write_text(TWO.format(z0=z0))
    return contact3d.build(load_scene(str(path)), 0)


def _geometric_gap(model, sol) -> np.ndarray:
    """(k,) the deformed slave surface above the deformed master one, node by node, from the
    nodal positions alone (the master's top linearly interpolated): not from the mortar."""
    from scipy.interpolate import LinearNDInterpolator

    f = contact3d.fields(model, sol)
    top, base = model.bodies
    sn = model.contact.tr.nodes
    xs = top.mesh.points[sn] + f["top.displacement"][sn]  # (k, 3)
    mn = np.unique(base.mesh.boundaries["top"])
    xm = base.mesh.points[mn] + f["base.displacement"][mn]
    return xs[:, 2] - LinearNDInterpolator(xm[:, :2], xm[:, 2])(xs[:, :2])


def test_two_bodies_that_start_apart(tmp_path):
    """The weighted mortar gap of two parallel faces 1e-4 m apart is 1e-4 m at every node; the
    tilted press closes it over part of the face: open and touching nodes, no penetration
    beyond the mortar's weak (O(h²)) sense, and Newton and the fixed point agree."""
    model = _two_bodies(tmp_path)
    c = model.contact
    assert np.abs(c.gap0 / c.W[c.rows_n] - GAP).max() <= 1e-10 * GAP
    sol = _solve(model)
    st = contact3d.contact_state(model, sol)
    assert (st["state"] == "open").any() and st["touch"].any()
    d = _geometric_gap(model, sol)
    assert np.nanmin(d) >= -0.1 * GAP, np.nanmin(d)
    assert np.abs(d[st["touch"]]).max() <= 0.1 * GAP
    assert np.nanmin(st["gap"]) >= -1e-12 * GAP and st["lemma_4_2"] <= 1e-12
    sep = contact3d_checks.separation(model, sol)
    assert max(sep.values()) <= 1e-10, sep
    fp = vi_core.solve(model.vi, "fixed_point", inner="ssn", tol=1e-12)
    assert fp.converged
    assert np.abs(fp.lam - sol.lam).max() <= 1e-8 * np.abs(sol.lam).max()


def test_the_geometric_gap_sees_a_wrong_sign_of_the_two_body_gap(tmp_path, monkeypatch):
    real = surface_contact._positions
    monkeypatch.setattr(surface_contact, "_positions", lambda *a: -real(*a))
    model = _two_bodies(tmp_path)
    sol = _solve(model)
    d = _geometric_gap(model, sol)
    touch = contact3d.contact_state(model, sol)["touch"]
    # the bodies now press on each other while 2e-4 m apart (a gap of −1e-4 to close)
    assert touch.any() and np.abs(d[touch]).max() > 0.5 * GAP


def test_separation_check_sees_a_dropped_mortar_row(tmp_path, monkeypatch):
    """A normal row of the two-body problem lost from the VI's B (the check reads the
    model's B_full, which keeps it) lets the slave sink into the master at that node."""
    model = _two_bodies(tmp_path)
    c = model.contact
    B = model.vi.B.tolil()
    pressed = int(np.argmax(_solve(model).lam[c.rows()[0]]))  # the node pressed hardest
    B[c.rows()[0][pressed], :] = 0.0
    model.vi = type(model.vi)(
        A=model.vi.A, B=B.tocsr(), f=model.vi.f, Lambda=model.vi.Lambda, gap=model.vi.gap
    )
    sep = contact3d_checks.separation(model, _solve(model))
    assert sep["penetration"] > 1e-3, sep


def test_overlapping_bodies_are_refused(tmp_path):
    with pytest.raises(SceneError, match="overlaps by 0.05"):
        _two_bodies(tmp_path, z0=0.45)
    _two_bodies(tmp_path, z0=0.5 - 1e-3)  # within OVERLAP_TOL: accepted


def test_line_nodes_of_a_roller_side_carry_a_two_dimensional_contact_set():
    """A roller on the left side (u_x = 0) leaves the bottom's left edge nodes one tangent
    (y): vi_core's contact set with dim = 2 there, beside the discs; Newton and the fixed point
    agree and the separation checks hold."""
    roller = "{boundary='left', components='x', value=[0.0, 0.0, 0.0]}"
    top = "{boundary='top', value=[0.0, '1.0e-7', '-1.0e-6 + 1.6e-6*x']}"
    model = _model("block3d_liftoff", 0, f"bodies.block.displacement=[{top}, {roller}]")
    c = model.contact
    dims = sorted(b.dim for b in model.vi.Lambda.blocks() if hasattr(b, "dim"))
    assert c.line.size > 0 and c.disc.size > 0 and dims == [2, 3]
    sol = _solve(model)
    sep = contact3d_checks.separation(model, sol)
    assert max(sep.values()) <= 1e-10, sep
    fp = vi_core.solve(model.vi, "fixed_point", inner="ssn", tol=1e-12)
    assert fp.converged
    assert np.abs(fp.lam - sol.lam).max() <= 1e-8 * np.abs(sol.lam).max()
    st = contact3d.contact_state(model, sol)
    line_lam = st["lam_t_vec"][c.line]  # along the kept tangent ±e_y only
    assert np.abs(line_lam[:, [0, 2]]).max() <= 1e-12 * np.abs(sol.lam).max()


# ------------------------------------------------------------------ load paths
def _strip_path(tmp_path) -> str:
    """coulomb_strip3d sheared by δ = 1e-3 m (t = 1: the whole base slides 6.5e-4 m) and
    then back to δ = 5e-4 m (t = 2): the base sticks where it slid to, the shear strain is
    (5e-4 − 6.5e-4)/H = −1.5e-4 and λ_t = −1.5e5 ê Pa, inside the bound 3.5e5 Pa."""
    text = (SCENES_DIR / "coulomb_strip3d.toml").read_text()
    back = "where(t > 1.5, 0.5, 1.0)"
    gamma = "where(t > 1.5, -1.5e-4, 3.5e-4)"
    text = text.replace(
        "value = [8.0e-4, 6.0e-4, -2.0e-4]", f'value = ["8.0e-4*{back}", "6.0e-4*{back}", -2.0e-4]'
    )
    text = text.replace(
        '"5.2e-4 + 2.8e-4*z", "3.9e-4 + 2.1e-4*z"',
        f'"0.8*(6.5e-4 + {gamma}*z)", "0.6*(6.5e-4 + {gamma}*z)"',
    )
    text = text.replace("[bodies.block]", "[load_path]\nt = [1.0, 2.0]\n\n[bodies.block]")
    path = tmp_path / "strip_path.toml"
    path.write_text(text)
    return str(path)


def _unloaded(res) -> None:
    st = contact3d.contact_state(res.model, res.solution)
    has = st["has_t"]
    u = contact3d.fields(res.model, res.solution)["block.displacement"]
    z = res.model.bodies[0].mesh.points[:, 2:3]
    exact = (6.5e-4 - 1.5e-4 * z) * E_HAT + np.array([0.0, 0.0, -2.0e-4]) * z
    assert np.abs(u - exact).max() <= 1e-9 * np.abs(exact).max()
    assert np.abs(st["lam_t_vec"][has] + 1.5e5 * E_HAT).max() <= 1e-9 * 1.5e5
    assert not st["slip"][has].any()


def test_a_load_path_acts_on_the_slip_increments(tmp_path):
    import problems

    res = problems.solve_scene(_strip_path(tmp_path), level=0, tol=TOL)
    assert [s["converged"] for s in res.info["steps"]] == [True, True]
    _unloaded(res)
    sep = contact3d_checks.separation(res.model, res.solution)
    assert max(sep.values()) <= 1e-10, sep


def test_the_total_form_misses_the_unloading(tmp_path, monkeypatch):
    """Mutation: without `incremental` the second step is the fresh problem at δ = 5e-4 m
    (slip 1.5e-4 m, λ_t = +3.5e5 ê): the unloading checks fail."""
    import problems

    monkeypatch.delattr(contact3d, "incremental")
    res = problems.solve_scene(_strip_path(tmp_path), level=0, tol=TOL)
    with pytest.raises(AssertionError):
        _unloaded(res)
