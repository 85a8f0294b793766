"""The pieces both contact fronts share (`problems.plugins.contact.interface`, `rows`,
`reports`), in 2D and 3D."""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest

import vi_core
from fem.facets import facet_integrals
from problems.errors import SceneError
from problems.plugins import registry
from problems.plugins.contact import bodies, contact_state, interface
from problems.scene import load_scene


@pytest.mark.parametrize(
    ("name", "override"),
    [
        ("rigid_foundation", "contact.g='-1e6 + 1e7*x'"),  # 2D: negative near x = 0
        ("block3d", "contact.g='-1e6 + 1e7*z'"),  # 3D: negative on the contact face z = 0
    ],
)
def test_a_friction_bound_negative_somewhere_on_the_contact_is_refused(name, override):
    """`rows.checked_bound`: an expression ≥ 0 as text but negative at a quadrature point
    of Γ3 is refused at build, naming the field (mutation: drop the guard, this fails)."""
    scene = load_scene(name, [override])
    with pytest.raises(SceneError) as err:
        registry.for_scene(scene).build(scene, 0)
    assert err.value.key == "contact.g" and "≥ 0 everywhere on Γ3" in err.value.allowed


def test_friction_warnings_say_apart_frictionless_or_tied():
    """`reports.friction_warnings` (both fronts' summary.json warnings): nothing touches,
    g = 0, no node slips (with the share of the bound λ_t uses), and silence otherwise."""
    import numpy as np

    from problems.plugins.contact.reports import friction_warnings

    states = np.array(["stick", "slip"])
    g, lam_t, slip, touch = np.array([2.0, 2.0]), np.array([1.0, 2.0]), np.array([0, 1]), [1, 1]
    assert friction_warnings(states, g, lam_t, slip.astype(bool), np.array(touch, bool)) == []
    apart = friction_warnings(states, g, lam_t, slip.astype(bool), np.zeros(2, bool))
    assert apart == ["no node of Γ3 touches: the bodies are apart (λ = 0)"]
    free = friction_warnings(states, 0 * g, lam_t, slip.astype(bool), np.ones(2, bool))
    assert any("frictionless" in w for w in free)
    tied = friction_warnings(states, g, np.array([-1.0, 0.5]), np.zeros(2, bool), np.ones(2, bool))
    assert any("uses at most 0.5 of the friction bound" in w and "tied" in w for w in tied)


@pytest.mark.parametrize(
    "module, name", [("curve_contact", "Contact"), ("surface_contact", "SolidContact")]
)
def test_the_former_interface_classes_are_deprecated_names_of_interface(module, name):
    """2D `Contact` and 3D `SolidContact` became the one `interface.Interface` (issue 30)."""
    mod = importlib.import_module(f"problems.plugins.contact.{module}")
    with pytest.warns(DeprecationWarning, match=f"{name} is deprecated"):
        assert getattr(mod, name) is interface.Interface


def _interface(name: str, *overrides: str):
    scene = load_scene(name, list(overrides))
    return registry.for_scene(scene).build(scene, 0).contact


@pytest.mark.parametrize("name", ["rigid_foundation", "block3d"])
def test_surf_is_a_deprecated_name_of_the_slave_trace(name):
    """3D `SolidContact.surf` became `Interface.tr`: it still answers, with a warning naming
    the new spelling (mutation: drop the warning or return another trace, this fails)."""
    c = _interface(name)
    with pytest.warns(
        DeprecationWarning, match=r"Interface\.surf is deprecated: use Interface\.tr"
    ):
        assert c.surf is c.tr


@pytest.mark.parametrize(
    ("name", "override"),
    [
        ("rigid_foundation", "contact.g='1e6 + 1e7*x*x'"),
        ("paper_two_body", "contact.g='2e7 + 1e7*x*x'"),
        ("block3d", "contact.g='1e6 + 1e7*x*y'"),
        ("shear_strip", "contact.g='1e6 + 1e7*x*x'"),  # merged ends: W_t ≠ W next to them
        ("bracket3d", "contact.g='1e6 + 1e7*x*y'"),  # the same in 3D
    ],
)
def test_g_weights_is_the_former_integral_of_g_per_tangential_row(name, override):
    """2D `Contact.g_weights` was (N_t,) ∫gφ̃_k per tangential row: recomputed here from the
    scene's g by the slave trace's quadrature and the tangential basis Q_t (mutation: W for W_t,
    which differs where an end merged its function in, or g per trace node, this fails)."""
    c = _interface(name, override)
    order = {} if c.dim == 2 else {"order": interface.SURFACE_ORDER[c.slave.mesh.cell_type]}
    gloc = facet_integrals(c.slave.mesh, c.tr, c.bound_field, **order)  # (n_f, m)
    expected = c.Q_t @ gloc.ravel()  # (N_t,) ∫gφ̃_k
    with pytest.warns(DeprecationWarning, match=r"use Interface\.g\[rows_t\] \* Interface\.W_t"):
        got = c.g_weights
    assert got.shape == (c.rows_t.size,)
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=0)


