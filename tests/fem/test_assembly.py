"""Assembly in 2D and 3D: matrix properties, patch tests, loads, post-processing, convergence,
chunked assembly; in 3D also geometry, rigid-body modes, energies against full tensors, rotation
consistency — each with the fault it must catch (a missing factor 2 in the Voigt shear strains, a
Voigt shear order mix-up, a sign flip of the coupling block, a wrong Bond matrix)."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given
from hypothesis import strategies as st

import fem.assembly as asm
import fem.tensors as tensors
from fem.assembly import (
    boundary_load,
    cell_fields,
    cell_geometry,
    coupling_matrix,
    elasticity_matrix,
    facet_geometry,
    h1_seminorm_error,
    interpolate,
    l2_error,
    mass_matrix,
    permittivity_matrix,
    piezo_matrix,
    stiffness_matrix,
    strain_operator,
    volume_load,
)
from fem.dirichlet import expand, reduce_dirichlet
from fem.mesh import Mesh
from fem.meshing import SIDES, box, rectangle, transform
from fem.refine import refine
from fem.tensors import NAMED, VOIGT_PAIRS, Material3D, orthotropic, poled, rotate

from .helpers import full_tensors, same_matrix, shifted_geometry

ELEMENTS = ["quad", "triangle"]

# BaTiO3 (docs/design.md §4), made dimensionless with c0 = 1e10 Pa, κ0 = 1e-8 F/m and length 1:
# potential scale φ0 = sqrt(c0/κ0), so C̃ = C/c0, ẽ = e/sqrt(c0 κ0), κ̃ = κ/κ0 (all of order 1).
C0, K0 = 1e10, 1e-8
C_BTO = np.array([[15.0e10, 6.6e10, 0.0], [6.6e10, 14.6e10, 0.0], [0.0, 0.0, 4.4e10]]) / C0
E_BTO = np.array([[0.0, 0.0, 11.4], [-4.35, 17.5, 0.0]]) / np.sqrt(C0 * K0)
KAPPA_BTO = np.diag([9.87e-9, 1.116e-8]) / K0
# a fully anisotropic (but SPD) Voigt matrix for the pure elasticity patch test
C_ANISO = np.array([[15.0, 6.6, 2.0], [6.6, 14.6, -1.5], [2.0, -1.5, 4.4]])


def boundary_mask(mesh: Mesh) -> np.ndarray:
    mask = np.zeros(mesh.n_nodes, dtype=bool)
    mask[np.concatenate(list(mesh.boundaries.values())).ravel()] = True
    return mask


def distorted(element: str, cells=(4, 3), seed: int = 1, amount: float = 0.25) -> Mesh:
    """[0, 2] × [0, 1.5] with interior nodes moved randomly by up to `amount` · h."""
    mesh = rectangle((0.0, 2.0), (0.0, 1.5), cells, element)
    rng = np.random.default_rng(seed)
    pts = mesh.points.copy()
    inner = ~boundary_mask(mesh)
    pts[inner] += amount * 0.5 * rng.uniform(-1, 1, (inner.sum(), 2))
    return Mesh(pts, mesh.cells, mesh.boundaries)


def test_distorted_mesh_is_really_distorted():
    for element in ELEMENTS:
        g = cell_geometry(distorted(element), order=2)
        # gradients vary between cells more than on a uniform mesh
        assert np.ptp(g.w.sum(axis=1)) > 1e-2


@pytest.mark.parametrize("element", ELEMENTS)
def test_geometry(element):
    mesh = distorted(element)
    g = cell_geometry(mesh, order=2)
    n_loc = mesh.cells.shape[1]
    n_qp = g.phi.shape[0]
    assert g.x.shape == (mesh.n_cells, n_qp, 2)
    assert g.w.shape == (mesh.n_cells, n_qp)
    assert g.grad.shape == (mesh.n_cells, n_qp, n_loc, 2)
    assert np.isclose(g.w.sum(), 3.0)
    # physical gradients reproduce the gradient of linear functions: ∑_a x_a ∇φ_a = I
    X = mesh.points[mesh.cells]  # (n_cells, n_loc, 2)
    assert np.allclose(np.einsum("cai,cqaj->cqij", X, g.grad), np.eye(2), atol=1e-12)


@pytest.mark.parametrize("element", ELEMENTS)
def test_inverted_cell_raises(element):
    mesh = rectangle((0, 1), (0, 1), (2, 2), element)
    cells = mesh.cells.copy()
    cells[2] = cells[2, ::-1]  # clockwise
    with pytest.raises(ValueError, match="cell 2"):
        cell_geometry(Mesh(mesh.points, cells, mesh.boundaries))


def test_nonconvex_quad_raises():
    """A quad with a reflex corner has det J < 0 near that corner."""
    pts = np.array([[0.0, 0.0], [2.0, 0.0], [0.3, 0.3], [0.0, 2.0]])
    with pytest.raises(ValueError, match="cell 0"):
        cell_geometry(Mesh(pts, np.array([[0, 1, 2, 3]])))


def rigid_modes(mesh) -> np.ndarray:
    """(dN, 3) in 2D, (dN, 6) in 3D: the d translations and the infinitesimal rotations
    (in the x–y plane; in 3D ω × x for ω = e_x, e_y, e_z)."""
    N, d = mesh.points.shape
    modes = []
    for k in range(d):
        t = np.zeros((N, d))
        t[:, k] = 1.0
        modes.append(t.ravel())
    for i, j in [(0, 1)] if d == 2 else [(1, 2), (2, 0), (0, 1)]:  # rotation in the (i, j) plane
        r = np.zeros((N, d))
        r[:, i], r[:, j] = -mesh.points[:, j], mesh.points[:, i]
        modes.append(r.ravel())
    return np.stack(modes, axis=1)


@pytest.mark.parametrize("element", ELEMENTS)
def test_elasticity_matrix_kernel(element):
    mesh = distorted(element, cells=(3, 3))
    K = elasticity_matrix(mesh, C_ANISO)
    assert K.shape == (2 * mesh.n_nodes,) * 2
    assert abs(K - K.T).max() <= 1e-13 * abs(K).max()
    lam = np.linalg.eigvalsh(K.toarray())
    assert lam.min() > -1e-12 * lam.max()
    assert (lam < 1e-10 * lam.max()).sum() == 3
    R = rigid_modes(mesh)
    assert np.abs(K @ R).max() <= 1e-12 * lam.max()


@pytest.mark.parametrize("element", ELEMENTS)
def test_coupling_and_permittivity(element):
    mesh = distorted(element, cells=(3, 3))
    G = coupling_matrix(mesh, E_BTO)
    assert G.shape == (mesh.n_nodes, 2 * mesh.n_nodes)
    assert np.abs(G @ rigid_modes(mesh)).max() <= 1e-13 * abs(G).max()
    # G is not trivially zero: a uniform strain couples to ∇θ
    assert abs(G).max() > 0.1
    P = permittivity_matrix(mesh, KAPPA_BTO).toarray()
    assert np.allclose(P, P.T, rtol=0, atol=1e-14 * abs(P).max())
    assert np.allclose(P.sum(axis=1), 0, atol=1e-13)
    lam = np.linalg.eigvalsh(P[1:, 1:])
    assert lam.min() > 1e-6 * lam.max()


@pytest.mark.parametrize("element", ELEMENTS)
def test_stiffness_and_mass(element):
    mesh = distorted(element)
    A = stiffness_matrix(mesh)
    assert np.allclose(np.asarray(A.sum(axis=1)).ravel(), 0, atol=1e-13)
    assert abs(A - A.T).max() < 1e-14
    M = mass_matrix(mesh)
    assert np.isclose(M.sum(), 3.0, rtol=1e-13)
    assert abs(M - M.T).max() < 1e-15
    # ∫ x y over the domain via the mass matrix and the exact nodal interpolants of x and y
    x, y = mesh.points.T
    # (x y det J has degree ≤ 3 in each reference variable for Q1, so 2×2 Gauss is exact)
    assert np.isclose(x @ M @ y, 2.0 * 1.125, rtol=1e-12)


def assemble_piezo(mesh: Mesh) -> sp.csr_matrix:
    """A = [[K, Gᵀ], [−G, P]] on dofs (u interleaved, then φ)."""
    K = elasticity_matrix(mesh, C_BTO)
    G = coupling_matrix(mesh, E_BTO)
    P = permittivity_matrix(mesh, KAPPA_BTO)
    return sp.bmat([[K, G.T], [-G, P]], format="csr")


@pytest.mark.parametrize("element", ELEMENTS)
def test_patch_elasticity(element):
    mesh = distorted(element)
    A = elasticity_matrix(mesh, C_ANISO)
    x, y = mesh.points.T
    exact = np.stack([0.3 + 0.02 * x - 0.05 * y, -0.1 + 0.04 * x + 0.01 * y], 1).ravel()
    fixed = np.repeat(boundary_mask(mesh), 2)
    Ar, fr, free = reduce_dirichlet(A, np.zeros(2 * mesh.n_nodes), fixed, exact)
    u = expand(spla.spsolve(Ar.tocsc(), fr), free, exact)
    assert np.abs(u - exact).max() <= 1e-10 * np.abs(exact).max()


@pytest.mark.parametrize("element", ELEMENTS)
def test_patch_piezo(element):
    mesh = distorted(element, seed=7)
    A = assemble_piezo(mesh)
    n = mesh.n_nodes
    x, y = mesh.points.T
    u_ex = np.stack([1e-3 * (1 + 2 * x - y), 1e-3 * (-0.5 + 0.7 * x + 3 * y)], 1).ravel()
    phi_ex = 2e-3 * (0.4 - x + 2.5 * y)
    exact = np.concatenate([u_ex, phi_ex])
    bnd = boundary_mask(mesh)
    fixed = np.concatenate([np.repeat(bnd, 2), bnd])
    Ar, fr, free = reduce_dirichlet(A, np.zeros(3 * n), fixed, exact)
    sol = expand(spla.spsolve(Ar.tocsc(), fr), free, exact)
    assert np.abs(sol[: 2 * n] - u_ex).max() <= 1e-10 * np.abs(u_ex).max()
    assert np.abs(sol[2 * n :] - phi_ex).max() <= 1e-10 * np.abs(phi_ex).max()


OUTWARD = {"bottom": (0.0, -1.0), "right": (1.0, 0.0), "top": (0.0, 1.0), "left": (-1.0, 0.0)}


@pytest.mark.parametrize("element", ELEMENTS)
def test_piezo_signs_by_boundary_fluxes(element):
    """For linear u, φ: A [u; φ] = [∫_Γ σn·v; −∫_Γ D·n θ] with σ = Cε + eᵀ∇φ, D = eε − κ∇φ.

    Unlike the patch test (where each block annihilates linear fields on interior rows), this
    checks the sign and transposition of every block, including G against Gᵀ.
    """
    mesh = distorted(element, seed=3)
    grad_u = np.array([[0.2, -0.5], [0.4, 0.1]])  # ∂u_k/∂x_i
    u = (mesh.points @ grad_u.T).ravel()
    E = np.array([0.3, -0.7])  # ∇φ
    phi = mesh.points @ E
    eps = np.array([grad_u[0, 0], grad_u[1, 1], grad_u[0, 1] + grad_u[1, 0]])
    s = C_BTO @ eps + E_BTO.T @ E  # (σ_xx, σ_yy, σ_xy)
    sigma = np.array([[s[0], s[2]], [s[2], s[1]]])
    D = E_BTO @ eps - KAPPA_BTO @ E
    r_u = sum(boundary_load(mesh, nm, sigma @ nv, 2) for nm, nv in OUTWARD.items())
    r_phi = sum(boundary_load(mesh, nm, -(D @ nv), 1) for nm, nv in OUTWARD.items())
    got = assemble_piezo(mesh) @ np.concatenate([u, phi])
    expected = np.concatenate([r_u, r_phi])
    assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()


@pytest.mark.parametrize("element", ELEMENTS)
def test_cell_fields(element):
    mesh = distorted(element)
    x, y = mesh.points.T
    grad_u = np.array([[0.02, -0.05], [0.04, 0.01]])  # ∂u_k/∂x_i
    u = np.stack([grad_u[0, 0] * x + grad_u[0, 1] * y, grad_u[1, 0] * x + grad_u[1, 1] * y], 1)
    phi = 0.3 * x - 0.7 * y + 1.0
    eps = np.array([0.02, 0.01, -0.05 + 0.04])
    E = np.array([0.3, -0.7])
    sigma, D = cell_fields(mesh, u.ravel(), phi, C_BTO, E_BTO, KAPPA_BTO)
    assert sigma.shape == (mesh.n_cells, 3) and D.shape == (mesh.n_cells, 2)
    assert np.allclose(sigma, C_BTO @ eps + E_BTO.T @ E, rtol=1e-12, atol=1e-14)
    assert np.allclose(D, E_BTO @ eps - KAPPA_BTO @ E, rtol=1e-12, atol=1e-14)
    sigma, D = cell_fields(mesh, u.ravel(), None, C_BTO, None, None)
    assert np.allclose(sigma, C_BTO @ eps, rtol=1e-12, atol=1e-14)
    assert np.array_equal(D, np.zeros((mesh.n_cells, 2)))


@pytest.mark.parametrize("element", ELEMENTS)
def test_interpolate_and_errors_of_linear_functions(element):
    mesh = distorted(element)
    f = lambda x, y: np.stack([1 + x - 2 * y, 3 * x], axis=-1)  # noqa: E731
    df = lambda x, y: np.broadcast_to(np.array([[1.0, -2.0], [3.0, 0.0]]), x.shape + (2, 2))  # noqa: E731
    uh = interpolate(mesh, f, 2)
    assert uh.shape == (2 * mesh.n_nodes,)
    assert np.allclose(uh[::2], 1 + mesh.points[:, 0] - 2 * mesh.points[:, 1])
    assert l2_error(mesh, uh, f, 2) < 1e-12
    assert h1_seminorm_error(mesh, uh, df, 2) < 1e-12
    # scalar (ncomp = 1) conventions and known non-zero errors: u_h = 0 against u = 2 and u = x
    assert interpolate(mesh, 2.0, 1).shape == (mesh.n_nodes,)
    zero = np.zeros(mesh.n_nodes)
    assert np.isclose(l2_error(mesh, zero, 2.0, 1), 2 * np.sqrt(3.0))
    grad_x = lambda x, y: np.stack([np.ones_like(x), np.zeros_like(x)], axis=-1)  # noqa: E731
    assert np.isclose(h1_seminorm_error(mesh, zero, grad_x, 1), np.sqrt(3.0))
    with pytest.raises(ValueError, match="grad_exact"):
        h1_seminorm_error(mesh, uh, lambda x, y: np.zeros(x.shape + (2, 3)), 2)


@pytest.mark.parametrize("element", ELEMENTS)
def test_volume_load_exact(element):
    mesh = distorted(element)  # [0, 2] × [0, 1.5]
    x, y = mesh.points.T
    F = volume_load(mesh, lambda x, y: x * y, 1)
    assert F.shape == (mesh.n_nodes,)
    assert np.isclose(F.sum(), 2.0 * 1.125, rtol=1e-13)  # ∫ x y = (4/2)(2.25/2)
    assert np.isclose(F @ x, 8 / 3 * 1.125, rtol=1e-13)  # ∫ x² y
    Fv = volume_load(mesh, (1.0, -2.0), 2)
    assert Fv.shape == (2 * mesh.n_nodes,)
    assert np.isclose(Fv[0::2].sum(), 3.0) and np.isclose(Fv[1::2].sum(), -6.0)
    Fv = volume_load(mesh, lambda x, y: np.stack([y, x * x], -1), 2)
    assert np.isclose(Fv[0::2].sum(), 2 * 1.125) and np.isclose(Fv[1::2] @ y, 8 / 3 * 1.125)
    with pytest.raises(ValueError, match="constant"):
        volume_load(mesh, (1.0, 2.0, 3.0), 2)
    with pytest.raises(ValueError, match="function values"):  # a scalar field for ncomp = 2
        volume_load(mesh, lambda x, y: x, 2)


def _poisson_errors(element: str, levels: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """−Δu = f on (0, 1) × (0, 2), u = sin(πx) sin(πy/2) + x y (non-zero Dirichlet data)."""
    k = np.pi / 2

    def u(x, y):
        return np.sin(np.pi * x) * np.sin(k * y) + x * y

    def grad_u(x, y):
        return np.stack(
            [
                np.pi * np.cos(np.pi * x) * np.sin(k * y) + y,
                k * np.sin(np.pi * x) * np.cos(k * y) + x,
            ],
            axis=-1,
        )

    def f(x, y):
        return (np.pi**2 + k**2) * np.sin(np.pi * x) * np.sin(k * y)

    mesh = rectangle((0.0, 1.0), (0.0, 2.0), (2, 4), element)
    hs, e0, e1 = [], [], []
    for _ in range(levels):
        mesh = refine(mesh)
        A = stiffness_matrix(mesh)
        b = volume_load(mesh, f, 1)
        fixed = boundary_mask(mesh)
        g = interpolate(mesh, u, 1)
        Ar, br, free = reduce_dirichlet(A, b, fixed, g)
        uh = expand(spla.spsolve(Ar.tocsc(), br), free, g)
        hs.append(mesh.h)
        e0.append(l2_error(mesh, uh, u, 1))
        e1.append(h1_seminorm_error(mesh, uh, grad_u, 1))
    return np.array(hs), np.array(e0), np.array(e1)


@pytest.mark.parametrize("element", ELEMENTS)
def test_poisson_convergence(element):
    h, e0, e1 = _poisson_errors(element)
    rate_l2 = np.polyfit(np.log(h), np.log(e0), 1)[0]
    rate_h1 = np.polyfit(np.log(h), np.log(e1), 1)[0]
    assert rate_l2 >= 1.8, (rate_l2, e0)
    assert rate_h1 >= 0.9, (rate_h1, e1)
    # and not suspiciously high (superconvergence would hint at a broken norm)
    assert rate_l2 < 2.3 and rate_h1 < 1.3


@pytest.mark.parametrize("element", ELEMENTS)
def test_boundary_load_exact(element):
    mesh = refine(rectangle((-1.0, 2.0), (0.0, 1.5), (2, 3), element))
    x, y = mesh.points.T
    F = boundary_load(mesh, "bottom", lambda x, y: x**2, 1)
    assert F.shape == (mesh.n_nodes,)
    assert np.isclose(F.sum(), 3.0, rtol=1e-13)  # ∫_{-1}^{2} x² dx
    assert np.isclose(F @ x, 15 / 4, rtol=1e-13)  # ∫ x³ dx
    nodes = np.setdiff1d(np.arange(mesh.n_nodes), mesh.boundary_nodes("bottom"))
    assert np.array_equal(F[nodes], np.zeros(nodes.size))
    # a uniform traction integrates to force × length
    T = boundary_load(mesh, "top", (2.0, -5.0), 2)
    assert T.shape == (2 * mesh.n_nodes,)
    assert np.isclose(T[0::2].sum(), 6.0) and np.isclose(T[1::2].sum(), -15.0)
    L = boundary_load(mesh, "left", lambda x, y: np.stack([y**4, x + y], -1), 2)
    assert np.isclose(L[0::2].sum(), 1.5**5 / 5, rtol=1e-13)
    assert np.isclose(L[1::2].sum(), -1.5 + 1.5**2 / 2, rtol=1e-13)
    with pytest.raises(KeyError, match="bottom, left, right, top"):
        boundary_load(mesh, "contact", 1.0, 1)


@pytest.mark.parametrize("element", ELEMENTS)
def test_facet_geometry_of_edges(element):
    """Edge quadrature: outward unit normals, weights summing to each part's length."""
    mesh = distorted(element)  # [0, 2] × [0, 1.5], boundary nodes not moved
    for name, normal in OUTWARD.items():
        x, w, phi, n = facet_geometry(mesh, name)
        assert np.allclose(n, normal, rtol=0, atol=1e-15)
        assert np.isclose(w.sum(), 2.0 if name in ("bottom", "top") else 1.5, rtol=1e-14)
        assert np.allclose(phi.sum(axis=1), 1.0) and x.shape == w.shape + (2,)


