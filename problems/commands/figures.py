"""`mixvi figures`: Fig. 5.4, the contact multiplier and jump for several friction bounds."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import vi_core
from problems.errors import SceneError
from problems.output import plots
from problems.output.files import atomic_output
from problems.plugins import registry
from problems.scene import load_scene

from .options import DEFAULT_SCENE


def cmd_figures(args: argparse.Namespace) -> int:
    """Solve the scene for three friction bounds and plot them side by side."""
    bounds = (1.5e8, 1.0e8, 0.6e8)
    probe = load_scene(args.scene or DEFAULT_SCENE, args.set or [])
    if not hasattr(registry.for_scene(probe), "contact_state"):
        raise SceneError(
            "scene.plugin",
            probe.data.get("scene", {}).get("plugin"),
            "a contact plug-in (figures compares friction bounds)",
        )
    states = []
    for g in bounds:
        scene = load_scene(args.scene or DEFAULT_SCENE, [*(args.set or []), f"contact.g={g!r}"])
        plugin = registry.for_scene(scene)
        model = plugin.build(scene, args.level)
        sol = vi_core.solve(model.vi, method="ssn")
        if not sol.converged:
            print(
                f"mixvi: g = {g:g} did not converge (residual {sol.residual:.2e})", file=sys.stderr
            )
            return 1
        states.append((g, plugin.contact_state(model, sol)))
        st = states[-1][1]
        print(f"g = {g:.2e}: stick {int((~st['slip']).sum())}, slip {int(st['slip'].sum())}")
    out = Path(args.out) if args.out else Path("out") / f"{scene.name}_figures"
    with atomic_output(out) as tmp:
        plots.friction_comparison(states, tmp / "fig_5_4.png", title=scene.name)
    print(f"wrote {out}/fig_5_4.png")
    return 0
