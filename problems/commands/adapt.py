"""`mixvi solve SCENE --accuracy 1e-3`: adaptive refinement to a relative error estimate
(`problems.pipeline.adaptive.adapt`), one console line per cycle, the cycle table in
summary.json and a convergence plot (estimate and exact error against unknowns, adaptive and
uniform)."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from problems.errors import SceneError
from problems.output.files import output_folder
from problems.output.jsonable import jsonable
from problems.pipeline import adaptive
from problems.plugins.contract import solve_model

from . import resources
from .options import ACCURACY

UNIFORM_LIMIT = 4  # uniform levels computed beside the adaptive run: 0 … at most this


def run(args: argparse.Namespace, loaded, accuracy: float) -> int:
    """The adaptive loop of `loaded` to `accuracy` into --out (default out/SCENE-adaptive);
    exit 0 when the accuracy was reached, 1 when a limit or a solve that did not converge
    stopped it first."""
    t0 = time.perf_counter()
    scene, plugin = loaded.scene, loaded.plugin
    if not hasattr(plugin, "estimate"):
        raise SceneError(
            "--accuracy",
            accuracy,
            f"a preset name ({', '.join(ACCURACY)}) for scene {scene.name!r}: a number asks for "
            f"adaptive refinement, which needs an error estimate, and plug-in {plugin.NAME!r} "
            f"gives none for this scene"
            + (" (its estimate is 2D only)" if plugin.NAME == "contact" else ""),
        )
    if loaded.spec.load_path is not None:
        raise SceneError(
            "--accuracy",
            accuracy,
            f"a preset name ({', '.join(ACCURACY)}) for scene {scene.name!r}: it has a "
            f"[load_path], and adaptive refinement solves one static problem (the loads at "
            f"t = 0), not the path",
        )
    options = {"method": args.solver or "ssn", "tol": args.tol or 1e-10}
    options["linear_solver"] = args.linear_solver  # each cycle's:
    # `adaptive.cycle_linear_solver`; the uniform levels beside it: a solve's own "auto"
    _, available = resources.memory()
    # unknowns whose modelled peak fits in half the available memory (splu: the worst case)
    cap = adaptive.MAX_UNKNOWNS
    while cap > 1000 and resources.peak_bytes(cap, 12 * cap, "splu") > 0.5 * available:
        cap //= 2
    out = Path(args.out) if args.out else Path("out") / f"{scene.name}-adaptive"
    print(
        f"{scene.name}: adaptive refinement to a relative estimate {accuracy:g} (≤ {cap} unknowns)"
    )
    heads = ("cycle", 5), ("unknowns", 9), ("estimate", 10), ("relative", 9), ("contact", 7)
    print("  " + " ".join(f"{h:>{w}}" for h, w in heads) + f" {'time s':>7}")

    def line(r: dict) -> None:
        print(
            f"  {r['cycle']:5d} {r['unknowns']:9d} {r['total']:10.3e} {r['relative']:9.2e} "
            f"{r['contact_nodes']:7d} {r['time_s']:7.2f}",
            flush=True,
        )

    with output_folder(out, "--out", overwrite=args.overwrite, inputs=scene.files()) as folder:
        with folder.staging() as tmp:
            model, sol, cycles, why = adaptive.adapt(
                plugin,
                scene,
                accuracy,
                max_unknowns=cap,
                solve_options=options,
                on_cycle=line,
                contact_zone=args.contact_zone,
            )
            uniform = _uniform(plugin, scene, options, cycles[-1]["unknowns"])
            extras = plugin.postprocess(model, sol, tmp)
            est = adaptive.estimate_output(plugin, model, sol, tmp)
            files = [*extras.get("files", []), *est.get("files", []), "convergence.png"]
            adaptive.convergence_plot(tmp / "convergence.png", cycles, uniform, scene.name)
            reached = cycles[-1]["relative"] <= accuracy and cycles[-1]["converged"]
            summary = {
                "scene": scene.name,
                "plugin": plugin.NAME,
                "accuracy": accuracy,
                "contact_zone": args.contact_zone,
                "reached": reached,
                "stopped": why,
                "cycles": cycles,
                "uniform": uniform,
                "estimate": est.get("estimate"),
                "files": ["summary.json", *files],
                "time_s": time.perf_counter() - t0,
            }
            (tmp / "summary.json").write_text(json.dumps(jsonable(summary), indent=2) + "\n")
    print(f"  stopped: {why}; wrote {out}/: summary.json, {', '.join(files)}")
    return 0 if reached else 1


def _uniform(plugin, scene, options: dict, unknowns: int) -> list[dict]:
    """Uniform levels 0, 1, … beside the adaptive run, up to the level past its last
    unknowns (at most UNIFORM_LIMIT): {"level", "unknowns", "total", "relative", "errors"}."""
    rows = []
    for level in range(UNIFORM_LIMIT + 1):
        model = plugin.build(scene, level)
        sol = solve_model(plugin, model, **options)
        row = {"level": level, "unknowns": int(sum(model.dofs.values()))}
        row.update(adaptive.totals(plugin.estimate(model, sol)))
        errors = plugin.exact_errors(model, sol) if hasattr(plugin, "exact_errors") else None
        if errors is not None:
            row["errors"] = errors
        rows.append(row)
        if row["unknowns"] > unknowns:
            break
    return rows