def test_degenerate_cell_raises():
    """A triangle of area ~1e-17 (relative to the mesh's extent²) is refused, not assembled."""
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 1e-17], [0.0, 1.0]])
    with pytest.raises(ValueError, match="degenerate cell 0"):
        stiffness_matrix(Mesh(pts, np.array([[0, 1, 2], [0, 1, 3]])))


# chunked assembly: any chunk size gives the one-shot matrix (same pattern, values to rounding)
_FORMS = {
    "elasticity": lambda mesh, chunk: elasticity_matrix(mesh, C_ANISO, chunk=chunk),
    "coupling": lambda mesh, chunk: coupling_matrix(mesh, E_BTO, chunk=chunk),
    "permittivity": lambda mesh, chunk: permittivity_matrix(mesh, KAPPA_BTO, chunk=chunk),
    "mass": lambda mesh, chunk: mass_matrix(mesh, chunk=chunk),
}


def _one_shot_stiffness(mesh: Mesh) -> sp.csr_matrix:
    """∫ ∇φ·∇θ from the whole mesh's geometry and one global COO array (the reference)."""
    g = cell_geometry(mesh, order=2)
    Ke = np.einsum("cq,cqai,cqbi->cab", g.w, g.grad, g.grad)  # (n_cells, n_loc, n_loc)
    R = np.broadcast_to(mesh.cells[:, :, None], Ke.shape)  # (n_cells, n_loc, n_loc)
    C = np.broadcast_to(mesh.cells[:, None, :], Ke.shape)  # (n_cells, n_loc, n_loc)
    n = mesh.n_nodes
    return sp.csr_matrix((Ke.ravel(), (R.ravel(), C.ravel())), shape=(n, n))


