"""The solve pipeline shared by `mixvi solve` and the Python API: scene → validated model →
plug-in build → MixedVI → solve (nested iteration) → results.

    load(name_or_path, overrides)      read, migrate, override and validate (before any build)
    solve(loaded, level, method, tol)  build and solve; a `Run` with the model and solution
    solve_built(loaded, model, ...)    the solve of a built model (also each load step's,
                                       problems.pipeline.load_path)
    results(loaded, run)               fields, contact state and info as objects
    nested_iteration(plugin, scene, model, tol, linear_solver)
                                       the coarse levels of an ssn solve and the fine
                                       level's warm start (mixvi solve's and mixvi bench's)

Nothing here writes files: `mixvi solve` (problems.commands.solve) adds the output folder,
`problems.solve_scene` returns the objects.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

import vi_core
from problems.errors import SceneError
from problems.pipeline.contact_results import ContactResults
from problems.plugins import registry

# the commands' one entry point to solve a scene's model, and the problem its answer solves
from problems.plugins.contract import nested_start as nested_start
from problems.plugins.contract import problem_at as problem_at
from problems.plugins.contract import solve_model as solve_model
from problems.scene import Scene, SceneModel, load_scene
from problems.scene.fields import load_parameter
from problems.scene.model import METHODS
from vi_core.coulomb import ContactSet

# progress of an ssn solve: (level, info), info as `vi_core.ssn.solve_ssn`'s on_step gives it
OnStep = Callable[[int, dict], None]
# what `solve_built` accepts as method, `mixvi solve --solver` and a scene's [solver] method
# alike: vi_core's for fixed convex sets, and the Coulomb fixed point
# (`vi_core.tresca_fixed_point`) for contact sets
SOLVERS = METHODS
# the methods a load step starts from the previous step's solution (conic, homotopy and auto
# solve every step from zero)
WARM_STARTED = ("ssn", "fixed_point")
CONDITION_LIMIT = 200_000  # estimate the Newton matrix's condition up to this many unknowns
# nested iteration solves its coarse levels to max(tol, NESTED_TOL) (`coarse_tol`): what the
# finer level takes from them — the active set (stick/slip/inactive partition) and a start —
# is settled far above the requested tolerance (a coarse level's discretisation error is ~1e-3
# relative), and the fine level is solved to tol from there. Paper scene, level 5 nested:
# fine level one Newton step and 16 GMRES iterations whether levels 0–4 are solved to 1e-10,
# 1e-6, 1e-4 or 1e-3; their GMRES iterations 12, 12, 13, 15 at 1e-10, 7, 7, 7, 8 at 1e-6
NESTED_TOL = 1e-6


@dataclass
class Loaded:
    """A scene validated by its plug-in's scene model, before anything is built."""

    scene: Scene
    plugin: Any
    spec: SceneModel

    @property
    def notices(self) -> list[str]:
        """Migration notices (format-1 scenes), one line each."""
        return self.scene.notices


def validated(scene: Scene) -> Loaded:
    """The scene checked by its plug-in's SCENE_MODEL (SceneError naming the field)."""
    plugin = registry.for_scene(scene)
    return Loaded(scene, plugin, scene.validated(plugin.SCENE_MODEL))


def load(name_or_path: str, overrides: list[str] | tuple[str, ...] = ()) -> Loaded:
    """Read a scene (file or shipped name), apply `--set` overrides and validate it."""
    return validated(load_scene(name_or_path, overrides))


@dataclass
class Run:
    """One solve: the built model, the solution and how it was reached."""

    model: Any
    solution: vi_core.Solution
    method: str
    tol: float
    nested: list[dict] = field(default_factory=list)  # per level: iterations, time
    linear_solver: str = "auto"  # as asked (solver_info says what ran)
    time_build: float = 0.0
    time_solve: float = 0.0


