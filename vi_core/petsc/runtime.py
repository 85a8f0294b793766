"""petsc4py and mpi4py, imported on demand: whether they are there, the communicator's rank and
size, and the global reductions the Newton loop needs (sums over the ranks' owned parts)."""

from __future__ import annotations

from typing import Any

import numpy as np


def available() -> bool:
    """Whether petsc4py and mpi4py import (the ``petsc`` extra, ``.ci/install_petsc``)."""
    try:
        import mpi4py  # noqa: F401
        import petsc4py  # noqa: F401
    except ImportError:
        return False
    return True


def petsc() -> Any:
    """The initialised petsc4py.PETSc module (ImportError naming the install path if absent)."""
    try:
        import petsc4py
        from mpi4py import MPI  # noqa: F401  MPI_Init_thread(MULTIPLE) before petsc4py.init:
        # the solve runs in mixvi solve's worker thread (PETSc's own MPI_Init asks for less)
    except ImportError as err:
        raise ImportError(
            "the petsc engine needs petsc4py and mpi4py: pip install -e '.[petsc]' against "
            "Debian's PETSc (.ci/install_petsc does both)"
        ) from err
    petsc4py.init()
    from petsc4py import PETSc

    _restore_malloc()
    return PETSc


# glibc's mallopt parameters and their defaults (malloc.h; mallopt(3))
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_MMAP_MAX = -1, -3, -4
MALLOPT_DEFAULTS = (
    (M_MMAP_MAX, 65536),
    (M_MMAP_THRESHOLD, 128 * 1024),
    (M_TRIM_THRESHOLD, 128 * 1024),
)


def _restore_malloc() -> bool:
    """glibc's malloc defaults again after PETSc's libraries are loaded; whether it could.

    Debian's SuperLU_dist 8.1.2, which libpetsc loads, calls mallopt(M_MMAP_MAX, 0) when it is
    loaded: no allocation is then served by mmap, so a freed NumPy array stays in the heap and
    the process never gives it back (a 50 MB array: RSS 449 MB after `del` against 68 MB
    before). Each rank then kept every transient peak of the model build and of the set-up
    resident (paper_two_body level 4, 1 rank: 300 MB above the imports against the serial
    path's 146 MB). Open MPI's shared-memory and TCP transports need no pinned heap."""
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return False
    return all(libc.mallopt(param, value) == 1 for param, value in MALLOPT_DEFAULTS)


def peak_mb() -> float:
    """This process's peak resident memory so far (ru_maxrss) in MiB."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def comm_rank_size() -> tuple[int, int]:
    """(rank, size) of PETSc's world communicator."""
    comm = petsc().COMM_WORLD
    return comm.getRank(), comm.getSize()


class Reductions:
    """Global sums over the ranks of values each rank computes on what it owns (the reduction
    protocol of docs/distributed.md): sum of squares → a 2-norm, concatenation of owned parts
    → the replicated vector."""

    def __init__(self, comm: Any):
        self.comm = comm.tompi4py()  # mpi4py communicator of the PETSc one

    def norm(self, local: np.ndarray) -> float:
        """‖x‖₂ of the vector whose owned parts the ranks hold (`local`, (k,))."""
        return float(np.sqrt(self.comm.allreduce(float(local @ local))))

    def gather(self, index: np.ndarray, local: np.ndarray, size: int) -> np.ndarray:
        """The replicated (size,) vector whose entries `index` (k,) this rank owns (`local`)."""
        out = np.zeros(size)
        for idx, val in self.comm.allgather((index, local)):
            out[idx] = val
        return out

    def gatherv(self, local: np.ndarray) -> np.ndarray:
        """The ranks' `local` arrays (1-D, one dtype on every rank) concatenated in rank order
        on every rank, received into one array (MPI_Allgatherv: no per-rank copies)."""
        local = np.ascontiguousarray(local)
        counts = self.comm.allgather(local.size)
        out = np.empty(sum(counts), local.dtype)
        self.comm.Allgatherv(local, [out, counts])  # the type from the buffers' format
        return out

    def all_true(self, flag: bool) -> bool:
        """Whether `flag` holds on every rank."""
        return bool(self.comm.allreduce(int(bool(flag)), op=_min()) == 1)


class RowPartition(Reductions):
    """The row partition the engine installs for the model builders (`vi_core.engine.using`,
    `row_partition`) and the Newton loop uses: PETSc's default layout of n rows over
    COMM_WORLD, and the reductions."""

    def __init__(self, PETSc: Any):
        super().__init__(PETSc.COMM_WORLD)
        self._petsc = PETSc
        self._ranges: dict[int, tuple[int, int]] = {}  # n → [lo, hi), computed once per n

    def owned(self, n: int) -> tuple[int, int]:
        """[lo, hi): the rows of n this rank owns (PETSc's default layout, `PetscSplitOwnership`,
        the one a Vec or Mat of global size n gets with PETSC_DECIDE), computed at the first
        call for n (collective then: every rank asks for the same n in the same order) and
        kept: no PETSc object is made."""
        if n not in self._ranges:
            k, _ = self._petsc.Sys.splitOwnership(n, comm=self._petsc.COMM_WORLD)
            lo = self.comm.exscan(k) or 0  # rank 0 receives None
            self._ranges[n] = (lo, lo + k)
        return self._ranges[n]


def _min() -> Any:
    from mpi4py import MPI

    return MPI.MIN
