"""Quasi-static load paths: a scene with a `[load_path]` solved step by step.

    solve_path(loaded, level, method, tol, cold, linear_solver, on_step)  → PathRun

For each t of the path (`LoadPath.values()`): the scene is built with every expression at t
(`problems.scene.fields.load_parameter`), the plug-in's optional `incremental(model, previous,
previous_sol)` makes the step act on the increments since the previous step (a friction law on
the slip increment; contract, docs/plugins.md), and the step is solved warm-started from the
previous step's solution (ssn; the first step from the nested iteration like a single solve).
`cold` solves every step from zero. `on_step(step)` is called while the step's model is alive
(`mixvi solve` writes its files there); only the previous step is kept in memory.

Nothing here writes files (docs/load_paths.md).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import vi_core
from problems.errors import SceneError
from problems.scene.fields import load_parameter

from . import CONDITION_LIMIT, Loaded, Run, _nested, level_record, solve_model


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
        """Every step converged."""
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
) -> PathRun:
    """Solve the load path of `loaded` (SceneError if it has none): one state per t, each
    warm-started from the one before unless `cold`, in the incremental form where the plug-in
    declares `incremental`. Stops after the first step that does not converge (the later ones
    would start from a wrong history)."""
    scene, plugin, spec = loaded.scene, loaded.plugin, loaded.spec
    if spec.load_path is None:
        raise SceneError("load_path", None, "a [load_path] section (this scene has none)")
    incremental = hasattr(plugin, "incremental")
    prev: tuple[Any, vi_core.Solution] | None = None
    records: list[dict] = []
    last: Run | None = None
    t_build_total = 0.0
    for index, t in enumerate(spec.load_path.values(), start=1):
        t0 = time.perf_counter()
        with load_parameter(t):
            model = plugin.build(scene, level)
        if prev is not None and incremental:
            plugin.incremental(model, *prev)
        build_s = time.perf_counter() - t0
        t_build_total += build_s
        m = method or model.options.get("method", "ssn")
        if m not in vi_core.METHODS:
            raise SceneError("--solver", m, "one of " + ", ".join(vi_core.METHODS))
        tl = tol if tol is not None else model.options.get("tol", 1e-10)
        warm: dict = {}
        nested: list[dict] = []
        if m == "ssn" and not cold:
            if prev is not None and _same_shape(prev[1], model):
                warm = {"u0": prev[1].u, "lam0": prev[1].lam}
            elif prev is None and hasattr(plugin, "warm_start") and model.level > 0:
                with load_parameter(t):
                    nested, warm = _nested(plugin, scene, model, tl, linear_solver)
        if m == "ssn" and model.vi.n <= CONDITION_LIMIT:
            warm["estimate_condition"] = True
        sol = solve_model(plugin, model, method=m, tol=tl, linear_solver=linear_solver, **warm)
        sol.info["warm_start"] = "u0" in warm
        rec = step_record(index, t, model, sol, build_s)
        if nested:
            nested.append(level_record(model.level, model, sol))
            rec["nested"] = nested
        records.append(rec)
        prev = None  # the step before is no longer needed once this one is solved
        if on_step is not None:
            on_step(Step(index, t, model, sol, rec))
        t_solve = sum(r["time_s"]["solve"] for r in records)
        last = Run(model, sol, m, tl, nested, linear_solver, t_build_total, t_solve)
        prev = (model, sol)
        if not sol.converged:
            break
    return PathRun(last, records, incremental)


def _same_shape(sol: vi_core.Solution, model: Any) -> bool:
    """The previous step's solution fits `model` (same unknowns and multipliers)."""
    return np.shape(sol.u) == (model.vi.n,) and np.shape(sol.lam) == (model.vi.m,)