def solve(
    loaded: Loaded,
    level: int | None = None,
    method: str | None = None,
    tol: float | None = None,
    cold: bool = False,
    linear_solver: str = "auto",
    on_level: Callable[[Any, vi_core.Solution], None] | None = None,
    on_step: OnStep | None = None,
) -> Run:
    """Build `loaded` at `level` (None: the scene's) and solve it with `method` and `tol`
    (None: the scene's [solver], else ssn and 1e-10). With ssn and a plug-in that has
    `warm_start`, levels 0 … L−1 are solved first, each warm-starting the next (unless
    `cold`). `linear_solver` (auto|splu|pardiso|amg) solves the Newton steps, coarse levels
    included. `on_level(model, solution)` is called for each coarse level of the nested
    iteration while it is alive (mixvi solve --write-levels writes its results);
    `on_step(level, info)` with each ssn solve's progress (`vi_core.ssn.solve_ssn`'s on_step:
    Newton step, residual, active and slip rows, GMRES iterations), coarse levels included."""
    t0 = time.perf_counter()
    model = loaded.plugin.build(loaded.scene, level)
    t_build = time.perf_counter() - t0
    run = solve_built(loaded, model, method, tol, cold, linear_solver, on_level, on_step=on_step)
    run.time_build = t_build
    return run


def solve_built(
    loaded: Loaded,
    model: Any,
    method: str | None = None,
    tol: float | None = None,
    cold: bool = False,
    linear_solver: str = "auto",
    on_level: Callable[[Any, vi_core.Solution], None] | None = None,
    previous: vi_core.Solution | None = None,
    t: float | None = None,
    on_step: OnStep | None = None,
) -> Run:
    """Solve the built `model` of `loaded` as `solve` does (time_build left 0). A load step
    (`t`, the step's load parameter: the nested iteration's levels are built at t) after the
    first passes the `previous` step's solution: ssn (and the Coulomb fixed point) starts from
    it where it fits the model, without a nested iteration, and `solution.info["warm_start"]`
    says whether it did. The method must suit the model's multiplier set (`method_of`);
    `on_step` as in `solve`."""
    method = method_of(loaded, model, method)
    tol = tol if tol is not None else model.options.get("tol", 1e-10)
    nested: list[dict] = []
    warm: dict = {}
    start: dict = {}
    if method in WARM_STARTED and not cold:
        if previous is not None:
            if _same_shape(previous, model):
                warm = {"u0": previous.u, "lam0": previous.lam}
        elif method == "ssn" and nests(loaded.plugin, model):
            with load_parameter(t) if t is not None else nullcontext():
                nested, warm, start = nested_iteration(
                    loaded.plugin,
                    loaded.scene,
                    model,
                    tol,
                    linear_solver,
                    on_level,
                    on_step=on_step,
                )
    if method == "ssn" and model.vi.n <= CONDITION_LIMIT:
        warm["estimate_condition"] = True
    if method == "ssn" and on_step is not None:
        warm["on_step"] = partial(on_step, model.level)
    sol = solve_model(
        loaded.plugin, model, method=method, tol=tol, linear_solver=linear_solver, **warm
    )
    if t is not None:
        sol.info["warm_start"] = "u0" in warm
    if start:
        sol.info["nested_start"] = start
    if nested:
        nested.append(level_record(model.level, model, sol, tol))
    t_solve = sum(r["time_s"] for r in nested) if nested else sol.time
    return Run(model, sol, method, tol, nested, linear_solver, 0.0, t_solve)


