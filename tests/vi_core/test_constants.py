"""m_a, M_a, M_b, α, ρ, t_0 and the (3.5) constant: closed forms, dense vs ARPACK, limits."""

import numpy as np
import pytest
import scipy.sparse as sp

from vi_core import Box, MixedVI, constants, skew_ratio
from vi_core.testing import random_vi


def _two_by_two(c: float) -> MixedVI:
    A = np.diag([1.0, 4.0]) + c * np.array([[0.0, 1.0], [-1.0, 0.0]])
    return MixedVI(A=A, B=[[1.0, 0.0]], f=[1.0, 1.0], Lambda=Box(-1.0, 1.0))


def test_closed_form_identity_norms():
    c = 3.0
    vi = _two_by_two(c)
    k = constants(vi)
    assert k.m_a == pytest.approx(1.0)
    assert k.M_a == pytest.approx(np.linalg.norm(vi.A.toarray(), 2))
    assert k.alpha == pytest.approx(1.0) and k.M_b == pytest.approx(1.0)
    assert k.rho == pytest.approx(c / 2.0)  # A_0^{-1/2} C A_0^{-1/2} = [[0, c/2], [−c/2, 0]]
    assert k.t0 == pytest.approx(k.alpha * k.m_a / (k.M_a * (k.alpha + k.m_a + 2 * k.M_a)))
    assert k.stability == pytest.approx((k.alpha + k.m_a + 2 * k.M_a) / (k.alpha * k.m_a))


def test_closed_form_scaled_norms():
    """X = 2I halves m_a and M_a; α = σ_min(Y^{-1/2} B X^{-1/2}) = 1/sqrt(2) with Y = I."""
    vi = _two_by_two(0.0)
    k = constants(vi, X=2.0 * np.eye(2))
    assert k.m_a == pytest.approx(0.5) and k.M_a == pytest.approx(2.0)
    assert k.alpha == pytest.approx(1 / np.sqrt(2.0))
    assert k.dual_norm_x(np.array([2.0, 0.0])) == pytest.approx(np.sqrt(2.0))
    assert k.norm_x(np.array([1.0, 0.0])) == pytest.approx(np.sqrt(2.0))


@pytest.mark.parametrize("structure", ["symmetric", "skew-coupled", "general"])
def test_dense_and_arpack_agree(structure):
    vi = random_vi(3, n=60, m=20, structure=structure, rho=1.7, cond=50.0)
    rng = np.random.default_rng(0)
    R = sp.random(60, 60, density=0.05, random_state=1)
    X = (R @ R.T + sp.diags(rng.uniform(1.0, 2.0, 60))).tocsr()
    Y = sp.diags(rng.uniform(0.5, 2.0, 20))
    d = constants(vi, X=X, Y=Y)
    s = constants(vi, X=X, Y=Y, dense_limit=10)
    for name in ("m_a", "M_a", "M_b", "alpha", "rho", "t0", "stability"):
        assert getattr(s, name) == pytest.approx(getattr(d, name), rel=1e-7), name
    assert d.rho == pytest.approx(1.7 if structure != "symmetric" else 0.0, abs=1e-8)


def test_rho_is_invariant_under_change_of_units():
    vi = random_vi(2, n=30, m=10, structure="general", rho=0.9)
    S = sp.diags(10.0 ** np.linspace(-3, 3, 30))
    assert skew_ratio(S @ vi.A0 @ S, S @ vi.C @ S) == pytest.approx(0.9, rel=1e-8)


def test_refuses_above_max_size():
    vi = random_vi(0, n=20, m=8)
    with pytest.raises(ValueError, match="max_size = 10"):
        constants(vi, max_size=10)


def test_wrong_gram_shape():
    vi = random_vi(0, n=20, m=8)
    with pytest.raises(ValueError, match="X must be 20×20"):
        constants(vi, X=np.eye(3))


def test_gram_matrix_given_as_a_function():
    """vi.X may be a function returning the Gram matrix (a model assembles it when asked):
    the constants are those of the matrix itself. Mutation: a function that returns the
    identity instead is caught (the norms differ)."""
    vi = _two_by_two(1.0)
    X = np.diag([2.0, 3.0])
    direct = constants(vi, X=X)
    lazy = MixedVI(A=vi.A, B=vi.B, f=vi.f, Lambda=vi.Lambda, X=lambda: X)
    assert constants(lazy).m_a == pytest.approx(direct.m_a, rel=1e-12)
    assert constants(lazy).M_b == pytest.approx(direct.M_b, rel=1e-12)
    wrong = MixedVI(A=vi.A, B=vi.B, f=vi.f, Lambda=vi.Lambda, X=lambda: np.eye(2))
    assert constants(wrong).m_a != pytest.approx(direct.m_a, rel=1e-3)
