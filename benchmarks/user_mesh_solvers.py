"""The linear solvers on the user-like meshes: what `auto` picks against the others.

    python benchmarks/user_mesh_solvers.py [SCENE ...] [--levels L,...] [--solvers S,...]
        [--timeout S] [--out FILE]

SCENE is one of the scenes of benchmarks/user_meshes.py (read from tests/data/user_meshes/;
default: all six), a shipped scene's name or a scene file; its level is LEVEL_50K (the level at
which it has 50k–200k unknowns) for a user-like scene, the scene's own otherwise, or each of
--levels. Per (scene, level) and linear solver, the whole nested solve (`pipeline.solve`, what
`mixvi solve SCENE --level L --linear-solver X` runs, without writing results) in a child
process of its own, killed after --timeout seconds (`bench_ordering`'s children). Solvers:

* `auto`: the default (`linear_solvers.auto_linear_solver`), the chosen one printed;
* `splu`: SuperLU with the shipped ordering (`linalg.ORDERING` with SUPERLU_OPTIONS and
  PIVOT_THRESHOLD);
* `splu-colamd`: SuperLU with COLAMD (no SymmetricMode, the same pivot threshold), i.e. the
  fallback ordering used from the start;
* `amg`: the iterative path.

Printed per run: the unknowns and nnz(A) of the finest level, the solver that ran, the
finest level's factorisations (count, CPU seconds in all, fill nnz(L + U) / nnz(K) of the
matrix K factorised: the largest), Newton steps per level (coarse first), the fine level's
GMRES iterations, the whole solve's CPU time (process_time of the child: all its threads) and
wall time, and the child's peak resident memory (VmHWM, `resources.peak_rss`). Per case: auto's
time over the best of the runs that converged, in CPU and in wall time. The machine may be
shared: compare CPU times. The JSON (default user_mesh_solvers.json) holds every run; it is
written through `problems.output.files.claim` (a file this command did not write is never
replaced).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from problems.errors import SceneError
from problems.output.files import Output, claim

try:  # python -m benchmarks.NAME, or imported
    from .runner import in_child
except ImportError:  # python benchmarks/NAME.py
    from runner import in_child

ROOT = Path(__file__).resolve().parents[1]
USER_MESHES = ROOT / "tests" / "data" / "user_meshes"
SOLVERS = ("auto", "splu", "splu-colamd", "amg")


def _user_meshes():
    """benchmarks/user_meshes.py (its SCENES and LEVEL_50K)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    try:
        import user_meshes
    finally:
        sys.path.pop(0)
    return user_meshes


def _scene(text: str) -> tuple[str, int | None]:
    """(scene to load, default level) of a SCENE argument."""
    gen = _user_meshes()
    if text in gen.SCENES:
        return str(USER_MESHES / f"{text}.toml"), gen.LEVEL_50K[text]
    return text, None


def _run(scene: str, level: int | None, solver: str, q) -> None:
    """Child: the nested solve of `scene` at `level` with `solver` (SOLVERS); put its record
    (or {"error": cause})."""
    try:
        q.put(_measure(scene, level, solver))
    except BaseException as err:  # the cause goes into the table
        q.put({"error": f"{type(err).__name__}: {err}".splitlines()[0][:300]})


def _measure(scene: str, level: int | None, solver: str) -> dict:
    import problems.pipeline as pipeline
    import vi_core.linalg as linalg
    import vi_core.ssn as ssn
    from problems.commands.resources import fix_mmap_threshold, peak_rss

    fix_mmap_threshold()
    if solver == "splu-colamd":
        linalg.ORDERING, linalg.SUPERLU_OPTIONS = "COLAMD", {}
    factorisations = []  # (n, nnz, CPU s, wall s, fill, ordering) of every direct factorisation

    class Timed(ssn.Refactorizer):
        def __call__(self, A):
            t, c = time.perf_counter(), time.process_time()
            F = super().__call__(A)
            cpu, wall = time.process_time() - c, time.perf_counter() - t
            factorisations.append((A.shape[0], A.nnz, cpu, wall, F.fill, F.ordering))
            return F

    ssn.Refactorizer = Timed
    coarse_done = [0]  # factorisations made before the fine level (by the coarse levels)
    krylov: dict[int, int] = {}  # level → GMRES iterations of all its ssn solves
    before: dict[int, int] = {}  # level → its iterations before the ssn solve running now

    def on_level(model, solution) -> None:
        coarse_done[0] = len(factorisations)

    def on_step(level: int, info: dict) -> None:
        if info["done"]:  # "krylov_iterations" counts this ssn solve's (None: direct)
            if info["step"] == 1:  # a new ssn solve (the electrical fixed point runs several)
                before[level] = krylov.get(level, 0)
            krylov[level] = before[level] + (info["krylov_iterations"] or 0)

    t0, c0 = time.perf_counter(), time.process_time()
    loaded = pipeline.load(scene)
    run = pipeline.solve(
        loaded,
        level,
        linear_solver="splu" if solver == "splu-colamd" else solver,
        on_level=on_level,
        on_step=on_step,
    )
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    sol, vi = run.solution, run.model.vi
    fine = factorisations[coarse_done[0] :]
    return {
        "level": run.model.level,
        "unknowns": int(vi.n + vi.m),
        "nnz_A": int(vi.A.nnz),
        "chosen": sol.info.get("linear_solver"),
        "converged": bool(sol.converged),
        "residual": float(sol.residual),
        "newton_steps": [int(lev["iterations"]) for lev in run.nested] or [int(sol.iterations)],
        "krylov_iterations": krylov.get(run.model.level, 0),
        "factorisations": len(fine),
        "factor_n": max((f[0] for f in fine), default=0),
        "factor_cpu_s": sum(f[2] for f in fine),
        "factor_wall_s": sum(f[3] for f in fine),
        "fill": max((f[4] for f in fine), default=None),
        "orderings": sorted({f[5] for f in fine}),
        "fallback": sol.info.get("factorisation_fallback", ""),
        "cpu_s": cpu,
        "wall_s": wall,
        "peak_mib": peak_rss() / 2**20,
    }


