"""Benchmark: SuperLU orderings and pivoting on Newton matrices, and the linear solver `auto` picks.

    python benchmarks/bench_ordering.py [CASE ...] [--timeout S] [--no-solve]
        [--out FILE]

CASE is SCENE or SCENE@LEVEL (a shipped scene's name or a scene file; default: the scene's own
level). Per case:

* the first Newton matrix K of the fine level of a nested solve is recorded (before it is
  factorised) and factorised, each in a child process killed after S seconds (default 120),
  with every variant of VARIANTS: SuperLU's column orderings with and without SymmetricMode and
  pivot thresholds 1.0 / 0.1, and METIS nested dissection (`pymetis`, where it imports) applied
  symmetrically before a NATURAL-order factorisation. Printed: the fill nnz(L + U) / nnz(K),
  the factorisation's CPU time (process_time of the child) and the relative residual of one
  solve ('>S' for a factorisation killed at the time limit);
* unless --no-solve, the whole nested solve, each in a child process killed after S seconds,
  with --linear-solver auto (the default: what it chose), splu and amg: Newton steps of the
  fine level, CPU and wall time, the child's peak resident memory, the fill of its
  factorisations and any factorisation fallback.

The JSON written to FILE (default bench_ordering.json) holds one record per case with both
tables. CPU times are the child's own (the machine may be shared; wall times are printed
beside them).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.output.files import Output, claim

try:  # python -m benchmarks.NAME, or imported
    from .runner import in_child
except ImportError:  # python benchmarks/NAME.py
    from runner import in_child

# name → (column ordering, SymmetricMode, diag_pivot_thresh); "METIS" orders by pymetis first
VARIANTS = {
    "MMD_AT_PLUS_A (before)": ("MMD_AT_PLUS_A", False, 1.0),
    "MMD_AT_PLUS_A thr 0.1": ("MMD_AT_PLUS_A", False, 0.1),
    "MMD_AT_PLUS_A sym": ("MMD_AT_PLUS_A", True, 1.0),
    "MMD_AT_PLUS_A sym 0.1": ("MMD_AT_PLUS_A", True, 0.1),
    "COLAMD": ("COLAMD", False, 1.0),
    "COLAMD 0.1": ("COLAMD", False, 0.1),
    "METIS sym 0.1": ("METIS", True, 0.1),
}
SOLVERS = ("auto", "splu", "amg")


class _Stop(Exception):
    pass


def _record(scene: str, level: int | None, path: str, q) -> None:
    """Child: save the fine level's first Newton matrix (csr arrays) to `path`."""
    import problems.pipeline as pipeline
    import vi_core.ssn as ssn

    loaded = pipeline.load(scene)
    model = loaded.plugin.build(loaded.scene, level)
    n_fine = model.vi.n

    class Recording(ssn.Refactorizer):
        def __call__(self, A):
            if A.shape[0] == n_fine:
                A = sp.csr_matrix(A)
                A.sort_indices()
                np.savez(path, data=A.data, indices=A.indices, indptr=A.indptr, shape=A.shape)
                raise _Stop
            return super().__call__(A)

    ssn.Refactorizer = Recording
    try:
        pipeline.solve_built(loaded, model, linear_solver="splu")
    except _Stop:
        pass
    q.put({"level": model.level, "unknowns": int(model.vi.n + model.vi.m)})


def _metis(K: sp.csr_matrix) -> np.ndarray:
    """(n,) METIS nested-dissection permutation of the graph of K + Kᵀ."""
    import pymetis

    G = sp.csr_matrix(abs(K) + abs(K.T))
    G.setdiag(0)
    G.eliminate_zeros()
    perm, _ = pymetis.nested_dissection(xadj=G.indptr, adjncy=G.indices)
    return np.asarray(perm)


def _factor(path: str, variant: str, q) -> None:
    """Child: factorise the recorded matrix (its transpose, as vi_core.linalg does) with
    `variant`; put fill, CPU time and residual."""
    from problems.commands.resources import peak_rss

    z = np.load(path)
    K = sp.csr_matrix((z["data"], z["indices"], z["indptr"]), shape=tuple(z["shape"]))
    spec, sym, thresh = VARIANTS[variant]
    t0, c0 = time.perf_counter(), time.process_time()
    if spec == "METIS":
        p = _metis(K)
        K = sp.csr_matrix(K[p][:, p])
        spec = "NATURAL"
    Kt = sp.csc_matrix((K.data, K.indices, K.indptr), K.shape[::-1])
    opts = {"SymmetricMode": True} if sym else {}
    lu = spla.splu(Kt, permc_spec=spec, diag_pivot_thresh=thresh, options=opts)
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    b = np.ones(K.shape[0])
    x = lu.solve(b, trans="T")
    q.put(
        {
            "variant": variant,
            "fill": lu.nnz / K.nnz,
            "cpu_s": cpu,
            "wall_s": wall,
            "residual": float(np.linalg.norm(K @ x - b) / np.linalg.norm(b)),
            "peak_mib": peak_rss() / 2**20,
        }
    )


