"""`mixvi check` on the 3D scenes: ssn, homotopy and conic (second-order cones) agree on the
friction-disc problems, each raw answer judged by the independent checker (level 0 in CI,
level 1 under `slow`: homotopy needs 34 ssn solves, 70 s for block3d)."""

from __future__ import annotations

import pytest

from problems.commands.check import _check_level
from problems.plugins import contact3d
from problems.scene import load_scene

LEVELS = [
    pytest.param("block3d", 0),
    pytest.param("rigid_foundation_extruded", 0),
    pytest.param("block3d", 1, marks=pytest.mark.slow),
    pytest.param("rigid_foundation_extruded", 1, marks=pytest.mark.slow),
]


@pytest.mark.parametrize("name,level", LEVELS)
def test_ssn_homotopy_and_conic_agree_on_a_3d_scene(name, level):
    ok, rec = _check_level(load_scene(name), contact3d, level, 1e-10)
    assert ok, rec
    assert set(rec["methods"]) == {"ssn", "homotopy", "conic"}, rec
