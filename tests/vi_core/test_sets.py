"""Projections, Jacobians and scaling of the convex sets."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vi_core import Ball, Box, Free, NonNegative, product

seeds = st.integers(0, 2**32 - 1)


def _sets(rng):
    k = int(rng.integers(1, 6))
    g = rng.uniform(0, 2, k)
    return [
        Free(k),
        NonNegative(k),
        Box(-g, rng.uniform(0, 2, k)),
        Ball(rng.uniform(0, 2, k), dim=int(rng.integers(2, 4))),
        product(Free(2), Box(-g, g), Ball(g, 2), NonNegative(3)),
    ]


@given(seeds)
def test_projection_is_idempotent_and_obtuse(seed):
    """P(P(y)) = P(y) and (y − P(y))ᵀ(μ − P(y)) ≤ 0 for μ in the set."""
    rng = np.random.default_rng(seed)
    for S in _sets(rng):
        y = 3 * rng.standard_normal(S.size)
        p = S.project(y)
        np.testing.assert_allclose(S.project(p), p, atol=1e-14)
        assert S.contains(p, 1e-14)
        for _ in range(5):
            mu = S.project(3 * rng.standard_normal(S.size))
            assert (y - p) @ (mu - p) <= 1e-12 * (1 + np.abs(y).sum() ** 2)


@given(seeds)
def test_jacobian_matches_finite_differences(seed):
    """∂P(y) is the derivative of P where P is differentiable."""
    rng = np.random.default_rng(seed)
    for S in _sets(rng):
        y = 3 * rng.standard_normal(S.size)
        J = S.jacobian(y).toarray()
        d = rng.standard_normal(S.size)
        eps = 1e-7
        fd = (S.project(y + eps * d) - S.project(y - eps * d)) / (2 * eps)
        np.testing.assert_allclose(J @ d, fd, atol=1e-5)


def test_ball_coordinates_are_ball_by_ball():
    B = Ball([1.0, 2.0], dim=2)
    p = B.project(np.array([3.0, 4.0, 0.0, 1.0]))
    np.testing.assert_allclose(p, [0.6, 0.8, 0.0, 1.0])


def test_scaled_set_is_the_image():
    rng = np.random.default_rng(1)
    S = product(Box(-1.0, 2.0, size=3), Ball([1.0, 3.0], 2))
    t = np.array([2.0, 3.0, 4.0, 5.0, 5.0, 0.5, 0.5])
    y = rng.standard_normal(7) * 4
    np.testing.assert_allclose(S.scaled(t).project(y / t), S.project(y) / t, atol=1e-14)
    with pytest.raises(ValueError, match="uniformly"):
        Ball([1.0], 2).scaled(np.array([1.0, 2.0]))


def test_bad_sets_are_refused_clearly():
    with pytest.raises(ValueError, match="lo ≤ hi"):
        Box([0.0, 1.0], [1.0, 0.5])
    with pytest.raises(ValueError, match="radius"):
        Ball([-1.0], 2)
    with pytest.raises(ValueError, match="NaN"):
        Box(np.nan, 1.0, size=2)