@given(st.integers(0, 2**32 - 1), st.sampled_from(ELEMENTS))
def test_chunked_assembly_equals_one_shot_for_random_chunk_sizes(seed, element):
    rng = np.random.default_rng(seed)
    nx, ny = (int(k) for k in rng.integers(2, 9, 2))
    h = min(2.0 / nx, 1.5 / ny)
    mesh = distorted(element, cells=(nx, ny), seed=seed, amount=0.25 * h / 0.5)  # up to h/8
    chunk = int(rng.integers(1, mesh.n_cells + 3))
    assert same_matrix(stiffness_matrix(mesh, chunk=chunk), _one_shot_stiffness(mesh))
    for form in _FORMS.values():
        assert same_matrix(form(mesh, chunk), form(mesh, mesh.n_cells))


def test_mutation_a_chunk_assembled_from_the_wrong_cells_is_caught(monkeypatch):
    import fem.assembly as assembly

    mesh = distorted("quad", cells=(6, 5))
    good = _one_shot_stiffness(mesh)
    monkeypatch.setattr(assembly, "_geometry", shifted_geometry(assembly._geometry))
    assert not same_matrix(stiffness_matrix(mesh, chunk=7), good)
    assert same_matrix(stiffness_matrix(mesh, chunk=mesh.n_cells), good)  # one chunk: unaffected


