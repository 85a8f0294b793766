"""3D reference elements: Kronecker property, partition of unity, gradients, quadrature."""

from math import factorial

import numpy as np
import pytest

from fem.elements3d import FACES, reference_element3d

ELEMENTS = ["hexahedron", "tetra"]


@pytest.mark.parametrize("element", ELEMENTS)
def test_shape_functions(element):
    ref = reference_element3d(element)
    assert np.allclose(ref.values(ref.vertices), np.eye(ref.n_loc), rtol=0, atol=1e-15)
    pts = np.random.default_rng(0).uniform(0, 0.3, (7, 3))
    assert np.allclose(ref.values(pts).sum(axis=1), 1, rtol=0, atol=1e-15)
    assert np.allclose(ref.gradients(pts).sum(axis=1), 0, rtol=0, atol=1e-15)
    # the gradients against central differences (Q1 is quadratic along no line: exact to rounding)
    h = 1e-5
    for i in range(3):
        d = np.zeros(3)
        d[i] = h
        fd = (ref.values(pts + d) - ref.values(pts - d)) / (2 * h)
        assert np.allclose(ref.gradients(pts)[..., i], fd, rtol=0, atol=1e-9)
    # linear functions are reproduced: Σ_a x_a φ_a(ξ) = ξ
    assert np.allclose(ref.values(pts) @ ref.vertices, pts, rtol=0, atol=1e-15)


def _exact_monomial(element: str, p: int, q: int, r: int) -> float:
    if element == "tetra":  # ∫ s^p t^q u^r over the unit tetrahedron
        return factorial(p) * factorial(q) * factorial(r) / factorial(p + q + r + 3)
    return float(np.prod([(1 - (-1) ** (k + 1)) / (k + 1) for k in (p, q, r)]))


@pytest.mark.parametrize("element", ELEMENTS)
@pytest.mark.parametrize("order", range(7))
def test_quadrature_exactness(element, order):
    pts, w = reference_element3d(element).quadrature(order)
    degree_ok = (lambda p, q, r: p + q + r <= order) if element == "tetra" else (
        lambda p, q, r: max(p, q, r) <= order
    )  # fmt: skip
    exps = [(p, q, r) for p in range(7) for q in range(7) for r in range(7) if degree_ok(p, q, r)]
    for p, q, r in exps:
        got = w @ (pts[:, 0] ** p * pts[:, 1] ** q * pts[:, 2] ** r)
        assert np.isclose(got, _exact_monomial(element, p, q, r), rtol=1e-12, atol=1e-15), (
            p,
            q,
            r,
        )
    if element == "tetra":  # the points lie inside the tetrahedron
        assert (pts >= 0).all() and (pts.sum(axis=1) <= 1).all()


@pytest.mark.parametrize("element", ELEMENTS)
def test_quadrature_is_not_exact_beyond_its_order(element):
    """The exactness test can fail: a rule misses some monomial one degree higher."""
    order = 2
    pts, w = reference_element3d(element).quadrature(order)
    p = order + 1 if element == "tetra" else order + 2  # Gauss n = 2 is exact to degree 3
    got = w @ pts[:, 0] ** p
    assert not np.isclose(got, _exact_monomial(element, p, 0, 0), rtol=1e-8)


@pytest.mark.parametrize("element", ELEMENTS)
def test_local_faces_are_outward(element):
    ref = reference_element3d(element)
    X = ref.vertices  # (n_loc, 3)
    c = X.mean(axis=0)
    for face in FACES[element]:
        P = X[face]  # (k, 3)
        n = np.cross(P[1] - P[0], P[-1] - P[0])
        assert n @ (P.mean(axis=0) - c) > 0


def test_bad_input():
    with pytest.raises(ValueError, match="unknown cell type"):
        reference_element3d("prism")
    with pytest.raises(ValueError, match="non-negative"):
        reference_element3d("tetra").quadrature(-1)
