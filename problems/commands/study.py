"""`mixvi study`: accuracy and cost of every solver over a range of refinement levels.

    mixvi study SCENE [--levels A..B] [--solvers ssn,conic,...] [--tols 1e-6,1e-8,1e-10]
                      [--set KEY=VALUE ...] [--out DIR] [--no-progress] [--vtu]
                      [--workers N | --scheduler ADDRESS]

Defaults: levels 0..3, every solver that can run the scene (`applicable`: ssn, conic and
homotopy for a fixed convex set, conic only where A is not general; ssn and fixed_point for
Coulomb or unilateral contact blocks), tolerances 1e-6, 1e-8, 1e-10. A solver in --solvers
that cannot run the scene is refused (exit 2).

For each level, solver and tolerance it records the solve time (`Solution.time`, wall clock),
the iterations, the peak memory (tracemalloc peak during the solve: numpy arrays and Python
objects; native workspaces of SuperLU/PARDISO/Clarabel are not seen) and the error norms the
plug-in declares (contract v2: `NORMS`, `mesh_size`, `reference_errors`, optionally
`exact_errors` with its own names `EXACT_NORMS` where they differ; for the 2D contact
plug-in those of Theorem 4.1, `problems.plugins.contact.errors`): against the scene's exact
solution if it has one (`exact_errors` not None), otherwise against the finest level solved by
the same solver at the tightest tolerance. That level is then the reference: its records
are marked `"reference": true` (they carry only the solver error of looser tolerances, and
rounding at the tightest) and are left out of the rates, of the table's rate column and of the
figures.

With `--workers N` the (level, solver) cases run as Dask tasks on a local cluster of N
single-threaded worker processes (N lowered, with a one-line notice, to the cores, to the
workers whose memory estimate of the finest level fits in the memory available, and to the
cases); with `--scheduler ADDRESS` on a running dask.distributed
cluster (optional extra: `pip install -e ".[dask]"`). Every case is solved with BLAS limited to
one thread, in the serial run too, so every number except times and memory peaks is the same
either way. A task that fails (not bad input) is a failed record with its cause (`error`).

Output (committed into DIR, default out/SCENE_study, by problems.output.files): `study.json`

    {"scene", "plugin", "norms": [NORMS...], "reference": "exact" | "level N",
     "records": [{"level", "h", "unknowns", "solver", "tol", "time_s", "iterations",
                  "err": {norm: value for norm in NORMS},
                  "converged", "residual", "peak_mem_mb", ["reference": true]}],
     "rates": {"<solver>": {norm: slope or null}}}

(rates: slope of np.polyfit(log h, log err) over the last three levels with an error, at the
tightest tolerance; null when fewer than two levels), `errors_vs_h.png` and
`errors_vs_time.png`; with `--vtu` also each level's results at the tightest tolerance in
SOLVER/level_L/ and a ParaView collection SOLVER.pvd per solver (time step = level).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tracemalloc
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

import problems.pipeline as pipeline
import vi_core
from problems.errors import SceneError
from problems.output import signals
from problems.output.collection import vtu_datasets, write_pvd
from problems.output.files import output_folder
from problems.plugins import registry
from problems.plugins.contract import needs
from problems.scene import Scene, load_scene

from . import options, resources
from .failures import cores
from .options import level_range
from .progress import bar as progress_bar

SOLVERS = ("ssn", "conic", "homotopy", "fixed_point")
RATE_LEVELS = 3
STUDY_NEEDS = ("NORMS", "mesh_size", "reference_errors")  # exact_errors: optional


# ------------------------------------------------------------------ argument parsing
def applicable(model: Any) -> tuple[list[str], str]:
    """The solvers of SOLVERS that can run the built `model`, and why the others cannot: ssn
    and the fixed point for a multiplier set with Coulomb or unilateral contact blocks; ssn,
    conic (not for a general A) and homotopy for a fixed convex set."""
    if pipeline.has_contact_set(model.vi):
        return ["ssn", "fixed_point"], (
            "its multiplier set holds Coulomb or unilateral contact blocks: conic and "
            "homotopy need a fixed convex set"
        )
    if model.vi.structure == "general":
        return ["ssn", "homotopy"], (
            "a fixed convex set with a general A: conic needs a symmetric or skew-coupled A, "
            "fixed_point iterates on contact blocks"
        )
    return [
        "ssn",
        "conic",
        "homotopy",
    ], "a fixed convex set: fixed_point iterates on contact blocks"


def parse_tols(text: str) -> list[float]:
    """'1e-6,1e-8' → [1e-6, 1e-8] (positive finite numbers)."""
    try:
        tols = [float(s) for s in text.split(",")]
    except ValueError:
        tols = []
    if not tols or not all(math.isfinite(t) and 0 < t < 1 for t in tols):
        raise SceneError("--tols", text, "a comma-separated list of tolerances in (0, 1)")
    return sorted(set(tols), reverse=True)


# ------------------------------------------------------------------ the study
def _solve(plugin: Any, model: Any, solver: str, tol: float) -> tuple[vi_core.Solution, float]:
    """Solve the scene's problem (`pipeline.solve_model`: with the plug-in's outer iteration)
    and return (solution, tracemalloc peak in MB during the solve)."""
    tracemalloc.start()
    try:
        sol = pipeline.solve_model(plugin, model, method=solver, tol=tol)
        peak = tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()
    return sol, peak


def run_case(scene: Scene, level: int, solver: str, tols: list[float]) -> list[tuple]:
    """One study task: build `scene` at `level` and solve it with `solver` at every tolerance,
    BLAS single-threaded (serial and Dask runs then give the same numbers).

    Returns [(record, solution)] per tolerance; a failure other than bad input is one failed
    record per tolerance with its cause (`error`), so a study goes on without it."""
    plugin = registry.for_scene(scene)
    exact_errors = getattr(plugin, "exact_errors", lambda model, sol: None)
    with threadpool_limits(1):
        try:
            model = plugin.build(scene, level)
            if solver == "conic" and model.vi.structure == "general":
                raise SceneError("--solvers", solver, "ssn or homotopy: A of this scene is general")
            out = []
            for tol in tols:
                sol, peak = _solve(plugin, model, solver, tol)
                out.append(
                    (_record(plugin, model, solver, tol, sol, peak, exact_errors(model, sol)), sol)
                )
            return out
        except SceneError:
            raise
        except Exception as err:  # a failed task is a failed row, with its cause
            cause = f"{type(err).__name__}: {err}"
            return [({"level": level, "solver": solver, "tol": tol, "converged": False,
                      "err": None, "error": cause}, None) for tol in tols]  # fmt: skip


def run_study(
    scene: Scene,
    levels: list[int],
    solvers: list[str],
    tols: list[float],
    progress: bool = True,
    plugin: Any = None,
    client: Any = None,
    solutions: dict | None = None,
) -> dict:
    """Solve every (level, solver, tol) and measure errors; returns the study.json content.

    client : a `dask.distributed.Client`: the (level, solver) tasks run on its workers
        (`run_case`); None runs them one after the other here. Every number but the times and
        memory peaks is the same either way.
    solutions : a dict to receive the solutions, {(level, solver, tol): Solution or None}
        (`mixvi study --vtu` writes the results of the tightest tolerance from them)."""
    plugin = registry.for_scene(scene) if plugin is None else plugin
    needs(plugin, "mixvi study", *STUDY_NEEDS)
    tols = sorted(tols, reverse=True)
    cases = [(level, solver) for level in levels for solver in solvers]
    bar = progress_bar(total=len(cases) * len(tols), shown=progress, unit="solve")
    done: dict[tuple, list[tuple]] = {}
    try:
        if client is None:
            for level, solver in cases:
                bar.set_description(f"level {level} {solver}")
                # in a worker thread: a signal acts even inside compiled code
                done[level, solver] = signals.interruptible(run_case, scene, level, solver, tols)
                bar.update(len(tols))
        else:
            from dask.distributed import as_completed

            futures = {
                client.submit(run_case, scene, level, solver, tols, pure=False): (level, solver)
                for level, solver in cases
            }
            for future in as_completed(futures):
                done[futures[future]] = future.result()  # bad input (SceneError) raised here
                bar.update(len(tols))
    finally:
        bar.close()
    records, runs = [], {}
    for level, solver in cases:
        for record, sol in done[level, solver]:
            records.append(record)
            runs[level, solver, record["tol"]] = sol
    if solutions is not None:
        solutions.update(runs)
    solved = [r for r in records if "error" not in r]
    exact = bool(solved) and all(r["err"] is not None for r in solved)
    if not exact:  # the finest level is the reference (module docstring)
        signals.interruptible(
            _reference_errors, plugin, scene, records, runs, max(levels), tols[-1]
        )
        for r in records:
            if r["level"] == max(levels):
                r["reference"] = True
    ok = [r for r in records if r.get("err") is not None]
    norms = getattr(plugin, "EXACT_NORMS", plugin.NORMS) if exact else plugin.NORMS
    return {
        "scene": scene.name,
        "plugin": plugin.NAME,
        "norms": list(norms),
        "reference": "exact" if exact else f"level {max(levels)}",
        "records": records,
        # against the finest level, that level's own error is rounding: fit the levels below it
        "rates": fit_rates(ok, None if exact else max(levels), norms),
    }


def _record(plugin, model, solver: str, tol: float, sol, peak: float, err: dict | None) -> dict:
    return {
        "level": model.level,
        "h": float(plugin.mesh_size(model)),
        "unknowns": model.vi.n + model.vi.m,
        "solver": solver,
        "tol": tol,
        "time_s": sol.time,
        "iterations": sol.iterations,
        "err": err,
        "converged": sol.converged,
        "residual": sol.residual,
        "peak_mem_mb": peak,
    }


def _reference_errors(
    plugin, scene: Scene, records: list[dict], runs: dict, finest: int, tight: float
) -> None:
    """Fill `err` of every record against its solver's finest-level, tightest-tol solution
    (models rebuilt here: tasks return solutions, not models)."""
    models = {}

    def model(level):
        if level not in models:
            with threadpool_limits(1):
                models[level] = plugin.build(scene, level)
        return models[level]

    for r in records:
        ref = runs.get((finest, r["solver"], tight))
        sol = runs.get((r["level"], r["solver"], r["tol"]))
        if "error" in r or ref is None or sol is None:
            r["err"] = None  # the failed task, or its reference, has no error to measure
            continue
        with threadpool_limits(1):
            r["err"] = plugin.reference_errors(model(r["level"]), sol, model(finest), ref)


def fit_rates(records: list[dict], below: int | None = None, norms=None) -> dict:
    """Per solver: slope of log err against log h over the last three levels with a positive
    error at the tightest tolerance (None if fewer than two such levels); with `below`, only
    levels below it count (the reference level when errors are taken against the finest);
    `norms` default: the error keys of the first record."""
    if not records:
        return {}
    norms = list(records[0]["err"]) if norms is None else norms
    tight = min(r["tol"] for r in records)
    if below is not None:
        records = [r for r in records if r["level"] < below]
    rates = {}
    for solver in dict.fromkeys(r["solver"] for r in records):
        rows = sorted(
            (r for r in records if r["solver"] == solver and r["tol"] == tight),
            key=lambda r: r["level"],
        )
        rates[solver] = {}
        for k in norms:
            pts = [(r["h"], r["err"][k]) for r in rows if r["err"][k] > 0][-RATE_LEVELS:]
            if len(pts) < 2:
                rates[solver][k] = None
                continue
            h, e = np.log(np.array(pts)).T  # (p,) each
            rates[solver][k] = float(np.polyfit(h, e, 1)[0])
    return rates


# ------------------------------------------------------------------ reporting
def table(result: dict) -> str:
    """The records as a text table, with the observed rate against the previous level."""
    head = (
        f"{'level':>5} {'h':>9} {'unknowns':>9} {'solver':>9} {'tol':>7} {'it':>4} "
        f"{'time[s]':>8} {'mem[MB]':>8} " + " ".join(f"{k:>9} {'rate':>5}" for k in result["norms"])
    )
    lines = [head]
    prev: dict = {}
    for r in result["records"]:
        if r.get("err") is None:
            why = r.get("error", "no reference solution (its task failed)")
            lines.append(
                f"{r['level']:>5} {'':>9} {'':>9} {r['solver']:>9} {r['tol']:7.0e} failed: {why}"
            )
            continue
        key = (r["solver"], r["tol"])
        cells = []
        for k in result["norms"]:
            e, p = r["err"][k], prev.get(key)
            if r.get("reference"):
                cells.append(f"{e:9.2e} {'ref':>5}")
                continue
            ok = p is not None and e > 0 and p["err"][k] > 0
            rate = math.log(p["err"][k] / e) / math.log(p["h"] / r["h"]) if ok else None
            cells.append(f"{e:9.2e} {rate:5.2f}" if rate is not None else f"{e:9.2e} {'':>5}")
        prev[key] = r
        lines.append(
            f"{r['level']:>5} {r['h']:9.3e} {r['unknowns']:>9} {r['solver']:>9} "
            f"{r['tol']:7.0e} {r['iterations']:>4} {r['time_s']:8.2f} {r['peak_mem_mb']:8.1f} "
            + " ".join(cells)
        )
    ref = result["reference"]
    lines.append(
        f"errors against: {ref}"
        + ("" if ref == "exact" else " (its rows, 'ref': no rate, not in rates or figures)")
    )
    for solver, rates in result["rates"].items():
        txt = ", ".join(f"{k} {v:.2f}" if v is not None else f"{k} -" for k, v in rates.items())
        lines.append(f"rates ({solver}, last {RATE_LEVELS} levels, tightest tol): {txt}")
    return "\n".join(lines)


def write_outputs(result: dict, folder, series: tuple | None = None) -> None:
    """study.json and the two figures, committed into the claimed output folder; with
    `series` = (plugin, scene, solutions) also the results per solver and level
    (`write_series`)."""
    from problems.output.study_plots import plot_errors_vs_h, plot_errors_vs_time

    with folder.staging() as tmp:
        (tmp / "study.json").write_text(json.dumps(result, indent=2) + "\n")
        plot_errors_vs_h(result, tmp / "errors_vs_h.png")
        plot_errors_vs_time(result, tmp / "errors_vs_time.png")
        if series is not None:
            write_series(*series, tmp)


def write_series(plugin: Any, scene: Scene, solutions: dict, tmp: Path) -> list[str]:
    """`--vtu`: each level's results at the tightest tolerance (the plug-in's postprocess:
    VTU files, contact.csv, plots) in SOLVER/level_L/, and per solver a ParaView collection
    SOLVER.pvd over the levels (time = level); returns the collections written. Failed cases
    have no solution and are left out."""
    tight = min(t for _, _, t in solutions)
    series: dict[str, list] = {}
    for (level, solver, tol), sol in sorted(solutions.items()):
        if tol != tight or sol is None:
            continue
        sub = Path(solver) / f"level_{level}"
        (tmp / sub).mkdir(parents=True)
        with threadpool_limits(1):
            # the build in a worker thread (signals); the writes in this one, never in a worker
            model = signals.interruptible(plugin.build, scene, level)
            files = plugin.postprocess(model, sol, tmp / sub).get("files", [])
        series.setdefault(solver, []).extend(
            vtu_datasets(level, [(sub / f).as_posix() for f in files])
        )
    for solver, datasets in series.items():
        write_pvd(tmp / f"{solver}.pvd", datasets)
    return [f"{solver}.pvd" for solver in series]


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="mixvi study", description=__doc__.splitlines()[0])
    p.add_argument("scene", help="scene file or shipped name")
    p.add_argument("--levels", default="0..3", help="levels A..B (default 0..3)")
    p.add_argument(
        "--solvers",
        default=None,
        help="comma list of " + ", ".join(SOLVERS) + " (default: those that can run the scene)",
    )
    p.add_argument("--tols", default="1e-6,1e-8,1e-10", help="comma list of tolerances")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a scene value")
    p.add_argument("--out", default=None, help="output directory (default out/SCENE_study)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--vtu",
        action="store_true",
        help="also write each level's results at the tightest tolerance into SOLVER/level_L/ "
        "and per solver a ParaView collection SOLVER.pvd over the levels",
    )
    options.add_run_options(p)
    return p


# a Dask worker process beyond the memory model's own base (`resources.MEMORY_MODEL`, 115 MB):
# 175 MB resident with mixvi's imports in a LocalCluster worker against 115 MB (measured once)
DASK_WORKER_BYTES = 60e6


def worker_count(
    asked: int, per_worker: float, cases: int, command: str = "mixvi study"
) -> tuple[int, str | None]:
    """The local workers to start for `--workers asked`: at most the cores, as many as fit in
    the memory available now at `per_worker` bytes each (at least one) and no more than the
    cases; with the one-line notice (of `command`) to print when that is fewer than asked
    (else None)."""
    _, available = resources.memory()
    fit = max(1, int(available // per_worker))
    n = min(asked, cores(), fit, cases)
    if n == asked:
        return n, None
    why = (
        f"{cores()} cores, {resources.gb(available)} available at up to "
        f"{resources.gb(per_worker)} per worker, {cases} case(s)"
    )
    return n, f"{command}: --workers {asked} lowered to {n} ({why})"


def _end_workers() -> None:
    """After a signal: kill the local cluster's worker processes (this process's children) and
    silence Dask's log. A worker inside compiled code does not stop when asked: the cluster's
    close waited 4 s for it and logged two warnings after the signal."""
    import logging
    import multiprocessing

    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    for child in multiprocessing.active_children():
        child.kill()


@contextmanager
def _client(args: argparse.Namespace) -> Iterator[Any]:
    """A Dask client for --workers / --scheduler (None without either: a serial study)."""
    if args.workers is None and args.scheduler is None:
        yield None
        return
    option = "--workers" if args.workers is not None else "--scheduler"
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise SceneError(
            option, args.workers or args.scheduler, 'available after: pip install -e ".[dask]"'
        ) from None
    if args.workers is not None:
        with (
            LocalCluster(
                n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=":0"
            ) as cluster,
            Client(cluster) as client,
        ):
            try:
                yield client
            except KeyboardInterrupt:  # a signal: end the workers now (`_end_workers`)
                _end_workers()
                raise
        return
    try:
        client = Client(args.scheduler, timeout=30)
    except (OSError, ValueError, TimeoutError) as err:
        raise SceneError(
            "--scheduler", args.scheduler, f"a reachable Dask scheduler ({err})"
        ) from None
    with client:
        yield client


def study_main(argv: list[str] | None = None) -> int:
    """Entry point of `mixvi study`: 0 if every solve converged, 1 if not, 2 on bad input."""
    args = parser().parse_args(argv)
    a, b = level_range(args.levels)
    solvers = None if args.solvers is None else options.names(args.solvers, "--solvers", SOLVERS)
    tols = parse_tols(args.tols)
    scene = load_scene(args.scene, args.set or [])
    plugin = registry.for_scene(scene)
    needs(plugin, "mixvi study", *STUDY_NEEDS)
    sizes = resources.check_levels(plugin, scene, (a, b), "--levels", args.levels, args.force)
    with threadpool_limits(1):
        can, why = applicable(signals.interruptible(plugin.build, scene, a))
    if solvers is None:
        solvers = can
    for s in solvers:
        if s not in can:
            raise SceneError("--solvers", s, f"one of {', '.join(can)} for this scene ({why})")
    if args.workers is not None:  # 256 workers on 2 cores were killed for memory
        per_worker = sizes.estimate(b).upper_bytes + DASK_WORKER_BYTES
        args.workers, note = worker_count(args.workers, per_worker, (b - a + 1) * len(solvers))
        if note:
            print(note, file=sys.stderr)
    out = Path(args.out) if args.out else Path("out") / f"{scene.name}_study"
    inputs = scene.files()
    with output_folder(out, "--out", overwrite=args.overwrite, inputs=inputs) as folder:
        levels = list(range(a, b + 1))
        solutions: dict | None = {} if args.vtu else None
        with _client(args) as client:
            result = run_study(
                scene, levels, solvers, tols, not args.no_progress, plugin, client, solutions
            )
        write_outputs(result, folder, (plugin, scene, solutions) if args.vtu else None)
    print(table(result))
    print(f"wrote {out}/")
    return 0 if all(r["converged"] for r in result["records"]) else 1
