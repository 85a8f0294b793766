"""A MixedVI that holds A by rows (`MixedVI.partition`, issue 33): its checks, scaling,
residual, A u and equilibrated rows, computed from each process's rows and reductions, are the
whole VI's on every process — bit for bit where the serial computation is row by row (s_u,
s_lam, A u, the rows of A'), to rounding for the residual's norm (a sum of the processes' sums
of squares) — and a bad A is refused on every process with the serial message.

The processes are forked here, each with its rows of A and a stand-in of the engine's row
partition (`vi_core.petsc.runtime.RowPartition`: ``owned``, ``gatherv``, ``all_true``,
``norm``) whose collectives exchange through queues; the same protocol runs on MPI in the
petsc engine's tests (tests/vi_core/petsc)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from vi_core import MixedVI
from vi_core.testing import random_vi

from .processes import FAULTS, Rows, by_rows, cuts_of, on_processes


def same_answers(vi: MixedVI, cuts: list[int], u, lam, faulty=-1, fault="") -> bool:
    """Whether every process's scaling, A u, equilibrated owned rows and residual equal the
    whole VI's (bit for bit; the residual to 1e-13 relative)."""
    ref_s, ref_r = vi.scaling, vi.residual(u, lam)
    e_A = vi.equilibrated.A

    def work(rows: Rows):
        mine = by_rows(vi, rows)
        lo, hi = mine.row_range
        s = mine.scaling
        r = mine.residual(u, lam)
        return (
            np.array_equal(s.s_u, ref_s.s_u)
            and np.array_equal(s.s_lam, ref_s.s_lam)
            and np.array_equal(mine.matvec(u), vi.A @ u)
            and (mine.equilibrated_rows(np.arange(lo, hi)) != e_A[lo:hi]).nnz == 0
            and r.relative == pytest.approx(ref_r.relative, rel=1e-13, abs=1e-300)
            and r.equilibrium == pytest.approx(ref_r.equilibrium, rel=1e-13, abs=1e-300)
            and r.complementarity == ref_r.complementarity
        )

    return all(g is True for g in on_processes(cuts, work, faulty, fault))


def refusals(A: sp.csr_matrix, vi: MixedVI, cuts: list[int], faulty=-1, fault="") -> list[str]:
    """What each process raises building vi with A (cut by rows)."""

    def work_rows(rows: Rows):
        lo, hi = rows.owned(vi.n)
        try:
            MixedVI(A=A[lo:hi], B=vi.B, f=vi.f, Lambda=vi.Lambda, gap=vi.gap, partition=rows)
        except ValueError as err:
            return str(err)
        return "accepted"

    return on_processes(cuts, work_rows, faulty, fault)


def serial_refusal(A: sp.csr_matrix, vi: MixedVI) -> str:
    try:
        MixedVI(A=A, B=vi.B, f=vi.f, Lambda=vi.Lambda, gap=vi.gap)
    except ValueError as err:
        return str(err)
    return "accepted"


def bad_matrices(rng: np.random.Generator, vi: MixedVI) -> list[sp.csr_matrix]:
    """A with a NaN in a random row; A with a nonpositive diagonal in two random rows."""
    A = sp.csr_matrix(vi.A, copy=True)
    i = int(rng.integers(vi.n))
    A[i, int(rng.integers(vi.n))] = np.nan
    D = sp.lil_matrix(vi.A, copy=True)
    for i in rng.choice(vi.n, size=2, replace=False):
        D[i, i] = -float(rng.random())
    return [A, sp.csr_matrix(D)]


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_by_rows_is_the_whole_vi_on_every_process(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(12, 30))
    vi = random_vi(seed, n=n, m=int(rng.integers(5, n // 2 + 1)), spread=2.0)
    cuts = cuts_of(rng, n)
    u, lam = rng.standard_normal(vi.n), rng.standard_normal(vi.m)
    assert same_answers(vi, cuts, u, lam)
    for A in bad_matrices(rng, vi):
        assert refusals(A, vi, cuts) == [serial_refusal(A, vi)] * (len(cuts) - 1)


@pytest.mark.parametrize("fault", FAULTS)
@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_a_process_dropping_the_others_parts_is_seen(fault, seed):
    """Mutations: one process whose reduction keeps its own part only. Its scaling or its
    residual differ from the whole VI's, or the processes refuse a bad A unlike the serial
    build (one accepts what another refuses)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(12, 30))
    vi = random_vi(seed, n=n, m=int(rng.integers(5, n // 2 + 1)), spread=2.0)
    cuts = [0, n // 2, n]  # two processes, each with rows: each holds a part the other needs
    faulty = int(rng.integers(2))
    u, lam = rng.standard_normal(vi.n), rng.standard_normal(vi.m)
    assert same_answers(vi, cuts, u, lam)  # without the fault: the same (the test can pass)
    ok = same_answers(vi, cuts, u, lam, faulty, fault)
    if ok:  # all_true is read by the refusals only: a NaN in the other process's rows
        A = sp.csr_matrix(vi.A, copy=True)
        other = (n // 2) if faulty == 0 else 0
        A[other, other] = np.nan
        ok = refusals(A, vi, cuts, faulty, fault) == [serial_refusal(A, vi)] * 2
    assert not ok
