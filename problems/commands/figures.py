"""`mixvi figures`: the scene solved for each value of its plug-in's SWEEP, one panel each.

The plug-in declares (contract v2) `SWEEP = Sweep(path, label, values | factors, file)`: the
scene value at `path` is set to each of `values`, or to the scene's own value times each of
`factors`, and `draw(ax, model, sol)` (default `contract.draw_multiplier`) draws each panel.
For piezo_contact on the paper scene this is Fig. 5.4: g = 1.5e8, 1e8, 0.6e8 Pa.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import problems.pipeline as pipeline
from problems.errors import SceneError
from problems.output import plots, signals
from problems.output.files import output_folder
from problems.plugins import registry
from problems.plugins.contract import Sweep, draw_multiplier, needs
from problems.scene import Scene, load_scene

from . import resources
from .options import DEFAULT_SCENE
from .progress import bar as progress_bar


def sweep_values(sweep: Sweep, scene: Scene) -> list[float]:
    """The values of the sweep: absolute, or the scene's number at `sweep.path` × factors."""
    if sweep.values:
        return [float(v) for v in sweep.values]
    node = scene.data
    for part in sweep.path.split("."):
        node = node.get(part) if isinstance(node, dict) else None
    if isinstance(node, bool) or not isinstance(node, int | float) or not math.isfinite(node):
        raise SceneError(
            sweep.path,
            node,
            f"a number (mixvi figures sweeps it by the factors {list(sweep.factors)}; "
            f"set it with --set {sweep.path}=VALUE)",
            scene.path,
        )
    return [float(node) * f for f in sweep.factors]


def panel_heading(label: str, value: float) -> str:
    """'friction bound g [Pa]', 1.5e8 → 'friction bound g = 1.5e+08 Pa' (the unit of the
    label's brackets after the value; '[1]' is dimensionless)."""
    name, _, unit = label.partition(" [")
    unit = unit.rstrip("]")
    return f"{name} = {value:.3g}" + (f" {unit}" if unit and unit != "1" else "")


def _solve(plugin, scene: Scene, level: int) -> tuple:
    """(model, ssn's solution) of `scene` at `level` (the scene's problem:
    `pipeline.solve_model`)."""
    model = plugin.build(scene, level)
    return model, pipeline.solve_model(plugin, model, method="ssn")


def cmd_figures(args: argparse.Namespace) -> int:
    """Solve the scene for each value of the plug-in's SWEEP and plot them side by side."""
    name = args.scene or DEFAULT_SCENE
    probe = load_scene(name, args.set or [])
    plugin = registry.for_scene(probe)
    needs(plugin, "mixvi figures", "SWEEP")
    sweep: Sweep = plugin.SWEEP
    values = sweep_values(sweep, probe)
    draw = getattr(plugin, "draw", draw_multiplier)
    level = args.level if args.level is not None else resources.default_level(plugin, probe)
    option = "--level" if args.level is not None else "scene.level"  # where the level came from
    resources.check_levels(plugin, probe, (level, level), option, str(level), args.force)
    out = Path(args.out) if args.out else Path("out") / f"{probe.name}_figures"
    inputs = probe.files()
    with output_folder(out, "--out", overwrite=args.overwrite, inputs=inputs) as folder:
        panels = []
        for v in progress_bar(iterable=values, desc=f"solving for each {sweep.path}", unit="solve"):
            scene = load_scene(name, [*(args.set or []), f"{sweep.path}={v!r}"])
            # the scene's problem, in a worker thread: a signal acts inside compiled code
            model, sol = signals.interruptible(_solve, plugin, scene, level)
            if not sol.converged:
                print(
                    f"mixvi: {sweep.path} = {v:g} did not converge (residual {sol.residual:.2e})",
                    file=sys.stderr,
                )
                return 1
            panels.append((panel_heading(sweep.label, v), model, sol))
        with folder.staging() as tmp:
            title = probe.data.get("scene", {}).get("title") or probe.name
            titles = plots.sweep_figure(
                panels, draw, tmp / sweep.file, title=f"{title}\n(one panel per {sweep.label})"
            )
    for t in titles:
        print(t)
    print(f"wrote {out}/{sweep.file}")
    return 0
