"""Running the petsc engine's tests under mpiexec (oversubscribed: more ranks than cores)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
# as root, Open MPI refuses to start without these; --oversubscribe: 4 ranks on 2 cores
MPI_ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMP_NUM_THREADS": "1",
    # ranks waiting in a collective yield the core (Open MPI busy-polls unless it sees more
    # ranks than slots; the machine is shared): 2 ranks took 26 s CPU, yielding 18 s
    "OMPI_MCA_mpi_yield_when_idle": "1",
}


def need_petsc() -> None:
    """Skip unless petsc4py, mpi4py and mpiexec are there (.ci/install_petsc)."""
    pytest.importorskip("petsc4py", reason="the petsc engine needs petsc4py (.ci/install_petsc)")
    pytest.importorskip("mpi4py", reason="the petsc engine needs mpi4py (.ci/install_petsc)")
    if shutil.which("mpiexec") is None:
        pytest.skip("mpiexec not found (.ci/install_petsc installs openmpi-bin)")


def mpiexec(
    ranks: int, args: list[str], timeout: float = 300, **kw
) -> subprocess.Popen | subprocess.CompletedProcess:
    """`mpiexec -n ranks --oversubscribe args` run to its end (or started: popen=True)."""
    cmd = ["mpiexec", "-n", str(ranks), "--oversubscribe", *args]
    env = {**os.environ, **MPI_ENV, **kw.pop("env", {})}
    if kw.pop("popen", False):
        return subprocess.Popen(
            cmd,
            cwd=kw.pop("cwd", ROOT),
            env=env,
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            **kw,
        )
    return subprocess.run(
        cmd, cwd=kw.pop("cwd", ROOT), env=env, text=True, capture_output=True, timeout=timeout, **kw
    )


def mixvi() -> str:
    """The venv's mixvi console script."""
    return str(Path(sys.executable).parent / "mixvi")
