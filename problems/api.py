"""The Python API: solve a scene and get its results as objects (no files written or parsed).

    import problems
    spec = problems.load_scene("rigid_foundation")        # the validated scene model
    res = problems.solve_scene(spec, level=1, contact__g=5e6)
    res.fields["block.displacement"], res.contact["slip"], res.info["converged"]
    res.write("out/rf")        # the files mixvi solve writes (VTU, CSV, PNG, summary.json)

Overrides are keyword arguments with `__` for the dots of `--set` (contact__g=5e6 is
`--set contact.g=5e6`); every value is validated with the scene (SceneError naming the field).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import problems.pipeline as pipeline
from problems.scene import Scene, SceneModel
from problems.scene import load_scene as _read
from problems.scene.reader import toml_literal


def _loaded(path_or_model: str | Path | SceneModel, overrides: dict[str, Any]) -> pipeline.Loaded:
    sets = [f"{k.replace('__', '.')}={toml_literal(v)}" for k, v in overrides.items()]
    if isinstance(path_or_model, SceneModel):
        scene = Scene.from_model(path_or_model)
        if sets:  # the same path as a file's overrides: through the TOML text of each value
            from problems.scene.reader import apply_overrides

            apply_overrides(scene, sets)
    else:
        scene = _read(str(path_or_model), sets)
    loaded = pipeline.validated(scene)
    for notice in loaded.notices:
        warnings.warn(notice, DeprecationWarning, stacklevel=3)
    return loaded


def load_scene(path: str | Path, **overrides: Any) -> SceneModel:
    """The validated scene model of a scene file or shipped scene name."""
    return _loaded(path, overrides).spec


def solve_scene(
    path_or_model: str | Path | SceneModel,
    level: int | None = None,
    solver: str | None = None,
    tol: float | None = None,
    cold: bool = False,
    linear_solver: str = "auto",
    **overrides: Any,
) -> pipeline.Results:
    """Validate, build and solve a scene; its fields, contact state and info as objects.
    `linear_solver`: auto|splu|pardiso|amg for the Newton steps. A scene with a [load_path] is
    solved step by step (`problems.pipeline.load_path`): the answer is the last step's, with
    info["steps"] (per step: t, Newton steps, residual, converged, times) and
    info["converged"] true only if every step converged."""
    loaded = _loaded(path_or_model, overrides)
    if loaded.spec.load_path is not None:
        from problems.pipeline.load_path import solve_path

        path = solve_path(loaded, level, solver, tol, cold, linear_solver)
        res = pipeline.results(loaded, path.run)
        res.info["steps"] = path.steps
        res.info["converged"] = path.converged
        return res
    run = pipeline.solve(loaded, level, solver, tol, cold, linear_solver)
    return pipeline.results(loaded, run)
