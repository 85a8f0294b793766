"""`mixvi scenes`: the shipped scenes, the installed plug-ins and their scenes.

A plug-in that cannot be loaded, or a scene file that cannot be read, is listed as broken with
its error and the listing goes on (exit status 1 if anything is broken, else 0).
"""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path

from problems.errors import SceneError
from problems.plugins import registry
from problems.scene import SCENES_DIR


def _scene_row(p: Path, label: str) -> tuple[str, str, str, bool]:
    """(label, plug-in, title, ok) of one scene file; a broken one says why."""
    try:
        head = tomllib.loads(p.read_text()).get("scene", {})
        if not isinstance(head, dict):
            raise ValueError("[scene] is not a table")
        plugin, title = head.get("plugin", registry.DEFAULT), head.get("title", "")
        if not isinstance(plugin, str) or not isinstance(title, str):
            raise ValueError("[scene] plugin and title must be strings")
        return label, plugin, title, True
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, ValueError) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        return label, "?", f"BROKEN: {type(err).__name__}: {reason}", False


def cmd_scenes(args: argparse.Namespace) -> int:
    """The shipped scenes, the installed plug-ins, and the scenes plug-ins ship themselves."""
    dirs = [SCENES_DIR]
    plugins = []
    for name in registry.names():
        try:
            plug = registry.get(name)
            extra = getattr(plug, "SCENES_DIR", None)
            extra = None if extra is None else Path(extra)
        except SceneError as err:
            plugins.append((name, f"BROKEN: {err.allowed}", False))
            continue
        except Exception as err:  # third-party code: any failure is that plug-in's, not ours
            plugins.append((name, f"BROKEN: {type(err).__name__}: {err}", False))
            continue
        plugins.append((name, getattr(plug, "DESCRIPTION", ""), True))
        if extra is not None and extra not in dirs:
            dirs.append(extra)
    rows = []
    for d in dirs:
        try:
            files = sorted(Path(d).glob("*.toml"))
        except OSError as err:
            rows.append((str(d), "?", f"BROKEN: cannot list the folder ({err})", False))
            continue
        for p in files:
            rows.append(_scene_row(p, p.stem if d == SCENES_DIR else str(p)))
    w = max(len(r[0]) for r in rows)
    wp = max(len(r[1]) for r in rows)
    print("scenes:")
    for name, plugin, title, _ in rows:
        print(f"  {name:<{w}}  {plugin:<{wp}}  {title}")
    print("plug-ins:")
    wn = max(len(n) for n, _, _ in plugins)
    for name, desc, _ in plugins:
        print(f"  {name:<{wn}}  {desc}")
    broken = [r[0] for r in rows if not r[3]] + [n for n, _, ok in plugins if not ok]
    return 1 if broken else 0
