"""The petsc engine's iterative path (`--linear-solver amg`: GMRES(15) with GAMG and the
rigid-body near-null space, fieldsplit for the piezoelectric scene) on 2 ranks gives the serial
solution to 1e-8 (each field of u, λ) with the same contact states and Newton steps, in the CI
tier (one mpiexec launch, ~12 s here): a 2D Coulomb strip, a 3D piezoelectric Tresca box and
hertz (2D, the signorini plug-in, g = 0), whose node on the symmetry axis has a slip of 0
exactly, read 1e-15 to 2e-14 after a GMRES step (rtol 1e-12): its label must not follow that noise
(`vi_core.states.solution_thresholds` reads the step's accuracy, `LinearSolve.accuracy`; the
noise stands near the residual's floor, 100 · 16 eps · max|u|, so the `no_accuracy` mutation
below is seen here by a margin that depends on the noise: that the engine records the
accuracy is test_accuracy.py's check too, which fails without it). The states must be
equal, "ambiguous" included: no node is excused."""

from __future__ import annotations

import numpy as np
import pytest

from .helpers import need_petsc
from .test_every_scene import launch, mismatches, serial

pytestmark = pytest.mark.mpi

CASES = [("coulomb_strip", 1), ("manufactured3d", 0), ("hertz", 0), ("paper_two_body", 0)]
# PCFIELDSPLIT's blocks where the scene has two fields: (near-null space dimension, block size)
# by field. The displacement's rigid-body modes (2D: 2 translations, 1 rotation; 3D: 3 and 3),
# GAMG's nodes of d components where every rank's rows come in whole nodes (`ksp.node_block`;
# the balanced layout cuts no node, `layout.node_groups`: manufactured3d's 9 displacement nodes
# split 5 / 4; paper_two_body's even layout splits between nodes). None for the potential:
# GAMG's constant.
BLOCKS = {"manufactured3d": [(6, 3), (0, 1)], "paper_two_body": [(3, 2), (0, 1)]}


def wrong_blocks(got: dict[str, dict]) -> dict[str, list]:
    """scene → its fieldsplit blocks, for each scene whose blocks (rows, near-null dimension
    and block size of each field's block as PETSc solved it) are not its fields' (the serial
    solution's field sizes) with BLOCKS's dimensions and block sizes."""
    out = {}
    for scene, level in CASES:
        ref = serial(scene, level)
        want = [
            [ref[f"u:{f}"].size, d, bs]
            for f, (d, bs) in zip(
                ("displacement", "potential"), BLOCKS.get(scene, []), strict=False
            )
        ]
        if got[scene]["blocks"].tolist() != want:
            out[scene] = got[scene]["blocks"].tolist()
    return out


def test_amg_path_on_2_ranks_equals_serial(tmp_path):
    need_petsc()
    got = launch(tmp_path, 2, CASES, linear="amg")
    for scene, _ in CASES:  # the iterative path ran: GMRES at every step, no direct fallback
        assert len(got[scene]["krylov"]) == int(got[scene]["iterations"][-1]) > 0, scene
        assert int(got[scene]["fallbacks"]) == 0, scene
    assert not mismatches(got, 2, CASES)
    assert not wrong_blocks(got)
    assert np.size(got["manufactured3d"]["blocks"])  # fieldsplit ran there


def test_amg_path_on_1_rank_equals_serial(tmp_path):
    """One rank: PETSc's matrices are sequential there, whose products have no "allatonce"
    P^T A P (`LinearSolve` asks for it on several ranks only); paper_two_body, two fields, the
    displacement's GAMG on nodes of 2."""
    need_petsc()
    case = [("paper_two_body", 0)]
    got = launch(tmp_path, 1, case, linear="amg")
    assert int(got["paper_two_body"]["fallbacks"]) == 0
    assert not mismatches(got, 1, case)
    assert got["paper_two_body"]["blocks"][:, 1:].tolist() == [[3, 2], [0, 1]]


# faults of mpi_scene._mutate the comparisons above must see (slow tier: one launch each);
# fieldsplit_swapped, no_node_block and node_cut leave the answers alone (a preconditioner's
# faults): the blocks show them
@pytest.mark.slow
@pytest.mark.parametrize(
    "mutation",
    [
        "slave_sign",
        "local_gather",
        "no_accuracy",
        "rhs_order",
        "fieldsplit_swapped",
        "no_node_block",
        "node_cut",
    ],
)
def test_amg_mutation_is_seen(tmp_path, mutation):
    need_petsc()
    got = launch(tmp_path, 2, CASES, mutation=mutation, linear="amg")
    assert mismatches(got, 2, CASES) or wrong_blocks(got), f"{mutation}: not seen"
