"""The bodies' operators assembled by owned rows under an engine's row partition (issue 33,
docs/distributed.md): each process assembles a contiguous block of the full rows only
(`fem.assembly`'s owned-rows forms), and the blocks are gathered in rank order into the whole
A_full, bit for bit the serial `sp.block_diag` of the bodies' whole operators."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from .bodies import operator


def full_range(fixed: np.ndarray, lo: int, hi: int) -> tuple[int, int]:
    """[start, end): the full rows (fixed (n_full,) bool, the prescribed dofs) that go with the
    owned unknowns [lo, hi) of the free numbering: from the first owned unknown's full row to
    the next rank's (the prescribed rows between fall to the rank before them; rank 0 starts at
    0, the last ends at n_full), so the ranks' blocks tile the full rows in rank order."""
    free = np.flatnonzero(~fixed)  # (n_free,)

    def cut(k: int) -> int:
        return 0 if k == 0 else fixed.size if k == free.size else int(free[k])

    return cut(lo), cut(hi)


def rows_block(bodies: list[Any], start: int, end: int) -> sp.csr_matrix:
    """(end − start, n_full) rows [start, end) of the bodies' operators side by side (each body
    assembles only its rows in that range: `bodies.operator(rows=)`)."""
    n_full = sum(b.size for b in bodies)
    mine = np.zeros(n_full, dtype=bool)
    mine[start:end] = True
    blocks = [operator(b, rows=mine[b.offset : b.offset + b.size]) for b in bodies]
    return sp.block_diag(blocks, format="csr")[start:end]


def assemble(bodies: list[Any], partition: Any) -> sp.csr_matrix:
    """(n_full, n_full) the bodies' operators side by side, the whole A_full on every process,
    from each process's owned rows (`full_range` of `partition.owned(n_free)`) gathered by
    `partition.gatherv`: no process assembles a row it does not own."""
    fixed = np.concatenate([b.fixed for b in bodies])  # (n_full,)
    start, end = full_range(fixed, *partition.owned(int((~fixed).sum())))
    own = rows_block(bodies, start, end)  # (end − start, n_full)
    counts = partition.gatherv(np.diff(own.indptr))  # (n_full,) entries per row
    indptr = np.zeros(fixed.size + 1, own.indptr.dtype)
    np.cumsum(counts, out=indptr[1:])
    data, indices = own.data, own.indices
    del own
    A = sp.csr_matrix(
        (partition.gatherv(data), partition.gatherv(indices), indptr), shape=(fixed.size,) * 2
    )
    return A
