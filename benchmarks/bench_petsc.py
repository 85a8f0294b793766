"""Benchmark: the petsc engine: time and per-rank peak memory against unknowns, on 1
and 2 ranks, beside the serial solve (direct and amg) of the same scene and level.

    python benchmarks/bench_petsc.py [--cases paper_two_body:2,3,4 block3d:1] [--ranks 1,2]
                                     [--linear auto,amg] [--pc fieldsplit,gamg]
                                     [--json bench_petsc.json]

Each run is a fresh process (`mpiexec -n P python benchmarks/bench_petsc.py --worker ...` for
the engine, `python ... --worker` with P = 0 for serial), so peak memory (ru_maxrss, per rank)
is that run's: the interpreter and its imports included (printed apart: the baseline of a
process that imported everything and built nothing). Solves as `mixvi solve` does (nested
iteration, tol 1e-10), linear solver auto (serial: direct or amg by size; engine: MUMPS) and
amg (engine: GMRES preconditioned by each of --pc: PCFIELDSPLIT over displacement and potential
with GAMG per field, or GAMG on the whole matrix; `vi_core.petsc.ksp`). Prints a table and writes
JSON.

Memory per rank, in MiB above the imports: "build" is the peak once the model is built (inside the
engine's block, as `mixvi solve`: each rank assembles its owned rows of A,
`contact.owned`), "set-up" the peak once the engine has its owned rows in PETSc (the
fine level's Newton loop), "peak" the run's; "kB/unknown" is the peak above the imports per
unknown the rank owns (n / P; serial: n), and "× serial" that against the serial amg run of the
same case (the issue's target: within 1.5×).
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
    """One solve; rank 0 writes {n, time_build, time_solve, cpu_s (each rank's process CPU
    time, imports included), peak_mb per rank, baseline_mb, build_mb per rank, the engine's
    set-up peak per rank, its preconditioner and iterations}."""
    import problems.pipeline as pipeline
    from problems.commands import engine

    eng = engine.start(engine_name)
    loaded = pipeline.load(scene)
    base = _peak_mb()
    with engine.running(eng):  # the build too, as `mixvi solve` (the engine's row partition)
        t0 = time.perf_counter()
        model = loaded.plugin.build(loaded.scene, level)
        t1 = time.perf_counter()
        built = _peak_mb()
        run = pipeline.solve_built(loaded, model, linear_solver=linear)
    t2 = time.perf_counter()
    peaks = eng.comm.allgather(_peak_mb()) if eng.comm is not None else [_peak_mb()]
    bases = eng.comm.allgather(base) if eng.comm is not None else [base]
    builds = eng.comm.allgather(built) if eng.comm is not None else [built]
    cpu = time.process_time()
    cpus = eng.comm.allgather(cpu) if eng.comm is not None else [cpu]
    if eng.rank == 0:
        sol = run.solution
        its = sol.info.get("krylov_iterations")
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
            "cpu_s": cpus,
            "peak_mb": peaks,
            "baseline_mb": bases,
            "build_mb": builds,
            "set_up_mb": sol.info.get("peak_mb", {}).get("set_up"),
            "pc": sol.info.get("preconditioner"),
            "krylov_iterations": None if its is None else int(sum(its)),
        }
        Path(out).write_text(json.dumps(record))


def run_case(scene: str, level: int, ranks: int, linear: str, tmp: Path, pc: str = "") -> dict:
    """One run in a fresh process (ranks 0: serial); pc: the engine's -mixvi_amg_pc."""
    out = tmp / f"{scene}_{level}_{ranks}_{linear}_{pc}.json"
    me = [sys.executable, str(Path(__file__).resolve()), "--worker", scene, str(level), linear]
    if ranks == 0:
        cmd = [*me, "serial", str(out)]
    else:
        cmd = ["mpiexec", "-n", str(ranks), "--oversubscribe", *me, "petsc", str(out)]
    env = {**os.environ, **MPI_ENV, "OMP_NUM_THREADS": "1"}
    if pc:
        env["PETSC_OPTIONS"] = f"{env.get('PETSC_OPTIONS', '')} -mixvi_amg_pc {pc}".strip()
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        return {"scene": scene, "level": level, "ranks": ranks, "error": done.stderr[-500:]}
    return json.loads(out.read_text())


def per_unknown(r: dict, serial: dict | None) -> None:
    """r's largest peak above the imports per owned unknown (kB) and its ratio to `serial`'s
    (the serial amg run of the case), added to r."""
    if "error" in r:
        return
    above = max(p - b for p, b in zip(r["peak_mb"], r["baseline_mb"], strict=True))
    r["kb_per_unknown"] = above * 1024.0 / (r["n"] / max(r["ranks"], 1))
    if serial is not None and "kb_per_unknown" in serial:
        r["vs_serial"] = r["kb_per_unknown"] / serial["kb_per_unknown"]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--worker":
        worker(argv[1], int(argv[2]), argv[3], argv[4], argv[5])
        return 0
    p = argparse.ArgumentParser(prog="python benchmarks/bench_petsc.py")
    p.add_argument("--cases", nargs="+", default=["paper_two_body:2,3,4", "block3d:0,1"])
    p.add_argument("--ranks", default="1,2")
    p.add_argument("--linear", default="auto,amg")
    p.add_argument("--pc", default="fieldsplit", help="the engine's amg preconditioners")
    p.add_argument("--json", default="bench_petsc.json")
    args = p.parse_args(argv)
    import tempfile

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            scene, levels = case.split(":")
            for level in map(int, levels.split(",")):
                for linear in args.linear.split(","):
                    serial = run_case(scene, level, 0, linear, Path(tmp))
                    per_unknown(serial, None)
                    rows.append(serial)
                    _print(serial)
                    pcs = args.pc.split(",") if linear == "amg" else [""]
                    for pc in pcs:
                        for ranks in map(int, args.ranks.split(",")):
                            r = run_case(scene, level, ranks, linear, Path(tmp), pc)
                            per_unknown(r, serial if linear == "amg" else None)
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

    def above(key: str) -> str:
        vals = r.get(key)
        if not vals:
            return "-"
        return "/".join(f"{x - b:.0f}" for x, b in zip(vals, r["baseline_mb"], strict=True))

    ran = r["ran"] + (f"+{r['pc']}" if r.get("pc") else "")
    its = "" if r.get("krylov_iterations") is None else f" its={r['krylov_iterations']}"
    ratio = f" ({r['vs_serial']:.2f}× serial)" if "vs_serial" in r else ""
    print(
        f"{head} {r['linear_solver']:>4} ({ran}) n={r['n']:>8} steps={r['newton_steps']:>2}{its} "
        f"build {r['time_build_s']:6.2f} s solve {r['time_solve_s']:7.2f} s | MiB above imports "
        f"build {above('build_mb')} set-up {above('set_up_mb')} peak {above('peak_mb')} "
        f"(imports {'/'.join(f'{x:.0f}' for x in r['baseline_mb'])}) "
        f"{r['kb_per_unknown']:.2f} kB/unknown{ratio}"
    )


if __name__ == "__main__":
    sys.exit(main())
