"""`checks.finite_data`, the build-time guard both fronts pass to `model.mixed_vi`: an
overflowing friction bound, gap or load is refused naming what overflowed (2D and 3D)."""

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from problems.errors import SceneError
from problems.plugins.contact import checks, plane, solid
from problems.scene import load_scene


@pytest.mark.parametrize(("front", "scene"), [(plane, "rigid_foundation"), (solid, "block3d")])
def test_finite_data_names_what_overflows(front, scene):
    model = front.build(load_scene(scene), 0)
    c, A = model.contact, sp.csr_matrix(np.eye(2))
    f, values = np.zeros(2), np.zeros(2)
    checks.finite_data(A, f, values, c)  # the built data pass
    with pytest.raises(SceneError, match="loads"):
        checks.finite_data(A, np.array([np.inf, 0.0]), values, c)
    bad_g = dataclasses.replace(c, g=np.where(np.arange(c.g.size) == 0, np.inf, c.g))
    with pytest.raises(SceneError, match="friction bound g"):
        checks.finite_data(A, f, values, bad_g)
