"""fem.estimator: fluxes on facets, jumps, the volume residual with div F_h (P1, Q1)."""

import numpy as np
import pytest

from fem import estimator
from fem.estimator import divergence, facet_fluxes, jump_indicator, volume_indicator
from fem.mesh import Mesh
from fem.meshing import rectangle

GRAD = np.eye(2)  # the scalar flux F = ∇U: L = identity on vec ∇U (c = 1, d = 2)


def _distorted(element: str, seed: int = 0) -> Mesh:
    """A 4 × 3 mesh of [0, 1]² with its interior nodes moved at random (not affine per cell)."""
    m = rectangle((0.0, 1.0), (0.0, 1.0), (4, 3), element)
    rng = np.random.default_rng(seed)
    P = m.points.copy()
    inner = (P[:, 0] > 0) & (P[:, 0] < 1) & (P[:, 1] > 0) & (P[:, 1] < 1)
    P[inner] += rng.uniform(-0.06, 0.06, (inner.sum(), 2))
    return Mesh(P, m.cells, m.boundaries)


@pytest.mark.parametrize("element", ["triangle", "quad"])
def test_linear_field_has_no_residual(element):
    """U = a·x + b is in the space on every cell (the Q1 map is isoparametric): no jump, and
    div F_h = 0 — on Q1 only with the Hessian of the map (mutation: HX dropped, below)."""
    m = _distorted(element)
    U = (m.points @ np.array([0.7, -1.3]) + 0.2)[:, None]  # (N, 1)
    ff = facet_fluxes(m, U, GRAD)
    assert np.abs(jump_indicator(ff, m.n_cells)).max() < 1e-24
    div, _, _ = divergence(m, U, GRAD)
    assert np.abs(div).max() < 1e-12


def test_facet_flux_is_its_cell_s_flux_on_triangles():
    """On P1 cells ∇U_h is constant: the flux on every facet instance is its own cell's F_h n
    (computed here from the cell's nodes), a random field on a distorted mesh. Mutation: the
    per-cell flux handed to the neighbouring instance (below)."""
    m = _distorted("triangle", seed=3)
    U = np.random.default_rng(3).normal(size=(m.n_nodes, 1))
    ff = facet_fluxes(m, U, GRAD)
    X = m.points[m.cells]  # (n_cells, 3, 2)
    E = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]], axis=1)  # (n_cells, 2, 2) edge rows
    dU = U[m.cells[:, 1:], 0] - U[m.cells[:, :1], 0]  # (n_cells, 2)
    G = np.linalg.solve(E, dU[..., None])[..., 0]  # (n_cells, 2) ∇U per cell
    expect = np.einsum("nd,nqd->nq", G[ff.cell], ff.normal)  # (n_i, q)
    assert np.allclose(ff.flux[..., 0], expect, rtol=0, atol=1e-12 * np.abs(G).max())


def test_mutation_facet_flux_from_the_wrong_cell(monkeypatch):
    real = estimator.fluxes
    monkeypatch.setattr(
        estimator, "fluxes", lambda m, U, L, cells, pts: np.roll(real(m, U, L, cells, pts), 1, 0)
    )
    with pytest.raises(AssertionError):
        test_facet_flux_is_its_cell_s_flux_on_triangles()


def test_divergence_of_bilinear_field():
    """U = x y on a tensor grid of rectangles (exactly Q1): F = (∂_y U, 0) has div F = 1, and
    F = ∇U has div F = Δ(x y) = 0; h_T² ‖1‖²_T is the volume indicator of the first."""
    m = rectangle((0.0, 2.0), (0.0, 1.0), (3, 2), "quad", focus=(0.3, 0.2), grading=(1.5, 1.3))
    U = (m.points[:, 0] * m.points[:, 1])[:, None]
    swap = np.array([[0.0, 1.0], [0.0, 0.0]])  # vec F = (∂_y U, 0)
    assert np.allclose(divergence(m, U, swap)[0], 1.0)
    assert np.abs(divergence(m, U, GRAD)[0]).max() < 1e-12
    diag = m.points[m.cells[:, 2]] - m.points[m.cells[:, 0]]  # (n_cells, 2) axis-aligned
    area = diag[:, 0] * diag[:, 1]
    eta2 = volume_indicator(m, U, swap, None, np.ones(1))
    assert np.allclose(eta2, estimator.cell_diameters(m) ** 2 * area)


def test_jump_of_a_kink():
    """U = max(x − ½, 0) on triangles with the line x = ½ made of edges: [∂_n U] = 1 on those
    edges, so Σ_T ½ Σ_E h_E ‖1‖²_E = Σ_E h_E |E| = 4 · (¼)² on the 4 edges of length ¼."""
    m = rectangle((0.0, 1.0), (0.0, 1.0), (4, 4), "triangle")
    U = np.maximum(m.points[:, 0] - 0.5, 0.0)[:, None]
    eta2 = jump_indicator(facet_fluxes(m, U, GRAD), m.n_cells)
    assert eta2.sum() == pytest.approx(4 * 0.25**2, rel=1e-12)
    near = (np.abs(m.points[m.cells][..., 0] - 0.5) < 1e-12).sum(axis=1) == 2  # an edge on it
    assert (eta2[~near] == 0).all() and (eta2[near] > 0).all()


def test_facet_instances_on_a_part():
    """`on` finds a boundary part's facets and refuses an interior one."""
    m = rectangle((0.0, 1.0), (0.0, 1.0), (2, 2), "triangle")
    ff = facet_fluxes(m, np.zeros((m.n_nodes, 1)), GRAD)
    i = ff.on(m.boundaries["bottom"])
    assert np.allclose(ff.normal[i], [0.0, -1.0]) and np.allclose(ff.x[i][..., 1], 0.0)
    interior = ff.nodes[np.flatnonzero(ff.interior)[:1]]
    with pytest.raises(ValueError, match="not boundary facets"):
        ff.on(interior)


def test_mutation_map_hessian_dropped(monkeypatch):
    """Mutation: without the map's Hessian (H_ξ x) the Q1 divergence of a linear field is not
    0 on a distorted mesh — the first test sees it."""
    m = _distorted("quad")
    U = (m.points @ np.array([0.7, -1.3]))[:, None]
    real = estimator._map_hessians
    monkeypatch.setattr(estimator, "_map_hessians", lambda Hr, X: 0.0 * real(Hr, X))
    assert np.abs(divergence(m, U, GRAD)[0]).max() > 1e-3
