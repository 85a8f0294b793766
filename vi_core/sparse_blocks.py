"""Blocks of a large sparse matrix gathered from its index arrays, in chunks: a block plus a
low-rank correction (`restricted_plus`), the entries whose transpose is not stored
(`lone_entries`) and the symmetric part in place (`symmetric_part`).

Why: the multigrid set-up of the iterative path (`vi_core.block_amg`, `vi_core.amg`) needs the
field blocks of a matrix that differs from A by corrections of the rank of the contact
interface; fancy indexing (A[rows][:, cols]), sums and transposes each make full-size
temporaries (paper scene level 5: forming Â and taking its blocks peaked at 685 MB from 365
held). Here the only full-size arrays are the results'.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

CHUNK = 1 << 18  # entries per chunk of the one-pass gathers (`gather_rows`): its temporaries


def row_chunks(A: sp.csr_matrix):
    """(rows (e,), slice) per chunk of A's rows of about CHUNK entries: the row of each entry
    of the chunk and the chunk's slice of A's index and data arrays."""
    r0, n = 0, A.shape[0]
    while r0 < n:
        r1 = int(np.searchsorted(A.indptr, A.indptr[r0] + CHUNK, side="right")) - 1
        r1 = min(max(r1, r0 + 1), n)
        rows = np.repeat(np.arange(r0, r1), np.diff(A.indptr[r0 : r1 + 1]))  # (e,)
        yield rows, slice(int(A.indptr[r0]), int(A.indptr[r1]))
        r0 = r1


def gather_rows(
    A: sp.csr_matrix,
    row_of: np.ndarray,
    col_of: np.ndarray,
    shape: tuple[int, int],
    extra: sp.csr_matrix,
) -> sp.csr_matrix:
    """The (shape) csr matrix holding, in row row_of[r] ≥ 0, the stored entries (c, v) of A's
    row r with col_of[c] ≥ 0, at column col_of[c], and the rows of `extra` (shape, few stored
    rows, none of them a row row_of gives). row_of must increase over the rows it keeps,
    col_of over the columns. Built from A's index arrays in chunks of about CHUNK entries:
    the only full-size arrays are the result's (fancy indexing such as A[rows][:, cols] makes
    an intermediate of the rows, a sum a copy of both)."""
    n_rows, n_cols = shape
    extra = sp.csr_matrix(extra)
    extra.sum_duplicates()

    def kept():  # A's entries that land in the result, per chunk: (their rows (k,), slice, mask)
        for rows, sl in row_chunks(A):
            keep = (row_of[rows] >= 0) & (col_of[A.indices[sl]] >= 0)  # (e,)
            yield rows[keep], sl, keep

    count = np.diff(extra.indptr).astype(np.int64)  # (n_rows,) entries per row of the result
    for rows, _, _ in kept():
        count += np.bincount(row_of[rows], minlength=n_rows)
    nnz = int(count.sum())
    idx = np.int32 if max(nnz, n_rows, n_cols) < np.iinfo(np.int32).max else np.int64
    indptr = np.zeros(n_rows + 1, dtype=idx)
    np.cumsum(count, out=indptr[1:])
    del count
    indices = np.empty(nnz, dtype=idx)
    data = np.empty(nnz, dtype=np.result_type(A.dtype, extra.dtype))
    for rows, sl, keep in kept():
        # rank of each kept entry within its row (rows ascending: a row's entries adjoin)
        rank = np.arange(rows.size) - np.searchsorted(rows, rows)  # (k,)
        dest = indptr[row_of[rows]] + rank  # (k,)
        indices[dest] = col_of[A.indices[sl][keep]]
        data[dest] = A.data[sl][keep]
    rows = np.repeat(np.arange(n_rows), np.diff(extra.indptr))  # (extra.nnz,)
    dest = indptr[rows] + np.arange(extra.nnz) - extra.indptr[rows]  # (extra.nnz,)
    indices[dest] = extra.indices
    data[dest] = extra.data
    out = sp.csr_matrix((data, indices, indptr), shape=shape)
    out.sort_indices()
    return out


def restricted_plus(
    A: sp.csr_matrix,
    rows: np.ndarray,
    cols: np.ndarray,
    Z: sp.csr_matrix,
    lone: tuple[np.ndarray, np.ndarray] | None = None,
) -> sp.csr_matrix:
    """(k_r, k_c) A[rows][:, cols] + Z, where an entry −1 of rows/cols stands for a row/column
    of zeros (their other entries increasing) and Z has few stored rows: A's rows outside Z's
    gathered from A's index arrays (`gather_rows`), Z's rows summed with A's there (a small
    sum). Stored zeros are kept; given lone = `lone_entries(A)` (with rows = cols) the pattern
    is widened by stored zeros to a symmetric one (`symmetric_part` then needs no transpose):
    the transposes of Z's entries and of the lone entries in the block."""
    row_of = np.full(A.shape[0], -1, dtype=np.int64)  # (n,) the result's row of A's rows
    row_of[rows[rows >= 0]] = np.flatnonzero(rows >= 0)
    col_of = np.full(A.shape[1], -1, dtype=np.int64)  # (n,) the result's column of A's
    col_of[cols[cols >= 0]] = np.flatnonzero(cols >= 0)
    Z = sp.coo_matrix(Z)
    if lone is not None:  # Zᵀ's pattern and that of the lone entries' transposes, as zeros
        r, c = lone
        inside = (row_of[r] >= 0) & (col_of[c] >= 0)  # (k,) the lone entries in the block
        add_r = np.concatenate([Z.col, col_of[c[inside]]])
        add_c = np.concatenate([Z.row, row_of[r[inside]]])
        Z = sp.coo_matrix(
            (np.concatenate([Z.data, np.zeros(add_r.size)]),
             (np.concatenate([Z.row, add_r]), np.concatenate([Z.col, add_c]))),
            shape=Z.shape,
        )  # fmt: skip
    t = np.unique(Z.row[rows[Z.row] >= 0])  # (k,) Z's rows that have a row of A
    row_of[rows[t]] = -1  # those rows come from the sum below
    A_t = A[rows[t]]  # (k, n) A's rows there
    r = np.repeat(t, np.diff(A_t.indptr))  # (nnz_t,) their rows in the result
    c = col_of[A_t.indices]  # (nnz_t,) their columns in the result, −1 dropped
    Z = sp.coo_matrix(  # (k_r, k_c) the sum on Z's rows, stored zeros kept (tocsr)
        (np.concatenate([Z.data, A_t.data[c >= 0]]),
         (np.concatenate([Z.row, r[c >= 0]]), np.concatenate([Z.col, c[c >= 0]]))),
        shape=Z.shape,
    ).tocsr()  # fmt: skip
    return gather_rows(A, row_of, col_of, Z.shape, extra=Z)


