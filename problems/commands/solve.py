"""`mixvi solve`: build a scene, solve it (nested iteration for ssn), write the results."""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import problems.pipeline as pipeline
from problems.errors import SceneError
from problems.output import signals
from problems.output.collection import vtu_datasets, write_pvd
from problems.output.files import output_folder
from problems.pipeline import written
from problems.plugins.contact.reports import PATCH_DEFECT_LIMIT

from . import engine, load_path, resources
from .options import ACCURACY, DEFAULT_SCENE, solver_options
from .progress import bar as progress_bar
from .progress import newton_status


def cmd_solve(args: argparse.Namespace) -> int:
    """Solve one scene; exit status 0 converged, 1 not converged or (without --allow-defect) a
    contact interface whose mortar patch defect exceeds PATCH_DEFECT_LIMIT."""
    t0 = time.perf_counter()
    eng = engine.start(args.engine)
    if isinstance(args.accuracy, float) and eng.name != "serial":
        raise SceneError("--accuracy", str(args.accuracy), "a preset name with --engine petsc")
    if args.contact_zone and not isinstance(args.accuracy, float):
        raise SceneError(
            "--contact-zone",
            True,
            "only with --accuracy NUMBER (adaptive refinement), e.g. --accuracy 1e-3",
        )
    if isinstance(args.accuracy, float):  # adaptive refinement to that estimate
        from .adapt import run

        _adaptive_options(args)
        return run(args, load(args), args.accuracy)
    # on every rank of --engine petsc, refused on all of them if on one (the memory check
    # reads what is available when each rank looks); then the ranks on one host together
    loaded, level, estimate, option = eng.unanimous(_checked, args)
    if not args.force and eng.size > 1:  # one process: `_checked` has checked its memory
        eng.unanimous(_fits_host, eng, estimate, option)
    out = Path(args.out) if args.out else Path("out") / loaded.scene.name
    inputs = loaded.scene.files()
    with engine.running(eng):
        if not eng.writes:  # ranks above 0 of --engine petsc: the same solve, no output
            if not eng.agree(None):
                print(f"mixvi: rank {eng.rank}: output folder refused on rank 0", file=sys.stderr)
                return 2
            return eng.guarded(_solve_unwritten, args, loaded, level)
        with ExitStack() as stack:
            try:
                folder = stack.enter_context(
                    output_folder(out, "--out", overwrite=args.overwrite, inputs=inputs)
                )
            except BaseException:
                eng.agree(False)  # every rank ends, none waits on rank 0
                raise
            eng.agree(True)
            return eng.guarded(_solve, args, t0, loaded, level, folder)


def _adaptive_options(args: argparse.Namespace) -> None:
    """SceneError on an option that `--accuracy NUMBER` would otherwise ignore or fail on
    only after its first cycle: --level, --cold and --write-levels (the adaptive loop starts
    from the scene's level-0 mesh, chooses its own meshes and starts each from the previous
    one), an unknown --solver."""
    why = (
        f"not with --accuracy {args.accuracy:g} (adaptive refinement starts from the scene's "
        f"level-0 mesh and chooses its meshes itself); drop it, or give a preset --accuracy "
        f"({', '.join(ACCURACY)})"
    )
    for option, value in (
        ("--level", args.level),
        ("--cold", args.cold or None),
        ("--write-levels", args.write_levels or None),
    ):
        if value is not None:
            raise SceneError(option, value, why)
    _check_solver(args.solver)


def _check_solver(method: str | None) -> None:
    """SceneError on a --solver that is not one of `pipeline.SOLVERS` (None: not given)."""
    if method is not None and method not in pipeline.SOLVERS:
        raise SceneError("--solver", method, "one of " + ", ".join(pipeline.SOLVERS))


