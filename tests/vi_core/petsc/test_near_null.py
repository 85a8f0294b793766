"""The near-null vectors handed to GAMG (`vi_core.petsc.ksp.orthonormal`): an orthonormal basis
of their span, dependent columns dropped (the rigid-body modes on the free dofs of a
much-constrained coarse mesh are dependent; Cholesky QR alone failed on
paper_two_body_extruded level 0 with `--linear-solver amg`). Pure NumPy on one rank: the
allreduce is the identity (the ranks' sums are the MPI tests')."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vi_core.petsc.ksp import orthonormal

ONE_RANK = SimpleNamespace(comm=SimpleNamespace(allreduce=lambda local: local))


@pytest.mark.parametrize("dependent", [False, True])
def test_orthonormal_spans_the_columns_dropping_dependent_ones(dependent):
    rng = np.random.default_rng(3)
    N = rng.standard_normal((40, 3)) * [1.0, 1e2, 1e-2]  # (k, d) scaled apart
    if dependent:
        N = np.hstack([N, N[:, :1] - 2e2 * N[:, 2:]])  # a fourth column in the span
    Q = orthonormal(N, ONE_RANK)
    assert Q.shape == (40, 3)
    np.testing.assert_allclose(Q.T @ Q, np.eye(3), atol=1e-13)
    np.testing.assert_allclose(Q @ (Q.T @ N), N, atol=1e-10 * np.abs(N).max())  # same span