def _solve(scene: str, level: int | None, linear_solver: str, q) -> None:
    """Child: the nested solve with `linear_solver`; put steps, times, peak and fill."""
    import problems.pipeline as pipeline
    from problems.commands.resources import fix_mmap_threshold, peak_rss

    fix_mmap_threshold()
    t0, c0 = time.perf_counter(), time.process_time()
    run = pipeline.solve(pipeline.load(scene), level, linear_solver=linear_solver)
    info = run.solution.info
    q.put(
        {
            "linear_solver": linear_solver,
            "chosen": info.get("linear_solver"),
            "newton_steps": run.solution.iterations,
            "converged": run.solution.converged,
            "residual": run.solution.residual,
            "cpu_s": time.process_time() - c0,
            "wall_s": time.perf_counter() - t0,
            "peak_mib": peak_rss() / 2**20,
            "factor_fill": info.get("factor_fill", []),
            "fallback": info.get("factorisation_fallback", ""),
        }
    )


def _case(text: str) -> tuple[str, int | None]:
    scene, _, level = text.partition("@")
    return scene, (int(level) if level else None)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (prints the tables, writes JSON)."""
    p = argparse.ArgumentParser(prog="python benchmarks/bench_ordering.py")
    p.add_argument("cases", nargs="*", default=["paper_two_body@4"])
    p.add_argument("--timeout", type=float, default=120.0)
    p.add_argument("--no-solve", action="store_true")
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--out", default="bench_ordering.json")
    args = p.parse_args(argv)
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    for v in variants:
        if v not in VARIANTS:
            p.error(f"--variants: {v!r} unknown; allowed: {', '.join(VARIANTS)}")
    try:
        import pymetis  # noqa: F401
    except ImportError:
        variants = [v for v in variants if VARIANTS[v][0] != "METIS"]
    records = []
    scenes = [Path(_case(text)[0]) for text in args.cases]
    inputs = [("a scene file", s) for s in scenes if s.is_file()]
    out = [Output(args.out, "--out", "json")]
    with claim(out, inputs) as run, tempfile.TemporaryDirectory() as tmp:
        for text in args.cases:
            scene, level = _case(text)
            path = os.path.join(tmp, "K.npz")
            head = in_child(_record, (scene, level, path), 20 * args.timeout)
            if head is None:
                print(f"{text}: could not record its Newton matrix")
                continue
            z = np.load(path)
            n, nnz = int(z["shape"][0]), int(z["data"].size)
            name = Path(scene).stem
            print(
                f"\n{name} level {head['level']}: {head['unknowns']:,} unknowns, "
                f"Newton matrix n = {n:,}, nnz = {nnz:,}"
            )
            print(
                f"{'variant':<24}{'fill':>8}{'cpu [s]':>10}{'wall [s]':>10}{'residual':>10}"
                f"{'peak MiB':>10}"
            )
            rows = []
            for v in variants:
                r = in_child(_factor, (path, v), args.timeout) or {"variant": v, "killed": True}
                rows.append(r)
                if r.get("killed"):
                    print(f"{v:<24}{'-':>8}{'>' + format(args.timeout, '.0f'):>10}")
                else:
                    print(
                        f"{v:<24}{r['fill']:>8.1f}{r['cpu_s']:>10.2f}{r['wall_s']:>10.2f}"
                        f"{r['residual']:>10.1e}{r['peak_mib']:>10.0f}"
                    )
            solves = []
            if not args.no_solve:
                print(
                    f"{'--linear-solver':<16}{'chosen':>8}{'steps':>7}{'cpu [s]':>9}"
                    f"{'wall [s]':>10}{'peak MiB':>10}  fill / fallback"
                )
                for ls in SOLVERS:
                    r = in_child(_solve, (scene, level, ls), args.timeout) or {
                        "linear_solver": ls,
                        "killed": True,
                    }
                    solves.append(r)
                    if r.get("killed"):
                        print(f"{ls:<16}{'-':>8}{'-':>7}{'>' + format(args.timeout, '.0f'):>9}")
                        continue
                    fill = ", ".join(f"{f:.1f}" for f in r["factor_fill"][:4])
                    print(
                        f"{ls:<16}{r['chosen']:>8}{r['newton_steps']:>7}{r['cpu_s']:>9.1f}"
                        f"{r['wall_s']:>10.1f}{r['peak_mib']:>10.0f}  {fill} {r['fallback']}"
                    )
            records.append(
                {"case": text, **head, "n": n, "nnz": nnz, "factorisations": rows, "solves": solves}
            )
        run.file("--out").write({"timeout_s": args.timeout, "cases": records})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
