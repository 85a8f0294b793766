"""`mixvi solve` of a scene with a `[load_path]`: the steps solved in order
(`problems.pipeline.load_path`), each step's files under steps/NNNN/, the collection steps.pvd
(time = t), the last step's files beside summary.json (with `steps: [...]`), a progress bar per
step on a terminal and a per-step table on the console (docs/load_paths.md)."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

from tqdm import tqdm

import problems.pipeline as pipeline
from problems.output.collection import vtu_datasets, write_pvd
from problems.output.files import OutputFolder, jsonable
from problems.pipeline.load_path import Step, solve_path

COUNTS = ("nodes", "stick", "slip", "open")  # contact counts kept per step


def run(
    args: argparse.Namespace,
    t0: float,
    loaded: pipeline.Loaded,
    level: int,
    folder: OutputFolder,
    console_summary: Callable[[dict, list[dict]], list[str]],
) -> int:
    """Solve the load path of `loaded` into `folder`; exit status 0 if every step converged.
    `console_summary(summary, levels)` gives the lines about the last step (mixvi solve's)."""
    plugin = loaded.plugin
    ts = loaded.spec.load_path.values()
    datasets: list[tuple[float, str]] = []
    with folder.staging() as tmp:
        bar = tqdm(total=len(ts), unit="step", disable=None, desc=loaded.scene.name, leave=False)

        def write_step(step: Step) -> None:
            sub = Path("steps") / f"{step.index:04d}"
            (tmp / sub).mkdir(parents=True)
            write = getattr(plugin, "step_output", plugin.postprocess)
            extras = write(step.model, step.solution, tmp / sub)
            c = extras.get("contact") or {}
            if c:
                step.record["contact"] = {k: c[k] for k in COUNTS if k in c}
            files = [(sub / f).as_posix() for f in extras.get("files", [])]
            datasets.extend(vtu_datasets(step.t, files))
            bar.set_postfix(t=f"{step.t:.4g}", newton=step.solution.iterations)
            bar.update(1)

        try:
            path = solve_path(
                loaded,
                level,
                args.solver,
                args.tol,
                args.cold,
                args.linear_solver,
                on_step=write_step,
            )
        finally:
            bar.close()
        run_ = path.run
        model, sol = run_.model, run_.solution
        extras = plugin.postprocess(model, sol, tmp)
        write_pvd(tmp / "steps.pvd", datasets)
        warnings = model.warnings + sol.warnings + extras.get("warnings", [])
        if not path.incremental:
            warnings.append(
                f"plug-in {plugin.NAME!r} does not declare `incremental`: every load step is "
                "solved in total form (no history; the same as solving each t on its own)"
            )
        stopped = len(path.steps) < len(ts)
        if stopped:
            warnings.append(
                f"load step {len(path.steps)} (t = {path.steps[-1]['t']:.6g}) did not converge: "
                f"the path stopped there ({len(ts) - len(path.steps)} steps not solved)"
            )
        summary = {
            **pipeline.info(loaded, run_),
            **extras,
            "files": sorted([*extras.get("files", []), "steps.pvd"]),
            "load_path": {
                "t": ts,
                "form": "incremental" if path.incremental else "total",
                "warm_start": "cold" if args.cold else "previous step",
                "steps_solved": len(path.steps),
            },
            "steps": path.steps,
            "scaling": pipeline.scaling_summary(model),
            "solver_info": sol.info,
            "warnings": warnings,
            "nested": run_.nested,
            "time_s": {
                "build": run_.time_build,
                "solve": run_.time_solve,
                "total": time.perf_counter() - t0,
            },
        }
        (tmp / "summary.json").write_text(json.dumps(jsonable(summary), indent=2) + "\n")
    last = pipeline.level_record(model.level, model, sol)
    for line in console_summary(summary, [last]):
        print(line)
    for line in step_table(summary):
        print(line)
    out = folder.path
    print(f"  wrote {out}/: summary.json, {', '.join(summary['files'])} and steps/")
    return 0 if path.converged and not stopped else 1


def step_table(summary: dict) -> list[str]:
    """The per-step lines of the console: t, Newton steps, residual, contact counts, time."""
    steps = summary["steps"]
    lp = summary["load_path"]
    newton = sum(s["iterations"] for s in steps)
    out = [
        f"  load path: {len(steps)} of {len(lp['t'])} steps, {lp['form']} form, each "
        f"warm-started from {lp['warm_start']}; {newton} Newton steps in all "
        "(the state above is the last step's)",
        f"  {'step':>5} {'t':>9} {'Newton':>6} {'residual':>9} {'stick':>6} {'slip':>6} "
        f"{'open':>6} {'time [s]':>9}",
    ]
    for s in steps:
        c = s.get("contact", {})
        counts = " ".join(
            f"{c[k]:>6}" if k in c else f"{'-':>6}" for k in ("stick", "slip", "open")
        )
        mark = "" if s["converged"] else "  NOT converged"
        out.append(
            f"  {s['step']:>5} {s['t']:>9.4g} {s['iterations']:>6} {s['residual']:>9.1e} "
            f"{counts} {s['time_s']['build'] + s['time_s']['solve']:>9.2f}{mark}"
        )
    return out
