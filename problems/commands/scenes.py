"""`mixvi scenes`: the shipped scenes, the installed plug-ins and their scenes."""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path

from problems.errors import SceneError
from problems.plugins import registry
from problems.scene import SCENES_DIR


def cmd_scenes(args: argparse.Namespace) -> int:
    """The shipped scenes, the installed plug-ins, and the scenes plug-ins ship themselves."""
    dirs = [SCENES_DIR]
    plugins = []
    for name in registry.names():
        try:
            plug = registry.get(name)
        except SceneError as err:
            plugins.append((name, f"(cannot be loaded: {err})"))
            continue
        plugins.append((name, getattr(plug, "DESCRIPTION", "")))
        extra = getattr(plug, "SCENES_DIR", None)
        if extra is not None and Path(extra) not in dirs:
            dirs.append(Path(extra))
    rows = []
    for d in dirs:
        for p in sorted(Path(d).glob("*.toml")):
            head = tomllib.loads(p.read_text()).get("scene", {})
            label = p.stem if d == SCENES_DIR else str(p)
            rows.append((label, head.get("plugin", "piezo_contact"), head.get("title", "")))
    w = max(len(r[0]) for r in rows)
    wp = max(len(r[1]) for r in rows)
    print("scenes:")
    for name, plugin, title in rows:
        print(f"  {name:<{w}}  {plugin:<{wp}}  {title}")
    print("plug-ins:")
    wn = max(len(n) for n, _ in plugins)
    for name, desc in plugins:
        print(f"  {name:<{wn}}  {desc}")
    return 0
