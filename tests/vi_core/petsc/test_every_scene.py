"""Every shipped scene (`mixvi scenes`: the contact plug-in's 2D and 3D scenes, Tresca and
Coulomb, one and two bodies, load paths; the signorini, obstacle and antiplane plug-ins' too)
solved with the petsc engine equals the serial solution to 1e-8 (each field of u, λ, the
contact states) on 1, 2 and 4 ranks (oversubscribed on this machine's 2 cores). One mpiexec
launch per rank count solves every scene (the imports paid once per rank)."""

from __future__ import annotations

import sys
from functools import cache

import numpy as np
import pytest

from problems.scene import SCENES_DIR

from .helpers import mpiexec, need_petsc
from .mpi_scene import solved
from .test_scenes import MPI_SCENE, differences, equal

pytestmark = pytest.mark.mpi  # these run where .ci/install_petsc has installed the engine

SCENES = sorted(p.stem for p in SCENES_DIR.glob("*.toml"))
# the coarsest level; level 1 where it is cheap, so the CI tier also runs the nested iteration
# (level 0 solved first, warm-starting level 1) on the engine
LEVEL_1 = {"manufactured", "coulomb_strip", "paper_two_body"}
CASES = [(s, 1 if s in LEVEL_1 else 0) for s in SCENES]


@cache
def serial(scene: str, level: int) -> dict:
    return solved(scene, level, "auto")


def launch(
    tmp_path, ranks: int, cases=CASES, mutation: str = "", linear: str = "auto"
) -> dict[str, dict]:
    """Every case of `cases` solved on `ranks` ranks in one mpiexec launch: scene → record."""
    args = [sys.executable, "-m", MPI_SCENE, "--many", str(tmp_path), linear]
    args += [f"{s}:{lev}" for s, lev in cases]
    done = mpiexec(ranks, [*args, *(["--mutation", mutation] if mutation else [])], timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return {s: dict(np.load(tmp_path / f"{s}.npz")) for s, _ in cases}


def mismatches(got: dict[str, dict], ranks: int, cases=CASES) -> dict[str, dict]:
    """scene → its differences from the serial solution, for each scene that differs by more
    than 1e-8, did not converge, took other Newton steps than the serial loop (the engine
    takes the same iterates) or did not run on the engine's `ranks` ranks."""
    out = {}
    for scene, level in cases:
        g, ref = got[scene], serial(scene, level)
        ran = int(g["ranks"]) == ranks and str(g["engine"]) == "petsc"
        if int(g["steps"]) != int(ref["steps"]):  # a load path stopped at a step
            out[scene] = {"steps": (int(g["steps"]), int(ref["steps"])), "ran": ran}
            continue
        d = differences(ref, g)
        newton = g["iterations"].tolist(), ref["iterations"].tolist()
        if not (ran and bool(g["converged"]) and equal(d) and newton[0] == newton[1]):
            out[scene] = {**d, "ran": ran, "converged": bool(g["converged"]), "newton": newton}
    return out


def test_the_scenes_are_all_there():
    """The list is the shipped scenes, 2D and 3D, Tresca and Coulomb, with a load path."""
    for scene in ("manufactured", "manufactured3d", "coulomb_strip", "coulomb_strip3d"):
        assert scene in SCENES
    assert "shear_strip_path" in SCENES and len(SCENES) >= 30


@pytest.mark.parametrize("ranks", [1, 2, 4])
def test_every_scene_equals_serial(tmp_path, ranks):
    need_petsc()
    got = launch(tmp_path, ranks)
    assert not mismatches(got, ranks)
    if ranks > 1:  # both layouts of the linear solve ran (`vi_core.petsc.layout.chosen`)
        assert {str(g["layout"]) for g in got.values()} == {"even", "fields"}


@pytest.mark.slow
def test_every_scene_on_gamg_equals_serial(tmp_path):
    """The iterative path (GMRES + GAMG, `--linear-solver amg`) on 2 ranks gives the serial
    solution too: its KSP is made again at every Newton step (`ksp.LinearSolve.solve` frees
    it after each solve), the near-null spaces made once. The same states, "ambiguous"
    included: the thresholds read the last GMRES step's accuracy (rtol 1e-12,
    `vi_core.states.solution_thresholds`), not only the residual it reaches."""
    need_petsc()
    got = launch(tmp_path, 2, linear="amg")
    assert not mismatches(got, 2)


# the faults of mpi_scene._mutate; each must make the comparison above fail on 2 ranks
@pytest.mark.slow
@pytest.mark.parametrize("mutation", ["local_gather", "slave_sign"])
def test_mutation_is_seen(tmp_path, mutation):
    need_petsc()
    got = launch(tmp_path, 2, mutation=mutation)
    bad = mismatches(got, 2)
    assert bad, f"{mutation}: every scene still equals the serial solution"
