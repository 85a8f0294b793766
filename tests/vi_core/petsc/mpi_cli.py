"""Run under mpiexec by the tests: the `mixvi` command with a fault of `mpi_scene._mutate`
injected first.

    mpiexec -n P python -m tests.vi_core.petsc.mpi_cli [--mutation MUTATION] ARGS...
"""

from __future__ import annotations

import sys

from problems.commands.entry import run

from .mpi_scene import _mutate


def main(argv: list[str]) -> int:
    if argv[:1] == ["--mutation"]:
        _mutate(argv[1])
        argv = argv[2:]
    sys.argv = ["mixvi", *argv]
    return run()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
