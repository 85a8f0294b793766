"""`mixvi solve --engine petsc`: the Newton loop on PETSc over the ranks of an `mpiexec` run
(`vi_core.petsc`), output written once, by rank 0.

Under `mpiexec -n P mixvi solve SCENE --engine petsc` every rank reads and validates the scene and
builds the model; the ranks agree on the checks of the input (`Engine.unanimous`: refused on one
rank, e.g. by a memory limit of its own, it is refused on every rank, exit status 2, before the
solve's first collective call: no rank waits on another), then on the memory of each host: the
ranks that share one are refused together when the sum of their upper estimates exceeds what it
has available now (`Engine.on_host`, `resources.check_host`); rank 0 alone opens the output
folder and tells the others whether it could (`Engine.agree`): a refused folder ends every rank
with status 2.
Then every rank runs the same solve (nested iteration included: each level's Newton loop is
`vi_core.petsc.solve_ssn_petsc`); rank 0 writes the results as the serial command does (same files,
same summary.json fields, plus solver_info["engine"] and ["ranks"]), the other ranks write nothing
and exit with the same status. An exception on one rank mid-solve ends that rank with the serial
line and exit status once its clean-up has run, and mpiexec ends the others; a rank killed by a
signal ends the run through mpiexec, and so does a rank interrupted by SIGTERM or SIGINT: it ends
at once with 143 or 130, without the exit handlers, which are collective
(`signals.one_rank_of_several`, `signals.command_done`, `signals.ends_alone`). Rank 0 opens its
staging folder only once the solve is done (`solve._solve`): inside a PETSc call (petsc4py holds
the GIL) it cannot run its SIGTERM handling before mpiexec's SIGKILL, so a run ended mid-solve
leaves the claimed folder as it was but for its lock file (a load path's steps, written as they
end, are the exception: a killed run's lock and staging folder are cleared by the next run there,
with a note).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

from problems.errors import SceneError
from problems.output import signals

ENGINES = ("serial", "petsc")
T = TypeVar("T")


@dataclass
class Engine:
    """The engine a `mixvi solve` runs on: its rank and size (0 and 1 for serial)."""

    name: str
    rank: int = 0
    size: int = 1
    comm: Any = None  # mpi4py communicator (petsc only)

    @property
    def writes(self) -> bool:
        """Whether this process writes the output (rank 0)."""
        return self.rank == 0

    def agree(self, ok: bool | None) -> bool:
        """Rank 0's verdict on the output folder (`ok`), told to every rank."""
        if self.comm is None:
            return bool(ok)
        return bool(self.comm.bcast(ok, root=0))

    def unanimous(self, check: Callable[..., T], *args: Any, **kw: Any) -> T:
        """`check(*args, **kw)` (the checks of the input, before any other collective call) on
        every rank, its verdict agreed: if it raised on one rank, it raises on every rank — on
        that rank its own exception, on the others the first failing rank's SceneError (the
        same line: bad input), or a RuntimeError naming that rank (exit 3) — and no rank goes on
        into the solve to wait there for one that has stopped. A refusal may depend on the
        rank: the memory available when each one looks, a limit (ulimit -v) set on one.
        Interruptions pass on (`signals.one_rank_of_several`)."""
        if self.comm is None or self.size == 1:
            return check(*args, **kw)
        mine: Exception | None = None
        try:
            value = check(*args, **kw)
        except Exception as err:
            mine = err
        verdicts = self.comm.allgather(_verdict(mine))
        if mine is not None:
            raise mine
        failed = [(rank, v) for rank, v in enumerate(verdicts) if v is not None]
        if not failed:
            return value
        refused = [fields for _, (kind, fields) in failed if kind == "scene"]
        if refused:
            raise SceneError(*refused[0])
        rank, (_, line) = failed[0]
        raise RuntimeError(f"rank {rank} of {self.size} failed: {line}")

    def on_host(self, value: T) -> list[T]:
        """`value` of every rank on this rank's host (the ranks that share its memory, MPI's
        COMM_TYPE_SHARED: `host_ranks`), this rank's among them; [value] on one rank.
        Collective: every rank calls it."""
        if self.comm is None or self.size == 1:
            return [value]
        host = host_ranks(self.comm)
        try:
            return host.allgather(value)
        finally:
            host.Free()

    def guarded(self, solve: Callable[..., Any], *args: Any, **kw: Any) -> Any:
        """`solve(*args, **kw)`; an exception on this rank ends this rank alone once its
        clean-up has run, with the serial command's line and exit status (a SceneError 2,
        memory 1, an internal error 3) and without the exit handlers, which are collective
        (`signals.ends_alone`): mpiexec then ends the others, so no rank waits forever on one
        that has stopped. The error may be this rank's alone (rank 0's output refused mid-way,
        a failure on one rank) or every rank's. Interruptions pass on."""
        if self.comm is None or self.size == 1:
            return solve(*args, **kw)
        try:
            return solve(*args, **kw)
        except Exception as err:
            if not isinstance(err, SceneError):  # bad input: its own line says why
                print(
                    f"mixvi: rank {self.rank} of {self.size} failed ({type(err).__name__}); "
                    "mpiexec ends the other ranks",
                    file=sys.stderr,
                    flush=True,
                )
            signals.ends_alone()
            raise


