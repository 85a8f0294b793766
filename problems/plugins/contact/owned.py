"""The bodies' operators assembled by owned rows under an engine's row partition (the petsc
engine, docs/distributed.md): each process assembles a contiguous block of the full rows only
(`fem.assembly`'s owned-rows forms), and the blocks' Dirichlet-reduced parts are gathered in
rank order, bit for bit the slices of the serial A_full (`sp.block_diag` of the bodies' whole
operators), which is never formed."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from vi_core.engine import gathered_rows

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


def reduced(
    bodies: list[Any], partition: Any
) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """The Dirichlet-reduced blocks of the bodies' operators side by side from each process's
    owned rows (`full_range` of `partition.owned(n_free)`, assembled by `rows_block`): no
    process assembles a row it does not own, and A_full is never formed whole. Returns
    A (k, n_free) this process's rows [lo, hi) of A_full[free][:, free] (the MixedVI holds A
    by rows: `MixedVI.partition`), and, gathered on every process (`partition.gatherv`),
    A_fixed (n_free, n_fixed) = A_full[free][:, fixed] (`model.Rhs`) and fixed_rows
    (n_fixed, n_full) = A_full[fixed], the prescribed dofs' rows (each body's reactions); each
    bit for bit the slice of the serial A_full (rows are sliced row by row)."""
    fixed = np.concatenate([b.fixed for b in bodies])  # (n_full,)
    free, dof = np.flatnonzero(~fixed), np.flatnonzero(fixed)  # (n_free,), (n_fixed,)
    start, end = full_range(fixed, *partition.owned(free.size))
    own = rows_block(bodies, start, end)  # (end − start, n_full)
    mine = (start <= free) & (free < end)  # (n_free,) the owned unknowns
    rows = own[free[mine] - start]  # (k, n_full)
    fixed_rows = own[dof[(start <= dof) & (dof < end)] - start]  # (k_D, n_full)
    del own
    n = fixed.size
    return (
        rows[:, free].tocsr(),
        gathered_rows(partition.gatherv, rows[:, dof].tocsr(), dof.size),
        gathered_rows(partition.gatherv, fixed_rows.tocsr(), n),
    )


def check(
    check: Callable, partition: Any, parts: tuple, f_full: np.ndarray, values: np.ndarray
) -> None:
    """The plug-in's data check `check(matrix, f_full, values)` of the model whose A_full is
    in `parts` (`reduced`'s: every entry of A_full is in one of them, A's only on the process
    owning its row), every process refusing alike: the parts' finiteness is reduced over the
    processes (`partition.all_true`) and a non-finite entry anywhere is checked as one
    non-finite matrix entry on every process (the check's stiffness refusal); f_full and
    values, whole on every process, are checked there."""
    finite = partition.all_true(all(np.isfinite(p.data).all() for p in parts))
    check(parts[0] if finite else sp.csr_matrix(np.array([[np.nan]])), f_full, values)
