"""One value type per kind for 2D and 3D scenes: an expression of (x, y[, z]), and the former
3D names that the docs named served for one release with a DeprecationWarning."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from problems.scene.fields import Expression

RENAMED = [("fields", "Expression3", "Expression"), ("exact", "ExactSection3", "ExactSection")]


@pytest.mark.parametrize("module,old,new", RENAMED)
def test_a_former_3d_name_is_the_one_type_with_a_warning(module, old, new):
    mod = importlib.import_module(f"problems.scene.{module}")
    with pytest.warns(DeprecationWarning, match=f"{old} is deprecated .* use {new}"):
        assert getattr(mod, old) is getattr(mod, new)
    with pytest.raises(AttributeError, match="Vector3"):
        mod.Vector3  # noqa: B018 (a name that never was public stays unknown)


def test_one_expression_takes_2d_and_3d_points():
    """z is 0 where a 2D scene calls it; an expression of z needs three coordinates."""
    x, y, z = np.array([0.5, 1.0]), np.array([2.0, 3.0]), np.array([4.0, 5.0])
    assert np.array_equal(Expression("x*y")(x, y), Expression("x*y")(x, y, z))
    assert np.array_equal(Expression("x + z")(x, y, z), x + z)
    with pytest.raises(TypeError, match="x, y, z"):
        Expression("x + z")(x, y)