def test_chunk_size_must_be_positive():
    with pytest.raises(ValueError, match="chunk"):
        mass_matrix(rectangle((0, 1), (0, 1), (2, 2)), chunk=0)


# ---- 3D: hexahedra and tetrahedra ----

ELEMENTS_3D = ["hexahedron", "tetra"]


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


def wavy_box(element: str, n: int = 2, level: int = 0) -> Mesh:
    return transform(box((0, 1), (0, 1), (0, 1), (n, n, n), element, level=level), wavy)


def voigt_strain(Du: np.ndarray) -> np.ndarray:
    """Engineering Voigt strain (6,) of a displacement gradient Du[i, j] = ∂u_i/∂x_j."""
    E = 0.5 * (Du + Du.T)
    return np.array([E[i, j] * (1 if i == j else 2) for i, j in VOIGT_PAIRS])


def test_geometry_3d():
    for element in ELEMENTS_3D:
        mesh = wavy_box(element)
        g = cell_geometry(mesh, order=2)
        assert np.isclose(g.w.sum(), 1.0, rtol=1e-13)
        X = mesh.points[mesh.cells]  # (n_cells, n_loc, 3)
        assert np.allclose(np.einsum("cai,cqaj->cqij", X, g.grad), np.eye(3), atol=1e-12)
        assert np.ptp(g.w.sum(axis=1)) > 1e-3  # really distorted


