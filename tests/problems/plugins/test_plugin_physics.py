"""The built-in scalar and Signorini plug-ins: signs, rates, limiting cases and bad input."""

from __future__ import annotations

import numpy as np
import pytest

import vi_core
from problems.errors import SceneError
from problems.plugins import registry
from problems.scene import load_scene


def _solve(name, level, *overrides, method="ssn"):
    scene = load_scene(name, overrides)
    model = registry.get(scene.data["scene"]["plugin"]).build(scene, level)
    sol = vi_core.solve(model.vi, method=method, tol=1e-10)
    assert sol.converged
    return model, sol


def test_obstacle_h1_rate_against_exact_solution():
    errs, hs = [], []
    for level in (1, 2, 3):
        model, sol = _solve("obstacle", level, method="conic")
        e = model.errors(sol)
        errs.append(e["h1"])
        hs.append(e["h"])
    rate = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert rate >= 0.9, (rate, errs)


def test_obstacle_signs_and_free_boundary():
    model, sol = _solve("obstacle", 2)
    u = model.full(sol.u)
    assert (u >= model.psi - 1e-10).all()  # above the obstacle
    assert (sol.lam >= 0).all()  # the obstacle pushes up
    touch = sol.lam > 1e-9 * sol.lam.max()
    r = np.linalg.norm(model.mesh.points[model.free[touch]], axis=1)
    assert r.max() <= 0.698 + model.mesh.h  # contact only inside r* (up to one cell)


def test_antiplane_limits_of_g():
    model, sol = _solve("antiplane", 1, "friction.g=1e9")  # huge bound: everything sticks
    assert np.abs(model.vi.B @ sol.u).max() <= 1e-12 * np.abs(sol.u).max()
    model, sol = _solve("antiplane", 1, "friction.g=0.0")  # no friction: λ = 0
    assert np.abs(sol.lam).max() == 0.0
    model, sol = _solve("antiplane", 1)
    st = registry.get("antiplane").contact_state(model, sol)
    assert 0 < st["slip"].sum() < st["slip"].size  # the shipped scene has stick and slip
    assert (np.sign(st["lam_t"][st["slip"]]) == np.sign(st["jump_t"][st["slip"]])).all()


def test_signorini_contact_and_separation():
    model, sol = _solve("signorini", 1)
    st = registry.get("signorini").contact_state(model, sol)
    assert 0 < st["touch"].sum() < st["touch"].size
    assert 0 < st["slip"].sum() < st["slip"].size
    assert (st["u_n"] <= st["gap"] + 1e-12).all() and (st["lam_n"] >= 0).all()
    np.testing.assert_allclose(st["u_n"][st["touch"]], st["gap"][st["touch"]], atol=1e-12)


def test_signorini_far_obstacle_is_free_problem():
    model, sol = _solve("signorini", 0, "contact.gap=1.0", "contact.g=0.0")
    free = np.linalg.solve(model.vi.A.toarray(), model.vi.f)
    assert np.abs(sol.lam).max() <= 1e-12 * np.abs(model.vi.f).max()
    np.testing.assert_allclose(sol.u, free, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize(
    ("name", "override", "key"),
    [
        ("obstacle", "domain.obstacel=0", "domain.obstacel"),
        ("obstacle", "domain.load='x +'", "domain.load"),
        ("antiplane", "domain.shear_modulus=-1", "domain.shear_modulus"),
        ("antiplane", "friction.boundary='middle'", "friction.boundary"),
        ("antiplane", "friction.g=-1.0", "friction.g"),
        ("signorini", "contact.gap=-1e-3", "contact.gap"),
        ("signorini", "body.material='BaTiO3'", "body.material"),
        ("signorini", "scene.plugin='obstacle'", "body"),  # an obstacle scene has no [body]
    ],
)
def test_bad_input_names_the_key(name, override, key):
    scene = load_scene(name, [override])
    with pytest.raises(SceneError) as err:
        registry.get(scene.data["scene"]["plugin"]).build(scene, 0)
    assert err.value.key == key


def test_unknown_plugin_lists_known_ones():
    with pytest.raises(SceneError, match="obstacle, antiplane, signorini"):
        registry.get("obstacel")
