"""Quasi-static load paths: a scene with a `[load_path]` solved step by step.

    solve_path(loaded, level, method, tol, cold, linear_solver, on_step, rebuild)  → PathRun

For each t of the path (`LoadPath.values()`): the scene is built with every expression at t
(`problems.scene.fields.load_parameter`) — or, after the first step, the previous step's model
is updated to t by the plug-in's optional `update(model, scene, t)` (only the loads and
prescribed values re-read; mesh and operators kept) — the plug-in's optional
`incremental(model, previous, previous_sol)` makes the step act on the increments since the
previous step (a friction law on the slip increment; contract, docs/plugins.md), and the step
is solved warm-started from the previous step's solution (ssn and the fixed point,
`WARM_STARTED`; conic, homotopy and auto from zero; the first ssn step from the nested
iteration like a single solve).
`cold` solves every step from zero. `on_step(step)` is called while the step's model is alive
(`mixvi solve` writes its files there); only the previous step is kept in memory.

Nothing here writes files (docs/load_paths.md).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import vi_core
from problems.errors import SceneError
from problems.scene.fields import load_parameter

from . import Loaded, Run, solve_built


@dataclass
class Step:
    """One solved load step: its index (from 1), t, the model, the solution and its record."""

    index: int
    t: float
    model: Any
    solution: vi_core.Solution
    record: dict


@dataclass
class PathRun:
    """A solved load path: the last step as a `Run` and one record per step."""

    run: Run
    steps: list[dict] = field(default_factory=list)
    incremental: bool = False  # the plug-in acted on increments (it declares `incremental`)

    @property
    def converged(self) -> bool:
        """Every step converged: the whole path was solved (`solve_path` stops after a step
        that does not converge)."""
        return all(s["converged"] for s in self.steps)


def step_record(index: int, t: float, model: Any, sol: vi_core.Solution, build_s: float) -> dict:
    """What summary.json records per step: t, Newton steps, residual, converged, times."""
    return {
        "step": index,
        "t": t,
        "iterations": sol.iterations,
        "residual": sol.residual,
        "converged": sol.converged,
        "warm": bool(sol.info.get("warm_start", False)),
        "time_s": {"build": build_s, "solve": sol.time},
    }


def solve_path(
    loaded: Loaded,
    level: int | None = None,
    method: str | None = None,
    tol: float | None = None,
    cold: bool = False,
    linear_solver: str = "auto",
    on_step: Callable[[Step], None] | None = None,
    rebuild: bool = False,
) -> PathRun:
    """Solve the load path of `loaded` (SceneError if it has none): one state per t, each
    warm-started from the one before unless `cold`, in the incremental form where the plug-in
    declares `incremental`. After the first step a plug-in's `update(model, scene, t)` turns the
    previous step's model into the next one (only the t-dependent data re-read; None: build
    it); `rebuild` builds every step from the scene (the cross-check of update). Stops after
    the first step that does not converge (the later ones would start from a wrong history)."""
    scene, plugin, spec = loaded.scene, loaded.plugin, loaded.spec
    if spec.load_path is None:
        raise SceneError("load_path", None, "a [load_path] section (this scene has none)")
    incremental = hasattr(plugin, "incremental")
    update = None if rebuild else getattr(plugin, "update", None)
    prev: tuple[Any, vi_core.Solution] | None = None
    records: list[dict] = []
    last: Run | None = None
    t_build_total = 0.0
    for index, t in enumerate(spec.load_path.values(), start=1):
        t0 = time.perf_counter()
        with load_parameter(t):
            model = None if prev is None or update is None else update(prev[0], scene, t)
            updated = model is not None
            if model is None:
                model = plugin.build(scene, level)
        if prev is not None and incremental:
            plugin.incremental(model, *prev)
        build_s = time.perf_counter() - t0
        t_build_total += build_s
        previous = None if prev is None else prev[1]
        run = solve_built(loaded, model, method, tol, cold, linear_solver, previous=previous, t=t)
        del previous  # only this step is kept once it is solved (prev, below)
        sol = run.solution
        rec = step_record(index, t, model, sol, build_s)
        rec["updated"] = updated
        if run.nested:
            rec["nested"] = run.nested
        records.append(rec)
        prev = None  # the step before is no longer needed once this one is solved
        if on_step is not None:
            on_step(Step(index, t, model, sol, rec))
        run.time_build = t_build_total
        run.time_solve = sum(r["time_s"]["solve"] for r in records)
        last = run
        prev = (model, sol)
        if not sol.converged:
            break
    return PathRun(last, records, incremental)
