"""The near-null vectors handed to GAMG (`vi_core.petsc.ksp.orthonormal`): an orthonormal basis
of their span, dependent columns dropped (the rigid-body modes on the free dofs of a
much-constrained coarse mesh are dependent; Cholesky QR alone failed on
paper_two_body_extruded level 0 with `--linear-solver amg`). Pure NumPy on one rank: the
allreduce is the identity (the ranks' sums are the MPI tests')."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vi_core.petsc.ksp import node_block, orthonormal

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


def _rigid_modes(rng: np.random.Generator, nodes: int, c: int) -> np.ndarray:
    """(nodes · c, c + rotations) the rigid-body modes of `nodes` random nodes with c components
    each, node by node, each row scaled as the equilibrated VI scales it (1 / s_u)."""
    p = rng.uniform(0.5, 2.0, (nodes, c))  # (nodes, c) coordinates off the axes
    comp = np.tile(np.arange(c), nodes)  # (k,) each row's component
    xyz = np.repeat(p, c, axis=0)  # (k, c) its node's coordinates
    rotations = {2: ((0, 1),), 3: ((1, 2), (2, 0), (0, 1))}[c]
    N = np.zeros((comp.size, c + len(rotations)))
    N[np.arange(comp.size), comp] = 1.0
    for r, (i, j) in enumerate(rotations):
        N[comp == i, c + r] = -xyz[comp == i, j]
        N[comp == j, c + r] = xyz[comp == j, i]
    return N / rng.uniform(0.1, 10.0, comp.size)[:, None]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), c=st.sampled_from([2, 3]))
def test_node_block_finds_whole_nodes_and_refuses_cut_ones(seed, c):
    """`node_block`: c on whole nodes of c components in order; 1 where a node is cut (a row
    dropped at either end), two components of a node swapped, or no translation columns (a
    constant); 0 without rows."""
    rng = np.random.default_rng(seed)
    nodes = int(rng.integers(1, 30))
    N = _rigid_modes(rng, nodes, c)
    assert node_block(N) == c
    assert node_block(N[1:]) == 1 and node_block(N[:-1]) == 1
    at = c * int(rng.integers(nodes))  # a node's first row
    swapped = N.copy()
    swapped[[at, at + 1]] = swapped[[at + 1, at]]
    assert node_block(swapped) == 1
    assert node_block(np.ones((N.shape[0], 1))) == 1
    assert node_block(N[:0]) == 0
