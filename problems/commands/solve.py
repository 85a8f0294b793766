"""`mixvi solve`: build a scene, solve it (nested iteration for ssn), write the results."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import vi_core
from problems.errors import SceneError
from problems.output.files import jsonable, output_folder
from problems.plugins import registry
from problems.plugins.piezo_contact import PATCH_DEFECT_LIMIT
from problems.scene import load_scene

from . import resources
from .options import DEFAULT_SCENE

# --accuracy presets: (level, tol); measured time and error on the paper scene in the README
ACCURACY = {"fast": (1, 1e-6), "balanced": (2, 1e-8), "fine": (3, 1e-10)}
CONDITION_LIMIT = 200_000  # estimate the Newton matrix's condition up to this many unknowns


def _scaling_summary(model) -> dict:
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


def cmd_solve(args: argparse.Namespace) -> int:
    """Solve one scene; exit status 0 converged, 1 not converged or (without --allow-defect) a
    contact interface whose mortar patch defect exceeds PATCH_DEFECT_LIMIT."""
    t0 = time.perf_counter()
    if args.accuracy is not None:  # a preset fills in what was not given explicitly
        level, tol = ACCURACY[args.accuracy]
        args.level = level if args.level is None else args.level
        args.tol = tol if args.tol is None else args.tol
    scene, plugin = load(args)
    method = args.solver
    if method is not None and method not in vi_core.METHODS:
        raise SceneError("--solver", method, "one of " + ", ".join(vi_core.METHODS))
    level = args.level if args.level is not None else resources.default_level(plugin, scene)
    option = "--level" if args.level is not None else "scene.level"  # where the level came from
    resources.check_levels(plugin, scene, (level, level), option, str(level), args.force)
    out = Path(args.out) if args.out else Path("out") / scene.name
    with output_folder(out, "--out", overwrite=args.overwrite) as folder:
        return _solve(args, t0, scene, plugin, level, folder)


def _solve(args, t0, scene, plugin, level, folder) -> int:
    model = plugin.build(scene, level)
    t_build = time.perf_counter() - t0
    method = args.solver or model.options.get("method", "ssn")
    if method not in vi_core.METHODS:
        raise SceneError("--solver", method, "one of " + ", ".join(vi_core.METHODS))
    tol = args.tol if args.tol is not None else model.options.get("tol", 1e-10)
    linear = {"linear_solver": args.linear_solver}
    nested, warm = [], {}
    if method == "ssn" and hasattr(plugin, "warm_start") and model.level > 0 and not args.cold:
        nested, warm = _nested(plugin, scene, model, tol, linear)
    if method == "ssn" and model.vi.n <= CONDITION_LIMIT:
        warm["estimate_condition"] = True
    sol = vi_core.solve(model.vi, method=method, tol=tol, **linear, **warm)
    if nested:
        nested.append({"level": model.level, "iterations": sol.iterations, "time_s": sol.time})
    out = folder.path
    with folder.staging() as tmp:
        extras = plugin.postprocess(model, sol, tmp)
        summary = {
            "scene": scene.name,
            "scene_file": scene.path,
            "plugin": plugin.NAME,
            "level": model.level,
            "solver": method,
            "linear_solver": args.linear_solver,  # as asked; solver_info: what ran
            "tol": tol,
            "dofs": model.dofs,
            "converged": sol.converged,
            "iterations": sol.iterations,
            "residual": sol.residual,
            "residual_history": sol.history,
            **extras,
            "scaling": _scaling_summary(model),
            "condition_estimate": sol.info.get("condition_estimate"),
            "solver_info": sol.info,
            "warnings": model.warnings + sol.warnings + extras.get("warnings", []),
            "nested": nested,
            "time_s": {
                "build": t_build,
                "solve": sum(r["time_s"] for r in nested) if nested else sol.time,
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


def _nested(plugin, scene, model, tol: float, linear: dict) -> tuple[list[dict], dict]:
    """Nested iteration: levels 0 … L−1 solved first, each warm-starting the next; returns
    their records and the warm start of `model`. The coarse models are gone when it returns
    (none of them is alive while the fine level is factorised)."""
    nested, prev = [], None
    for lev in range(model.level):
        coarse = plugin.build(scene, lev)
        kw = plugin.warm_start(*prev, coarse) if prev else {}
        prev = None  # the level before is no longer needed
        csol = vi_core.solve(coarse.vi, method="ssn", tol=tol, **linear, **kw)
        nested.append({"level": lev, "iterations": csol.iterations, "time_s": csol.time})
        prev = (coarse, csol)
    return nested, plugin.warm_start(*prev, model)


def load(args: argparse.Namespace):
    """The scene (with its --set overrides) and its plug-in."""
    scene = load_scene(args.scene or DEFAULT_SCENE, args.set or [])
    return scene, registry.for_scene(scene)
