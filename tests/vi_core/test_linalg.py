"""Sparse factorisations: solves, transposed solves and the condition estimate."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core.linalg import Factorization, Refactorizer, condition_estimate, pardiso_available

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


def _same_pattern_sequence(seed, k=4, n=60):
    """k matrices with one sparsity pattern and different values (explicit zeros included)."""
    A = _matrix(seed, n)
    rng = np.random.default_rng(seed + 1)
    out = []
    for _ in range(k):
        B = A.copy()
        B.data = B.data * rng.uniform(0.5, 2.0, B.nnz)
        B.data[rng.random(B.nnz) < 0.05] = 0.0  # explicit zeros stay in the pattern
        B.setdiag(A.diagonal() * rng.uniform(1, 2, n))
        out.append(B)
    return out


@pytest.mark.parametrize("backend", BACKENDS)
def test_refactorizer_solves_every_matrix_of_a_sequence(backend):
    R = Refactorizer(backend)
    mats = _same_pattern_sequence(3)
    b = np.ones(mats[0].shape[0])
    for A in mats:
        assert A.nnz == mats[0].nnz
        x = R(A)(b)
        assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b) * np.abs(A).max()
    assert R.factorizations == len(mats)
    # SuperLU has no symbolic reuse; PARDISO analyses the common pattern once
    assert R.analyses == (1 if backend == "pardiso" else len(mats))


@pytest.mark.skipif(not pardiso_available(), reason="pypardiso not installed (extra [fast])")
def test_pardiso_reanalyses_when_the_pattern_changes_and_old_factors_go_stale():
    R = Refactorizer("pardiso")
    a, b = _matrix(1), _matrix(2)
    Fa = R(a)
    Fb = R(b)
    assert R.analyses == 2
    with pytest.raises(RuntimeError, match="replaced"):
        Fa(np.ones(a.shape[0]))
    x = Fb(np.ones(b.shape[0]))
    assert np.linalg.norm(b @ x - 1.0) <= 1e-10 * np.abs(b).max() * np.sqrt(b.shape[0])
