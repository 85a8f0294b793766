"""`mixvi schema`: the JSON Schema of scenes (every installed plug-in's scene model), for
editors that complete and check TOML/JSON scenes; `mixvi validate SCENE [--set k=v ...]`:
check a scene and its overrides without building or solving anything (exit 0 or 2)."""

from __future__ import annotations

import argparse
import json
import sys

from problems.plugins import registry
from problems.scene.model import json_schema

from .solve import load


def scene_schema() -> dict:
    """The JSON Schema of the scenes of every installed plug-in."""
    return json_schema({name: p.SCENE_MODEL for name, p in registry.plugins().items()})


def cmd_schema(args: argparse.Namespace) -> int:
    """Print the JSON Schema of scenes."""
    sys.stdout.write(json.dumps(scene_schema(), indent=2, ensure_ascii=False) + "\n")
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    """Validate a scene and its overrides (SceneError → exit 2); nothing is built."""
    loaded = load(args)
    head = loaded.spec.scene
    print(
        f"{loaded.scene.path}: valid {loaded.plugin.NAME} scene (format "
        f"{loaded.spec.format}, level {head.level}){': ' + head.title if head.title else ''}"
    )
    return 0
