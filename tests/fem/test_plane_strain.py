"""Issue 18, 5(a) at the element level: a 2D plane-strain piezoelectric problem in the x–y plane
of the 2D code is the 3D problem in the x–z plane on a mesh one hexahedral cell thick (in y) with
w = u_y = 0, BaTiO3 poled along z, and the 2D constants = the 3D ones restricted to x–z.

Prolongation P: 2D dofs (u_x, u_y, φ) of node (i, k) ↦ 3D dofs (u_x, 0, u_z, φ) of nodes (i, 0, k)
and (i, 1, k). Then Pᵀ A₃ P = t A₂ and Pᵀ F₃ = t F₂ to rounding (t the thickness), and the 3D
solution with only w = 0 imposed (front and back faces free) equals the 2D one to rounding: the
problem is symmetric under y ↦ t − y (a mirror plane of 6mm containing the poling axis), so its
unique solution is y-independent and solves the Galerkin restriction, which is t × the 2D one.
"""

import sys

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import fem.assembly as asm
from fem.mesh import Mesh
from fem.meshing import box, rectangle, transform
from fem.tensors import NAMED, Material3D, plane_strain

C0, K0 = 1e10, 1e-8
_M = NAMED["BaTiO3"]
MAT3 = Material3D("BaTiO3 (scaled)", _M.C / C0, _M.e / np.sqrt(C0 * K0), _M.kappa / K0)
MAT2 = plane_strain(MAT3, "xz")
NX, NZ, T = 5, 3, 0.37  # cells along x and z (2D y), thickness


