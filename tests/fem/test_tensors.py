"""3D Voigt tensors: Bond rotations against full-tensor rotations, 6mm, isotropic, orthotropic,
published constants and their plane-strain restriction against the 2D constants in use."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import fem.tensors as tensors
from fem.tensors import (
    EPS0,
    NAMED,
    VOIGT_PAIRS,
    Material3D,
    bond_matrix,
    crystal_6mm,
    isotropic,
    orthotropic,
    plane_strain,
    poled,
    rotate,
    rotation_to,
)

from .helpers import full_tensors


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    Q, Rr = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(Rr))
    return Q if np.linalg.det(Q) > 0 else -Q


def rotation_defect(m: Material3D, R: np.ndarray) -> float:
    """max |Bond-rotated − tensor-rotated| relative to the entries, over C, e and κ."""
    c, e = full_tensors(m)
    c_rot = np.einsum("ia,jb,kc,ld,abcd->ijkl", R, R, R, R, c)
    e_rot = np.einsum("ka,ib,jc,abc->kij", R, R, R, e)
    k_rot = R @ m.kappa @ R.T
    cb, eb = full_tensors(rotate(m, R))
    return max(
        np.abs(cb - c_rot).max() / np.abs(c).max(),
        np.abs(eb - e_rot).max() / np.abs(e).max(),
        np.abs(rotate(m, R).kappa - k_rot).max() / np.abs(m.kappa).max(),
    )


@given(seed=st.integers(0, 2**32 - 1), name=st.sampled_from(sorted(NAMED)))
def test_bond_rotation_equals_tensor_rotation(seed, name):
    R = random_rotation(np.random.default_rng(seed))
    assert rotation_defect(NAMED[name], R) < 1e-13


def test_bond_rotation_check_catches_the_strain_matrix(monkeypatch):
    """Fault: the strain Bond matrix M⁻ᵀ used in place of the stress one M."""
    R = random_rotation(np.random.default_rng(3))
    good = bond_matrix
    monkeypatch.setattr(tensors, "bond_matrix", lambda R: np.linalg.inv(good(R)).T)
    assert rotation_defect(NAMED["PZT-5H"], R) > 1e-2


def test_bond_rotation_check_catches_a_missing_shear_term(monkeypatch):
    """Fault: the shear columns of M without the σ_lk half (a missing factor 2 in shear)."""
    R = random_rotation(np.random.default_rng(4))
    i, j = VOIGT_PAIRS.T

    def half(R):
        return R[i[:, None], i[None, :]] * R[j[:, None], j[None, :]]

    monkeypatch.setattr(tensors, "bond_matrix", half)
    assert rotation_defect(NAMED["BaTiO3"], R) > 1e-2


@given(seed=st.integers(0, 2**32 - 1))
def test_bond_matrix_is_a_representation(seed):
    rng = np.random.default_rng(seed)
    R1, R2 = random_rotation(rng), random_rotation(rng)
    assert np.allclose(bond_matrix(R1 @ R2), bond_matrix(R1) @ bond_matrix(R2), atol=1e-13)
    assert np.allclose(bond_matrix(R1.T), np.linalg.inv(bond_matrix(R1)), atol=1e-12)
    assert np.allclose(bond_matrix(np.eye(3)), np.eye(6), atol=0)


@pytest.mark.parametrize("name", sorted(NAMED))
def test_named_6mm_constants(name):
    m = NAMED[name]
    assert np.array_equal(m.C, m.C.T)
    assert np.linalg.eigvalsh(m.C).min() > 0
    assert np.linalg.eigvalsh(m.kappa).min() > 0
    assert np.isclose(m.C[5, 5], 0.5 * (m.C[0, 0] - m.C[0, 1]))
    # transversely isotropic about the poling axis: any rotation about z leaves it unchanged
    for a in (0.3, 1.0, np.pi / 3):
        Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        r = rotate(m, Rz)
        assert np.allclose(r.C, m.C, rtol=0, atol=1e-12 * np.abs(m.C).max())
        assert np.allclose(r.e, m.e, rtol=0, atol=1e-12 * np.abs(m.e).max())
        assert np.allclose(r.kappa, m.kappa, rtol=0, atol=1e-12 * np.abs(m.kappa).max())


def test_poling_direction():
    m = NAMED["PZT-4"]
    x = poled(m, [2.0, 0.0, 0.0])  # poled along +x
    e31, e33, e15 = m.e[2, 0], m.e[2, 2], m.e[0, 4]
    assert np.isclose(x.C[0, 0], m.C[2, 2]) and np.isclose(x.C[1, 1], m.C[0, 0])
    assert np.isclose(x.e[0, 0], e33) and np.isclose(x.e[0, 1], e31)
    assert np.isclose(x.e[0, 2], e31) and np.isclose(abs(x.e[2, 4]), e15)
    assert np.isclose(x.kappa[0, 0], m.kappa[2, 2])
    down = poled(m, [0.0, 0.0, -1.0])  # reversed poling flips the coupling, not C or κ
    assert np.allclose(down.C, m.C) and np.allclose(down.kappa, m.kappa)
    assert np.allclose(down.e[2], -m.e[2])
    # the rotation about the axis is irrelevant: two rotations taking e_z to d agree
    d = np.array([1.0, -2.0, 0.5])
    a = 0.7
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    R = rotation_to(d)
    assert np.allclose(R @ [0, 0, 1], d / np.linalg.norm(d))
    p1, p2 = rotate(m, R), rotate(m, R @ Rz)
    assert np.allclose(p1.C, p2.C, rtol=0, atol=1e-12 * np.abs(m.C).max())
    assert np.allclose(p1.e, p2.e, rtol=0, atol=1e-12 * np.abs(m.e).max())
    with pytest.raises(ValueError, match="non-zero"):
        poled(m, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="reflection"):
        rotate(m, np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="orthogonal"):
        rotate(m, 2 * np.eye(3))


def test_isotropic():
    E, nu = 2.0e11, 0.3
    m = isotropic(E, nu)
    S = np.linalg.inv(m.C)
    assert np.isclose(S[0, 0], 1 / E) and np.isclose(S[0, 1], -nu / E)
    assert np.isclose(S[3, 3], 2 * (1 + nu) / E)  # 1/G with engineering shear
    R = random_rotation(np.random.default_rng(5))
    assert np.allclose(rotate(m, R).C, m.C, rtol=0, atol=1e-12 * E)
    with pytest.raises(ValueError):
        isotropic(E, 0.5)


def test_orthotropic():
    E, nu, G = (1.4e11, 0.9e10, 0.9e10), (0.3, 0.3, 0.49), (3.0e9, 5.0e9, 5.0e9)
    m = orthotropic(E, nu, G)
    S = np.linalg.inv(m.C)
    assert np.allclose(1 / np.diag(S)[:3], E, rtol=1e-12)
    assert np.allclose(1 / np.diag(S)[3:], G, rtol=1e-12)
    assert np.isclose(-S[0, 1] * E[0], nu[0]) and np.isclose(-S[1, 2] * E[1], nu[2])
    assert np.isclose(-S[1, 0] * E[1], nu[0] * E[1] / E[0])  # ν21 = ν12 E2/E1
    # the isotropic case is the isotropic material
    iso = orthotropic((2.0,) * 3, (0.25,) * 3, (0.8,) * 3)
    assert np.allclose(iso.C, isotropic(2.0, 0.25).C, rtol=1e-13)
    with pytest.raises(ValueError, match="positive definite"):
        orthotropic((1.0, 1.0, 1.0), (0.9, 0.9, 0.9), (1.0, 1.0, 1.0))


def test_plane_strain_layout():
    m = crystal_6mm("t", 11.0, 12.0, 13.0, 33.0, 44.0, 31.0, 3.3, 15.0, 1.1, 3.3)
    p = plane_strain(m, "xz")
    assert np.array_equal(p.C, [[11.0, 13.0, 0], [13.0, 33.0, 0], [0, 0, 44.0]])
    assert np.array_equal(p.e, [[0, 0, 15.0], [31.0, 3.3, 0]])
    assert np.array_equal(p.kappa, np.diag([1.1, 3.3]))
    assert plane_strain(isotropic(1.0, 0.2), "xy").e is None
    with pytest.raises(ValueError, match="unknown plane"):
        plane_strain(m, "zx")


def test_3d_constants_restricted_to_the_xz_plane_match_the_2d_ones():
    """The 2D scenes' constants (poling axis 3 = y in the 2D x–y plane) are the 3D ones, poled
    along z, in the x–z plane. C and e agree exactly; PZT-5H's κ too (both 1700 ε0, 1470 ε0);
    BaTiO3's 2D κ11 = 9.87e-9, κ33 = 1.116e-8 are 1115 ε0, 1260 ε0 rounded (+2.5e-4, −3.3e-4)."""
    from problems.scene.materials import NAMED as NAMED_2D

    for name in ("BaTiO3", "PZT-5H"):
        p, q = plane_strain(NAMED[name], "xz"), NAMED_2D[name]
        assert np.array_equal(p.C, np.array(q["C"])), name
        assert np.array_equal(p.e, np.array(q["e"])), name
        rel = np.abs(p.kappa - np.array(q["kappa"])).max() / np.abs(p.kappa).max()
        assert rel < 4e-4, (name, rel)
    assert np.isclose(NAMED["BaTiO3"].kappa[0, 0], 9.87e-9, rtol=1e-3)
    assert EPS0 == pytest.approx(8.854e-12, rel=1e-4)