def _checked(
    args: argparse.Namespace,
) -> tuple[pipeline.Loaded, int, resources.Estimate, str]:
    """The scene loaded and validated, the level to solve, its estimate and the option that
    gave the level (an --accuracy preset fills in --level and --tol where they were not
    given); SceneError on a bad solver, a level out of range or one that does not fit in the
    memory available now."""
    if args.accuracy is not None:  # a preset fills in what was not given explicitly
        level, tol = ACCURACY[args.accuracy]
        args.level = level if args.level is None else args.level
        args.tol = tol if args.tol is None else args.tol
    loaded = load(args)
    scene, plugin = loaded.scene, loaded.plugin
    _check_solver(args.solver)
    level, option = resources.requested_level(args.level, plugin, scene)
    sizes = resources.check_levels(
        plugin, scene, (level, level), option, str(level), args.force, args.linear_solver
    )
    return loaded, level, sizes.estimate(level), option


def _fits_host(eng: engine.Engine, e: resources.Estimate, option: str) -> None:
    """Refuse (SceneError on `option`) the level of `e` if the ranks on this rank's host
    together need more than the host has available (each builds the level): their upper
    estimates summed against the smallest reading of the host's memory available now. Every
    rank of `eng` calls it (`Engine.on_host` is collective)."""
    here = eng.on_host((e.upper_bytes, resources.host_memory()[1]))
    uppers, available = zip(*here, strict=True)
    resources.check_host(e, list(uppers), min(available), option, str(e.level))


def _solve_unwritten(args, loaded: pipeline.Loaded, level: int) -> int:
    """What a rank above 0 of `--engine petsc` runs: the solve rank 0 runs in `_solve` (the
    same collective calls in the same order), nothing written but a load path's steps in a
    temporary folder; exit status 0 converged, else 1 (rank 0 adds the patch defect's)."""
    if loaded.spec.load_path is not None:
        with tempfile.TemporaryDirectory() as tmp:
            path, _ = load_path.solve_steps(args, loaded, level, Path(tmp))
        return 0 if path.converged else 1
    run = pipeline.solve(loaded, level, **solver_options(args))
    return 0 if run.solution.converged else 1


def _solve(args, t0, loaded: pipeline.Loaded, level, folder) -> int:
    """Solve `loaded` into `folder`: one state (the nested iteration's coarse levels under
    levels/L/ with --write-levels), or every step of its load path (under steps/NNNN/); the
    last state's files, the collection (.pvd), summary.json and the console lines. Exit
    status 0 converged, 1 not (a load path: any step) or a mortar patch defect above the
    limit without --allow-defect."""
    out = folder.path
    path = None  # the load path's steps, if the scene has one
    solved = None
    if loaded.spec.load_path is None:
        # the solve before the staging folder exists: a run ended mid-solve by a signal it
        # cannot act on in time (a rank of --engine petsc inside a PETSc call, which holds
        # the GIL, is killed by mpiexec a moment after its SIGTERM) leaves no staged files
        solved = _solve_levels(args, loaded, level)
    with folder.staging() as tmp:
        if solved is None:  # one solve per load step, each step's files written as it ends
            path, datasets = load_path.solve_steps(args, loaded, level, tmp)
            run, coarse = path.run, {}
        else:
            run, coarse_states = solved
            coarse = _write_levels(loaded.plugin, coarse_states, tmp)
        model, sol, nested = run.model, run.solution, run.nested
        extras, files, warnings = written.state_files(loaded, run, tmp)
        if path is None:
            per_level = [*sorted(coarse.items()), (model.level, files)]
            datasets = [d for lev, fs in per_level for d in vtu_datasets(lev, fs)]
            files += written.collection(tmp, datasets, "results.pvd")
            before, after = {}, {"condition_estimate": sol.info.get("condition_estimate")}
        else:
            write_pvd(tmp / "steps.pvd", datasets)
            files = sorted([*files, "steps.pvd"])
            warnings += load_path.path_warnings(loaded, path)
            before, after = load_path.entries(args, loaded, path), {}
        total = time.perf_counter() - t0
        summary = written.summary_of(loaded, run, extras, files, warnings, before, after, total)
        if coarse:
            summary["levels_written"] = {str(lev): fs for lev, fs in sorted(coarse.items())}
        written.write_summary(tmp, summary)
    last = [pipeline.level_record(model.level, model, sol, run.tol)]
    for line in console_summary(summary, last if path is not None else nested or last):
        print(line)
    if path is not None:
        for line in load_path.step_table(summary):
            print(line)
    steps = "" if path is None else " and steps/"
    print(f"  wrote {out}/: {', '.join(['summary.json', *files])}{steps}")
    if coarse:
        print(f"  and the coarse levels' results in {out}/levels/{{{','.join(map(str, coarse))}}}/")
    elif args.write_levels and path is None:
        print(
            "  note: --write-levels: no coarse level was solved (only the nested ssn solve "
            "of a level above 0 has them)"
        )
    defect = summary.get("contact", {}).get("mortar_patch_defect")
    if defect is not None and defect > PATCH_DEFECT_LIMIT and not args.allow_defect:
        print("  exit status 1: mortar patch defect above the limit (--allow-defect to accept)")
        return 1
    if path is not None:
        return 0 if path.converged else 1
    return 0 if sol.converged else 1