@pytest.mark.parametrize("element", ELEMENTS_3D)
def test_elasticity_kernel_is_the_six_rigid_modes(element):
    mesh = wavy_box(element)
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


@pytest.mark.parametrize("element", ELEMENTS_3D)
def test_piezo_blocks(element):
    mesh = wavy_box(element)
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
    mesh = wavy_box(element)
    rng = np.random.default_rng(11)
    Du, a, b = rng.normal(size=(3, 3)), rng.normal(size=3), rng.normal(size=3)
    u = (mesh.points @ Du.T).ravel()  # u(x) = Du x
    phi, theta = mesh.points @ a, mesh.points @ b  # φ = a·x, θ = b·x
    c, e = full_tensors(PIEZO)
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


@pytest.mark.parametrize("element", ELEMENTS_3D)
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


def piezo_patch_defect(mesh: Mesh, m: Material3D = PIEZO) -> float:
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


@pytest.mark.parametrize("element", ELEMENTS_3D)
def test_piezo_patch_test(element):
    assert piezo_patch_defect(wavy_box(element)) < 1e-11


def test_patch_test_on_an_elastic_orthotropic_body():
    m = rotate(orthotropic((3.0, 1.0, 2.0), (0.2, 0.3, 0.25), (0.6, 0.7, 0.8)), _rotation(2))
    m = Material3D("o", m.C, np.zeros((3, 6)), np.eye(3))  # no coupling
    for element in ELEMENTS_3D:
        assert piezo_patch_defect(wavy_box(element), m) < 1e-11


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
    assert piezo_patch_defect(wavy_box("hexahedron")) > 1e-3


