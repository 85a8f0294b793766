"""`mixvi solve` of a scene with a `[load_path]` (the command body: `problems.commands.solve`):
the steps solved in order (`problems.pipeline.load_path`), each step's files under
steps/NNNN/, the rows of the collection steps.pvd (time = t), summary.json's `load_path` and
`steps` entries and warnings, a progress bar per step on a terminal and a per-step table on
the console (docs/load_paths.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

import problems.pipeline as pipeline
from problems.output import signals
from problems.output.collection import vtu_datasets
from problems.pipeline.load_path import PathRun, Step, solve_path

from .options import solver_options
from .progress import bar as progress_bar

STARTS = {  # the console's words for load_path.warm_start
    "previous step": "warm-started from the previous step",
    "cold": "solved from zero (--cold)",
    "none": "solved from zero ({solver} takes no warm start)",
}
COUNTS = ("nodes", "stick", "slip", "open")  # contact counts kept per step


def solve_steps(
    args: argparse.Namespace, loaded: pipeline.Loaded, level: int, tmp: Path
) -> tuple[PathRun, list[tuple[float, str]]]:
    """Solve the load path of `loaded`, each step's files under tmp/steps/NNNN/ as it is
    solved (with a progress bar per step on a terminal); the path and the rows of steps.pvd."""
    plugin = loaded.plugin
    datasets: list[tuple[float, str]] = []
    n = len(loaded.spec.load_path.values())
    bar = progress_bar(total=n, unit="step", desc=f"solving {loaded.scene.name}", leave=False)

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
        bar.set_postfix(t=f"{step.t:.4g}", newton=step.solution.iterations, refresh=False)
        bar.update(1)
        bar.refresh()  # every step is shown, however fast (tqdm skips updates within 0.1 s)

    with bar:  # the work in a worker thread, each step's writes in this one (signals module)
        path = signals.interruptible(
            solve_path, loaded, level, **solver_options(args), on_step=signals.in_main(write_step)
        )
    return path, datasets


def stopped(loaded: pipeline.Loaded, path: PathRun) -> bool:
    """The path stopped at a step that did not converge (later steps not solved)."""
    return len(path.steps) < len(loaded.spec.load_path.values())


def path_warnings(loaded: pipeline.Loaded, path: PathRun) -> list[str]:
    """The load path's warnings: the total form, a stop before the end."""
    ts = loaded.spec.load_path.values()
    out = []
    if not path.incremental:
        out.append(
            f"plug-in {loaded.plugin.NAME!r} does not declare `incremental`: every load step is "
            "solved in total form (no history; the same as solving each t on its own)"
        )
    if stopped(loaded, path):
        out.append(
            f"load step {len(path.steps)} (t = {path.steps[-1]['t']:.6g}) did not converge: "
            f"the path stopped there ({len(ts) - len(path.steps)} steps not solved)"
        )
    return out


def warm_start(args: argparse.Namespace, path: PathRun) -> str:
    """summary.json's load_path.warm_start: "previous step" (ssn, the fixed point), "cold"
    (--cold) or "none" (conic, homotopy and auto solve every step from zero)."""
    if args.cold:
        return "cold"
    return "previous step" if path.run.method in pipeline.WARM_STARTED else "none"


def entries(args: argparse.Namespace, loaded: pipeline.Loaded, path: PathRun) -> dict:
    """summary.json's load_path and steps entries."""
    return {
        "load_path": {
            "t": loaded.spec.load_path.values(),
            "form": "incremental" if path.incremental else "total",
            "warm_start": warm_start(args, path),
            "steps_solved": len(path.steps),
        },
        "steps": path.steps,
    }


def step_table(summary: dict) -> list[str]:
    """The per-step lines of the console: t, Newton steps (fixed-point iterations with
    --solver fixed_point), residual, contact counts, time."""
    steps = summary["steps"]
    lp = summary["load_path"]
    newton = sum(s["iterations"] for s in steps)
    fixed_point = summary.get("solver") == "fixed_point"
    unit, column = (
        ("fixed-point iterations", "iters") if fixed_point else ("Newton steps", "Newton")
    )
    out = [
        f"  load path: {len(steps)} of {len(lp['t'])} steps, {lp['form']} form, each "
        f"{STARTS[lp['warm_start']].format(solver=summary.get('solver'))}; {newton} {unit} in "
        "all (the state above is the last step's)",
        f"  {'step':>5} {'t':>9} {column:>6} {'residual':>9} {'stick':>6} {'slip':>6} "
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