def _solve_levels(
    args, loaded: pipeline.Loaded, level: int
) -> tuple[pipeline.Run, list[tuple[Any, Any]]]:
    """One state, with a progress bar over the levels of the nested iteration (on a terminal
    only); with --write-levels each coarse level's model and solution (the second value, for
    `_write_levels` once the solve is done), else none."""
    coarse: list[tuple[Any, Any]] = []  # (model, solution) of each coarse level, in order
    bar = progress_bar(total=level + 1, unit="level", desc="solving", leave=False)

    def on_level(model, sol) -> None:  # a coarse level is solved
        bar.update(1)
        if args.write_levels:
            coarse.append((model, sol))

    with bar:  # the work in a worker thread, on_level in this one (signals module)
        run = signals.interruptible(
            pipeline.solve,
            loaded,
            level,
            **solver_options(args),
            on_level=signals.in_main(on_level),
            on_step=newton_status(bar),  # the Newton steps of the level being solved
        )
        bar.update(bar.total - bar.n)
        bar.refresh()  # the full bar is shown before it is cleared, however fast the last level
    return run, coarse


def _write_levels(plugin, coarse: list[tuple[Any, Any]], tmp: Path) -> dict[int, list[str]]:
    """Each coarse level's results under tmp/levels/L/; its files by level."""
    files: dict[int, list[str]] = {}
    for model, sol in coarse:
        sub = Path("levels") / str(model.level)
        (tmp / sub).mkdir(parents=True)
        written = plugin.postprocess(model, sol, tmp / sub).get("files", [])
        files[model.level] = [(sub / f).as_posix() for f in written]
    return files


def _vec(v) -> str:
    return "(" + ", ".join(f"{x + 0.0:.4g}" for x in v) + ")"  # + 0.0: no "-0"