def _find(A: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(k,) the position in A's index arrays of each entry (rows[t], cols[t]), −1 where it is
    not stored (A canonical: sorted indices, no duplicates): a binary search within each row."""
    end = A.indptr[rows + 1].astype(np.int64)  # (k,)
    lo, hi = A.indptr[rows].astype(np.int64), end.copy()  # (k,) the search interval
    last = max(A.nnz - 1, 0)
    while (active := lo < hi).any():
        mid = (lo + hi) // 2
        right = active & (A.indices[np.minimum(mid, last)] < cols)
        lo = np.where(right, mid + 1, lo)
        hi = np.where(active & ~right, mid, hi)
    found = lo < end
    found[found] = A.indices[lo[found]] == cols[found]
    return np.where(found, lo, -1)


def lone_entries(A: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """(rows (k,), cols (k,)) the stored entries of a square csr A (made canonical in place,
    the same values) whose transpose A does not store (`_find`, in chunks): A's pattern is
    symmetric but for exact zeros dropped on one side (2 entries at the paper scene's level
    5)."""
    A.sum_duplicates()
    out_r, out_c = [], []
    for r, sl in row_chunks(A):
        c = A.indices[sl]  # (e,)
        lone = _find(A, c, r) < 0  # (e,)
        out_r.append(r[lone])
        out_c.append(c[lone])
    return np.concatenate(out_r), np.concatenate(out_c)


def symmetric_part(K: sp.csr_matrix) -> sp.csr_matrix:
    """(K + Kᵀ)/2 of a square csr K, its zeros dropped, computed in K's data in place for each
    stored (i, j) above the diagonal with a stored (j, i): the same numbers as the sum, without
    the transpose copy and the sum's arrays. Where K's pattern is not symmetric, that sum of
    the result follows (its averaged pairs are (v + v)/2 = v exactly: the same numbers)."""
    K.sum_duplicates()
    n_upper = n_lower = 0
    matched = True
    for rows, sl in row_chunks(K):
        cols = K.indices[sl]  # (e,)
        upper = cols > rows  # (e,)
        n_upper += int(upper.sum())
        n_lower += int((cols < rows).sum())
        e = np.flatnonzero(upper) + sl.start  # (k,) the entries (i, j) above the diagonal
        p = _find(K, cols[upper], rows[upper])  # (k,) their (j, i)
        matched &= bool((p >= 0).all())
        e, p = e[p >= 0], p[p >= 0]
        v = 0.5 * (K.data[e] + K.data[p])  # (k,) as (a + b)·0.5 in the sum: the same numbers
        K.data[e] = v
        K.data[p] = v
    if not matched or n_upper != n_lower:
        K = (K + K.T).tocsr()
        K.data *= 0.5
    K.eliminate_zeros()
    return K
