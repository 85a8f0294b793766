"""`mixvi figures`: Fig. 5.4, the contact multiplier and jump for several friction bounds."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import vi_core
from problems.errors import SceneError
from problems.output import plots
from problems.output.files import output_folder
from problems.plugins import registry
from problems.scene import load_scene

from . import resources
from .options import DEFAULT_SCENE


def cmd_figures(args: argparse.Namespace) -> int:
    """Solve the scene for three friction bounds and plot them side by side."""
    bounds = (1.5e8, 1.0e8, 0.6e8)
    probe = load_scene(args.scene or DEFAULT_SCENE, args.set or [])
    plugin = registry.for_scene(probe)
    if not hasattr(plugin, "contact_state"):
        raise SceneError(
            "scene.plugin",
            getattr(plugin, "NAME", None),
            "a contact plug-in with a friction bound contact.g (figures compares friction "
            "bounds); this scene's plug-in has none",
        )
    level = args.level if args.level is not None else resources.default_level(plugin, probe)
    option = "--level" if args.level is not None else "scene.level"  # where the level came from
    resources.check_levels(plugin, probe, (level, level), option, str(level), args.force)
    out = Path(args.out) if args.out else Path("out") / f"{probe.name}_figures"
    with output_folder(out, "--out", overwrite=args.overwrite) as folder:
        states = []
        for g in bounds:
            scene = load_scene(args.scene or DEFAULT_SCENE, [*(args.set or []), f"contact.g={g!r}"])
            model = plugin.build(scene, level)
            sol = vi_core.solve(model.vi, method="ssn")
            if not sol.converged:
                print(
                    f"mixvi: g = {g:g} did not converge (residual {sol.residual:.2e})",
                    file=sys.stderr,
                )
                return 1
            states.append((g, plugin.contact_state(model, sol)))
            st = states[-1][1]
            print(f"g = {g:.2e}: stick {int((~st['slip']).sum())}, slip {int(st['slip'].sum())}")
        with folder.staging() as tmp:
            plots.friction_comparison(states, tmp / "fig_5_4.png", title=probe.name)
    print(f"wrote {out}/fig_5_4.png")
    return 0
