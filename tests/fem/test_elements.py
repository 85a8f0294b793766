"""Reference elements (P1/Q1 in 1D, 2D, 3D): Kronecker property, partition of unity, gradients,
quadrature exactness, outward local facets, the Jacobian algebra."""

from math import factorial

import numpy as np
import pytest

from fem.elements import FACETS, reference_element

ELEMENTS = ["line", "triangle", "quad", "tetra", "hexahedron"]
CELLS = ["triangle", "quad", "tetra", "hexahedron"]


@pytest.mark.parametrize("element", ELEMENTS)
def test_shape_functions(element):
    ref = reference_element(element)
    d = ref.dim
    assert np.allclose(ref.values(ref.vertices), np.eye(ref.n_loc), rtol=0, atol=1e-15)
    pts = np.random.default_rng(0).uniform(0, 0.3, (7, d))
    assert np.allclose(ref.values(pts).sum(axis=1), 1, rtol=0, atol=1e-15)
    assert np.allclose(ref.gradients(pts).sum(axis=1), 0, rtol=0, atol=1e-15)
    # the gradients against central differences (Q1 is quadratic along no line: exact to rounding)
    h = 1e-5
    for i in range(d):
        step = np.zeros(d)
        step[i] = h
        fd = (ref.values(pts + step) - ref.values(pts - step)) / (2 * h)
        assert np.allclose(ref.gradients(pts)[..., i], fd, rtol=0, atol=1e-9)
    # linear functions are reproduced: Σ_a x_a φ_a(ξ) = ξ
    assert np.allclose(ref.values(pts) @ ref.vertices, pts, rtol=0, atol=1e-15)


def _exact_monomial(element: str, exps: tuple[int, ...]) -> float:
    """∫ Π ξ_i^{p_i} over the reference cell."""
    if reference_element(element).simplex:  # unit simplex: Π p_i! / (Σ p_i + d)!
        return np.prod([factorial(p) for p in exps]) / factorial(sum(exps) + len(exps))
    return float(np.prod([(1 - (-1) ** (k + 1)) / (k + 1) for k in exps]))  # [−1, 1]^d


@pytest.mark.parametrize("element", ELEMENTS)
@pytest.mark.parametrize("order", range(7))
def test_quadrature_exactness(element, order):
    ref = reference_element(element)
    pts, w = ref.quadrature(order)
    for exps in np.ndindex(*[7] * ref.dim):
        if (sum(exps) if ref.simplex else max(exps)) > order:
            continue
        got = w @ np.prod(pts ** np.array(exps), axis=1)
        assert np.isclose(got, _exact_monomial(element, exps), rtol=1e-12, atol=1e-15), exps
    if ref.simplex:  # the points lie inside the simplex
        assert (pts >= 0).all() and (pts.sum(axis=1) <= 1).all()


@pytest.mark.parametrize("element", ["triangle", "tetra"])
@pytest.mark.parametrize("order", [7, 10, 12])
def test_collapsed_simplex_rules_are_exact(element, order):
    """Beyond the symmetric rules the simplices use collapsed Gauss (the facet rule of the 3D
    mortar, order up to 12): every monomial of total degree ≤ order."""
    ref = reference_element(element)
    pts, w = ref.quadrature(order)
    for exps in np.ndindex(*[order + 1] * ref.dim):
        if sum(exps) <= order:
            got = w @ np.prod(pts ** np.array(exps), axis=1)
            assert np.isclose(got, _exact_monomial(element, exps), rtol=1e-13, atol=0), exps
    assert (pts >= 0).all() and (pts.sum(axis=1) <= 1).all()


@pytest.mark.parametrize("element", ELEMENTS)
def test_quadrature_is_not_exact_beyond_its_order(element):
    """The exactness test can fail: a rule misses some monomial one degree higher."""
    order = 2
    ref = reference_element(element)
    pts, w = ref.quadrature(order)
    gauss = element in ("line", "quad", "hexahedron")
    p = order + 2 if gauss else order + 1  # Gauss n = 2 is exact to degree 3
    exps = (p,) + (0,) * (ref.dim - 1)
    got = w @ pts[:, 0] ** p
    assert not np.isclose(got, _exact_monomial(element, exps), rtol=1e-8)


@pytest.mark.parametrize("element", CELLS)
def test_local_facets_are_outward(element):
    ref = reference_element(element)
    X = ref.vertices  # (n_loc, d)
    c = X.mean(axis=0)
    assert len(FACETS[element]) == {"triangle": 3, "quad": 4, "tetra": 4, "hexahedron": 6}[element]
    for facet in FACETS[element]:
        P = X[facet]  # (k, d)
        if ref.dim == 2:  # the cell on the left of the edge: outward = tangent turned right
            t = P[1] - P[0]
            n = np.array([t[1], -t[0]])
        else:
            n = np.cross(P[1] - P[0], P[-1] - P[0])
        assert n @ (P.mean(axis=0) - c) > 0


def test_bad_input():
    with pytest.raises(ValueError, match="unknown cell type"):
        reference_element("prism")
    with pytest.raises(ValueError, match="unknown cell type"):
        reference_element("hexagon")
    with pytest.raises(ValueError, match="non-negative"):
        reference_element("tetra").quadrature(-1)
    with pytest.raises(ValueError, match="non-negative"):
        reference_element("quad").quadrature(-1)
    with pytest.raises(ValueError, match="non-negative"):
        reference_element("triangle").quadrature(-1)
