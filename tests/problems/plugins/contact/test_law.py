"""The shared [contact] law keys (problems.plugins.contact.law): the same refusals for the 2D
table (piezo_contact) and the 3D one (contact3d), and one table class per field type."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from problems.errors import SceneError
from problems.plugins.contact import law as contact_law
from problems.plugins.contact import plane as piezo_contact
from problems.plugins.contact import scene_model
from problems.plugins.contact import solid as contact3d
from problems.scene import load_scene

SCENES = {"piezo_contact": "coulomb_strip", "contact3d": "coulomb_strip3d"}
# (overrides, the key refused, words of the message)
BAD = [
    (["contact.law='bilateral'"], "contact.friction", "'tresca' with law = 'bilateral'"),
    (["contact.g=1e5"], "contact.g", "absent with friction = 'coulomb'"),
    (["contact.friction='tresca'"], "contact.g", "required with friction = 'tresca'"),
    (
        [
            "contact.law='bilateral'",
            "contact.friction='tresca'",
            "contact.g=1.0",
            "contact.gap=0.1",
        ],
        "contact.F",
        "absent with friction = 'tresca'",
    ),
    (["contact.gap=-1.0"], "contact.gap", "≥ 0"),
    (["contact.law='elastic'"], "contact.law", "bilateral"),
]


def test_one_law_table_for_both_fronts():
    assert issubclass(scene_model.ContactSection, contact_law.ContactLaw)
    assert piezo_contact.SCENE_MODEL is contact3d.SCENE_MODEL is scene_model.ContactScene


@pytest.mark.parametrize("plugin", sorted(SCENES))
@pytest.mark.parametrize(("over", "key", "words"), BAD)
def test_both_plugins_refuse_the_same_law_errors(plugin, over, key, words):
    with pytest.raises(SceneError) as err:
        load_scene(SCENES[plugin], over).validated(
            {"piezo_contact": piezo_contact, "contact3d": contact3d}[plugin].SCENE_MODEL
        )
    assert key in str(err.value) and words in str(err.value), str(err.value)


@given(
    F=st.floats(0.0, 10.0),
    dim=st.sampled_from([2, 3]),
    friction=st.sampled_from(["tresca", "coulomb"]),
)
def test_pair_set_radius_is_the_law(F, dim, friction):
    """Coulomb: ρ = F·max(y_n, 0); contact-only Tresca: ρ = g where y_n > 0, 0 elsewhere."""
    import numpy as np

    s = contact_law.pair_set(friction, np.array([F, F]), dim)
    assert s.dim == dim and s.quasi
    rho, _ = s.radius(np.array([2.0, -1.0]))
    want = [2.0 * F, 0.0] if friction == "coulomb" else [F, 0.0]
    assert np.allclose(rho, want)
