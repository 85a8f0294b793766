"""The files of one solved state, as `mixvi solve` writes them and `Results.write` does: the
plug-in's files (`postprocess`: a VTU per body, contact.csv and contact.vtu, plots), the error
estimate's VTU files where the plug-in has `estimate`, the collection results.pvd and the
entries of summary.json.

    extras, files, warnings = state_files(loaded, run, folder)
    summary = summary_of(loaded, run, extras, files, warnings, ...)

Both write into a folder they are given (a staging folder of `problems.output.files`: the
refusal rules, never replacing a user's file, are the caller's).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from problems.output.collection import vtu_datasets, write_pvd
from problems.output.jsonable import jsonable

from . import Loaded, Run, adaptive, info, scaling_summary


def state_files(loaded: Loaded, run: Run, folder: Path) -> tuple[dict, list[str], list[str]]:
    """The plug-in's files and the estimate's in `folder`; (their summary entries, the file
    names, the warnings of the model, the solution and the plug-in's results)."""
    plugin, model, sol = loaded.plugin, run.model, run.solution
    extras = plugin.postprocess(model, sol, folder)
    est = adaptive.estimate_output(plugin, model, sol, folder)  # {} without `estimate`
    extras = {**extras, **est, "files": [*extras.get("files", []), *est.get("files", [])]}
    warnings = model.warnings + sol.warnings + extras.get("warnings", [])
    return extras, [*extras["files"]], warnings


def collection(folder: Path, datasets: list[tuple[float, str]], name: str) -> list[str]:
    """`name` (a .pvd) of `datasets` in `folder`, as a list of the one file (none without
    datasets)."""
    if not datasets:
        return []
    write_pvd(folder / name, datasets)
    return [name]


def summary_of(
    loaded: Loaded,
    run: Run,
    extras: dict,
    files: list[str],
    warnings: list[str],
    before: dict | None = None,
    after: dict | None = None,
    total_s: float | None = None,
) -> dict:
    """summary.json of a solved state: the run's info, the plug-in's entries, the files, the
    scaling, the solver's info, warnings, the nested levels and the times (`total_s`: the
    whole command's; None: build + solve). `before` and `after` are entries placed before
    and after the scaling (a load path's, the condition estimate)."""
    model, sol = run.model, run.solution
    total = run.time_build + run.time_solve if total_s is None else total_s
    return {
        **info(loaded, run),
        **extras,
        "files": files,
        **(before or {}),
        "scaling": scaling_summary(model),
        **(after or {}),
        "solver_info": sol.info,
        "warnings": warnings,
        "nested": run.nested,
        "time_s": {"build": run.time_build, "solve": run.time_solve, "total": total},
    }


def write_summary(folder: Path, summary: dict[str, Any]) -> None:
    """summary.json in `folder` (numpy values as JSON numbers)."""
    (folder / "summary.json").write_text(json.dumps(jsonable(summary), indent=2) + "\n")


def write_state(loaded: Loaded, run: Run, folder: Path, steps: list[dict] | None = None) -> dict:
    """Every file `mixvi solve` writes for the state of `run` (without --write-levels) into
    `folder`: the plug-in's and the estimate's files, results.pvd and summary.json; returns the
    summary. `steps`: a load path's step records (summary.json's `steps`; only the last
    step's state is at hand, so no steps/ folders and no steps.pvd)."""
    extras, files, warnings = state_files(loaded, run, folder)
    files += collection(folder, vtu_datasets(run.model.level, files), "results.pvd")
    before, after = {}, {"condition_estimate": run.solution.info.get("condition_estimate")}
    if steps is not None:  # a load path's: its steps, and no condition estimate
        before, after = {"steps": steps}, {}
    summary = summary_of(loaded, run, extras, files, warnings, before, after)
    write_summary(folder, summary)
    return summary
