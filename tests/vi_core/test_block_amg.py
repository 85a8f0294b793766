"""The block multigrid preconditioner over the fields (`vi_core.block_amg`): the coupling
blocks applied."""

import numpy as np
import pytest
import scipy.sparse as sp

from vi_core import block_amg

from .newton_systems import laplacian

pytest.importorskip("pyamg")


def test_block_preconditioner_applies_the_coupling():
    """Blocks small enough for one level (a direct coarse solve) make BlockAMG the exact inverse
    of a block lower-triangular K = [[K_a, 0], [−G, K_b]]: the coupling block must be applied
    (mutation: couple=False leaves a residual of the size of G)."""
    k = 12
    L = laplacian(k)
    K = sp.bmat([[L, None], [-5.0 * L, 2 * L]]).tocsr()
    n1 = k * k
    fields = [("a", np.arange(2 * n1) < n1, None), ("b", np.arange(2 * n1) >= n1, None)]
    b = np.random.default_rng(0).standard_normal(2 * n1)
    rel = {}
    for couple in (True, False):
        M = block_amg.BlockAMG(block_amg.field_blocks(K, fields, couple))
        assert all(len(blk.ml.levels) == 1 for blk in M.blocks)
        rel[couple] = np.linalg.norm(K @ M(b) - b) / np.linalg.norm(b)
    assert rel[True] < 1e-12 and rel[False] > 0.1, rel
