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
from problems.plugins.contact.owned import full_range, reduced, rows_block
from vi_core import engine as vi_engine
from vi_core.ssn import solve_ssn

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


class _OneRank:
    """The row partition of one process (`vi_core.engine.row_partition`): every row owned."""

    def owned(self, n: int) -> tuple[int, int]:
        return 0, n

    def gatherv(self, local: np.ndarray) -> np.ndarray:
        return local

    def all_true(self, flag: bool) -> bool:
        return bool(flag)

    def norm(self, local: np.ndarray) -> float:
        return float(np.sqrt(local @ local))


@pytest.mark.parametrize("name", SCENES)
def test_reduced_parts_are_the_serial_slices(name):
    bodies, whole = _bodies(name)
    fixed = np.concatenate([b.fixed for b in bodies])  # (n_full,)
    free, dof = np.flatnonzero(~fixed), np.flatnonzero(fixed)
    A, A_fixed, fixed_rows = reduced(bodies, _OneRank())
    for got, want in [
        (A, whole[free][:, free]),
        (A_fixed, whole[free][:, dof]),
        (fixed_rows, whole[dof]),
    ]:
        want = want.tocsr()
        assert got.shape == want.shape
        np.testing.assert_array_equal(got.indptr, want.indptr)
        np.testing.assert_array_equal(got.indices, want.indices)
        np.testing.assert_array_equal(got.data, want.data)  # bit for bit


def _csr_equal(got: sp.csr_matrix, want: sp.csr_matrix) -> None:
    assert got.shape == want.shape
    np.testing.assert_array_equal(got.indptr, want.indptr)
    np.testing.assert_array_equal(got.indices, want.indices)
    np.testing.assert_array_equal(got.data, want.data)


@pytest.mark.parametrize("name", SCENES)
def test_a_model_built_by_rows_is_the_serial_model(name):
    """The whole build under a (one-process) row partition: vi.A, f, the Rhs's A_fixed and
    each body's A_fixed (its reactions) are the serial build's bit for bit."""
    loaded = pipeline.load(name)
    serial = loaded.plugin.build(loaded.scene, 0)
    with vi_engine.using(solve_ssn, rows=_OneRank()):
        by_rows = loaded.plugin.build(loaded.scene, 0)
    _csr_equal(by_rows.vi.A, serial.vi.A)
    np.testing.assert_array_equal(by_rows.vi.f, serial.vi.f)
    _csr_equal(by_rows.rhs.A_fixed, serial.rhs.A_fixed)
    for got, want in zip(by_rows.bodies, serial.bodies, strict=True):
        _csr_equal(got.A_fixed.tocsr(), want.A_fixed.tocsr())