def bend(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A smooth distortion of [0, 2] × [0, 1] (in-plane coordinates a = x, b = z or 2D y)."""
    return a + 0.12 * np.sin(np.pi * b) * np.sin(1.3 * a), b + 0.08 * np.sin(np.pi * a / 2) * b


def meshes() -> tuple[Mesh, object]:
    m2 = rectangle((0.0, 2.0), (0.0, 1.0), (NX, NZ), "quad")
    a, b = bend(*m2.points.T)
    m2 = Mesh(np.stack([a, b], axis=1), m2.cells, m2.boundaries)

    def bend3(p):
        a, b = bend(p[:, 0], p[:, 2])
        return np.stack([a, p[:, 1], b], axis=1)

    m3 = transform(box((0.0, 2.0), (0.0, T), (0.0, 1.0), (NX, 1, NZ)), bend3)
    return m2, m3


def prolongation(m2: Mesh, m3) -> sp.csr_matrix:
    """(4 N₃ × 3 N₂) from 2D dofs [u (2 N₂ interleaved), φ] to 3D dofs [u (3 N₃), φ]."""
    N2, N3 = m2.n_nodes, m3.n_nodes
    i, k = np.arange(N2) % (NX + 1), np.arange(N2) // (NX + 1)  # 2D node (i, k)
    rows, cols = [], []
    for j in (0, 1):  # the two node planes y = 0, y = T
        n3 = i + (NX + 1) * (j + 2 * k)  # (N2,) the 3D node of (i, j, k)
        assert np.allclose(m3.points[n3][:, [0, 2]], m2.points) and np.allclose(
            m3.points[n3][:, 1], j * T
        )
        rows += [3 * n3, 3 * n3 + 2, 3 * N3 + n3]  # u_x, u_z, φ
        cols += [2 * np.arange(N2), 2 * np.arange(N2) + 1, 2 * N2 + np.arange(N2)]
    r, c = np.concatenate(rows), np.concatenate(cols)
    return sp.csr_matrix((np.ones(r.size), (r, c)), shape=(4 * N3, 3 * N2))


def piezo2(m2: Mesh) -> sp.csr_matrix:
    K = asm.elasticity_matrix(m2, MAT2.C)
    G = asm.coupling_matrix(m2, MAT2.e)
    P = asm.permittivity_matrix(m2, MAT2.kappa)
    return sp.bmat([[K, G.T], [-G, P]], format="csr")


def body(x, z):
    return np.stack([np.sin(x + z), 0.5 * np.cos(2 * x) * z], axis=-1)  # (f_x, f_z)


def charge(x, z):
    return 0.3 * x * z - 0.1


def loads2(m2: Mesh) -> np.ndarray:
    f = asm.volume_load(m2, body, 2) + asm.boundary_load(m2, "top", [0.4, -1.0], 2)
    q = asm.volume_load(m2, charge, 1) + asm.boundary_load(m2, "top", lambda x, y: 0.2 * x, 1)
    return np.concatenate([f, q])


def loads3(m3) -> np.ndarray:
    def body3(x, y, z):
        f = body(x, z)
        return np.stack([f[..., 0], 0 * x, f[..., 1]], axis=-1)

    f = asm.volume_load(m3, body3, 3) + asm.boundary_load(m3, "top", [0.4, 0.0, -1.0], 3)
    q = asm.volume_load(m3, lambda x, y, z: charge(x, z), 1) + asm.boundary_load(
        m3, "top", lambda x, y, z: 0.2 * x, 1
    )
    return np.concatenate([f, q])


def operator_defect() -> float:
    """max |Pᵀ A₃ P − t A₂| / max |A₂| and the same for the loads."""
    m2, m3 = meshes()
    P = prolongation(m2, m3)
    A2 = piezo2(m2)
    A3 = asm.piezo_matrix(m3, MAT3.C, MAT3.e, MAT3.kappa)
    F2, F3 = loads2(m2), loads3(m3)
    return max(
        abs(P.T @ A3 @ P - T * A2).max() / abs(A2).max(),
        np.abs(P.T @ F3 - T * F2).max() / np.abs(F2).max(),
    )


def solution_defect() -> float:
    """Solve both (u = 0, φ = 0 on the bottom; in 3D also w = 0 everywhere), compare."""
    m2, m3 = meshes()
    N2, N3 = m2.n_nodes, m3.n_nodes
    fixed2 = np.zeros(3 * N2, dtype=bool)
    b2 = m2.boundary_nodes("bottom")
    fixed2[np.concatenate([2 * b2, 2 * b2 + 1, 2 * N2 + b2])] = True
    fixed3 = np.zeros(4 * N3, dtype=bool)
    b3 = m3.boundary_nodes("bottom")
    fixed3[np.concatenate([3 * b3, 3 * b3 + 2, 3 * N3 + b3])] = True
    fixed3[3 * np.arange(N3) + 1] = True  # w = 0
    out = []
    for A, F, fixed in (
        (piezo2(m2), loads2(m2), fixed2),
        (asm.piezo_matrix(m3, MAT3.C, MAT3.e, MAT3.kappa), loads3(m3), fixed3),
    ):
        free = np.flatnonzero(~fixed)
        x = np.zeros(A.shape[0])
        x[free] = spla.spsolve(sp.csc_matrix(A.tocsr()[free][:, free]), F[free])
        out.append(x)
    x2, x3 = out
    P = prolongation(m2, m3)
    return np.abs(x3 - P @ x2).max() / np.abs(x2).max()


def test_restricted_operator_and_loads_are_t_times_the_2d_ones():
    assert operator_defect() < 1e-14


def test_3d_solution_one_cell_thick_equals_the_2d_one():
    assert solution_defect() < 1e-12


@pytest.mark.parametrize("fault", ["half_shear", "flip", "wrong_plane"])
def test_the_comparison_catches(monkeypatch, fault):
    if fault == "half_shear":  # a missing factor 2 in the 3D Voigt shear strains
        good = asm.strain_operator
        monkeypatch.setattr(asm, "strain_operator", lambda g: _half_shear_of(good, g))
    elif fault == "flip":  # the 3D coupling blocks with swapped signs (Gᵀ ↔ −G)
        good_pm = asm.piezo_matrix

        def flipped(mesh, C, e, kappa):
            A = good_pm(mesh, C, e, kappa).tolil()
            n = 3 * mesh.n_nodes
            A[:n, n:], A[n:, :n] = -A[:n, n:], -A[n:, :n]
            return A.tocsr()

        monkeypatch.setattr(asm, "piezo_matrix", flipped)
    else:  # the 2D constants taken from the wrong plane of the 3D tensors
        monkeypatch.setattr(sys.modules[__name__], "MAT2", plane_strain(MAT3, "xy"))
    assert operator_defect() > 1e-3
    assert solution_defect() > 1e-3


def _half_shear_of(good, grad):
    B = good(grad)
    B[..., 3:, :] *= 0.5  # tensor shear ε_ij in place of γ_ij = 2 ε_ij
    return B
