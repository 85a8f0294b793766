"""`mixvi bench`: speed of the nonlinear solve against one linear solve, measured in one run.

For each (scene, level) a child process builds the model and times
- the nonlinear solve: semismooth Newton with nested iteration, that of `mixvi solve`
  (`pipeline.nested_iteration`: levels 0 … L solved in turn, each warm-started from the
  coarser one, the coarse ones to `pipeline.coarse_tol`; the coarse levels' warm starts and
  solves are timed, the models' construction is not), and the conic and homotopy paths where
  asked;
- one linear solve of the same matrix size: the stick limit (every multiplier Free, i.e. the
  tied problem), by the same machinery (ssn on a linear problem = one condensed factorisation
  and solve);
and reports their ratio in wall-clock time and in CPU time (`time.process_time` of the child,
all its threads: the iterative path runs BLAS on one thread; on a machine shared with other
jobs the wall-clock ratio moves with the load — paper scene level 6, the same code: 1.15 at a
load average of 4 against 1.78 on an idle machine — where the CPU-time ratio measures the work
done, 1.73 in the loaded run), the child's peak resident memory (`resources.peak_rss`: VmHWM,
which — unlike tracemalloc — includes the sparse factorisations' C allocations, and — unlike
ru_maxrss — not the parent's memory at the spawn), that peak in bytes per
unknown, and the memory estimate of `resources` for the same level (made before the child
starts), so the model can be checked. A second table (JSON key "memory") lists per case the
peak, the bytes per unknown and the estimate with its ratio estimate / measured.

A case whose child raises, is killed (e.g. by the out-of-memory killer) or exceeds `--timeout`
seconds becomes a failed row with its cause; the parent polls the child's liveness and never
waits without a time limit. The table (failed rows included) is written in every case; exit
status 1 if any case failed or did not converge. `--baseline OLD.json` compares every case
with an earlier run's (`bench_compare`) and exits 1 if one regressed.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import platform
import queue
import signal
import time
from pathlib import Path

import numpy as np

import problems.pipeline as pipeline
import vi_core
from problems.errors import SceneError
from problems.output import signals
from problems.output.files import Output, claim
from problems.plugins.contract import relative_difference
from vi_core import Free, MixedVI
from vi_core.linalg import resolve_backend
from vi_core.linear_solvers import LINEAR_SOLVERS, thread_settings

from . import bench_compare, bench_scaling, options, resources

DEFAULT = {"paper_two_body": (2, 5), "rigid_foundation": (3, 6)}
DEFAULT_TIMEOUT = 3600.0  # seconds per (scene, level): the paper scene at level 5 takes ~5 min
POLL = 0.2  # seconds between liveness checks of a child


def _clocks() -> np.ndarray:
    """(2,) wall-clock and CPU seconds now: `time.perf_counter`, `time.process_time`."""
    return np.array([time.perf_counter(), time.process_time()])


def _nested_ssn(plugin, scene, level: int, tol: float, linear_solver: str = "auto"):
    """(model, solution) of the finest level, the wall-clock and CPU seconds of the whole nested
    solve and the Newton steps per level, coarse levels first. The nested solve is `mixvi
    solve`'s (`pipeline.nested_iteration`, then the finest level from its warm start); its time
    is every level's warm start and solve, the models' construction excluded. A plug-in
    without `warm_start`: the finest level alone, from a cold start (as `mixvi solve`)."""
    model = plugin.build(scene, level)
    built = np.zeros(2)  # (2,) wall-clock and CPU seconds spent building the coarse models

    def build(scene, lev: int):
        nonlocal built
        t = _clocks()
        coarse = plugin.build(scene, lev)
        built = built + _clocks() - t
        return coarse

    t = _clocks()
    nested, kw = [], {}
    if pipeline.nests(plugin, model):
        nested, kw, _ = pipeline.nested_iteration(
            plugin, scene, model, tol, linear_solver, build=build
        )
    sol = pipeline.solve_model(
        plugin, model, method="ssn", tol=tol, linear_solver=linear_solver, **kw
    )
    wall, cpu = _clocks() - t - built
    iters = [r["iterations"] for r in nested] + [sol.iterations]
    return model, sol, float(wall), float(cpu), iters


def stick_limit(vi: MixedVI) -> MixedVI:
    """vi with Λ = Rᵐ (every multiplier Free: the tied linear problem), sharing vi's A and B.
    Its solve equilibrates it, inside the linear timing, as the nonlinear solve's equilibration
    of the finest level lies inside the nonlinear timing (sharing vi's equilibrated problem
    left that cost out of the linear solve only: paper scene level 5, about 0.6 s of 10). vi's
    cached equilibrated problem is dropped first, so one equilibrated A is held at a time (with
    two, the reference, not the nonlinear solve, was the peak of a case: paper scene level 5,
    1386 against 1267 MB)."""
    vi.__dict__.pop("equilibrated", None)  # the cached property (recomputed where asked again)
    return MixedVI(
        A=vi.A, B=vi.B, f=vi.f, Lambda=Free(vi.m), gap=vi.gap, fields=vi.fields,
        near_null=vi.near_null,
    )  # fmt: skip


def _record(
    scene_name: str, level: int, solvers: list[str], tol: float, linear_solver: str = "auto"
) -> list[dict]:
    from problems.plugins import registry
    from problems.scene import load_scene

    scene = load_scene(scene_name)
    plugin = registry.for_scene(scene)
    out = []
    # warm-up (untimed): library loading and first-call costs must not land on either timing
    for backend in ("splu", "auto", *(("amg",) if linear_solver == "amg" else ())):
        pipeline.solve_model(
            plugin, plugin.build(scene, 0), method="ssn", tol=tol, linear_solver=backend
        )
    model, sol, t_nl, c_nl, iters = _nested_ssn(plugin, scene, level, tol, linear_solver)
    vi = pipeline.problem_at(plugin, model, sol)  # the problem ssn's answer solves
    # the linear reference: same matrix size, same linear solver (for amg: hierarchy set-up
    # and one GMRES solve to tol — ssn solves a linear VI's first step to tol at once)
    tied = stick_limit(vi)
    t = _clocks()
    lin = vi_core.solve(tied, "ssn", tol=tol, linear_solver=linear_solver)
    t_lin, c_lin = (float(x) for x in _clocks() - t)
    if not lin.converged:
        raise RuntimeError(f"the tied linear solve did not converge ({lin.residual:.1e})")
    base = {"scene": scene_name, "level": level, "unknowns": vi.n + vi.m}
    out.append(
        {
            **base,
            "solver": "ssn",
            "iterations": sol.iterations,
            "iterations_per_level": iters,
            "converged": sol.converged,
            "time_nonlinear_s": t_nl,
            "time_linear_s": t_lin,
            "ratio": t_nl / t_lin,
            "cpu_nonlinear_s": c_nl,
            "cpu_linear_s": c_lin,
            "cpu_ratio": c_nl / c_lin,
            "linear_solver": sol.info.get("linear_solver"),
            "krylov_iterations": sol.info.get("krylov_iterations"),  # per fine-level step
            "krylov_iterations_linear": (lin.info.get("krylov_iterations") or [None])[0],
            "fallbacks": len(sol.info.get("fallback", [])),
            "threads": sol.info.get("threads"),
        }
    )
    for meth in solvers:
        if meth == "ssn" or (meth == "conic" and vi.structure == "general"):
            continue
        c = time.process_time()
        s = pipeline.solve_model(plugin, model, method=meth, tol=tol)
        c = time.process_time() - c
        out.append(
            {
                **base,
                "solver": meth,
                "iterations": s.iterations,
                "converged": s.converged,
                "time_nonlinear_s": s.time,
                "time_linear_s": t_lin,
                "ratio": s.time / t_lin,
                "cpu_nonlinear_s": c,
                "cpu_linear_s": c_lin,
                "cpu_ratio": c / c_lin,
                "difference_to_ssn": relative_difference(s.u, sol.u),
            }
        )
    peak = resources.peak_rss()  # the child's own peak (not ru_maxrss: `peak_rss`)
    for r in out:
        r["peak_mem_mb"] = peak / 2**20
        r["bytes_per_unknown"] = peak / r["unknowns"]
    return out


def _die_with_parent() -> None:
    """Linux: the kernel kills this process when its parent dies (no orphaned solves)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def _child(scene_name: str, level: int, solvers: list[str], tol: float, q, linear="auto"):
    """Run one case in a worker process and put ("ok", rows) or ("error", cause) on `q`."""
    signals.ignore_in_child()
    _die_with_parent()
    resources.fix_mmap_threshold()
    try:
        q.put(("ok", _record(scene_name, level, solvers, tol, linear)))
    except MemoryError:
        q.put(("error", "out of memory (MemoryError in the child)"))
    except SceneError as err:
        q.put(("error", f"bad input: {err}"))
    except BaseException as err:  # the cause goes into the table; the parent decides the exit
        q.put(("error", f"{type(err).__name__}: {err}".splitlines()[0][:300]))


