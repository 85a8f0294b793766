"""`mpiexec -n 2 mixvi solve SCENE --engine petsc` where the post-processing, which rank 0 runs
alone after the solve, reads A: with A held by rows (`MixedVI.partition`) A u is a collective,
so the engine gathers A u at its answer on every rank at the end of the solve and
`MixedVI.matvec` returns it there again without communication (hertz: the unilateral law's
force scale in `contact_state`; electrical_block: the electrical report's flux, gathered at
the end of the coupling's fixed point). Without it rank 0 waits forever (the mutation)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from .helpers import mpiexec, need_petsc

pytestmark = pytest.mark.mpi

CLI = "tests.vi_core.petsc.mpi_cli"
SCENES = ["hertz", "electrical_block"]


def solve(tmp_path, scene: str, mutation: str = "", timeout: float = 180):
    """The 2-rank `mixvi solve scene --level 0 --engine petsc` (mpi_cli, `mutation` injected)."""
    args = [sys.executable, "-m", CLI, *(["--mutation", mutation] if mutation else [])]
    args += ["solve", scene, "--level", "0", "--engine", "petsc", "--out", str(tmp_path / scene)]
    return mpiexec(2, args, timeout=timeout)


@pytest.mark.parametrize("scene", SCENES)
def test_rank_0_post_processes_alone(tmp_path, scene):
    need_petsc()
    done = solve(tmp_path, scene)
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads((tmp_path / scene / "summary.json").read_text())
    assert summary["solver_info"]["ranks"] == 2


@pytest.mark.slow
def test_without_the_kept_product_rank_0_waits(tmp_path):
    need_petsc()
    # rank 0 waits on the others, which have ended: the hang the test guards (an end of any
    # kind, a crash of the injection included, fails)
    with pytest.raises(subprocess.TimeoutExpired):
        solve(tmp_path, "hertz", "no_kept_product", timeout=90)
