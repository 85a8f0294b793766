"""Sparse factorisations: solves, transposed solves and the condition estimate."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core.linalg import Factorization, condition_estimate, pardiso_available

BACKENDS = ["splu"] + (["pardiso"] if pardiso_available() else [])


def _matrix(seed, n=60):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, 0.1, random_state=rng) + sp.diags(rng.uniform(1, 3, n))
    scale = sp.diags(10.0 ** rng.uniform(-4, 4, n))  # badly scaled rows
    return sp.csr_matrix(scale @ A)


@pytest.mark.parametrize("backend", BACKENDS)
@given(st.integers(0, 2**32 - 1))
def test_solves_and_condition_estimate(backend, seed):
    A = _matrix(seed)
    F = Factorization(A, backend)
    b = np.random.default_rng(seed).standard_normal(A.shape[0])
    assert np.linalg.norm(A @ F(b) - b) <= 1e-9 * np.linalg.norm(b) * np.abs(A).max()
    x = F.solve_transposed(b)
    assert np.linalg.norm(A.T @ x - b) <= 1e-9 * np.linalg.norm(b) * np.abs(A).max()
    true = np.linalg.cond(A.toarray(), 1)
    est = condition_estimate(F)
    assert true / 3 <= est <= true * (1 + 1e-8)  # Hager–Higham never overestimates