def death_cause(exitcode: int | None) -> str:
    """Why a child ended without a result, from its exit code."""
    if exitcode is None:
        return "still running"
    if exitcode < 0:
        name = signal.Signals(-exitcode).name
        hint = " (out of memory? the kernel's OOM killer sends SIGKILL)" if exitcode == -9 else ""
        return f"the child process was killed by {name}{hint}"
    return f"the child process exited with status {exitcode} without a result"


def run_case(
    ctx,
    name: str,
    level: int,
    solvers: list[str],
    tol: float,
    timeout: float,
    linear_solver: str = "auto",
):
    """("ok", rows) or ("error", cause) of one case run in a fresh child process; the child is
    polled every POLL seconds and killed after `timeout` seconds or on any exception here."""
    q = ctx.Queue()
    proc = ctx.Process(
        target=_child, args=(name, level, solvers, tol, q, linear_solver), daemon=True
    )
    proc.start()
    deadline = time.monotonic() + timeout
    try:
        while True:
            try:
                return q.get(timeout=POLL)
            except queue.Empty:
                pass
            if not proc.is_alive():
                try:  # a result put just before the child ended
                    return q.get(timeout=1.0)
                except queue.Empty:
                    return "error", death_cause(proc.exitcode)
            if time.monotonic() > deadline:
                return "error", f"timed out after {timeout:g} s (--timeout)"
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(10)
        q.close()
        q.cancel_join_thread()


