"""Dirichlet elimination: reduce_dirichlet and expand."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fem.dirichlet import expand, reduce_dirichlet


def random_system(n: int, seed: int) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    B = sp.random(n, n, density=0.3, random_state=rng) + sp.eye(n)
    A = (B @ B.T + n * sp.eye(n)).tocsr()  # SPD
    A = A + sp.triu(sp.random(n, n, density=0.2, random_state=rng), 1)  # and non-symmetric
    f = rng.normal(size=n)
    fixed = rng.random(n) < 0.3
    fixed[0] = True
    values = rng.normal(size=n)
    return A.tocsr(), f, fixed, values


def test_reduce_shapes_and_round_trip():
    A, f, fixed, values = random_system(20, 0)
    Ar, fr, free = reduce_dirichlet(A, f, fixed, values)
    m = (~fixed).sum()
    assert isinstance(Ar, sp.csr_matrix) and Ar.shape == (m, m) and fr.shape == (m,)
    assert np.array_equal(free, np.flatnonzero(~fixed))
    z = np.arange(m, dtype=float)
    x = expand(z, free, values)
    assert np.array_equal(x[fixed], values[fixed])
    assert np.array_equal(x[free], z)
    assert np.array_equal(expand(x[free], free, values), x)
    # expand does not modify its inputs
    assert not np.shares_memory(x, values)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_reduced_solution_equals_row_replacement(seed):
    A, f, fixed, values = random_system(30, seed)
    Ar, fr, free = reduce_dirichlet(A, f, fixed, values)
    x = expand(spla.spsolve(Ar.tocsc(), fr), free, values)
    # reference: Dirichlet rows replaced by identity rows with the prescribed values
    R = A.tolil()
    b = f.copy()
    for i in np.flatnonzero(fixed):
        R.rows[i], R.data[i] = [int(i)], [1.0]
        b[i] = values[i]
    ref = spla.spsolve(R.tocsc(), b)
    assert np.allclose(x, ref, rtol=1e-12, atol=1e-12)
    # and the free equations hold
    assert np.allclose((A @ x - f)[free], 0, atol=1e-10)


def test_non_fixed_values_are_ignored():
    A, f, fixed, values = random_system(15, 4)
    other = np.where(fixed, values, 1e6)
    r1 = reduce_dirichlet(A, f, fixed, values)
    r2 = reduce_dirichlet(A, f, fixed, other)
    assert np.allclose(r1[1], r2[1])


def test_reduce_bad_input():
    A, f, fixed, values = random_system(10, 5)
    with pytest.raises(ValueError, match="boolean"):
        reduce_dirichlet(A, f, fixed.astype(int), values)
    with pytest.raises(ValueError, match="values"):
        reduce_dirichlet(A, f, fixed, values[:-1])
    with pytest.raises(ValueError, match="square"):
        reduce_dirichlet(A[:, :-1], f, fixed, values)
