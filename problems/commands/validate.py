"""`mixvi validate SCENE [--set k=v ...]`: check a scene and everything it refers to, writing
nothing and solving nothing.

First the scene model (keys, types, ranges, names, expressions: the field path of every error),
then the plug-in builds the scene at level 0: that opens every mesh file the scene names and
makes the checks a solve makes at build time — missing or misspelt physical groups (the
available ones listed), unsupported cells, inverted or degenerate cells, a contact boundary
that is not one simple curve, crosspoints and uncovered contact nodes, a [solver] method the
scene's multiplier set cannot take. Any of them is exit 2 with the field path, exactly as
`mixvi solve` would refuse it. Refinement keeps a valid mesh valid, so level 0 stands for every
level; the size of the requested level is the solve's own check (memory estimate and cell
limit).
"""

from __future__ import annotations

import argparse

import problems.pipeline as pipeline

from .solve import load


def cmd_validate(args: argparse.Namespace) -> int:
    """Validate a scene, its overrides and its mesh files (SceneError → exit 2)."""
    loaded = load(args)
    model = loaded.plugin.build(loaded.scene, 0)  # the solve's build-time checks, level 0
    pipeline.method_of(loaded, model)  # the scene's [solver] method suits its multiplier set
    head = loaded.spec.scene
    print(
        f"{loaded.scene.path}: valid {loaded.plugin.NAME} scene (format "
        f"{loaded.spec.format}, level {head.level}){': ' + head.title if head.title else ''}"
    )
    warnings = list(getattr(model, "warnings", []))
    for w in warnings:
        print(f"  warning (level 0): {w}")
    return 0
