"""Benchmark: PARDISO symbolic reuse across the Newton steps of semismooth Newton.

    python benchmarks/bench_reuse.py [SCENE] [--level L]

Records the Newton matrices of a cold ssn solve (fixed sparsity pattern, explicit zeros kept),
then factorises the same sequence twice in one run: with a fresh PARDISO analysis per matrix
(phase 12, what a new solver object per factorisation does) and with `vi_core.linalg.
Refactorizer` (one analysis, then phase 22 numerical factorisations). Prints both times and
their ratio, and checks that both give the same solutions; then times one SuperLU and one
PARDISO factorisation of the last matrix. Needs the optional pypardiso.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import vi_core.ssn as ssn
from problems.plugins import registry
from problems.scene import load_scene
from vi_core import linalg, solve


class _Recording(linalg.Refactorizer):
    matrices: list = []

    def __call__(self, A):
        _Recording.matrices.append(A.copy())
        return super().__call__(A)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; exit status 2 without pypardiso."""
    p = argparse.ArgumentParser(prog="python benchmarks/bench_reuse.py")
    p.add_argument("scene", nargs="?", default="paper_two_body")
    p.add_argument("--level", type=int, default=4)
    args = p.parse_args(argv)
    if not linalg.pardiso_available():
        print("pypardiso is not installed (pip install -e '.[fast]')")
        return 2
    scene = load_scene(args.scene)
    model = registry.for_scene(scene).build(scene, args.level)
    orig, ssn.Refactorizer = ssn.Refactorizer, _Recording
    try:
        sol = solve(model.vi, "ssn", linear_solver="pardiso")
    finally:
        ssn.Refactorizer = orig
    mats = _Recording.matrices
    n, nnz = mats[0].shape[0], sorted({m.nnz for m in mats})
    print(f"{args.scene} level {args.level}: {len(mats)} Newton matrices, n = {n}, nnz = {nnz}")
    print(f"ssn: {sol.iterations} steps, residual {sol.residual:.1e}")
    rhs = np.ones(n)
    t0 = time.perf_counter()
    fresh = []
    for K in mats:
        F = linalg.Factorization(K, "pardiso")
        fresh.append(F._solve(rhs))
        F.free()
    t_fresh = time.perf_counter() - t0
    t0 = time.perf_counter()
    reuse, R = [], linalg.Refactorizer("pardiso")
    for K in mats:
        reuse.append(R(K)._solve(rhs))
    t_reuse = time.perf_counter() - t0
    R.free()
    t0 = time.perf_counter()
    x_lu = linalg.Factorization(mats[-1], "splu")._solve(rhs)
    t_lu = time.perf_counter() - t0
    t0 = time.perf_counter()
    F = linalg.Factorization(mats[-1], "pardiso")
    x_pd = F._solve(rhs)
    t_pd = time.perf_counter() - t0
    F.free()
    print(
        f"one factorisation + solve of the last matrix: SuperLU ({linalg.ORDERING}) {t_lu:.2f} s, "
        f"PARDISO {t_pd:.2f} s (ratio {t_lu / t_pd:.1f}; difference "
        f"{np.linalg.norm(x_lu - x_pd) / np.linalg.norm(x_pd):.1e})"
    )
    diff = max(np.linalg.norm(a - b) / np.linalg.norm(a) for a, b in zip(fresh, reuse, strict=True))
    print(f"fresh analysis per matrix: {t_fresh:.2f} s ({len(mats)} analyses)")
    print(f"symbolic reuse:            {t_reuse:.2f} s ({R.analyses} analysis)")
    print(
        f"ratio fresh / reuse:       {t_fresh / t_reuse:.2f}; largest relative difference "
        f"{diff:.1e}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
