"""The petsc engine's slave rows (issue 33, `vi_core.petsc.newton._slave_rows`): every rank
needs the m slave rows of A' (the multipliers' recovery and the condensed rows read
D^{-T} A_S), and under a row partition each holds only its own rows of A; each rank scales the
slave rows it owns and the ranks' blocks are gathered, in the order of S: bit for bit the rows
`equilibrated_rows(S)` of the whole A gives (values, column indices, row pointers). Forked
processes with a stand-in partition (tests/vi_core/processes.py); the mpi tier runs it on MPI."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vi_core.petsc.newton import _slave_rows
from vi_core.testing import random_vi

from ..processes import Rows, by_rows, cuts_of, on_processes


def slave_rows_everywhere(seed: int, fault: str = "") -> list:
    """Whether each process's `_slave_rows` of a random VI (held by random row blocks, the
    slave dofs a random permutation: S in no particular order) equals the whole VI's rows of
    A' at S; `fault` on process 0 (`processes.FAULTS`)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(12, 30))
    vi = random_vi(seed, n=n, m=int(rng.integers(5, n // 2 + 1)), spread=2.0)
    S = rng.permutation(n)[: vi.m]  # (m,)
    ref = vi.equilibrated_rows(S)
    cuts = cuts_of(rng, n) if not fault else [0, n // 2, n]

    def work(rows: Rows) -> bool:
        mine = by_rows(vi, rows)
        got = _slave_rows(mine, S, *mine.row_range, rows)
        return all(
            a.dtype == b.dtype and np.array_equal(a, b)
            for a, b in ((got.data, ref.data), (got.indices, ref.indices), (got.indptr, ref.indptr))
        )

    return on_processes(cuts, work, 0, fault)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_slave_rows_gathered_are_the_whole_vis(seed):
    assert all(g is True for g in slave_rows_everywhere(seed))


@pytest.mark.parametrize("fault", ["gatherv"])
@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_a_rank_dropping_the_others_rows_is_seen(fault, seed):
    """Mutation: rank 0's gather keeps its own part only (the other rank's rows zero)."""
    assert not all(g is True for g in slave_rows_everywhere(seed, fault))