def _scenes(text: str) -> list[str]:
    from problems.scene import SCENES_DIR, find_scene

    items = [x.strip() for x in text.split(",")]
    if not text.strip() or any(not x for x in items):
        shipped = ", ".join(sorted(q.stem for q in SCENES_DIR.glob("*.toml")))
        raise SceneError(
            "--scenes", text, f"a non-empty comma-separated list of scene files or of: {shipped}"
        )
    seen: dict[Path, str] = {}
    for x in items:  # one scene named twice (or by a second path) would be run twice
        real = find_scene(x).resolve()
        if real in seen:
            raise SceneError(
                "--scenes", text, f"distinct scenes ({seen[real]!r} and {x!r} are one scene)"
            )
        seen[real] = x
    return items


def _timeout(text: str) -> float:
    return options.number(text, float, lambda v: 0 < v < float("inf"), "a time in seconds, > 0")


HEAD = (
    f"{'scene':<18}{'level':>6}{'unknowns':>10}{'solver':>10}{'linear':>9}{'iter':>6}"
    f"{'krylov/step':>12}"
    f"{'nonlinear [s]':>15}{'linear [s]':>12}{'ratio':>8}{'cpu ratio':>11}{'peak [MB]':>11}"
    f"{'B/unknown':>11}"
)
MEMORY_HEAD = (
    f"{'scene':<18}{'level':>6}{'linear':>9}{'unknowns':>10}{'peak [MB]':>11}{'B/unknown':>11}"
    f"{'est. [MB]':>11}{'est./peak':>11}"
)


