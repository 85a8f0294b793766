"""Electrical contact conditions (problems/plugins/contact/electrical.py): the law, its
boundary assembly, the outer fixed point, and the integrated piezo_contact scene against the
uniaxial closed form (problems/scene/contact_references.py), with fault injections."""

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from problems.plugins.contact import electrical as ec
from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from problems.scene.contact_references import (
    Layer,
    two_layer_electrical_contact,
    uniaxial_electrical_contact,
)
from problems.scene.materials import NAMED

MATCH = 1e-8  # FE against the closed form: linear fields are exact in Q1 (rounding + tol 1e-10)
_M = NAMED["BaTiO3"]
C33, E33, K33 = _M["C"][1][1], _M["e"][1][1], _M["kappa"][1][1]
H, W = 1e-2, 2e-2  # the shipped scene's block


# ------------------------------------------------------------------ the law
@given(
    k0=st.floats(1e-9, 1e-3),
    lam_star=st.floats(1e3, 1e9),
    p=st.floats(0.2, 4.0),
    seed=st.integers(0, 2**31),
)
def test_laws_vanish_apart_and_grow_with_pressure(k0, lam_star, p, seed):
    """k = 0 for λ_n ≤ 0, nondecreasing in λ_n, k(λ*) = k0, saturated bounded by k0."""
    rng = np.random.default_rng(seed)
    lam = np.sort(rng.uniform(-2 * lam_star, 3 * lam_star, 40))
    for law in (ec.Law("saturated", k0, lam_star, p), ec.Law("power", k0, lam_star, p)):
        k = law(lam)
        assert (k[lam <= 0] == 0).all()
        assert (np.diff(k) >= 0).all()
        assert law(np.array([lam_star]))[0] == pytest.approx(k0, rel=1e-12)
    sat = ec.Law("saturated", k0, lam_star, p)(lam)
    assert sat.max() <= k0 and sat[lam >= lam_star] == pytest.approx(k0)
    pw = ec.Law("power", k0, lam_star, p)(lam)
    pos = lam > 0
    assert pw[pos] == pytest.approx(k0 * (lam[pos] / lam_star) ** p, rel=1e-12)


def test_grounded_law_acts_only_where_touching():
    law = ec.Law("grounded", 5.0, 1.0, 1.0)
    assert law(np.array([-1.0, 0.0, 1e-12, 2.0, 3.0])).tolist() == [0, 0, 0, 5, 5]
    assert law(np.array([-1.0, 0.0])).tolist() == [0, 0]  # nothing touches: nothing grounded
    assert ec.Law("none", 5.0, 1.0, 1.0)(np.array([1.0, 2.0])).tolist() == [0, 0]


