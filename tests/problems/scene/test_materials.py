"""Materials of 2D and 3D scenes from one crystal table: the 2D constants are the plane-strain
reduction of the 3D tensors poled along y (the published 6mm layout, exactly), the same kinds
read the same in both dimensions with matrices of the scene's sizes, and a material given by its
full tensors solves the same problem as the named one."""

import numpy as np
import pytest

from problems.errors import SceneError
from problems.plugins.contact import plane as pc
from problems.plugins.contact import solid as contact3d
from problems.scene import load_scene
from problems.scene import materials as mt
from vi_core import solve


@pytest.mark.parametrize("name", sorted(mt.CRYSTALS))
def test_the_2d_constants_are_the_6mm_layout_poled_along_y(name):
    """C on (xx, yy, xy), the σ_zz rows, e and κ of a crystal poled along y, entry by entry."""
    c11, c12, c13, c33, c44, e31, e33, e15, k11, k33 = mt.CRYSTALS[name]
    m = mt.NamedMaterial(name=name).material(2)
    assert np.array_equal(m.C, [[c11, c13, 0.0], [c13, c33, 0.0], [0.0, 0.0, c44]])
    assert np.array_equal(m.C_zz, [c12, c13, 0.0])
    assert np.array_equal(m.e, [[0.0, 0.0, e15], [e31, e33, 0.0]])
    assert np.array_equal(m.e_zz, [0.0, e31])
    assert np.array_equal(m.kappa, np.diag([k11, k33]))
    assert {k: np.array(v).tolist() for k, v in mt.NAMED[name].items()} == {
        k: getattr(m, k).tolist() for k in ("C", "e", "kappa", "C_zz", "e_zz")
    }


def test_mutation_a_wrong_out_of_plane_row_is_told_apart(monkeypatch):
    """Reducing with the wrong σ row (yy instead of zz) is caught by the test above."""

    def wrong(m):
        p = mt.in_plane(m, "xy")
        return mt.Material(m.name, p.C, p.e, p.kappa, m.C[1, [0, 1, 5]], m.e[:2, 2])

    monkeypatch.setattr(mt, "plane_strain", wrong)
    with pytest.raises(AssertionError):
        test_the_2d_constants_are_the_6mm_layout_poled_along_y("BaTiO3")


def test_isotropic_is_the_same_law_in_2d_and_3d():
    table = mt.Isotropic(kind="isotropic", E=2.0e11, nu=0.3)
    m2, m3 = table.material(2), table.material(3)
    assert np.array_equal(m2.C, m3.C[np.ix_([0, 1, 5], [0, 1, 5])])
    assert np.array_equal(m2.C_zz, m3.C[2, [0, 1, 5]]) and m2.e is None and m3.e is None
    lam = m3.C[0, 1]
    assert np.allclose(m3.C[:3, :3], lam + (m3.C[0, 0] - lam) * np.eye(3), rtol=1e-15)


def test_the_default_poling_is_the_vertical_axis():
    for dim, axis in ((2, [0.0, 1.0, 0.0]), (3, [0.0, 0.0, 1.0])):
        named = mt.NamedMaterial
        a, b = named(name="PZT-5H").material(dim), named(name="PZT-5H", poling=axis).material(dim)
        assert np.array_equal(a.C, b.C) and np.array_equal(a.e, b.e)
    sideways = mt.NamedMaterial(name="PZT-5H", poling=[1.0, 0.0, 0.0]).material(2)
    assert sideways.e[0, 0] == mt.CRYSTALS["PZT-5H"][6]  # D_x ← ε_xx: e33 along x


def _solved(build, scene, level=0):
    model = build(scene, level)
    sol = solve(model.vi, "ssn", tol=1e-12)
    assert sol.converged
    return np.concatenate([sol.u, sol.lam])


def _table(m) -> str:
    """A material's tensors as a TOML inline table of kind piezoelectric."""

    def mat(a):
        return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in r) + "]" for r in a) + "]"

    return f"{{kind='piezoelectric', C={mat(m.C)}, e={mat(m.e)}, kappa={mat(m.kappa)}}}"


@pytest.mark.parametrize(
    ("name", "plugin", "dim"),
    [("rigid_foundation", pc, 2), ("block3d", contact3d, 3)],
)
def test_full_tensors_solve_the_named_material_s_problem(name, plugin, dim):
    """The named BaTiO3 written out as a piezoelectric table (3×3/2×3/2×2 in 2D, 6×6/3×6/3×3
    in 3D) gives the same solution; with e's sign flipped it does not (mutation)."""
    named = _solved(plugin.build, load_scene(name))
    m = mt.NamedMaterial(name="BaTiO3").material(dim)
    written = load_scene(name, [f"bodies.block.material={_table(m)}"])
    scale = np.abs(named).max()
    assert np.allclose(_solved(plugin.build, written), named, rtol=1e-12, atol=1e-14 * scale)
    flipped = type(m)(m.name, m.C, -m.e, m.kappa)
    wrong = load_scene(name, [f"bodies.block.material={_table(flipped)}"])
    assert not np.allclose(_solved(plugin.build, wrong), named, rtol=1e-6, atol=1e-8 * scale)


@pytest.mark.parametrize(
    ("name", "value", "key", "words"),
    [
        ("block3d", "{kind='anisotropic', C=[[1,0,0],[0,1,0],[0,0,1]]}", ".C", "6×6 matrix"),
        ("rigid_foundation", "{kind='anisotropic', C=[[1,0],[0,1]]}", ".C", "3×3 matrix"),
        ("block3d", "{name='BaTiO3', poling=[0,0,0]}", ".poling", "non-zero direction"),
        ("rigid_foundation", "{name='BaTiO3', poling=[0,1]}", ".poling", "3 or more"),
        ("block3d", "{kind='iso', E=1, nu=0.3}", "", "kind = isotropic | anisotropic"),
    ],
)
def test_a_material_of_the_wrong_size_is_refused_naming_the_key(name, value, key, words):
    plugin = contact3d if name == "block3d" else pc
    with pytest.raises(SceneError) as err:
        load_scene(name, [f"bodies.block.material={value}"]).validated(plugin.SCENE_MODEL)
    assert err.value.key == "bodies.block.material" + key and words in str(err.value)
