"""The pieces both contact fronts share (`problems.plugins.contact.interface`), in 2D and 3D."""

from __future__ import annotations

import importlib

import pytest

from problems.errors import SceneError
from problems.plugins import registry
from problems.plugins.contact import interface
from problems.scene import load_scene


@pytest.mark.parametrize(
    ("name", "override"),
    [
        ("rigid_foundation", "contact.g='-1e6 + 1e7*x'"),  # 2D: negative near x = 0
        ("block3d", "contact.g='-1e6 + 1e7*z'"),  # 3D: negative on the contact face z = 0
    ],
)
def test_a_friction_bound_negative_somewhere_on_the_contact_is_refused(name, override):
    """`interface.checked_bound`: an expression ≥ 0 as text but negative at a quadrature point
    of Γ3 is refused at build, naming the field (mutation: drop the guard, this fails)."""
    scene = load_scene(name, [override])
    with pytest.raises(SceneError) as err:
        registry.for_scene(scene).build(scene, 0)
    assert err.value.key == "contact.g" and "≥ 0 everywhere on Γ3" in err.value.allowed


def test_friction_warnings_say_apart_frictionless_or_tied():
    """`interface.friction_warnings` (both fronts' summary.json warnings): nothing touches,
    g = 0, no node slips (with the share of the bound λ_t uses), and silence otherwise."""
    import numpy as np

    from problems.plugins.contact.interface import friction_warnings

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
