"""Blocks gathered from a sparse matrix's index arrays (`vi_core.sparse_blocks`)."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core import sparse_blocks

seeds = st.integers(0, 2**32 - 1)


def _block(A: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(k_r, k_c) dense A[rows][:, cols], rows/columns −1 zero."""
    out = np.zeros((rows.size, cols.size))
    out[np.ix_(rows >= 0, cols >= 0)] = A[rows[rows >= 0]][:, cols[cols >= 0]].toarray()
    return out


@given(seeds)
def test_restricted_plus_is_the_block_plus_the_corrections(seed):
    """`restricted_plus` (A's rows and columns gathered in chunks from its index arrays, a few
    rows replaced by their sum with Z) is A[rows][:, cols] + Z, with rows/columns −1 zero and
    explicit zeros in A, over chunks of a few entries; given A's lone entries its pattern is
    symmetric, also where A's lacks one transpose. Mutations: Z's rows put in place of A's
    rows instead of added to them, or Zᵀ's pattern and A's lone entries left out, are not."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 40))
    A = sp.random(n, n, density=0.3, format="csr", random_state=rng)
    A.data[rng.uniform(size=A.nnz) < 0.1] = 0.0  # explicit zeros

    def some():  # (k,) an increasing subset of A's rows, then a few −1
        sub = np.flatnonzero(rng.uniform(size=n) < 0.7)
        return np.concatenate([sub, -np.ones(int(rng.integers(0, 5)), dtype=int)])

    rows, cols = some(), some()
    Z = sp.random(rows.size, cols.size, density=0.3, format="csr", random_state=rng)
    Z = sp.diags((rng.uniform(size=rows.size) < 0.3).astype(float)) @ Z  # a few rows
    ref = _block(A, rows, cols) + Z.toarray()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sparse_blocks, "CHUNK", int(rng.integers(1, 8)))
        out = sparse_blocks.restricted_plus(A, rows, cols, Z)
    assert out.has_sorted_indices
    assert np.array_equal(out.toarray(), ref)
    row_of = np.full(n, -1)
    row_of[rows[rows >= 0]] = np.flatnonzero(rows >= 0)
    col_of = np.full(n, -1)
    col_of[cols[cols >= 0]] = np.flatnonzero(cols >= 0)
    stored = np.diff(Z.indptr) > 0  # (k_r,) Z's rows
    row_of[rows[stored & (rows >= 0)]] = -1
    replaced = sparse_blocks.gather_rows(A, row_of, col_of, Z.shape, extra=Z)
    if (stored & (np.abs(ref - Z.toarray()).sum(axis=1) > 0)).any():  # A's row there not zero
        assert not np.array_equal(replaced.toarray(), ref)
    # symmetric: the pattern of A's pattern (symmetric but for one entry) plus a square Z is
    S = (A + A.T).tocsr()
    i, j = S.nonzero()
    if (i != j).any():  # one entry (i, j) dropped, (j, i) kept
        k = np.flatnonzero(i != j)[0]
        S[i[k], j[k]] = 0.0
        S.eliminate_zeros()
    Z = sp.random(rows.size, rows.size, density=0.3, format="csr", random_state=rng)
    Z = sp.diags((rng.uniform(size=rows.size) < 0.3).astype(float)) @ Z

    def pattern(symmetric):  # (k_r, k_r) 0/1 and whether the values are right
        out = sparse_blocks.restricted_plus(
            S, rows, rows, Z, sparse_blocks.lone_entries(S) if symmetric else None
        )
        ok = np.array_equal(out.toarray(), _block(S, rows, rows) + Z.toarray())
        out.data[:] = 1.0
        return out.toarray(), ok

    P, ok = pattern(True)
    assert ok and np.array_equal(P, P.T)
    P, ok = pattern(False)
    ones = sp.csr_matrix((np.ones(S.nnz), S.indices, S.indptr), shape=S.shape)
    Q = (_block(ones, rows, rows) + abs(Z).toarray()) > 0  # (k_r, k_r) the two patterns
    assert ok and np.array_equal(P > 0, Q)
    if not np.array_equal(Q, Q.T):  # without Zᵀ's pattern the result's is not symmetric
        assert not np.array_equal(P, P.T)


@given(seeds)
def test_symmetric_part(seed):
    """`symmetric_part` is (K + Kᵀ)/2 as the sum computes it, the same numbers, with its zeros
    dropped: in place for a symmetric pattern (values not symmetric, explicit zeros, entries
    with a zero symmetric part), and by the sum for a pattern that is not symmetric."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 30))
    mask = rng.uniform(size=(n, n)) < 0.3  # (n, n) the pattern
    if rng.uniform() < 0.7:
        mask |= mask.T  # symmetric
    Kd = np.where(mask, rng.standard_normal((n, n)), 0.0)  # (n, n) values not symmetric
    i, j = np.nonzero(np.triu(mask, 1))
    Kd[j[:2], i[:2]] = -Kd[i[:2], j[:2]]  # pairs with a zero symmetric part
    P = sp.csr_matrix(mask.astype(float))
    P.sort_indices()
    data = Kd[np.repeat(np.arange(n), np.diff(P.indptr)), P.indices]  # (nnz,)
    data[rng.uniform(size=data.size) < 0.1] = 0.0  # explicit zeros
    K = sp.csr_matrix((data, P.indices, P.indptr), shape=(n, n))
    K.sort_indices()
    ref = (K + K.T).tocsr()
    ref.data *= 0.5
    ref.eliminate_zeros()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sparse_blocks, "CHUNK", int(rng.integers(1, 8)))
        out = sparse_blocks.symmetric_part(K.copy())
    out.sort_indices()
    assert np.array_equal(out.indptr, ref.indptr) and np.array_equal(out.indices, ref.indices)
    assert np.array_equal(out.data, ref.data)