def _verdict(err: Exception | None) -> tuple[str, Any] | None:
    """What one rank tells the others of its checks (`Engine.unanimous`): None (passed), a
    SceneError's fields, or another exception's line."""
    if err is None:
        return None
    if isinstance(err, SceneError):
        return "scene", (
            err.key,
            str(err.value) if _odd(err.value) else err.value,
            err.allowed,
            err.file,
        )
    return "other", f"{type(err).__name__}: {err}"


def _odd(value: Any) -> bool:
    """Whether `value` is anything but a plain str, number, bool or None (sent as its text)."""
    return not isinstance(value, str | int | float | bool | type(None))


def host_ranks(comm: Any) -> Any:
    """The ranks of `comm` on the calling rank's host, as a new communicator (the caller frees
    it): those that can share memory (`MPI.COMM_TYPE_SHARED`), one host's ranks whatever their
    order in `comm`."""
    from mpi4py import MPI

    return comm.Split_type(MPI.COMM_TYPE_SHARED)


def launched_processes() -> int:
    """How many processes the MPI launcher started with this one (Open MPI's
    OMPI_COMM_WORLD_SIZE, MPICH's and Slurm's PMI_SIZE; 1 when not under a launcher)."""
    for var in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE"):
        try:
            return max(int(os.environ[var]), 1)
        except (KeyError, ValueError):
            continue
    return 1


def start(name: str) -> Engine:
    """The engine `name` (ENGINES), its rank and size; SceneError on --engine if unknown, if
    petsc4py/mpi4py are missing, or if serial under an MPI launcher of several processes (on
    every rank alike)."""
    if name not in ENGINES:
        raise SceneError("--engine", name, "one of " + ", ".join(ENGINES))
    if name == "serial":
        launched = launched_processes()
        if launched > 1:
            raise SceneError(
                "--engine",
                name,
                f"petsc under mpiexec with {launched} processes: the serial engine would solve "
                "the whole problem once per process, each into the same folder (add --engine "
                "petsc, or run without mpiexec)",
            )
        return Engine(name)
    from vi_core import petsc as vi_petsc

    if not vi_petsc.available():
        raise SceneError(
            "--engine",
            name,
            "needs petsc4py and mpi4py (pip install -e '.[petsc]' against Debian's PETSc: "
            ".ci/install_petsc)",
        )
    rank, size = vi_petsc.comm_rank_size()
    if size > 1:  # an interruption then ends this rank without the collective exit handlers
        signals.one_rank_of_several()
    from mpi4py import MPI

    return Engine(name, rank, size, MPI.COMM_WORLD)


@contextmanager
def running(eng: Engine) -> Iterator[None]:
    """Within the block, method="ssn" runs on the engine's Newton loop, and a model built there
    assembles its rows by the engine's partition (`vi_core.engine.row_partition`)."""
    if eng.name == "serial":
        yield
        return
    from vi_core import engine as vi_engine
    from vi_core.petsc import solve_ssn_petsc
    from vi_core.petsc.runtime import RowPartition, petsc

    with vi_engine.using(solve_ssn_petsc, rows=RowPartition(petsc())):
        yield
