"""The petsc engine's rows-only A (issue 33): during a solve each rank's vi.A holds its own rows
[lo, hi) only, and the ranks' rows make the whole A again at the end, bit for bit (the serial
post-processing reads it). Pure SciPy: the ranks' allgather is played by a stand-in."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from vi_core.petsc.newton import _rows_only, _whole


def _ranks(A: sp.csr_matrix, cuts: list[int]) -> list[tuple[int, int, sp.csr_matrix]]:
    """Each rank's (lo, hi, rows-only A) for the row ranges between `cuts`."""
    return [(lo, hi, _rows_only(A, lo, hi)) for lo, hi in zip(cuts[:-1], cuts[1:], strict=True)]


def _gathered(ranks: list[tuple[int, int, sp.csr_matrix]], lo: int, hi: int, mine):
    """`_whole` on one rank, each of its gathers (`Reductions.gatherv`: the rows' counts, then
    the data, then the indices) answered with every rank's part concatenated in rank order."""
    parts = []
    for lo_r, hi_r, A_r in ranks:
        p0, p1 = A_r.indptr[lo_r], A_r.indptr[hi_r]
        parts.append((np.diff(A_r.indptr[lo_r : hi_r + 1]), A_r.data[p0:p1], A_r.indices[p0:p1]))
    calls = iter(range(3))

    def gatherv(local: np.ndarray) -> np.ndarray:
        k = next(calls)
        return np.concatenate([p[k] for p in parts])

    return _whole(mine, lo, hi, SimpleNamespace(gatherv=gatherv))


@settings(max_examples=10)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_rows_only_then_whole_is_A_bit_for_bit(seed, mutate):
    """A rank's rows-only A has its rows and no other entry; gathered, the ranks' rows give A's
    data, indices and indptr exactly. Mutation (mutate): one rank's last row dropped from its
    copy, caught by the round trip."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 30))
    A = sp.random(n, n, density=0.3, random_state=rng, format="csr") + sp.identity(n)
    A = sp.csr_matrix(A)
    A.sort_indices()
    P = int(rng.integers(1, min(n, 4) + 1))
    cuts = [0, *sorted(rng.choice(np.arange(1, n), size=P - 1, replace=False).tolist()), n]
    ranks = _ranks(A, cuts)
    for lo, hi, A_r in ranks:
        dense = A.toarray()
        dense[:lo], dense[hi:] = 0.0, 0.0
        assert np.array_equal(A_r.toarray(), dense)
    if mutate:  # the last rank's copy without its last row (every row holds its diagonal)
        lo, hi, _ = ranks[-1]
        bad = A.tolil()
        bad[hi - 1, :] = 0.0
        ranks[-1] = (lo, hi, _rows_only(sp.csr_matrix(bad), lo, hi))
    for lo, hi, A_r in ranks:
        W = _gathered(ranks, lo, hi, A_r)
        same = all(
            a.shape == b.shape and np.array_equal(a, b)
            for a, b in ((W.data, A.data), (W.indices, A.indices), (W.indptr, A.indptr))
        )
        assert same != mutate
