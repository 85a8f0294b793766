"""Assembly: matrix properties, patch tests, loads, post-processing, convergence."""

from math import factorial

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given
from hypothesis import strategies as st

from fem.assembly import (
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
    stiffness_matrix,
    volume_load,
)
from fem.dirichlet import expand, reduce_dirichlet
from fem.elements import reference_element
from fem.mesh import Mesh
from fem.meshing import rectangle
from fem.refine import refine

from .helpers import same_matrix, shifted_geometry

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
def test_reference_elements(element):
    ref = reference_element(element)
    # Kronecker property and partition of unity
    assert np.allclose(ref.values(ref.vertices), np.eye(ref.n_loc))
    pts = np.random.default_rng(0).uniform(0, 0.5, (7, 2))
    assert np.allclose(ref.values(pts).sum(axis=1), 1)
    assert np.allclose(ref.gradients(pts).sum(axis=1), 0)
    # gradients against finite differences
    h = 1e-6
    for i in range(2):
        d = np.zeros(2)
        d[i] = h
        fd = (ref.values(pts + d) - ref.values(pts - d)) / (2 * h)
        assert np.allclose(ref.gradients(pts)[..., i], fd, atol=1e-8)


@pytest.mark.parametrize("element", ELEMENTS)
@pytest.mark.parametrize("order", [0, 1, 2, 3, 4, 5])
def test_quadrature_exactness(element, order):
    ref = reference_element(element)
    pts, w = ref.quadrature(order)
    for p in range(order + 1):
        for q in range(order + 1 - p if element == "triangle" else order + 1):
            got = w @ (pts[:, 0] ** p * pts[:, 1] ** q)
            if element == "triangle":  # ∫ s^p t^q over the unit triangle = p! q! / (p + q + 2)!
                exact = factorial(p) * factorial(q) / factorial(p + q + 2)
            else:
                exact = np.prod([(1 - (-1) ** (k + 1)) / (k + 1) for k in (p, q)])
            assert np.isclose(got, exact, rtol=1e-12, atol=1e-14), (p, q)


def test_quadrature_bad_order():
    with pytest.raises(ValueError):
        reference_element("triangle").quadrature(6)
    with pytest.raises(ValueError):
        reference_element("quad").quadrature(-1)
    with pytest.raises(ValueError):
        reference_element("hexagon")


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


def rigid_modes(mesh: Mesh) -> np.ndarray:
    x, y = mesh.points.T
    one, zero = np.ones_like(x), np.zeros_like(x)
    return np.stack(
        [
            np.stack([one, zero], 1).ravel(),
            np.stack([zero, one], 1).ravel(),
            np.stack([-y, x], 1).ravel(),
        ],
        axis=1,
    )  # (2N, 3)


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
