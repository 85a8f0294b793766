"""A MixedVI holding A by rows on real MPI (`MixedVI.partition` with the engine's
`RowPartition`, 3 ranks, one of them possibly owning few rows): on every rank the whole VI's
scaling, A u, rows of A' and residual, and a bad A refused with the serial message
(tests/vi_core/petsc/mpi_rows.py; the same checks on forked processes:
tests/vi_core/test_partition.py). Mutation: every rank's gatherv dropping the others' parts."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from .helpers import mpiexec, need_petsc

pytestmark = pytest.mark.mpi


def verdicts(tmp_path, mutation: str = "") -> dict[str, list[str]]:
    seeds = [str(s) for s in np.random.default_rng().integers(0, 2**32 - 1, size=6)]
    out = tmp_path / "rows.json"
    args = [sys.executable, "-m", "tests.vi_core.petsc.mpi_rows", str(out), *seeds]
    done = mpiexec(3, [*args, *(["--mutation", mutation] if mutation else [])], timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(out.read_text())


def test_by_rows_on_mpi_is_the_whole_vi(tmp_path):
    need_petsc()
    found = verdicts(tmp_path)
    assert all(v == ["ok"] * 3 for v in found.values()), found


@pytest.mark.slow
def test_dropped_remote_parts_are_seen(tmp_path):
    need_petsc()
    found = verdicts(tmp_path, "drop_remote")
    assert all(any(r != "ok" for r in v) for v in found.values()), found
