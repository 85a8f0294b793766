"""Run under mpiexec by the tests: the `mixvi` command with a fault of `mpi_scene._mutate`
injected first, and stand-ins for what the machine would tell.

    mpiexec -n P python -m tests.vi_core.petsc.mpi_cli [--mutation MUTATION]
        [--available BYTES] [--host-per-rank] ARGS...

--available BYTES: the host's memory available now (`resources.host_memory`) reads BYTES;
--host-per-rank: each rank is on a host of its own (`engine.host_ranks`), as if the run spanned
P machines.
"""

from __future__ import annotations

import sys

from problems.commands import engine, resources
from problems.commands.entry import run

from .mpi_scene import _mutate


def main(argv: list[str]) -> int:
    while argv[:1] in (["--mutation"], ["--available"], ["--host-per-rank"]):
        option = argv.pop(0)
        if option == "--mutation":
            _mutate(argv.pop(0))
        elif option == "--available":
            reading = (resources.host_memory()[0], float(argv.pop(0)))  # (total, available)
            resources.host_memory = lambda reading=reading: reading
        else:
            engine.host_ranks = lambda comm: comm.Split(comm.Get_rank())
    sys.argv = ["mixvi", *argv]
    return run()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
