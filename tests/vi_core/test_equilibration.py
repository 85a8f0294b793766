"""Equilibration consistency and the gallery's own guarantees."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vi_core import solve
from vi_core.constants import skew_ratio
from vi_core.testing import SET_TYPES, manufactured_strategy, manufactured_vi, random_vi

from .helpers import FAST


def test_equilibrated_unit_diagonal_and_rows():
    vi = random_vi(7, n=30, m=12, structure="general", rho=1.0, spread=3)
    e = vi.equilibrated
    assert np.allclose(e.A.diagonal(), 1.0)
    rows = np.sqrt(np.asarray(e.B.multiply(e.B).sum(axis=1)).ravel())
    # ball blocks use the mean scale of the ball, so only free/box/nonneg rows are exactly 1
    assert np.allclose(np.median(rows), 1.0)


@settings(max_examples=40)
@given(manufactured_strategy())
def test_manufactured_solution_has_zero_residual(mf):
    vi = mf.vi
    assert vi.Lambda.contains(mf.lam, tol=1e-12)
    assert vi.residual(mf.u, mf.lam).relative <= 1e-12


@settings(max_examples=20)
@given(st.integers(0, 2**32 - 1), st.floats(0.1, 3.0), st.sampled_from(["skew-coupled", "general"]))
def test_gallery_hits_requested_rho(seed, rho, structure):
    vi = random_vi(seed, n=24, m=8, structure=structure, rho=rho, spread=2)
    assert vi.structure == structure
    e = vi.equilibrated
    assert skew_ratio(e.A0, e.C) == pytest.approx(rho, rel=1e-8)


def test_gallery_covers_every_kind():
    mf = manufactured_vi(3, n=40, m=20, active=0.3, degenerate=0.4)
    kinds = set(mf.kind)
    assert {"free", "inactive", "active", "degenerate"} <= kinds
    names = {type(b).__name__ for b in mf.vi.Lambda.blocks()}
    assert names == {"Box", "Ball", "Free", "NonNegative"}
    assert len(SET_TYPES) == 4


@pytest.mark.parametrize("seed", range(5))
def test_units_do_not_change_the_solution(seed):
    """A change of units u = S ũ (spread 3 decades) leaves S ũ and λ unchanged."""
    a = manufactured_vi(seed, n=30, m=10, structure="general", rho=0.8, spread=0.0)
    b = manufactured_vi(seed, n=30, m=10, structure="general", rho=0.8, spread=3.0)
    sa, sb = solve(a.vi, "ssn", **FAST), solve(b.vi, "ssn", **FAST)
    assert sa.converged and sb.converged
    np.testing.assert_allclose(sb.lam, b.lam, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(sa.lam, a.lam, rtol=1e-7, atol=1e-9)


@given(st.integers(0, 2**32 - 1))
def test_equilibrated_A_is_su_A_su_on_shared_index_arrays(seed):
    """e.A = Su A Su, stored on A's own index arrays (memory); a non-canonical A given by the
    caller (unsorted, duplicates, explicit zeros) is copied first and left as it was, and e.A
    has the structure of the product Su A Su (no explicit zeros: a direct solver's ordering
    follows it). Mutations: scaling the rows only, sorting the caller's arrays in place, or
    keeping the zeros, are caught."""
    import scipy.sparse as sp

    from vi_core import Free, MixedVI

    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 20))
    M = sp.random(n, n, density=0.3, random_state=rng) + sp.identity(n) * n
    coo = sp.coo_matrix(M)
    dup = rng.integers(0, coo.nnz)  # one entry split into two halves: a duplicate
    row = np.concatenate([coo.row, [coo.row[dup]]])
    col = np.concatenate([coo.col, [coo.col[dup]]])
    data = np.concatenate([coo.data, [coo.data[dup] / 2]])
    data[dup] /= 2
    off = np.flatnonzero(coo.row != coo.col)
    if off.size:  # an explicit zero: the product Su A Su drops it, so does e.A
        data[off[0]] = 0.0
    order = rng.permutation(row.size)  # unsorted within rows
    A = sp.csr_matrix((n, n))
    A.indptr = np.concatenate([[0], np.cumsum(np.bincount(row, minlength=n))]).astype(np.int32)
    by_row = order[np.argsort(row[order], kind="stable")]
    A.indices, A.data = col[by_row].astype(np.int32), data[by_row]
    A.has_canonical_format = A.has_sorted_indices = False
    before = (A.data.copy(), A.indices.copy(), A.indptr.copy())
    dense = A.toarray()
    vi = MixedVI(A, sp.csr_matrix((0, n)), np.ones(n), Free(0))
    e = vi.equilibrated
    s = vi.scaling.s_u
    assert np.allclose(e.A.toarray(), s[:, None] * dense * s, rtol=1e-13, atol=0)
    assert np.allclose(vi.A.toarray(), dense, rtol=1e-13, atol=0)
    assert np.shares_memory(e.A.indices, vi.A.indices)
    assert e.A.nnz == (sp.diags(s) @ A @ sp.diags(s)).tocsr().nnz
    for a, b in zip((A.data, A.indices, A.indptr), before, strict=True):
        assert np.array_equal(a, b)


@settings(max_examples=10)
@given(st.integers(0, 2**32 - 1))
def test_equilibrated_rows_and_parts_are_equilibrated_s_exactly(seed):
    """`equilibrated_rows(rows)` is rows `rows` of e.A bit for bit (values, indices, pattern:
    the petsc engine's owned rows must give the serial Newton matrix), built without e; and
    `equilibrated_parts` is e but A. A non-canonical A (duplicates, an explicit zero) asked by
    rows first is made canonical as e.A's is. Mutations: the column scaling dropped, the rows'
    scale taken from their positions instead of their indices, are caught."""
    import scipy.sparse as sp

    from vi_core import Box, MixedVI

    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(3, 20)), 2
    M = sp.random(n, n, density=0.3, random_state=rng) + sp.identity(n) * n
    coo = sp.coo_matrix(M)
    row, col = np.append(coo.row, coo.row[0]), np.append(coo.col, coo.col[0])
    data = np.append(coo.data, coo.data[0] / 2)  # a duplicate
    data[0] /= 2
    off = np.flatnonzero(coo.row != coo.col)
    if off.size:
        data[off[0]] = 0.0  # an explicit zero
    A = sp.csr_matrix((data, (row, col)), shape=(n, n))
    B = sp.random(m, n, density=0.5, random_state=rng) + sp.eye(m, n)
    f = rng.standard_normal(n)

    def vi():
        return MixedVI(A.copy(), B, f, Box(-np.ones(m), np.ones(m)), np.ones(m))

    rows = rng.integers(0, n, size=int(rng.integers(1, 2 * n)))  # unsorted, repeated
    by_rows = vi()
    got = by_rows.equilibrated_rows(rows)
    assert "equilibrated" not in by_rows.__dict__  # no whole copy made
    e = vi().equilibrated
    want = e.A[rows]
    for a, b in ((got.data, want.data), (got.indices, want.indices), (got.indptr, want.indptr)):
        assert np.array_equal(a, b)
    parts = by_rows.equilibrated_parts()
    assert (parts["B"] != e.B).nnz == 0
    for key in ("f", "gap"):
        assert np.array_equal(parts[key], getattr(e, key))
    y = rng.standard_normal(m) * 3
    assert np.array_equal(parts["Lambda"].project(y), e.Lambda.project(y))