def _line(r: dict) -> str:
    if r.get("error"):
        return f"{r['scene']:<18}{r['level']:>6}{r['unknowns']:>10}  FAILED: {r['error']}"
    its = r.get("krylov_iterations")
    kry = f"{np.mean(its):.1f}" if its else "-"
    if r.get("fallbacks"):
        kry += f" ({r['fallbacks']}fb)"
    return (
        f"{r['scene']:<18}{r['level']:>6}{r['unknowns']:>10}{r['solver']:>10}"
        f"{r.get('linear_solver') or '-':>9}{r['iterations']:>6}{kry:>12}"
        f"{r['time_nonlinear_s']:>15.2f}{r['time_linear_s']:>12.2f}"
        f"{r['ratio']:>8.2f}{r['cpu_ratio']:>11.2f}{r['peak_mem_mb']:>11.0f}"
        f"{r['bytes_per_unknown']:>11.0f}"
    )


def memory_table(records: list[dict]) -> list[dict]:
    """One row per case that ran: peak resident memory, bytes per unknown, the estimate of
    `resources` made before the case and their ratio estimate / measured."""
    rows, seen = [], set()
    for r in records:
        key = (r["scene"], r["level"], r.get("linear_solver"))
        if r.get("error") or key in seen:
            continue
        seen.add(key)
        rows.append(
            {
                "scene": r["scene"],
                "level": r["level"],
                "linear_solver": r.get("linear_solver"),
                "unknowns": r["unknowns"],
                "peak_mem_mb": r["peak_mem_mb"],
                "bytes_per_unknown": r["bytes_per_unknown"],
                "estimate_mem_mb": r["estimate_mem_mb"],
                "estimate_ratio": r["estimate_mem_mb"] / r["peak_mem_mb"],
            }
        )
    return rows


def _memory_line(m: dict) -> str:
    return (
        f"{m['scene']:<18}{m['level']:>6}{m['linear_solver'] or '-':>9}{m['unknowns']:>10}"
        f"{m['peak_mem_mb']:>11.0f}"
        f"{m['bytes_per_unknown']:>11.0f}{m['estimate_mem_mb']:>11.0f}{m['estimate_ratio']:>11.2f}"
    )