def console_summary(summary: dict, levels: list[dict]) -> list[str]:
    """What `mixvi solve` prints: a header, one row per level solved (unknowns, Newton steps,
    time, the tolerance it was solved to, residual), the outcome, the contact line (stick/slip
    counts and lengths, total force on the slave body), the electrical contact's fixed point
    where there is one, the time and the warnings — no raw dicts."""
    dofs = summary["dofs"]
    out = [
        f"{summary['scene']} (plug-in {summary['plugin']}, solver {summary['solver']}, "
        f"tol {summary['tol']:g}), level {summary['level']}: "
        + " + ".join(f"{n:,} {k}" for k, n in dofs.items())
        + f" = {sum(dofs.values()):,} unknowns"
    ]
    info = summary.get("solver_info") or {}
    fixed_point = summary["solver"] == "fixed_point"  # iterations: fixed-point, not Newton
    steps = "iterations" if fixed_point else "Newton steps"
    out.append(
        f"  {'level':>5} {'unknowns':>10} {steps:>12} {'time [s]':>9} {'tol':>7} {'residual':>9}"
    )
    for r in levels:
        out.append(
            f"  {r['level']:>5} {r['unknowns']:>10,} {r['iterations']:>12} "
            f"{r['time_s']:>9.2f} {r['tol']:>7.0e} {r['residual']:>9.1e}"
        )
    if len(levels) > 1:
        out.append(
            "  (nested iteration: each level starts from the one below; the coarser ones are "
            f"solved to max(tol, {pipeline.NESTED_TOL:.0e}))"
        )
    identity = ""
    if summary.get("lemma_4_2") is not None:
        identity = f"; Lemma 4.2 identity defect {summary['lemma_4_2']:.1e}"
    elif summary.get("complementarity") is not None:
        identity = f"; complementarity defect {summary['complementarity']:.1e}"
    verdict = "converged" if summary["converged"] else "NOT converged"
    if fixed_point:
        rate = info.get("contraction")
        steps = (
            f"fixed-point iterations g ← F·λ_n (contraction {_num(rate, '.3g')}, "
            f"{sum(info.get('inner_iterations', []))} {info.get('inner')} Newton steps inside)"
        )
    out.append(
        f"  {verdict} in {summary['iterations']} {steps}, residual "
        f"{summary['residual']:.2e}{identity}"
    )
    c = summary.get("contact")
    if c:
        parts = [f"{c['nodes']} nodes", f"stick {c['stick']}", f"slip {c['slip']}"]
        if c.get("open"):
            parts.append(f"open {c['open']}")
        if c.get("ambiguous"):
            parts.append(f"ambiguous {c['ambiguous']}")
        for measure, unit in (("length", "m"), ("area", "m²")):  # a 2D curve, a 3D surface
            if f"stick_{measure}" in c:
                parts[1] += f" ({c[f'stick_{measure}']:.4g} {unit})"
                parts[2] += f" ({c[f'slip_{measure}']:.4g} {unit})"
        bare = c.get("counts", {}).get("no_multiplier")
        if bare:
            parts.append(f"{bare} node{'s' if bare > 1 else ''} without multiplier")
        line = "  contact: " + ", ".join(parts)
        if "force_on_slave" in c:
            unit = c.get("force_units", "N/m").split(" ")[0]
            line += f"; force on the slave {_vec(c['force_on_slave'])} {unit}"
        if c.get("mortar_patch_defect") is not None:
            line += f"; mortar patch defect {c['mortar_patch_defect']:.1e}"
        out.append(line)
    el = summary.get("electrical") or {}
    fp = el.get("fixed_point")
    if fp:
        line = (
            f"  electrical contact ({el['kind']}): {fp['iterations']} fixed-point steps on k, "
            f"{'converged' if fp['converged'] else 'NOT converged'}, contraction "
            f"{_num(fp['contraction'], '.3g')}, law defect {_num(el['law_defect'], '.1e')}"
        )
        if el.get("potential_gap_touching") is not None:
            line += f"; potential jump where touching {el['potential_gap_touching']:.6g} V"
        out.append(line)
    if "krylov_iterations" in info:
        fb = info["fallback"]
        out.append(
            "  linear solver amg: Krylov iterations per Newton step "
            f"{info['krylov_iterations']}, {len(fb)} direct fallback(s)"
            + "".join(f"; step {f['step']}: {f['reason']}" for f in fb)
        )
    if "estimate" in summary:  # the plug-in's a posteriori estimate
        est = summary["estimate"]
        out.append(f"  error estimate {est['total']:.3e} (relative {est['relative']:.2e})")
    t = summary["time_s"]
    out.append(f"  time {t['total']:.2f} s (build {t['build']:.2f} s, solve {t['solve']:.2f} s)")
    out += [f"  warning: {w}" for w in summary["warnings"]]
    out += [f"  note: {n}" for n in summary.get("notes", [])]
    return out


def _num(x: float | None, fmt: str) -> str:
    """`x` formatted, or 'n/a' where there is none (a contraction after one step)."""
    return "n/a" if x is None else format(x, fmt)


def load(args: argparse.Namespace) -> pipeline.Loaded:
    """The scene (with its --set overrides), validated by its plug-in's scene model before
    anything is built; migration notices go to stderr (one line each)."""
    loaded = pipeline.load(args.scene or DEFAULT_SCENE, args.set or [])
    for notice in loaded.notices:
        print(f"mixvi: note: {notice}", file=sys.stderr)
    return loaded
