"""`mixvi solve`: build a scene, solve it (nested iteration for ssn), write the results."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import problems.pipeline as pipeline
import vi_core
from problems.errors import SceneError
from problems.output.files import jsonable, output_folder
from problems.plugins.piezo_contact import PATCH_DEFECT_LIMIT

from . import resources
from .options import DEFAULT_SCENE

# --accuracy presets: (level, tol); measured time and error on the paper scene in the README
ACCURACY = {"fast": (1, 1e-6), "balanced": (2, 1e-8), "fine": (3, 1e-10)}


def cmd_solve(args: argparse.Namespace) -> int:
    """Solve one scene; exit status 0 converged, 1 not converged or (without --allow-defect) a
    contact interface whose mortar patch defect exceeds PATCH_DEFECT_LIMIT."""
    t0 = time.perf_counter()
    if args.accuracy is not None:  # a preset fills in what was not given explicitly
        level, tol = ACCURACY[args.accuracy]
        args.level = level if args.level is None else args.level
        args.tol = tol if args.tol is None else args.tol
    loaded = load(args)
    scene, plugin = loaded.scene, loaded.plugin
    method = args.solver
    if method is not None and method not in vi_core.METHODS:
        raise SceneError("--solver", method, "one of " + ", ".join(vi_core.METHODS))
    level = args.level if args.level is not None else resources.default_level(plugin, scene)
    option = "--level" if args.level is not None else "scene.level"  # where the level came from
    resources.check_levels(plugin, scene, (level, level), option, str(level), args.force)
    out = Path(args.out) if args.out else Path("out") / scene.name
    with output_folder(out, "--out", overwrite=args.overwrite) as folder:
        return _solve(args, t0, loaded, level, folder)


def _solve(args, t0, loaded: pipeline.Loaded, level, folder) -> int:
    scene, plugin = loaded.scene, loaded.plugin
    run = pipeline.solve(loaded, level, args.solver, args.tol, args.cold, args.linear_solver)
    model, sol, method, nested = run.model, run.solution, run.method, run.nested
    out = folder.path
    with folder.staging() as tmp:
        extras = plugin.postprocess(model, sol, tmp)
        summary = {
            **pipeline.info(loaded, run),
            **extras,
            "scaling": pipeline.scaling_summary(model),
            "condition_estimate": sol.info.get("condition_estimate"),
            "solver_info": sol.info,
            "warnings": model.warnings + sol.warnings + extras.get("warnings", []),
            "nested": nested,
            "time_s": {
                "build": run.time_build,
                "solve": run.time_solve,
                "total": time.perf_counter() - t0,
            },
        }
        (tmp / "summary.json").write_text(json.dumps(jsonable(summary), indent=2) + "\n")
    c = summary.get("contact", {})
    print(
        f"{scene.name} level {model.level}: {sum(model.dofs.values())} unknowns "
        f"{model.dofs}, solver {method}"
    )
    identity = ""
    if "lemma_4_2" in summary:
        identity = f", lemma 4.2 gap {summary['lemma_4_2']:.1e}"
    elif "complementarity" in summary:
        identity = f", complementarity defect {summary['complementarity']:.1e}"
    print(
        f"  converged {sol.converged} in {sol.iterations} iterations, "
        f"residual {sol.residual:.2e}{identity}"
    )
    if nested:
        its = ", ".join(f"L{r['level']}: {r['iterations']}" for r in nested)
        print(f"  nested iteration (Newton steps per level, each warm-started): {its}")
    defect = c.get("mortar_patch_defect")
    if c:
        extra = f"; mortar patch defect {defect:.1e}" if defect is not None else ""
        print(f"  contact nodes {c['nodes']}: stick {c['stick']}, slip {c['slip']}{extra}")
    if "krylov_iterations" in sol.info:
        fb = sol.info["fallback"]
        print(
            "  linear solver amg: Krylov iterations per Newton step "
            f"{sol.info['krylov_iterations']}"
            f", {len(fb)} direct fallback(s)"
            + "".join(f"; step {f['step']}: {f['reason']}" for f in fb)
        )
    print(f"  time {summary['time_s']['total']:.2f} s; wrote {out}/")
    for w in summary["warnings"]:
        print(f"  warning: {w}")
    if defect is not None and defect > PATCH_DEFECT_LIMIT and not args.allow_defect:
        print("  exit status 1: mortar patch defect above the limit (--allow-defect to accept)")
        return 1
    return 0 if sol.converged else 1


def load(args: argparse.Namespace) -> pipeline.Loaded:
    """The scene (with its --set overrides), validated by its plug-in's scene model before
    anything is built; migration notices go to stderr (one line each)."""
    loaded = pipeline.load(args.scene or DEFAULT_SCENE, args.set or [])
    for notice in loaded.notices:
        print(f"mixvi: note: {notice}", file=sys.stderr)
    return loaded