def bench_main(argv: list[str] | None = None) -> int:
    """Entry point of `mixvi bench` (prints a table, writes bench.json); 0 if every case ran
    and converged, 1 if one failed (its row says why), 2 on bad input."""
    p = argparse.ArgumentParser(prog="mixvi bench", description=__doc__.splitlines()[0])
    p.add_argument("--scenes", default=",".join(DEFAULT), help="comma-separated scene names")
    p.add_argument("--levels", default=None, help="A..B for every scene (default per scene)")
    p.add_argument("--solvers", default="ssn", help="comma-separated: ssn,conic,homotopy")
    p.add_argument(
        "--tol", type=options.tol, default=1e-10, help="relative residual (default 1e-10)"
    )
    p.add_argument(
        "--linear-solvers",
        default="auto",
        help="comma-separated Newton-step solvers, each case once per solver in its own child: "
        + ",".join(LINEAR_SOLVERS),
    )
    p.add_argument(
        "--timeout",
        type=_timeout,
        default=DEFAULT_TIMEOUT,
        help=f"seconds per case before its child is killed (default {DEFAULT_TIMEOUT:g})",
    )
    p.add_argument("--out", default="bench.json", help="JSON file (default bench.json)")
    p.add_argument(
        "--figure",
        default=None,
        help="scaling figure, SVG: time and memory against unknowns, log-log with the fitted "
        "exponents (default: --out with the suffix .svg)",
    )
    p.add_argument(
        "--baseline",
        default=None,
        metavar="OLD.json",
        help="an earlier run's JSON: each case's CPU times, peak memory and iterations against "
        "it; exit 1 if a case regressed (`bench_compare`)",
    )
    p.add_argument("--force", action="store_true", help="skip the memory estimate's refusal")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing --out or --figure file that mixvi did not write",
    )
    args = p.parse_args(argv)
    solvers = options.names(args.solvers, "--solvers", ("ssn", "conic", "homotopy"))
    linear = options.names(args.linear_solvers, "--linear-solvers", LINEAR_SOLVERS)
    from problems.plugins import registry
    from problems.scene import load_scene

    baseline = None if args.baseline is None else bench_compare.read_baseline(args.baseline)
    jobs, inputs = [], [] if args.baseline is None else [("the --baseline file", args.baseline)]
    for name in _scenes(args.scenes):
        scene = load_scene(name)
        inputs += scene.files()
        plugin = registry.for_scene(scene)
        if args.levels:
            a, b = options.level_range(args.levels)
            text = args.levels
        else:
            a, b = DEFAULT.get(name, (0, 3))
            text = f"{a}..{b}"
        mine = []
        for ls in linear:  # each linear solver's own memory model (resources.MEMORY_MODEL)
            sizes = resources.check_levels(
                plugin, scene, (a, b), "--levels", text, args.force, ls, "--linear-solvers"
            )
            mine += [(name, lev, sizes.estimate(lev), ls) for lev in range(a, b + 1)]
        # scenes in the order given; within a scene every solver of a level before the next level
        jobs += sorted(mine, key=lambda j: j[1])
    figure = args.figure or str(Path(args.out).with_suffix(".svg"))
    if args.figure is None and figure == args.out:
        raise SceneError(
            "--out",
            args.out,
            "a file whose name with the suffix .svg (the default --figure) is another path: "
            "give --figure, or an --out not ending in .svg",
        )
    outputs = [Output(args.out, "--out", "json"), Output(figure, "--figure", "svg")]
    with claim(outputs, inputs, overwrite=args.overwrite) as run:
        records = _run(jobs, solvers, args)
        machine = {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "cpus": mp.cpu_count(),
            "linear_solver": resolve_backend("auto"),  # what auto means here
            "threads": thread_settings(),
        }
        memory = memory_table(records)
        print("\npeak resident memory (VmHWM of each case's child process)")
        print(MEMORY_HEAD)
        for m in memory:
            print(_memory_line(m))
        fitted = bench_scaling.fits(records)
        if fitted:
            print("\nfitted exponents b of a·N^b (least squares over the sizes that converged)")
            for f in fitted:
                ex = f["exponent"]
                print(
                    f"{f['scene']:<18}{f['linear_solver']:>9}  nonlinear {ex['time_nonlinear']:.2f}"
                    f"  linear {ex['time_linear']:.2f}  peak memory {ex['peak_mem']:.2f}"
                )
        data = {"machine": machine, "records": records, "memory": memory, "fits": fitted}
        regressed = 0
        if baseline is not None:
            rows = bench_compare.compare(baseline, data)
            print("\n".join(bench_compare.table(rows, bench_compare.same_machine(baseline, data))))
            data["baseline"] = {"file": args.baseline, "cases": rows}
            regressed = sum(r["regressed"] for r in rows)
        run.file("--out").write(data)
        run.file("--figure").write(bench_scaling.figure_svg(records))
    print(f"wrote {args.out} and {figure}")
    if regressed:
        print(f"mixvi bench: {regressed} case(s) regressed against {args.baseline}")
    ok = all(not r.get("error") and r.get("converged") for r in records)
    return 0 if ok and not regressed else 1


def _run(jobs, solvers: list[str], args) -> list[dict]:
    print(HEAD)
    ctx = mp.get_context("spawn")
    records = []
    for name, lev, est, ls in jobs:
        kind, payload = run_case(ctx, name, lev, solvers, args.tol, args.timeout, ls)
        extra = {"estimate_unknowns": est.unknowns, "estimate_mem_mb": est.peak_bytes / 2**20}
        if kind == "ok":
            recs = [{**r, **extra} for r in payload]
        else:
            recs = [
                {
                    "scene": name,
                    "level": lev,
                    "unknowns": est.unknowns,
                    "solver": "ssn",
                    "linear_solver": ls,
                    "converged": False,
                    "error": payload,
                    **extra,
                }
            ]
        for r in recs:
            print(_line(r), flush=True)
        records += recs
    return records