def rotation_defect(element: str) -> float:
    """Rotate the mesh and the material together, carry the fields along: same energies."""
    mesh = wavy_box(element)
    R = _rotation(3)
    rng = np.random.default_rng(8)
    U = rng.normal(size=(mesh.n_nodes, 3))  # nodal displacements
    phi, theta = rng.normal(size=(2, mesh.n_nodes))
    rmesh = Mesh(mesh.points @ R.T, mesh.cells, mesh.boundaries)
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


@pytest.mark.parametrize("element", ELEMENTS_3D)
def test_rotating_mesh_and_poling_together_keeps_the_energies(element):
    assert rotation_defect(element) < 1e-12


def test_rotation_check_catches_a_wrong_bond_matrix(monkeypatch):
    good = tensors.bond_matrix
    monkeypatch.setattr(tensors, "bond_matrix", lambda R: np.linalg.inv(good(R)).T)
    assert rotation_defect("tetra") > 1e-3


@pytest.mark.parametrize("element", ELEMENTS_3D)
def test_loads_and_mass(element):
    mesh = wavy_box(element)
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


@pytest.mark.parametrize("element", ELEMENTS_3D)
def test_cell_fields_and_norms_of_linear_fields(element):
    mesh = wavy_box(element)
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
    mesh = wavy_box("tetra", n=1)
    with pytest.raises(ValueError, match=r"\(6, 6\)"):
        elasticity_matrix(mesh, np.eye(3))
    with pytest.raises(ValueError, match=r"\(3, 6\)"):
        coupling_matrix(mesh, np.zeros((6, 3)))
    cells = mesh.cells.copy()
    cells[0, [1, 2]] = cells[0, [2, 1]]
    with pytest.raises(ValueError, match="inverted"):
        elasticity_matrix(Mesh(mesh.points, cells), np.eye(6))


