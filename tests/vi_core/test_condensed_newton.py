"""The condensed Newton matrix applied without being stored (`vi_core.condensed_newton`)."""

import numpy as np
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from vi_core import condensed_newton

from .newton_systems import coupled_grid_vi, newton_matrix

seeds = st.integers(0, 2**32 - 1)


@given(seeds)
def test_condensed_newton_operator_is_the_newton_matrix(seed):
    """The iterative path's K, applied without being stored, and assembled for a fallback, is
    the condensed Newton matrix of its definition. Mutations: the R rows' correction with the
    wrong sign, or the S rows left as A's, are not."""
    from vi_core.ssn import Condensation

    rng = np.random.default_rng(seed)
    vi = coupled_grid_vi(rng, int(rng.integers(5, 12)), float(rng.uniform(0.0, 2.0)))
    cond = Condensation.detect(vi.B)
    tied = rng.uniform(size=vi.m) < 0.5
    A, B = vi.A.tocsr(), vi.B.tocsr()

    def K_S(t):  # (m, n) the S rows for the tied rows t
        J = sp.diags(t.astype(float))
        return (cond.D.T @ ((sp.identity(vi.m) - J) @ (cond.Dt_inv @ A[cond.S]) + J @ B)).tocsr()

    BR_t = sp.csr_matrix(B[:, cond.R].T)
    K = newton_matrix(vi, cond, tied)
    x = rng.standard_normal(vi.n)
    scale = np.linalg.norm(K @ x)

    def defect(op):
        return max(
            np.linalg.norm(op @ x - K @ x) / scale,
            np.linalg.norm(op.tocsr() @ x - K @ x) / scale,
        )

    assert (
        defect(condensed_newton.CondensedNewton(A, cond.R, cond.S, BR_t, cond.Dt_inv, K_S(tied)))
        < 1e-12
    )
    assert (
        defect(condensed_newton.CondensedNewton(A, cond.R, cond.S, -BR_t, cond.Dt_inv, K_S(tied)))
        > 1e-6
    )
    assert (
        defect(condensed_newton.CondensedNewton(A, cond.R, cond.S, BR_t, cond.Dt_inv, K_S(~tied)))
        > 1e-6
    )
