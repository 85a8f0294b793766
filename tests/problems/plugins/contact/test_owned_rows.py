"""The bodies' operators by owned rows (`contact.owned`, issue 33): on any partition of the
unknowns into contiguous ranks, the ranks' full-row blocks tile the full rows in rank order,
each owned unknown's row in its rank's block, and the blocks stacked are the serial A_full
(`sp.block_diag` of the bodies' whole operators) bit for bit: values, column indices and their
order, explicit zeros. Two bodies (elastic and piezoelectric, 2D) and a piezoelectric 3D block."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import problems.pipeline as pipeline
from problems.plugins.contact.bodies import operator
from problems.plugins.contact.owned import full_range, rows_block

SCENES = ["paper_two_body", "block3d"]


@cache
def _bodies(name: str):
    loaded = pipeline.load(name)
    model = loaded.plugin.build(loaded.scene, 0)
    whole = sp.block_diag([operator(b) for b in model.bodies], format="csr")
    return model.bodies, whole


def _cuts(seed: int, n: int, ranks: int) -> list[int]:
    """ranks + 1 increasing cut points 0 = c_0 ≤ … ≤ c_ranks = n (empty ranks allowed)."""
    rng = np.random.default_rng(seed)
    inner = np.sort(rng.integers(0, n + 1, ranks - 1))
    return [0, *map(int, inner), n]


@pytest.mark.parametrize("name", SCENES)
@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ranks=st.integers(1, 4))
def test_blocks_are_the_whole_operator(name, seed, ranks):
    bodies, whole = _bodies(name)
    fixed = np.concatenate([b.fixed for b in bodies])  # (n_full,)
    free = np.flatnonzero(~fixed)
    cuts = _cuts(seed, free.size, ranks)
    ranges = [full_range(fixed, lo, hi) for lo, hi in zip(cuts[:-1], cuts[1:], strict=True)]
    assert ranges[0][0] == 0 and ranges[-1][1] == fixed.size
    assert all(a[1] == b[0] for a, b in zip(ranges[:-1], ranges[1:], strict=True))
    for (lo, hi), (start, end) in zip(zip(cuts[:-1], cuts[1:], strict=True), ranges, strict=True):
        assert ((free[lo:hi] >= start) & (free[lo:hi] < end)).all()
    stacked = sp.vstack([rows_block(bodies, s, e) for s, e in ranges], format="csr")
    np.testing.assert_array_equal(stacked.indptr, whole.indptr)
    np.testing.assert_array_equal(stacked.indices, whole.indices)
    np.testing.assert_array_equal(stacked.data, whole.data)  # bit for bit
