"""Benchmark: the petsc engine (issue 33): time and per-rank peak memory against unknowns, on 1
and 2 ranks, beside the serial solve (direct and amg) of the same scene and level.

    python benchmarks/bench_petsc.py [--cases paper_two_body:2,3,4 block3d:1] [--ranks 1,2]
                                     [--json bench_petsc.json]

Each run is a fresh process (`mpiexec -n P python benchmarks/bench_petsc.py --worker ...` for
the engine, `python ... --worker` with P = 0 for serial), so peak memory (ru_maxrss, per rank)
is that run's: the interpreter and its imports included (printed apart: the baseline of a
process that imported everything and built nothing). Solves as `mixvi solve` does (nested
iteration, tol 1e-10), linear solver auto (serial: direct or amg by size; engine: MUMPS) and
amg (engine: GMRES + GAMG). Prints a table and writes JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def worker(scene: str, level: int, linear: str, engine_name: str, out: str) -> None:
    """One solve; rank 0 writes {n, time_build, time_solve, peak_mb per rank, baseline_mb}."""
    import problems.pipeline as pipeline
    from problems.commands import engine

    eng = engine.start(engine_name)
    loaded = pipeline.load(scene)
    base = _peak_mb()
    t0 = time.perf_counter()
    model = loaded.plugin.build(loaded.scene, level)
    t1 = time.perf_counter()
    with engine.running(eng):
        run = pipeline.solve_built(loaded, model, linear_solver=linear)
    t2 = time.perf_counter()
    peaks = eng.comm.allgather(_peak_mb()) if eng.comm is not None else [_peak_mb()]
    bases = eng.comm.allgather(base) if eng.comm is not None else [base]
    if eng.rank == 0:
        sol = run.solution
        record = {
            "scene": scene,
            "level": level,
            "engine": engine_name,
            "ranks": eng.size,
            "linear_solver": linear,
            "ran": sol.info.get("linear_solver"),
            "n": int(model.vi.n),
            "converged": bool(sol.converged),
            "newton_steps": sol.iterations,
            "time_build_s": t1 - t0,
            "time_solve_s": t2 - t1,
            "peak_mb": peaks,
            "baseline_mb": bases,
        }
        Path(out).write_text(json.dumps(record))


def run_case(scene: str, level: int, ranks: int, linear: str, tmp: Path) -> dict:
    out = tmp / f"{scene}_{level}_{ranks}_{linear}.json"
    me = [sys.executable, str(Path(__file__).resolve()), "--worker", scene, str(level), linear]
    if ranks == 0:
        cmd = [*me, "serial", str(out)]
    else:
        cmd = ["mpiexec", "-n", str(ranks), "--oversubscribe", *me, "petsc", str(out)]
    env = {**os.environ, **MPI_ENV, "OMP_NUM_THREADS": "1"}
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        return {"scene": scene, "level": level, "ranks": ranks, "error": done.stderr[-500:]}
    return json.loads(out.read_text())


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--worker":
        worker(argv[1], int(argv[2]), argv[3], argv[4], argv[5])
        return 0
    p = argparse.ArgumentParser(prog="python benchmarks/bench_petsc.py")
    p.add_argument("--cases", nargs="+", default=["paper_two_body:2,3,4", "block3d:0,1"])
    p.add_argument("--ranks", default="1,2")
    p.add_argument("--linear", default="auto,amg")
    p.add_argument("--json", default="bench_petsc.json")
    args = p.parse_args(argv)
    import tempfile

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            scene, levels = case.split(":")
            for level in map(int, levels.split(",")):
                for linear in args.linear.split(","):
                    for ranks in [0, *map(int, args.ranks.split(","))]:
                        r = run_case(scene, level, ranks, linear, Path(tmp))
                        rows.append(r)
                        _print(r)
    Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")
    print(f"wrote {args.json}")
    return 0


def _print(r: dict) -> None:
    where = "serial" if r["ranks"] == 0 else f"P={r['ranks']}"
    head = f"{r['scene']:>15} L{r['level']} {where:>6}"
    if "error" in r:
        print(f"{head}  failed: {r['error'].strip().splitlines()[-1:]}")
        return
    peaks = "/".join(f"{x:.0f}" for x in r["peak_mb"])
    base = "/".join(f"{x:.0f}" for x in r["baseline_mb"])
    print(
        f"{head} {r['linear_solver']:>4} ({r['ran']}) n={r['n']:>8} steps={r['newton_steps']:>2} "
        f"build {r['time_build_s']:6.2f} s solve {r['time_solve_s']:7.2f} s "
        f"peak MB per rank {peaks} (imports {base})"
    )


if __name__ == "__main__":
    sys.exit(main())
