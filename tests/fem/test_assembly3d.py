"""3D assembly: geometry, rigid-body modes, energies against full tensors, patch tests, rotation
consistency, symmetry/semi-definiteness, loads and post-processing — each with the fault it
must catch (a missing factor 2 in the Voigt shear strains, a Voigt shear order mix-up, a sign
flip of the coupling block, a wrong Bond matrix)."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given
from hypothesis import strategies as st

import fem.assembly3d as asm
import fem.tensors as tensors
from fem.assembly3d import (
    boundary_load,
    cell_fields,
    cell_geometry,
    coupling_matrix,
    elasticity_matrix,
    h1_seminorm_error,
    interpolate,
    l2_error,
    mass_matrix,
    permittivity_matrix,
    piezo_matrix,
    strain_operator,
    volume_load,
)
from fem.mesh import Mesh as Mesh3D
from fem.meshing import SIDES, box, transform
from fem.tensors import NAMED, VOIGT_PAIRS, Material3D, orthotropic, poled, rotate

from .helpers import same_matrix, shifted_geometry

ELEMENTS = ["hexahedron", "tetra"]
C0, K0 = 1e10, 1e-8  # dimensionless: C/C0, e/sqrt(C0 K0), κ/K0 (all of order 1)


def scaled(m: Material3D) -> Material3D:
    return Material3D(m.name, m.C / C0, m.e / np.sqrt(C0 * K0), m.kappa / K0)


# BaTiO3 poled along a direction that is no coordinate axis: every block of C, e, κ is full
PIEZO = scaled(poled(NAMED["BaTiO3"], [0.3, -0.5, 0.8]))


def wavy(p: np.ndarray, amount: float = 0.08) -> np.ndarray:
    """A smooth distortion of [0, 1]³ that keeps the faces plane (cells become curved)."""
    x, y, z = p.T
    b = np.stack([x * (1 - x), y * (1 - y), z * (1 - z)], axis=1)  # (n, 3) vanish on faces
    s = np.stack([np.sin(3 * y + 2 * z), np.cos(2 * x - z), np.sin(x + 2 * y)], axis=1)
    return p + 4 * amount * b * s


def distorted(element: str, n: int = 2, level: int = 0) -> Mesh3D:
    return transform(box((0, 1), (0, 1), (0, 1), (n, n, n), element, level=level), wavy)


def rigid_modes(mesh: Mesh3D) -> np.ndarray:
    """(3N, 6): three translations and three infinitesimal rotations ω × x."""
    N = mesh.n_nodes
    modes = []
    for k in range(3):
        t = np.zeros((N, 3))
        t[:, k] = 1.0
        modes.append(t.ravel())
    for k in range(3):
        w = np.zeros(3)
        w[k] = 1.0
        modes.append(np.cross(w, mesh.points).ravel())
    return np.stack(modes, axis=1)


def voigt_strain(Du: np.ndarray) -> np.ndarray:
    """Engineering Voigt strain (6,) of a displacement gradient Du[i, j] = ∂u_i/∂x_j."""
    E = 0.5 * (Du + Du.T)
    return np.array([E[i, j] * (1 if i == j else 2) for i, j in VOIGT_PAIRS])


def test_geometry():
    for element in ELEMENTS:
        mesh = distorted(element)
        g = cell_geometry(mesh, order=2)
        assert np.isclose(g.w.sum(), 1.0, rtol=1e-13)
        X = mesh.points[mesh.cells]  # (n_cells, n_loc, 3)
        assert np.allclose(np.einsum("cai,cqaj->cqij", X, g.grad), np.eye(3), atol=1e-12)
        assert np.ptp(g.w.sum(axis=1)) > 1e-3  # really distorted


@pytest.mark.parametrize("element", ELEMENTS)
def test_elasticity_kernel_is_the_six_rigid_modes(element):
    mesh = distorted(element)
    C = rotate(orthotropic((3.0, 1.0, 2.0), (0.2, 0.3, 0.25), (0.6, 0.7, 0.8)), _rotation()).C
    K = elasticity_matrix(mesh, C)
    assert K.shape == (3 * mesh.n_nodes,) * 2
    assert abs(K - K.T).max() <= 1e-14 * abs(K).max()
    lam = np.linalg.eigvalsh(K.toarray())
    assert lam.min() > -1e-12 * lam.max()
    assert (lam < 1e-10 * lam.max()).sum() == 6
    assert np.abs(K @ rigid_modes(mesh)).max() <= 1e-12 * lam.max()


def _rotation(seed: int = 7) -> np.ndarray:
    Q, Rr = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(Rr))
    return Q if np.linalg.det(Q) > 0 else -Q


@pytest.mark.parametrize("element", ELEMENTS)
def test_piezo_blocks(element):
    mesh = distorted(element)
    G = coupling_matrix(mesh, PIEZO.e)
    assert G.shape == (mesh.n_nodes, 3 * mesh.n_nodes)
    assert np.abs(G @ rigid_modes(mesh)).max() <= 1e-13 * abs(G).max()
    assert np.abs(np.ones(mesh.n_nodes) @ G).max() <= 1e-13 * abs(G).max()  # ∇1 = 0
    P = permittivity_matrix(mesh, PIEZO.kappa).toarray()
    assert np.allclose(P, P.T, rtol=0, atol=1e-14 * abs(P).max())
    lam = np.linalg.eigvalsh(P)
    assert (lam < 1e-10 * lam.max()).sum() == 1 and lam.min() > -1e-12 * lam.max()
    # the coupled operator: its symmetric part is blockdiag(K, P), positive semi-definite
    A = piezo_matrix(mesh, PIEZO.C, PIEZO.e, PIEZO.kappa)
    K = elasticity_matrix(mesh, PIEZO.C)
    S = 0.5 * (A + A.T)
    assert abs(S - sp.block_diag([K, sp.csr_matrix(P)])).max() <= 1e-14 * abs(A).max()


def energy_defect(element: str) -> float:
    """Discrete energies of linear fields against the full-tensor forms × volume."""
    mesh = distorted(element)
    rng = np.random.default_rng(11)
    Du, a, b = rng.normal(size=(3, 3)), rng.normal(size=3), rng.normal(size=3)
    u = (mesh.points @ Du.T).ravel()  # u(x) = Du x
    phi, theta = mesh.points @ a, mesh.points @ b  # φ = a·x, θ = b·x
    c, e = _full(PIEZO)
    eps = 0.5 * (Du + Du.T)
    exact = [
        np.einsum("ij,ijkl,kl->", eps, c, eps),  # ∫ ε:c:ε
        np.einsum("k,kij,ij->", b, e, eps),  # ∫ ∇θ·(e ε)
        a @ PIEZO.kappa @ b,  # ∫ κ∇φ·∇θ
    ]
    got = [
        u @ elasticity_matrix(mesh, PIEZO.C) @ u,
        theta @ coupling_matrix(mesh, PIEZO.e) @ u,
        phi @ permittivity_matrix(mesh, PIEZO.kappa) @ theta,
    ]
    return max(abs(g - x) / abs(x) for g, x in zip(got, exact, strict=True))


def _full(m: Material3D) -> tuple[np.ndarray, np.ndarray]:
    """c_ijkl and e_kij from the Voigt matrices (the definitions, independent of the kernels)."""
    c, e = np.zeros((3, 3, 3, 3)), np.zeros((3, 3, 3))
    for I, (i, j) in enumerate(VOIGT_PAIRS):
        for J, (k, l) in enumerate(VOIGT_PAIRS):
            for p, q in {(i, j), (j, i)}:
                for r, s in {(k, l), (l, k)}:
                    c[p, q, r, s] = m.C[I, J]
        for p, q in {(i, j), (j, i)}:
            e[:, p, q] = m.e[:, I]
    return c, e


@pytest.mark.parametrize("element", ELEMENTS)
def test_energies_equal_the_full_tensor_forms(element):
    assert energy_defect(element) < 1e-12


def _half_shear(grad):
    B = strain_operator(grad)
    B[..., 3:, :] *= 0.5  # tensor shear ε_ij instead of γ_ij = 2 ε_ij
    return B


def _swapped_shear(grad):
    return strain_operator(grad)[..., [0, 1, 2, 5, 4, 3], :]  # order (xy, xz, yz) for the shears


@pytest.mark.parametrize("fault", [_half_shear, _swapped_shear])
def test_energy_check_catches_voigt_faults(monkeypatch, fault):
    monkeypatch.setattr(asm, "strain_operator", fault)
    assert energy_defect("tetra") > 1e-2


def piezo_patch_defect(mesh: Mesh3D, m: Material3D = PIEZO) -> float:
    """Linear u and φ, Dirichlet data on "left", tractions σn and charges −D·n on the other
    sides: the discrete solution must be the exact one; returns the max relative nodal error."""
    rng = np.random.default_rng(5)
    Du, a = rng.normal(size=(3, 3)), rng.normal(size=3)
    u0, phi0 = rng.normal(size=3), 0.3
    N = mesh.n_nodes
    u_ex = (mesh.points @ Du.T + u0).ravel()  # (3N,)
    phi_ex = mesh.points @ a + phi0  # (N,)
    eps = voigt_strain(Du)  # (6,)
    sig_v = m.C @ eps + m.e.T @ a  # σ = Cε + eᵀ∇φ, Voigt (6,)
    sig = np.zeros((3, 3))
    for I, (i, j) in enumerate(VOIGT_PAIRS):
        sig[i, j] = sig[j, i] = sig_v[I]
    D = m.e @ eps - m.kappa @ a  # (3,)
    f = np.zeros(4 * N)
    for name in SIDES[1:]:  # outward normal of side s: ± e_axis
        axis, end = divmod(SIDES.index(name), 2)
        n = np.zeros(3)
        n[axis] = 1.0 if end else -1.0
        f[: 3 * N] += boundary_load(mesh, name, sig @ n, 3)
        f[3 * N :] -= boundary_load(mesh, name, D @ n, 1)  # −∫ D·∇θ = −∮ D·n θ (div D = 0)
    A = asm.piezo_matrix(mesh, m.C, m.e, m.kappa)  # through the module: faults patch it
    fixed = np.zeros(4 * N, dtype=bool)
    left = mesh.boundary_nodes("left")
    fixed[(3 * left[:, None] + np.arange(3)).ravel()] = True
    fixed[3 * N + left] = True
    x_ex = np.concatenate([u_ex, phi_ex])
    free = np.flatnonzero(~fixed)
    A = A.tocsr()
    rhs = f[free] - A[free][:, fixed] @ x_ex[fixed]
    x = x_ex.copy()
    x[free] = spla.spsolve(A[free][:, free].tocsc(), rhs)
    return max(
        np.abs(x[: 3 * N] - u_ex).max() / np.abs(u_ex).max(),
        np.abs(x[3 * N :] - phi_ex).max() / np.abs(phi_ex).max(),
    )


@pytest.mark.parametrize("element", ELEMENTS)
def test_piezo_patch_test(element):
    assert piezo_patch_defect(distorted(element)) < 1e-11


def test_patch_test_on_an_elastic_orthotropic_body():
    m = rotate(orthotropic((3.0, 1.0, 2.0), (0.2, 0.3, 0.25), (0.6, 0.7, 0.8)), _rotation(2))
    m = Material3D("o", m.C, np.zeros((3, 6)), np.eye(3))  # no coupling
    for element in ELEMENTS:
        assert piezo_patch_defect(distorted(element), m) < 1e-11


def _flipped_coupling(mesh, C, e, kappa):
    K, G, P = elasticity_matrix(mesh, C), coupling_matrix(mesh, e), permittivity_matrix(mesh, kappa)
    return sp.bmat([[K, -G.T], [G, P]], format="csr")  # the coupling blocks' signs swapped


def _coupling_shear_order(mesh, e):
    return coupling_matrix(mesh, e[:, [0, 1, 2, 5, 4, 3]])  # e given in (xy, xz, yz) order


@pytest.mark.parametrize("fault", ["half_shear", "flip", "e_order"])
def test_patch_test_catches(monkeypatch, fault):
    if fault == "half_shear":
        monkeypatch.setattr(asm, "strain_operator", _half_shear)
    elif fault == "flip":
        monkeypatch.setattr(asm, "piezo_matrix", _flipped_coupling)
    else:
        monkeypatch.setattr(asm, "coupling_matrix", _coupling_shear_order)
    assert piezo_patch_defect(distorted("hexahedron")) > 1e-3


def rotation_defect(element: str) -> float:
    """Rotate the mesh and the material together, carry the fields along: same energies."""
    mesh = distorted(element)
    R = _rotation(3)
    rng = np.random.default_rng(8)
    U = rng.normal(size=(mesh.n_nodes, 3))  # nodal displacements
    phi, theta = rng.normal(size=(2, mesh.n_nodes))
    rmesh = Mesh3D(mesh.points @ R.T, mesh.cells, mesh.boundaries)
    rm = tensors.rotate(PIEZO, R)
    u, ru = U.ravel(), (U @ R.T).ravel()  # u'(x') = R u(Rᵀx')
    pairs = [
        (u @ elasticity_matrix(mesh, PIEZO.C) @ u, ru @ elasticity_matrix(rmesh, rm.C) @ ru),
        (theta @ coupling_matrix(mesh, PIEZO.e) @ u, theta @ coupling_matrix(rmesh, rm.e) @ ru),
        (
            phi @ permittivity_matrix(mesh, PIEZO.kappa) @ theta,
            phi @ permittivity_matrix(rmesh, rm.kappa) @ theta,
        ),
    ]
    return max(abs(a - b) / abs(a) for a, b in pairs)


@pytest.mark.parametrize("element", ELEMENTS)
def test_rotating_mesh_and_poling_together_keeps_the_energies(element):
    assert rotation_defect(element) < 1e-12


def test_rotation_check_catches_a_wrong_bond_matrix(monkeypatch):
    good = tensors.bond_matrix
    monkeypatch.setattr(tensors, "bond_matrix", lambda R: np.linalg.inv(good(R)).T)
    assert rotation_defect("tetra") > 1e-3


@pytest.mark.parametrize("element", ELEMENTS)
def test_loads_and_mass(element):
    mesh = distorted(element)
    f = volume_load(mesh, lambda x, y, z: np.stack([x, y * z, 1 + 0 * x], -1), 3)
    assert f.shape == (3 * mesh.n_nodes,)
    # Σ_i f_i = ∫ f: ∫x = 1/2, ∫yz = 1/4, ∫1 = 1 over the unit cube
    assert np.allclose(f.reshape(-1, 3).sum(axis=0), [0.5, 0.25, 1.0], rtol=1e-12)
    t = boundary_load(mesh, "top", lambda x, y, z: x * y, 1)
    assert np.isclose(t.sum(), 0.25, rtol=1e-12)  # ∫_top x y
    assert set(np.flatnonzero(t)) <= set(mesh.boundary_nodes("top").tolist())
    M = mass_matrix(mesh)
    assert np.isclose(M.sum(), 1.0, rtol=1e-13)
    x, y = mesh.points[:, 0], mesh.points[:, 1]
    assert np.isclose(x @ M @ y, 0.25, rtol=1e-12)  # ∫ x y (x, y in the Q1/P1 space)
    with pytest.raises(KeyError, match="unknown boundary"):
        boundary_load(mesh, "side", 1.0, 1)
    with pytest.raises(ValueError, match="do not fit"):
        volume_load(mesh, [1.0, 2.0], 3)


@pytest.mark.parametrize("element", ELEMENTS)
def test_cell_fields_and_norms_of_linear_fields(element):
    mesh = distorted(element)
    rng = np.random.default_rng(9)
    Du, a = rng.normal(size=(3, 3)), rng.normal(size=3)
    u = interpolate(mesh, lambda x, y, z: np.stack([x, y, z], -1) @ Du.T, 3)
    phi = interpolate(mesh, lambda x, y, z: a[0] * x + a[1] * y + a[2] * z, 1)
    sigma, D = cell_fields(mesh, u, phi, PIEZO.C, PIEZO.e, PIEZO.kappa)
    eps = voigt_strain(Du)
    assert np.allclose(sigma, PIEZO.C @ eps + PIEZO.e.T @ a, atol=1e-12)
    assert np.allclose(D, PIEZO.e @ eps - PIEZO.kappa @ a, atol=1e-12)
    s0, d0 = cell_fields(mesh, u, None, PIEZO.C, None, None)
    assert np.allclose(s0, PIEZO.C @ eps, atol=1e-12) and not d0.any()
    exact = lambda x, y, z: np.stack([x, y, z], -1) @ Du.T  # noqa: E731
    grad = lambda x, y, z: np.broadcast_to(Du, x.shape + (3, 3))  # noqa: E731
    assert l2_error(mesh, u, exact, 3) < 1e-13
    assert h1_seminorm_error(mesh, u, grad, 3) < 1e-12
    assert l2_error(mesh, u + 1.0, exact, 3) == pytest.approx(np.sqrt(3.0), rel=1e-12)


def test_bad_shapes():
    mesh = distorted("tetra", n=1)
    with pytest.raises(ValueError, match=r"\(6, 6\)"):
        elasticity_matrix(mesh, np.eye(3))
    with pytest.raises(ValueError, match=r"\(3, 6\)"):
        coupling_matrix(mesh, np.zeros((6, 3)))
    cells = mesh.cells.copy()
    cells[0, [1, 2]] = cells[0, [2, 1]]
    with pytest.raises(ValueError, match="inverted"):
        elasticity_matrix(Mesh3D(mesh.points, cells), np.eye(6))


# chunked assembly: any chunk size gives the one-shot matrix (same pattern, values to rounding)
_FORMS = {
    "elasticity": lambda mesh, chunk: elasticity_matrix(mesh, PIEZO.C, chunk=chunk),
    "coupling": lambda mesh, chunk: coupling_matrix(mesh, PIEZO.e, chunk=chunk),
    "permittivity": lambda mesh, chunk: permittivity_matrix(mesh, PIEZO.kappa, chunk=chunk),
    "mass": lambda mesh, chunk: mass_matrix(mesh, chunk=chunk),
}


def _one_shot_elasticity(mesh: Mesh3D, C: np.ndarray) -> sp.csr_matrix:
    """∫ C ε(u)·ε(v) from the whole mesh's geometry and one global COO array (the reference)."""
    g = cell_geometry(mesh, 0 if mesh.cell_type == "tetra" else 2)
    B = strain_operator(g.grad)  # (n_cells, n_qp, 6, 3 n_loc)
    Ke = np.einsum("cq,cqIa,IJ,cqJb->cab", g.w, B, C, B)  # (n_cells, 3 n_loc, 3 n_loc)
    dofs = asm.vector_dofs(mesh)  # (n_cells, 3 n_loc)
    R = np.broadcast_to(dofs[:, :, None], Ke.shape)  # (n_cells, 3 n_loc, 3 n_loc)
    Cc = np.broadcast_to(dofs[:, None, :], Ke.shape)  # (n_cells, 3 n_loc, 3 n_loc)
    n = 3 * mesh.n_nodes
    return sp.csr_matrix((Ke.ravel(), (R.ravel(), Cc.ravel())), shape=(n, n))