# chunked assembly: any chunk size gives the one-shot matrix (same pattern, values to rounding)
_FORMS_3D = {
    "elasticity": lambda mesh, chunk: elasticity_matrix(mesh, PIEZO.C, chunk=chunk),
    "coupling": lambda mesh, chunk: coupling_matrix(mesh, PIEZO.e, chunk=chunk),
    "permittivity": lambda mesh, chunk: permittivity_matrix(mesh, PIEZO.kappa, chunk=chunk),
    "mass": lambda mesh, chunk: mass_matrix(mesh, chunk=chunk),
}


def _one_shot_elasticity(mesh: Mesh, C: np.ndarray) -> sp.csr_matrix:
    """∫ C ε(u)·ε(v) from the whole mesh's geometry and one global COO array (the reference)."""
    g = cell_geometry(mesh, 0 if mesh.cell_type == "tetra" else 2)
    B = strain_operator(g.grad)  # (n_cells, n_qp, 6, 3 n_loc)
    Ke = np.einsum("cq,cqIa,IJ,cqJb->cab", g.w, B, C, B)  # (n_cells, 3 n_loc, 3 n_loc)
    dofs = asm.vector_dofs(mesh)  # (n_cells, 3 n_loc)
    R = np.broadcast_to(dofs[:, :, None], Ke.shape)  # (n_cells, 3 n_loc, 3 n_loc)
    Cc = np.broadcast_to(dofs[:, None, :], Ke.shape)  # (n_cells, 3 n_loc, 3 n_loc)
    n = 3 * mesh.n_nodes
    return sp.csr_matrix((Ke.ravel(), (R.ravel(), Cc.ravel())), shape=(n, n))


