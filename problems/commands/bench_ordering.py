"""Benchmark: fill-in and time of SuperLU factorisations of a Newton matrix under three orderings.

    python -m problems.commands.bench_ordering [SCENE] [--level L] [--out FILE]

Records the last Newton matrix K of a cold ssn solve (SuperLU) and factorises it with SuperLU's
column orderings COLAMD and MMD on Aᵀ + A (`vi_core.linalg.ORDERING`), and with the nested
dissection of `vi_core.ordering` applied symmetrically before a NATURAL-order factorisation.
Prints, per ordering, the fill nnz(L + U) / nnz(K), the ordering and factorisation times and
the relative residual of one solve; writes the table as JSON to FILE (default
bench_ordering.json).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import vi_core.ssn as ssn
from problems.output.files import Output, claim
from problems.plugins import registry
from problems.scene import load_scene
from vi_core import linalg, solve
from vi_core.ordering import nested_dissection


class _Recording(linalg.Refactorizer):
    last = None

    def __call__(self, A):
        _Recording.last = A.copy()
        return super().__call__(A)


def _row(name: str, K: sp.csc_matrix, p: np.ndarray | None, spec: str, t_order: float) -> dict:
    Kp = K if p is None else sp.csc_matrix(K[p][:, p])
    t = time.perf_counter()
    lu = spla.splu(Kp, permc_spec=spec)
    t_lu = time.perf_counter() - t
    b = np.ones(K.shape[0])
    x = lu.solve(b)
    res = float(np.linalg.norm(Kp @ x - b) / np.linalg.norm(b))
    return {
        "ordering": name,
        "fill": (lu.L.nnz + lu.U.nnz) / K.nnz,
        "time_ordering_s": t_order,
        "time_factorisation_s": t_lu,
        "residual": res,
    }


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (prints a table, writes JSON)."""
    p = argparse.ArgumentParser(prog="python -m problems.commands.bench_ordering")
    p.add_argument("scene", nargs="?", default="paper_two_body")
    p.add_argument("--level", type=int, default=4)
    p.add_argument("--out", default="bench_ordering.json")
    args = p.parse_args(argv)
    scene = load_scene(args.scene)
    model = registry.for_scene(scene).build(scene, args.level)
    orig, ssn.Refactorizer = ssn.Refactorizer, _Recording
    try:
        solve(model.vi, "ssn", linear_solver="splu")
    finally:
        ssn.Refactorizer = orig
    K = sp.csc_matrix(_Recording.last)
    print(f"{args.scene} level {args.level}: Newton matrix n = {K.shape[0]}, nnz = {K.nnz}")
    rows = [
        _row("COLAMD", K, None, "COLAMD", 0.0),
        _row("MMD_AT_PLUS_A", K, None, "MMD_AT_PLUS_A", 0.0),
    ]
    t = time.perf_counter()
    perm = nested_dissection(K)
    rows.append(_row("nested dissection", K, perm, "NATURAL", time.perf_counter() - t))
    print(f"{'ordering':<20}{'fill':>8}{'order [s]':>11}{'factor [s]':>12}{'residual':>10}")
    for r in rows:
        print(
            f"{r['ordering']:<20}{r['fill']:>8.2f}{r['time_ordering_s']:>11.2f}"
            f"{r['time_factorisation_s']:>12.2f}{r['residual']:>10.1e}"
        )
    head = {"scene": args.scene, "level": args.level, "n": K.shape[0], "nnz": K.nnz}
    with claim([Output(args.out, "--out", "json")], scene.files()) as run:
        run.file("--out").write({**head, "orderings": rows})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