def method_of(loaded: Loaded, model: Any, method: str | None = None) -> str:
    """The method a solve of `model` (built from `loaded`) uses: `method` (--solver), else the
    scene's [solver] method, else ssn. It must suit the model's multiplier set: vi_core.METHODS
    for fixed convex sets, vi_core.CONTACT_METHODS (the fixed point among them) for contact
    blocks; a SceneError otherwise, naming where it came from (--solver, or solver.method and
    the scene file), the value and the methods allowed."""
    key, file = ("--solver", None) if method else ("solver.method", str(loaded.scene.path))
    method = method or model.options.get("method", "ssn")
    if method not in SOLVERS:
        raise SceneError(key, method, "one of " + ", ".join(SOLVERS), file)
    contact = has_contact_set(model.vi)
    allowed = vi_core.CONTACT_METHODS if contact else vi_core.METHODS
    if method not in allowed:
        if contact:
            why = (
                f"conic and homotopy need a fixed convex set; this scene's multiplier set "
                f"{model.vi.Lambda!r} holds Coulomb or unilateral Tresca contact blocks"
            )
        else:
            why = (
                "the fixed point g ← F·λ_n iterates on Coulomb or unilateral Tresca contact; "
                f"this scene's multiplier set {model.vi.Lambda!r} has none"
            )
        raise SceneError(key, method, f"one of {', '.join(allowed)} ({why})", file)
    return method


def has_contact_set(vi: vi_core.MixedVI) -> bool:
    """Whether Λ holds a contact block (Coulomb, unilateral Tresca: `vi_core.coulomb`)."""
    return any(isinstance(b, ContactSet) for b in vi.Lambda.blocks())


def _same_shape(sol: vi_core.Solution, model: Any) -> bool:
    """`sol` fits `model` (same unknowns and multipliers)."""
    return np.shape(sol.u) == (model.vi.n,) and np.shape(sol.lam) == (model.vi.m,)


def nests(plugin: Any, model: Any) -> bool:
    """Whether an ssn solve of the built `model` starts with a nested iteration
    (`nested_iteration`): its plug-in has `warm_start` and there is a coarser level."""
    return hasattr(plugin, "warm_start") and model.level > 0


def nested_iteration(
    plugin: Any,
    scene: Scene,
    model: Any,
    tol: float,
    linear_solver: str,
    on_level: Callable[[Any, vi_core.Solution], None] | None = None,
    build: Callable[[Scene, int], Any] | None = None,
    on_step: OnStep | None = None,
) -> tuple[list[dict], dict, dict]:
    """Nested iteration (where `nests(plugin, model)`): levels 0 … L−1 (L = model.level)
    built by `build(scene, level)` (default `plugin.build`; mixvi bench passes one that times
    the builds, to leave them out of its timing) and solved to `coarse_tol(tol)`, each
    warm-starting the next; returns their records, the warm start of `model` (keyword
    arguments of `solve_model`) and its description (`nested_start`); `on_step(level, info)`
    as in `solve`. The coarse models are
    gone when it returns (none of them is alive while the fine level is factorised) unless
    `on_level` or `build` keeps them."""
    build = build or plugin.build
    nested, prev = [], None
    for lev in range(model.level):
        coarse = build(scene, lev)
        kw, start = nested_start(plugin, *prev, coarse) if prev else ({}, {})
        prev = None  # the level before is no longer needed
        if on_step is not None:
            kw["on_step"] = partial(on_step, lev)
        csol = solve_model(
            plugin, coarse, method="ssn", tol=coarse_tol(tol), linear_solver=linear_solver, **kw
        )
        if start:
            csol.info["nested_start"] = start
        nested.append(level_record(lev, coarse, csol, coarse_tol(tol)))
        if on_level is not None:
            on_level(coarse, csol)
        prev = (coarse, csol)
    return nested, *nested_start(plugin, *prev, model)


def coarse_tol(tol: float) -> float:
    """The tolerance nested iteration solves a coarse level to, for a fine level solved to
    `tol`: max(tol, NESTED_TOL)."""
    return max(tol, NESTED_TOL)


def level_record(level: int, model: Any, sol: vi_core.Solution, tol: float) -> dict:
    """One level of a run: unknowns, Newton steps, time, the tolerance it was solved to
    (`coarse_tol` on the coarse levels of nested iteration), residual, converged."""
    return {
        "level": level,
        "unknowns": int(model.vi.n + model.vi.m),
        "iterations": sol.iterations,
        "time_s": sol.time,
        "tol": tol,
        "residual": sol.residual,
        "converged": sol.converged,
    }


