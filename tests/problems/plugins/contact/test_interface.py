"""The pieces both contact fronts share (`problems.plugins.contact.interface`), in 2D and 3D."""

from __future__ import annotations

import pytest

from problems.errors import SceneError
from problems.plugins import registry
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