@given(seed=st.integers(0, 2**31))
def test_conductance_matrix_is_the_trapezoidal_rule_of_the_trace_mass(seed):
    """diag(w k) against ∫ k_h φ_i φ_j on a random polyline, by 2-point Gauss: equal row sums
    for constant k (the lumped mass), and the same ∫ k φ φ as the nodal rule of k_h."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 12))
    lengths = rng.uniform(0.1, 2.0, n - 1)
    w = np.zeros(n)
    w[:-1] += lengths / 2
    w[1:] += lengths / 2
    k = rng.uniform(0.0, 3.0, n)
    D = ec.conductance_matrix(w, k).toarray()
    assert np.allclose(D, np.diag(w * k), rtol=1e-14, atol=0)
    # consistent mass with constant k: row sums are w·k
    kc = float(rng.uniform(0.1, 2.0))
    M = np.zeros((n, n))
    for e, L in enumerate(lengths):
        M[e : e + 2, e : e + 2] += kc * L / 6 * np.array([[2, 1], [1, 2]])
    assert np.allclose(M.sum(axis=1), np.diag(ec.conductance_matrix(w, np.full(n, kc)).toarray()))
    with pytest.raises(ValueError, match="k ≥ 0"):
        ec.conductance_matrix(w, -k - 1)


# ------------------------------------------------------------------ the fixed point on a toy VI
def _toy(seed):
    """A small VI: A SPD (n = 6), one Free multiplier row; potentials = unknowns 3..5."""
    from vi_core import Free, MixedVI, product

    rng = np.random.default_rng(seed)
    G = rng.normal(size=(6, 6))
    A = sp.csr_matrix(G @ G.T + 6 * np.eye(6))
    B = sp.csr_matrix(rng.normal(size=(1, 6)))
    vi = MixedVI(A=A, B=B, f=rng.normal(size=6), Lambda=product(Free(1)), gap=np.ones(1))
    return vi


@given(seed=st.integers(0, 2**31))
def test_frozen_problem_adds_w_k_on_the_potentials_and_flux_recovers_the_law(seed):
    rng = np.random.default_rng(seed)
    vi = _toy(seed)
    c = ec.Coupling(
        vi0=vi,
        phi=np.array([3, 5, -1]),
        normal=np.array([0, 0, 0]),
        weights=rng.uniform(0.5, 2.0, 3),
        law=ec.Law("saturated", 0.7, 1.0, 1.0),
        phi_F=float(rng.normal()),
    )
    k = rng.uniform(0, 2, 3)
    fz = c.frozen(k)
    dA = (fz.A - vi.A).toarray()
    expect = np.zeros(6)
    expect[[3, 5]] = c.weights[:2] * k[:2]
    assert np.allclose(dA, np.diag(expect), rtol=1e-14, atol=1e-14)
    assert np.allclose(fz.f - vi.f, expect * c.phi_F)
    import vi_core

    sol = vi_core.solve(fz, "ssn", tol=1e-12)
    flux = c.flux(sol.u, sol.lam)
    phi = sol.u[[3, 5]]
    assert flux[:2] == pytest.approx(k[:2] * (phi - c.phi_F), rel=1e-8, abs=1e-10)
    assert np.isnan(flux[2])


# The update k ← k(λ_n) of the outer fixed point on a problem solved by hand: unknowns
# (d1, d2, φ1, φ2), A = diag(2, 2, 3, 3), the normal rows B = [I 0] bilateral (Free) with the gap
# (0.5, 0.25), so d = gap and λ_n = f_d − 2·gap = (0.5, −1): node 1 pressed, node 2 in tension.
# The saturated law k0 = 4, λ* = 1 gives k = 4·min(λ_n⁺, 1) = (2, 0), and with w = (0.5, 0.25),
# φ_F = 10 the potentials solve (3 + w_i k_i) φ_i = q_i + w_i k_i φ_F: φ1 = (1 + 10)/4 = 2.75,
# φ2 = 2/3 (no conductance where the node is apart).
BY_HAND_U = np.array([0.5, 0.25, 2.75, 2.0 / 3.0])
BY_HAND_LAM = np.array([0.5, -1.0])


def _two_nodes_by_hand():
    from vi_core import Free, MixedVI, product

    vi = MixedVI(
        A=sp.diags([2.0, 2.0, 3.0, 3.0]).tocsr(),
        B=sp.csr_matrix(np.eye(2, 4)),
        f=np.array([1.5, -0.5, 1.0, 2.0]),
        Lambda=product(Free(2)),
        gap=np.array([0.5, 0.25]),
    )
    c = ec.Coupling(
        vi0=vi,
        phi=np.array([2, 3]),
        normal=np.array([0, 1]),
        weights=np.array([0.5, 0.25]),
        law=ec.Law("saturated", 4.0, 1.0, 1.0),
        phi_F=10.0,
    )
    sol, _ = ec.solve_coupled(c, method="ssn", tol=1e-12)
    return sol


def test_the_update_on_two_nodes_solved_by_hand():
    sol = _two_nodes_by_hand()
    assert sol.converged and sol.info["electrical"]["iterations"] == 2  # k⁰ = 0, then k(λ_n)
    assert np.abs(sol.u - BY_HAND_U).max() <= 1e-12
    assert np.abs(sol.lam - BY_HAND_LAM).max() <= 1e-12


def test_mutation_a_sign_flip_in_the_update_fails_the_hand_values(monkeypatch):
    """k(−λ_n): the node in tension conducts, the pressed one does not."""
    monkeypatch.setattr(ec.Coupling, "conductances", lambda self, lam: self.law(-lam[self.normal]))
    sol = _two_nodes_by_hand()
    assert np.abs(sol.u - BY_HAND_U).max() > 0.1


def test_fixed_point_reports_not_converged_when_it_stops_early():
    model = pc.build(load_scene("electrical_block", ["contact.electrical.max_iter=2"]))
    sol = pc.solve(model, method="ssn", tol=1e-10)
    rec = sol.info["electrical"]
    assert not sol.converged and not rec["converged"] and rec["iterations"] == 2
    assert any("not converged" in w for w in sol.warnings)


# ------------------------------------------------------------------ the scene vs the closed form
def _solve(overrides, level=0, delta=1e-6, V=0.0):
    scene = load_scene("electrical_block", overrides)
    body = scene.data["bodies"]["block"]
    body["displacement"][0]["value"] = [0.0, -delta]
    body["potential"][0]["value"] = V
    model = pc.build(scene, level)
    sol = pc.solve(model, method="ssn", tol=1e-10)
    return model, sol


def _bottom(model, sol):
    """(φ, λ_n) at the bottom nodes carrying λ_n."""
    c = model.electrical or ec.Coupling(model.vi, *_where(model), None, 0.0)
    return sol.u[c.phi], sol.lam[c.normal]


def _where(model):
    tmp = pc._electrical(
        ec.ElectricalSection(kind="insulating"), model.contact, model.vi, model.free
    )
    return tmp.phi, tmp.normal, tmp.weights


def _reference(delta, V, phi_F, law):
    def k(lam):
        return law(np.array([lam]))[0]

    return uniaxial_electrical_contact(C33, E33, K33, H, delta, V, phi_F, k)


@settings(max_examples=12)
@given(
    delta=st.floats(2e-7, 3e-6),
    V=st.floats(-500.0, 500.0),
    phi_F=st.floats(-1000.0, 1000.0),
    k0=st.floats(1e-8, 1e-5),
    law=st.sampled_from(["saturated", "power"]),
    p=st.floats(0.5, 2.0),
)
def test_conductive_block_matches_the_uniaxial_closed_form(delta, V, phi_F, k0, law, p):
    """Bottom potential and pressure against the scalar equation of the 1D state, over the
    load, the potentials, the law and its parameters; the recovered D·n obeys the law."""
    sets = [
        f"contact.electrical.phi_F={phi_F!r}",
        f"contact.electrical.k0={k0!r}",
        f"contact.electrical.law={law!r}".replace("'", '"'),
        f"contact.electrical.p={p!r}",
    ]
    model, sol = _solve(sets, delta=delta, V=V)
    assert sol.converged, sol.warnings
    ref = _reference(delta, V, phi_F, model.electrical.law)
    phi, lam = _bottom(model, sol)
    scale = max(abs(ref.phi0), abs(phi_F), abs(V), 1.0)
    assert np.abs(phi - ref.phi0).max() <= MATCH * scale
    assert np.abs(lam - ref.lam_n).max() <= MATCH * ref.lam_n
    assert ec.report(model.electrical, sol)["law_defect"] <= 1e-7


def test_insulating_is_the_natural_condition_and_k0_zero():
    """D·n = 0 on Γ3: the recovered flux vanishes, φ0 is the closed form's D_y = 0 value, and
    a conductive law with k0 = 0 gives the same answer as insulating and no table at all."""
    m_ins, s_ins = _solve(['contact.electrical.kind="insulating"'])
    rep = ec.report(m_ins.electrical, s_ins)
    phi, _ = _bottom(m_ins, s_ins)
    ref = _reference(1e-6, 0.0, 100.0, ec.Law("none", 0, 1, 1))
    assert np.abs(phi - ref.phi0).max() <= MATCH * abs(ref.phi0)
    flux_scale = K33 * abs(ref.phi0) / H  # |κ ∂φ/∂y| in the layer
    assert rep["flux_max"] <= 1e-9 * flux_scale
    m0, s0 = _solve(["contact.electrical.k0=0.0"])
    assert np.allclose(s0.u, s_ins.u, rtol=0, atol=1e-12 * np.abs(s_ins.u).max())
    scene = load_scene("electrical_block")
    del scene.data["contact"]["electrical"]
    m_none = pc.build(scene)
    s_none = pc.solve(m_none, method="ssn", tol=1e-10)
    assert m_none.electrical is None
    assert np.allclose(s_none.u, s_ins.u, rtol=0, atol=1e-12 * np.abs(s_ins.u).max())


def test_no_conductance_where_apart():
    """Pulled up (δ < 0) the bilateral contact carries tension, λ_n < 0: the contact counts as
    apart, k = 0, and the bottom potential is the insulating one."""
    model, sol = _solve([], delta=-1e-6)
    phi, lam = _bottom(model, sol)
    assert (lam < 0).all()
    ref = _reference(-1e-6, 0.0, 100.0, ec.Law("none", 0, 1, 1))
    assert np.abs(phi - ref.phi0).max() <= MATCH * abs(ref.phi0)


def test_grounded_is_the_limit_of_large_conductance():
    """Grounded: φ = φ_F on the touching nodes to the penalty's accuracy; the conductive law
    approaches it as k0 grows, with error ∝ 1/k0 (the closed form's φ0 − φ_F)."""
    mg, sg = _solve(['contact.electrical.kind="grounded"'])
    rep = ec.touching(mg.electrical, sg, pc.contact_state(mg, sg)["touch"])
    assert sg.converged and rep["touching_nodes"] == 5
    assert rep["potential_gap_touching"] <= 1e-5 * 100.0
    phi_g, _ = _bottom(mg, sg)
    gaps = []
    for k0 in (1e-4, 1e-3, 1e-2):
        m, s = _solve([f"contact.electrical.k0={k0!r}", "contact.electrical.lambda_star=1.0"])
        phi, _ = _bottom(m, s)
        gaps.append(np.abs(phi - phi_g).max())
        ref = _reference(1e-6, 0.0, 100.0, m.electrical.law)
        assert np.abs(phi - ref.phi0).max() <= MATCH * abs(ref.phi0)
    assert gaps[0] > gaps[1] > gaps[2]
    assert gaps[1] / gaps[2] == pytest.approx(10.0, rel=0.05)  # O(1/k0)


def test_elastic_slaves_and_a_foundation_potential_on_a_piezo_master_are_refused():
    """An elastic slave has no potential; with a piezoelectric master the charge flows into
    the master, so φ_F has no place."""
    from problems.errors import SceneError

    table = ['contact.electrical={kind = "conductive", k0 = 1e-6}']
    with pytest.raises(SceneError, match="only with a piezoelectric slave body"):
        load_scene("paper_two_body", table).validated(pc.SCENE_MODEL)
    with pytest.raises(SceneError, match="with a piezoelectric master body"):
        load_scene("electrical_two_body", ["contact.electrical.phi_F=5.0"]).validated(
            pc.SCENE_MODEL
        )


# ------------------------------------------------------------------ fault injection
_FROZEN = ec.Coupling.frozen  # the original, for faults built on it
FAULTS = {
    "Robin sign flipped": lambda c, k: dataclasses.replace(
        c.vi0, A=(c.vi0.A - _diag(c, k)).tocsr(), f=c.vi0.f - _diag(c, k) @ _const(c)
    ),
    "weights dropped (k instead of w k)": lambda c, k: _FROZEN(
        dataclasses.replace(c, weights=np.ones_like(c.weights)), k
    ),
    "φ_F load dropped": lambda c, k: dataclasses.replace(c.vi0, A=(c.vi0.A + _diag(c, k)).tocsr()),
}


def _const(c):
    return np.full(c.vi0.n, c.phi_F)


def _diag(c, k):
    d = np.zeros(c.vi0.n)
    keep = c.phi >= 0
    np.add.at(d, c.phi[keep], (c.weights * k)[keep])
    return sp.diags(d)


@pytest.mark.parametrize("fault", list(FAULTS))
def test_fault_injection_is_caught_by_the_closed_form(fault, monkeypatch):
    monkeypatch.setattr(ec.Coupling, "frozen", FAULTS[fault])
    model, sol = _solve([])
    ref = _reference(1e-6, 0.0, 100.0, model.electrical.law)
    phi, _ = _bottom(model, sol)
    assert not (np.abs(phi - ref.phi0).max() <= MATCH * abs(ref.phi0))


def test_fault_law_on_the_tangential_multiplier_is_caught(monkeypatch):
    """k evaluated at λ_t instead of λ_n (a wrong index map) fails the closed form."""

    def wrong(self, lam):
        return self.law(np.resize(lam[self.normal.size :], self.normal.size))

    monkeypatch.setattr(ec.Coupling, "conductances", wrong)
    model, sol = _solve([])
    ref = _reference(1e-6, 0.0, 100.0, model.electrical.law)
    phi, _ = _bottom(model, sol)
    assert not (np.abs(phi - ref.phi0).max() <= MATCH * abs(ref.phi0))


# ------------------------------------------------------------------ with unilateral contact
@pytest.mark.parametrize(
    "sets",
    [
        ['contact.electrical.kind="grounded"'],
        [
            'contact.electrical.kind="conductive"',
            "contact.electrical.k0=1e-7",
            "contact.electrical.lambda_star=1e9",
            "contact.electrical.tol=1e-12",
        ],
    ],
)
def test_electrical_conditions_act_only_where_the_body_touches(sets):
    """On the Hertz block (unilateral, only the middle of the top touches): D·n recovered on
    the open nodes is 0 (k = 0 apart) while it is not on the touching ones; grounded: φ = φ_F
    on the touching nodes to 1e-6 of the potential's scale; conductive: the law holds."""
    model = pc.build(load_scene("hertz_piezo", sets), 0)
    sol = pc.solve(model, method="ssn", tol=1e-12)
    assert sol.converged, sol.warnings
    c = model.electrical
    lam_n = sol.lam[c.normal]
    touch = lam_n > ec.TOUCH * lam_n.max()
    assert 0 < touch.sum() < touch.size
    flux = c.flux(sol.u, sol.lam)
    phi = sol.u[c.phi]
    top = np.abs(flux).max()
    assert np.abs(flux[~touch]).max() <= 1e-12 * top
    assert np.abs(flux[touch]).min() > 1e-6 * top
    if c.law.kind == "grounded":
        assert np.abs(phi[touch] - c.phi_F).max() <= 1e-6 * np.abs(phi).max()
    else:  # the law from the scene's numbers, not the code's Law or report
        k = 1e-7 * np.minimum(np.maximum(lam_n, 0.0) / 1e9, 1.0)
        assert np.abs(flux - k * (phi - c.phi_F)).max() <= 1e-6 * top


# ------------------------------------------------------------------ two bodies (dual mortar)
LAYER = Layer(C33, E33, K33, H)


def _two_body(overrides=(), level=0, delta=1e-6, V=0.0, V_m=0.0, base=None):
    """electrical_two_body with the load δ, the top potential V, the base's bottom potential
    V_m and optionally another base material."""
    scene = load_scene("electrical_two_body", list(overrides))
    bodies = scene.data["bodies"]
    bodies["block"]["displacement"][0]["value"] = [0.0, -delta]
    bodies["block"]["potential"][0]["value"] = V
    bodies["base"]["potential"][0]["value"] = V_m
    if base is not None:
        bodies["base"]["material"] = base
        bodies["base"].pop("potential")
    model = pc.build(scene, level)
    sol = pc.solve(model, method="ssn", tol=1e-10)
    assert sol.converged, sol.warnings
    return model, sol


def _two_body_errors(model, sol, delta=1e-6, V=0.0, V_m=0.0) -> dict[str, float]:
    """φ_s, Πφ_m and λ_n on Γ3 against the two-layer closed form (relative)."""
    c = model.electrical
    ref = two_layer_electrical_contact(
        LAYER, LAYER, delta, V, V_m, lambda lam: float(c.law(np.array([lam]))[0])
    )
    scale = max(abs(ref.phi_s), abs(ref.phi_m), abs(V), abs(V_m), 1.0)
    return {
        "phi_s": float(np.abs(sol.u[c.phi] - ref.phi_s).max()) / scale,
        "phi_m": float(np.abs(c.master @ sol.u + c.fixed - ref.phi_m).max()) / scale,
        "lam": float(np.abs(sol.lam[c.normal] - ref.lam_n).max()) / abs(ref.lam_n),
    }


@settings(max_examples=10)
@given(
    delta=st.floats(2e-7, 3e-6),
    V=st.floats(-500.0, 500.0),
    V_m=st.floats(-500.0, 500.0),
    k0=st.floats(1e-8, 1e-5),
    law=st.sampled_from(["saturated", "power"]),
    p=st.floats(0.5, 2.0),
    level=st.integers(0, 1),
)
def test_two_bodies_match_the_two_layer_closed_form(delta, V, V_m, k0, law, p, level):
    """Non-matching meshes (4 : 3 interface segments at level 0): the slave potential, the
    mortar mean of the master's and the pressure against the 3 × 3 closed form, and the
    recovered D·n obeys D·n = k(λ_n)(φ_s − Πφ_m)."""
    sets = [
        f"contact.electrical.k0={k0!r}",
        f"contact.electrical.law={law!r}".replace("'", '"'),
        f"contact.electrical.p={p!r}",
    ]
    model, sol = _two_body(sets, level, delta, V, V_m)
    err = _two_body_errors(model, sol, delta, V, V_m)
    assert max(err.values()) <= MATCH, err
    assert ec.report(model.electrical, sol)["law_defect"] <= 1e-7


def test_two_bodies_grounded_equalise_the_potentials_where_they_touch():
    """grounded: φ_s = Πφ_m on the touching nodes (the penalty's accuracy), the closed form
    with k = K."""
    model, sol = _two_body(['contact.electrical.kind="grounded"'], level=1)
    rep = ec.touching(model.electrical, sol, pc.contact_state(model, sol)["touch"])
    assert rep["touching_nodes"] == 9 and rep["potential_gap_touching"] <= 1e-5
    assert max(_two_body_errors(model, sol).values()) <= MATCH


def test_a_stiff_master_without_potential_is_the_rigid_foundation():
    """The rigid-foundation limit: an elastic base (a conductor at φ_F) 1e9 times stiffer than
    BaTiO3 gives the one-body closed form of electrical_block (its compliance: 1e-9)."""
    stiff = {"kind": "isotropic", "E": 1e20, "nu": 0.3}
    model, sol = _two_body(["contact.electrical.phi_F=100.0"], level=1, base=stiff)
    c = model.electrical
    assert c.master is None and c.phi_F == 100.0
    ref = _reference(1e-6, 0.0, 100.0, c.law)
    assert np.abs(sol.u[c.phi] - ref.phi0).max() <= 1e-8 * abs(ref.phi0)
    assert np.abs(sol.lam[c.normal] - ref.lam_n).max() <= 1e-8 * ref.lam_n


_JUMP = ec.Coupling.jump_matrix.fget  # the original, for faults built on it
TWO_BODY_FAULTS = {
    "master's sign flipped (φ_s + Πφ_m)": lambda c: _JUMP(c) + 2 * c.master,
    "master dropped (φ_s only)": lambda c: _JUMP(c) + c.master,
    "mortar mean not divided by W": lambda c: _JUMP(c) + c.master - sp.diags(c.weights) @ c.master,
}


@pytest.mark.parametrize("fault", list(TWO_BODY_FAULTS))
def test_two_body_fault_injection_is_caught_by_the_closed_form(fault, monkeypatch):
    monkeypatch.setattr(ec.Coupling, "jump_matrix", property(TWO_BODY_FAULTS[fault]))
    model, sol = _two_body()
    assert not max(_two_body_errors(model, sol).values()) <= MATCH