def _line(name: str, r: dict) -> str:
    head = f"{name:<14}"
    if "error" in r:
        return f"{head}{r['error']}"
    fact = "-"
    if r["factorisations"]:
        fact = f"{r['factorisations']} in {r['factor_cpu_s']:.1f} s, fill {r['fill']:.1f}"
    steps = "/".join(str(s) for s in r["newton_steps"])
    note = "" if r["converged"] else "  NOT CONVERGED"
    if r["fallback"]:
        note += f"  fallback: {r['fallback'][:60]}"
    return (
        f"{head}{r['chosen']:>7}  {fact:<24}{steps:>14}{r['krylov_iterations']:>7}"
        f"{r['cpu_s']:>9.1f}{r['wall_s']:>9.1f}{r['peak_mib']:>9.0f}{note}"
    )


def ratios(runs: dict[str, dict]) -> dict | None:
    """auto's CPU and wall time over the best of the converged runs (auto's own included), and
    which runs were best; None if auto did not converge."""
    ok = {k: r for k, r in runs.items() if "error" not in r and r["converged"]}
    if "auto" not in ok:
        return None
    out = {}
    for clock in ("cpu_s", "wall_s"):
        best = min(ok, key=lambda k: ok[k][clock])
        out[clock] = {"ratio": ok["auto"][clock] / ok[best][clock], "best": best}
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (prints the tables, writes JSON); exit 2 on bad input."""
    gen = _user_meshes()
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenes", nargs="*", default=list(gen.SCENES), metavar="SCENE")
    p.add_argument("--levels", default="", help="comma-separated levels (default: per scene)")
    p.add_argument("--solvers", default=",".join(SOLVERS), help=f"from {', '.join(SOLVERS)}")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds per run (wall)")
    p.add_argument("--out", default="user_mesh_solvers.json")
    args = p.parse_args(argv)
    solvers = [s.strip() for s in args.solvers.split(",") if s.strip()]
    bad = [s for s in solvers if s not in SOLVERS]
    if bad or not solvers:
        p.error(f"--solvers: {', '.join(bad) or 'none'}: expected some of {', '.join(SOLVERS)}")
    try:
        levels = [int(x) for x in args.levels.split(",") if x.strip()]
    except ValueError:
        p.error(f"--levels: {args.levels!r}: expected comma-separated integers, e.g. 2,3")
    if any(lev < 0 for lev in levels):
        p.error(f"--levels: {args.levels!r}: levels are ≥ 0")
    cases = [(text, *_scene(text)) for text in args.scenes]
    inputs = [("a scene file", s) for _, s, _ in cases if Path(s).is_file()]
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the start")
    records = []
    try:
        with claim([Output(args.out, "--out", "json")], inputs) as run:
            for text, scene, default in cases:
                for level in levels or [default]:
                    records.append(_case(text, scene, level, solvers, args.timeout))
            run.file("--out").write({"timeout_s": args.timeout, "cases": records})
    except SceneError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end; wrote {args.out}")
    return 0


def _case(text: str, scene: str, level: int | None, solvers: list[str], timeout: float) -> dict:
    """Every solver on one (scene, level): print the rows and the ratio; the record."""
    runs: dict[str, dict] = {}
    for solver in solvers:
        t = time.monotonic()
        r = in_child(_run, (scene, level, solver), timeout)
        if r is None:
            waited = time.monotonic() - t
            cause = "timed out" if waited >= timeout else "killed"
            r = {"error": f"{cause} after {waited:.0f} s (wall)"}
        if not runs:
            size = f"{r['unknowns']:,} unknowns, nnz(A) {r['nnz_A']:,}" if "level" in r else ""
            print(f"\n{Path(text).stem} level {r.get('level', level)}: {size}")
            print(
                f"{'solver':<14}{'ran':>7}  {'fine factorisations':<24}{'Newton':>14}"
                f"{'Krylov':>7}{'CPU [s]':>9}{'wall [s]':>9}{'peak MiB':>9}"
            )
        runs[solver] = r
        print(_line(solver, r), flush=True)
    ratio = ratios(runs)
    if ratio:
        print(
            f"auto / best: CPU {ratio['cpu_s']['ratio']:.2f} (best {ratio['cpu_s']['best']}), "
            f"wall {ratio['wall_s']['ratio']:.2f} (best {ratio['wall_s']['best']})"
        )
    first = next((r for r in runs.values() if "level" in r), {})
    return {
        "scene": text,
        "level": first.get("level", level),
        "unknowns": first.get("unknowns"),
        "nnz_A": first.get("nnz_A"),
        "runs": runs,
        "auto_over_best": ratio,
    }


if __name__ == "__main__":
    raise SystemExit(main())
