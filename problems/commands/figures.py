"""`mixvi figures`: the scene solved for each value of its plug-in's SWEEP, one panel each.

The plug-in declares (contract v2) `SWEEP = Sweep(path, label, values | factors, file,
otherwise)`: the scene value at `path` is set to each of `values`, or to the scene's own value
times each of `factors` (a scene without a number there: the `otherwise` sweep, e.g. Coulomb
friction's coefficient F where Tresca friction has a bound g), and `draw(ax, model, sol)`
(default `contract.draw_multiplier`) draws each panel.
For the contact plug-in on the paper scene this is Fig. 5.4: g = 1.5e8, 1e8, 0.6e8 Pa.
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


def _value(scene: Scene, path: str):
    """The scene's value at the dotted `path` (None where it has none)."""
    node = scene.data
    for part in path.split("."):
        node = node.get(part) if isinstance(node, dict) else None
    return node


def _number(node) -> bool:
    return not isinstance(node, bool) and isinstance(node, int | float) and math.isfinite(node)


def sweep_values(sweep: Sweep, scene: Scene) -> tuple[Sweep, list[float]]:
    """The sweep that applies to the scene (`sweep`, or the first of its `otherwise` chain with
    a number at its path) and its values: absolute, or that number × factors. SceneError where
    none applies, naming the key of the chain the scene sets (else the first) and what it must
    be: a Coulomb scene with a field F is told about F, never about g."""
    chain = [sweep]
    while chain[-1].otherwise is not None:
        chain.append(chain[-1].otherwise)
    for s in chain:
        if s.values:
            return s, [float(v) for v in s.values]
        node = _value(scene, s.path)
        if _number(node):
            return s, [float(node) * f for f in s.factors]
    named = next((s for s in chain if _value(scene, s.path) is not None), chain[0])
    raise SceneError(
        named.path,
        _value(scene, named.path),
        f"a number (mixvi figures sweeps it by the factors {list(named.factors)}; "
        f"set it with --set {named.path}=VALUE)",
        scene.path,
    )


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
    sweep, values = sweep_values(plugin.SWEEP, probe)
    draw = getattr(plugin, "draw", draw_multiplier)
    level, option = resources.requested_level(args.level, plugin, probe)
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
