"""Run under mpiexec by the tests: MixedVIs that hold A by rows on the engine's row partition
(`vi_core.petsc.runtime.RowPartition`, real MPI) against the whole VI, on every rank: s_u,
s_lam, A u and the owned rows of A' bit for bit, the residual to 1e-13, and a bad A (a NaN in a
random row, a nonpositive diagonal entry) refused with the serial message. Rank 0 writes
{seed: [each rank's verdict]} as JSON.

    mpiexec -n P python -m tests.vi_core.petsc.mpi_rows OUT.json SEED... [--mutation drop_remote]

drop_remote: every rank's gatherv keeps its own part only (the others' zero).
"""

from __future__ import annotations

import json
import sys

import numpy as np
import scipy.sparse as sp

from vi_core import MixedVI
from vi_core.petsc.runtime import RowPartition, petsc
from vi_core.testing import random_vi


def verdict(seed: int, rows: RowPartition) -> str:
    """ "ok", or what differs from the whole VI on this rank."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(12, 40))
    vi = random_vi(seed, n=n, m=int(rng.integers(5, n // 2 + 1)), spread=2.0)
    u, lam = rng.standard_normal(n), rng.standard_normal(vi.m)
    lo, hi = rows.owned(n)
    A = sp.csr_matrix(vi.A)

    def by_rows(M: sp.csr_matrix) -> MixedVI:
        return MixedVI(M[lo:hi], vi.B, vi.f, vi.Lambda, vi.gap, partition=rows)

    mine = by_rows(A)
    checks = {
        "s_u": np.array_equal(mine.scaling.s_u, vi.scaling.s_u),
        "s_lam": np.array_equal(mine.scaling.s_lam, vi.scaling.s_lam),
        "matvec": np.array_equal(mine.matvec(u), A @ u),
        "rows": (mine.equilibrated_rows(np.arange(lo, hi)) != vi.equilibrated.A[lo:hi]).nnz == 0,
        "residual": abs(mine.residual(u, lam).relative - vi.residual(u, lam).relative)
        <= 1e-13 * vi.residual(u, lam).relative,
    }
    bad_nan = A.copy()
    bad_nan[int(rng.integers(n)), int(rng.integers(n))] = np.nan
    bad_diag = A.tolil()
    for i in rng.choice(n, size=2, replace=False):
        bad_diag[i, i] = -float(rng.random())
    for name, bad in (("nan", bad_nan), ("diagonal", sp.csr_matrix(bad_diag))):
        try:
            MixedVI(bad, vi.B, vi.f, vi.Lambda, vi.gap)
        except ValueError as err:
            want = str(err)
        try:
            by_rows(bad)
            got = "accepted"
        except ValueError as err:
            got = str(err)
        checks[name] = got == want
    wrong = [k for k, ok in checks.items() if not ok]
    return "ok" if not wrong else ", ".join(wrong)


def main(argv: list[str]) -> int:
    mutation = argv[argv.index("--mutation") + 1] if "--mutation" in argv else ""
    argv = argv[: argv.index("--mutation")] if mutation else argv
    out, *seeds = argv
    rows = RowPartition(petsc())
    if mutation == "drop_remote":
        whole = rows.gatherv

        def gatherv(local: np.ndarray) -> np.ndarray:
            sizes = rows.comm.allgather(np.asarray(local).size)
            got = whole(local)
            start = sum(sizes[: rows.comm.Get_rank()])
            kept = np.zeros_like(got)
            kept[start : start + sizes[rows.comm.Get_rank()]] = np.asarray(local)
            return kept

        rows.gatherv = gatherv
    elif mutation:
        raise ValueError(f"unknown mutation {mutation!r}")
    found = {seed: rows.comm.allgather(verdict(int(seed), rows)) for seed in seeds}
    if rows.comm.Get_rank() == 0:
        with open(out, "w") as fh:
            json.dump(found, fh)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
