"""The piezo_contact plug-in on the rigid-foundation scene: convergence, Lemma 4.2, limits."""

import numpy as np
import pytest

from problems.plugins.contact import balance as piezo_balance
from problems.plugins.contact import plane as pc
from problems.scene import load_scene
from vi_core import solve

LIMIT_TOL = 1e-10


def _solve(overrides, level=1, drop_contact=False):
    scene = load_scene("rigid_foundation", overrides)
    if drop_contact:
        del scene.data["contact"]
    model = pc.build(scene, level)
    sol = solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged, sol.history
    return model, sol


def _bottom_dirichlet(components):
    # a Dirichlet part u = 0 on the bottom (all or some components)
    return {"boundary": "bottom", "value": [0.0, 0.0], "components": components}


def _with_bottom(components):
    scene = load_scene("rigid_foundation")
    del scene.data["contact"]
    scene.data["bodies"]["block"]["displacement"].append(_bottom_dirichlet(components))
    model = pc.build(scene, 1)
    sol = solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged and model.vi.m == 0
    return model, sol


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_shipped_scene_has_stick_and_slip_and_lemma_4_2():
    """Stick and slip both occur; Lemma 4.2 and the force balance hold when computed by
    quadrature, independently of the assembled B and friction weights (|λ·τ| = g on slip
    nodes and u_n = 0 are what the solver imposes: not asserted here)."""
    model, sol = _solve([])
    st = pc.contact_state(model, sol)
    assert sol.residual <= 1e-10
    assert 0 < st["slip"].sum() < st["slip"].size
    assert piezo_balance.lemma_4_2(model, sol)["gap"] <= 1e-10
    assert piezo_balance.force_balance(model, sol)["imbalance"] <= 1e-10


def test_g_zero_is_frictionless_sliding():
    """g = 0: the same as u_n = 0 strongly with zero tangential traction (a linear problem)."""
    m1, s1 = _solve(["contact.g=0.0"])
    m2, s2 = _with_bottom("y")
    assert _rel(m1.full(s1.u), m2.full(s2.u)) <= LIMIT_TOL
    assert np.abs(s1.lam[m1.contact.tr.size :]).max() == 0.0


def test_huge_g_is_tied():
    """g larger than any tangential stress: the same as u = 0 on Γ3 (a linear problem)."""
    m1, s1 = _solve(["contact.g=1e12"])
    m2, s2 = _with_bottom("xy")
    st = pc.contact_state(m1, s1)
    assert st["slip"].sum() == 0
    assert _rel(m1.full(s1.u), m2.full(s2.u)) <= LIMIT_TOL


def test_larger_g_means_more_stick():
    sticks = []
    for g in (5e6, 9e6, 1.2e7):
        model, sol = _solve([f"contact.g={g}"])
        st = pc.contact_state(model, sol)
        sticks.append(int((~st["slip"]).sum()))
    assert sticks == sorted(sticks) and sticks[0] < sticks[-1]


@pytest.mark.parametrize("element", ["quad", "triangle"])
def test_elements_and_levels_converge(element):
    for level in (0, 2):
        model, sol = _solve([f"bodies.block.geometry.element='{element}'"], level=level)
        assert piezo_balance.lemma_4_2(model, sol)["gap"] <= 1e-10


def test_elastic_body_has_no_potential():
    scene = load_scene(
        "rigid_foundation", ["bodies.block.material={kind='isotropic', E=1e10, nu=0.3}"]
    )
    del scene.data["bodies"]["block"]["potential"]
    del scene.data["output"]
    model = pc.build(scene, 1)
    assert model.dofs["potential"] == 0
    assert model.vi.structure == "symmetric"
    sol = solve(model.vi, "ssn")
    assert sol.converged


def test_a_models_gram_matrix_is_assembled_when_asked():
    """The contact plug-ins' vi.X is a function giving the bodies' H1 Gram matrices on the
    unknowns: symmetric positive definite, and the Dirichlet-reduced block of the full one."""
    import scipy.sparse as sp

    from problems.plugins.contact import bodies

    model = pc.build(load_scene("paper_two_body"), 0)
    X = model.vi.X()
    assert X.shape == (model.vi.n, model.vi.n)
    assert abs(X - X.T).max() <= 1e-14 * abs(X).max()
    assert np.linalg.eigvalsh(X.toarray()).min() > 0
    full = sp.block_diag([bodies.gram(b) for b in model.bodies], format="csr")
    assert abs(X - full[model.free][:, model.free]).max() == 0
