"""vi_core.petsc: the semismooth Newton loop of `vi_core.ssn` on PETSc, one problem on many MPI
processes (docs/distributed.md).

    from vi_core.petsc import available, solve_ssn_petsc
    with vi_core.engine.using(solve_ssn_petsc): vi_core.solve(vi, "ssn")

Layer: imports vi_core only (neither fem nor problems); petsc4py and mpi4py are optional (the
``petsc`` extra and ``.ci/install_petsc``): importing this package does not import them,
`available` tells whether they are there.
"""

from __future__ import annotations

from .newton import solve_ssn_petsc
from .runtime import available, comm_rank_size

__all__ = ["available", "comm_rank_size", "solve_ssn_petsc"]