def test_g_weights_is_zero_under_coulomb_friction():
    """The former `g_weights` was 0 for Coulomb friction (its bound is F λ_n, not g)."""
    c = _interface("coulomb_strip")
    with pytest.warns(DeprecationWarning):
        assert c.g_weights.shape == (c.rows_t.size,) and not c.g_weights.any()


def test_a_name_that_cannot_come_back_says_what_to_use():
    """`Contact.pairs` has no counterpart (3D nodes have triples): the AttributeError names
    `rows()`; other missing names keep the plain error, and hasattr stays False."""
    c = _interface("signorini")
    with pytest.raises(AttributeError, match=r"Interface\.pairs is gone.*Interface\.rows\(\)"):
        c.pairs  # noqa: B018
    with pytest.raises(AttributeError, match=r"^'Interface' object has no attribute 'nope'$"):
        c.nope  # noqa: B018
    assert not hasattr(c, "nope")


def test_the_3d_master_is_the_body_and_its_former_coupling_names_point_to_coupling():
    """3D `SolidContact.master` was the `Coupling`; now it is the master Body (2D and 3D
    alike): the Coupling's names on it raise an AttributeError naming `Interface.coupling`,
    and every name that hint answers is there (n_cells, dropped from the Coupling in 4587fd3,
    once sent users to a Coupling without it)."""
    c = _interface("two_blocks3d")
    assert c.master is c.coupling.body
    for name in sorted(bodies.COUPLING_NAMES):
        assert hasattr(c.coupling, name), name
        with pytest.raises(AttributeError, match=r"is Interface\.coupling"):
            getattr(c.master, name)
    with pytest.raises(AttributeError, match=r"^'Body' object has no attribute 'nope'$"):
        c.master.nope  # noqa: B018


def test_an_attribute_error_inside_a_property_is_not_hidden_by_the_hints():
    """The hints of former names (`interface.Gone`) do not answer for a property that raises
    AttributeError inside: the property's own error reaches the user. (Mutation: the former
    `__getattr__` hints on Interface and Body reported "'Interface' object has no attribute
    'W'" and "'Body' object has no attribute 'dim'" here, and this fails.)"""
    c = _interface("two_blocks3d")
    broken = dataclasses.replace(c, tr=object())  # a trace without weights
    with pytest.raises(AttributeError, match=r"'object' object has no attribute 'weights'"):
        broken.W  # noqa: B018
    body = dataclasses.replace(c.master, mesh=object())  # a mesh without points
    with pytest.raises(AttributeError, match=r"'object' object has no attribute 'points'"):
        body.dim  # noqa: B018
    with pytest.raises(AttributeError, match=r"is Interface\.coupling"):
        body.M_loc  # noqa: B018


@pytest.mark.parametrize("name", ["coulomb_strip", "coulomb_strip3d"])
def test_the_pressure_scale_is_the_largest_force_per_smallest_normal_row_weight(name):
    """One rule in 2D and 3D (`contact_state.jumps`): the pressure scale is the larger of the
    largest λ_n and the largest elastic nodal force |A u| per the smallest weight W_n,k of a row
    carrying λ_n. coulomb_strip3d's clamped corners carry no row and have 1/8 of that weight at
    level 0 (mutation: the former 3D rule, the smallest W of any trace node, gives 8 × the
    scale and fails)."""
    scene = load_scene(name, [])
    model = registry.for_scene(scene).build(scene, 0)
    sol = vi_core.solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged
    c = model.contact
    w_rows = c.W_n[c.rows_n].min()  # the smallest normal-row weight
    if c.dim == 3:  # the scene tells the rules apart
        assert c.W.min() < w_rows / 4
    disp = model.unknown_fields().get("displacement", slice(None))
    force = np.abs((model.vi.A @ sol.u)[disp]).max()  # the largest elastic nodal force
    expected = max(sol.lam[c.idx_n].max(), force / w_rows)
    assert contact_state.jumps(model, sol, np.zeros(0)).pressure == pytest.approx(expected, 1e-14)
    assert contact_state.contact_state(model, sol)["pressure"] == pytest.approx(expected, 1e-14)