@given(st.integers(0, 2**32 - 1), st.sampled_from(ELEMENTS_3D))
def test_chunked_assembly_equals_one_shot_for_random_chunk_sizes_3d(seed, element):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 4))
    mesh = transform(box((0, 1), (0, 1), (0, 1), (n, n, n), element), wavy)
    chunk = int(rng.integers(1, mesh.n_cells + 3))
    assert same_matrix(
        elasticity_matrix(mesh, PIEZO.C, chunk=chunk), _one_shot_elasticity(mesh, PIEZO.C)
    )
    for form in _FORMS_3D.values():
        assert same_matrix(form(mesh, chunk), form(mesh, mesh.n_cells))


def test_mutation_a_chunk_assembled_from_the_wrong_cells_is_caught_3d(monkeypatch):
    mesh = wavy_box("tetra", n=2)
    good = _one_shot_elasticity(mesh, PIEZO.C)
    monkeypatch.setattr(asm, "_geometry", shifted_geometry(asm._geometry))
    assert not same_matrix(elasticity_matrix(mesh, PIEZO.C, chunk=7), good)
    assert same_matrix(elasticity_matrix(mesh, PIEZO.C, chunk=mesh.n_cells), good)  # one chunk


def test_chunk_size_must_be_positive_3d():
    with pytest.raises(ValueError, match="chunk"):
        mass_matrix(wavy_box("tetra", n=1), chunk=0)


def test_an_inverted_cell_in_a_later_chunk_is_refused():
    """The cells are checked before the first chunk: an inverted cell past it is named."""
    mesh = wavy_box("tetra", n=2)
    cells = mesh.cells.copy()
    last = mesh.n_cells - 1
    cells[last, [1, 2]] = cells[last, [2, 1]]
    with pytest.raises(ValueError, match=f"inverted or degenerate cell {last} "):
        elasticity_matrix(Mesh(mesh.points, cells), PIEZO.C, chunk=3)