@given(st.integers(0, 2**32 - 1), st.sampled_from(ELEMENTS))
def test_chunked_assembly_equals_one_shot_for_random_chunk_sizes(seed, element):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 4))
    mesh = transform(box((0, 1), (0, 1), (0, 1), (n, n, n), element), wavy)
    chunk = int(rng.integers(1, mesh.n_cells + 3))
    assert same_matrix(
        elasticity_matrix(mesh, PIEZO.C, chunk=chunk), _one_shot_elasticity(mesh, PIEZO.C)
    )
    for form in _FORMS.values():
        assert same_matrix(form(mesh, chunk), form(mesh, mesh.n_cells))


def test_mutation_a_chunk_assembled_from_the_wrong_cells_is_caught(monkeypatch):
    mesh = distorted("tetra", n=2)
    good = _one_shot_elasticity(mesh, PIEZO.C)
    monkeypatch.setattr(asm, "_geometry", shifted_geometry(asm._geometry))
    assert not same_matrix(elasticity_matrix(mesh, PIEZO.C, chunk=7), good)
    assert same_matrix(elasticity_matrix(mesh, PIEZO.C, chunk=mesh.n_cells), good)  # one chunk


def test_chunk_size_must_be_positive():
    with pytest.raises(ValueError, match="chunk"):
        mass_matrix(distorted("tetra", n=1), chunk=0)


def test_an_inverted_cell_in_a_later_chunk_is_refused():
    """The cells are checked before the first chunk: an inverted cell past it is named."""
    mesh = distorted("tetra", n=2)
    cells = mesh.cells.copy()
    last = mesh.n_cells - 1
    cells[last, [1, 2]] = cells[last, [2, 1]]
    with pytest.raises(ValueError, match=f"inverted or degenerate cell {last} "):
        elasticity_matrix(Mesh3D(mesh.points, cells), PIEZO.C, chunk=3)
