"""Which Newton loop ``method="ssn"`` runs: the serial one (`vi_core.ssn.solve_ssn`), or one that
an engine package installs for a block of code (`using`), e.g. the distributed loop of
`vi_core.petsc` under ``mixvi solve --engine petsc``.

Why a process-wide setting and not an argument: the Newton loop is reached through the plug-ins'
outer iterations (nested iteration, load paths, Coulomb fixed points), which pass their options
on unchanged; vi_core does not import an engine package (the layout), the engine registers
itself here. A plain module global, not a ContextVar: `mixvi solve` runs the solve in a worker
thread, which a ContextVar would not reach.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import scipy.sparse as sp

_ssn: Callable | None = None  # the installed Newton loop; None: vi_core.ssn.solve_ssn
_rows: Any = None  # the installed engine's row partition; None: serial (every row here)


@contextmanager
def using(ssn: Callable, rows: Any = None) -> Iterator[None]:
    """Within the block, ``solve(vi, "ssn", ...)`` calls ``ssn(vi, tol=..., **options)`` (the
    signature of `vi_core.ssn.solve_ssn`) instead of the serial loop; `rows` (`row_partition`)
    tells the model builders which rows this process assembles."""
    global _ssn, _rows
    before, _ssn = (_ssn, _rows), ssn
    _rows = rows
    try:
        yield
    finally:
        _ssn, _rows = before


def row_partition() -> Any:
    """The installed engine's row partition, None for the serial loop: an object with
    ``owned(n) -> (lo, hi)``, the rows [lo, hi) of n unknowns this process owns (the engine's
    layout), and the reductions (collectives: every process calls them in the same order)
    ``gatherv(local) -> whole``, the processes' 1-D arrays concatenated in rank order on every
    process (sparse row blocks through it: `gathered_rows`), ``all_true(flag) -> bool``,
    whether the flag holds on every process, and ``norm(local) -> float``, the 2-norm of the
    vector whose parts the processes hold (`vi_core.petsc.runtime.RowPartition`). A MixedVI
    built under it may hold A by rows (`MixedVI.partition`)."""
    return _rows


def gathered_rows(
    gatherv: Callable[[np.ndarray], np.ndarray], block: sp.csr_matrix, ncol: int
) -> sp.csr_matrix:
    """The processes' row blocks `block` (k_p, ncol) stacked in rank order, on every process,
    through a row partition's `gatherv` (`row_partition`): the entries per row, the values and
    the column indices, each received straight into the whole array (no per-process copies)."""
    counts = gatherv(np.diff(block.indptr))  # (rows,) entries per row
    indptr = np.zeros(counts.size + 1, block.indptr.dtype)  # (rows + 1,)
    np.cumsum(counts, out=indptr[1:])
    data, indices = gatherv(block.data), gatherv(block.indices)  # (nnz,) each
    return sp.csr_matrix((data, indices, indptr), shape=(counts.size, ncol))


def ssn_loop() -> Callable:
    """The Newton loop ``method="ssn"`` runs now."""
    if _ssn is not None:
        return _ssn
    from .ssn import solve_ssn

    return solve_ssn