def scaling_summary(model: Any) -> dict:
    """The equilibration scales per field (geometric means): u = s_u·u', λ = s_λ·λ'."""
    sc = model.vi.scaling

    def gmean(v):
        return float(np.exp(np.mean(np.log(v)))) if v.size else None

    out = {"note": "u = s_u u', lambda = s_lam lambda' (Jacobi equilibration, geometric means)"}
    fields = model.unknown_fields() if hasattr(model, "unknown_fields") else {"u": slice(None)}
    for name, mask in fields.items():
        out[f"s_{name}"] = gmean(sc.s_u[mask])
    out["s_multiplier"] = gmean(sc.s_lam)
    return out


def info(loaded: Loaded, run: Run) -> dict:
    """What a run reached, as summary.json records it (without the plug-in's entries)."""
    model, sol = run.model, run.solution
    return {
        "scene": loaded.scene.name,
        "scene_file": loaded.scene.path,
        "plugin": loaded.plugin.NAME,
        "level": model.level,
        "solver": run.method,
        "linear_solver": run.linear_solver,
        "tol": run.tol,
        "dofs": model.dofs,
        "converged": sol.converged,
        "iterations": sol.iterations,
        "residual": sol.residual,
        "residual_history": sol.history,
    }


@dataclass
class Results:
    """A solved scene as objects (the Python API's answer)."""

    fields: dict[str, np.ndarray]  # nodal fields by name (the plug-in's `fields`)
    contact: ContactResults | None  # per-node contact state along Γ3, csv/vtu names
    info: dict  # converged, iterations, residual, dofs, level, solver, warnings, ...
    model: Any  # the built model (vi, meshes, ...)
    solution: vi_core.Solution
    loaded: Loaded | None = field(default=None, repr=False)  # what was solved
    run: Run | None = field(default=None, repr=False)  # how (method, tolerance, times)

    def write(self, folder: str | Path, overwrite: bool = False) -> list[str]:
        """Write the files `mixvi solve` writes for this state into `folder` (the same names
        and contents: a VTU per body, contact.csv and contact.vtu, the plots, the estimate's
        VTU files, results.pvd, summary.json), under the same rules: a folder holding files
        no mixvi run wrote is refused (SceneError) unless `overwrite`, and then only mixvi's
        names are replaced; nothing else is ever deleted; an error leaves the folder as it
        was. A load path's answer writes its last step's state (summary.json's `steps` holds
        every step's record; `mixvi solve` writes each step's files under steps/). Returns
        the names written, summary.json first."""
        from problems.output.files import output_folder

        from .written import write_state

        if self.loaded is None or self.run is None:
            raise ValueError("Results.write needs the results of problems.solve_scene")
        inputs = self.loaded.scene.files()
        command = f"python: Results.write of {self.loaded.scene.name}"
        with output_folder(Path(folder), "folder", command, overwrite, inputs) as out:
            with out.staging() as tmp:
                summary = write_state(self.loaded, self.run, tmp, self.info.get("steps"))
        return ["summary.json", *summary["files"]]


def results(loaded: Loaded, run: Run) -> Results:
    """Fields, contact state and info of a run (nothing written)."""
    plugin, model, sol = loaded.plugin, run.model, run.solution
    fields = plugin.fields(model, sol) if hasattr(plugin, "fields") else {}
    contact = None
    if hasattr(plugin, "contact_state") and getattr(model, "contact", True) is not None:
        contact = ContactResults(plugin.contact_state(model, sol))
    out = info(loaded, run)
    if hasattr(model, "complementarity"):
        out["complementarity"] = model.complementarity(sol)
    out["warnings"] = list(model.warnings) + list(sol.warnings)
    out["time_s"] = {"build": run.time_build, "solve": run.time_solve}
    out["nested"] = run.nested
    return Results(fields, contact, out, model, sol, loaded, run)
