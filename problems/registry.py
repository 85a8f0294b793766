"""Plug-in registry: built-in plug-ins plus third-party ones from the entry point group
`mixvi.plugins` (each entry point names a module with NAME, DESCRIPTION, build, postprocess)."""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from types import ModuleType

from .errors import SceneError

BUILTIN = {"piezo_contact": "problems.piezo_contact"}
GROUP = "mixvi.plugins"


def plugins() -> dict[str, ModuleType]:
    """All plug-ins by name (built-in first; entry points may add, not replace)."""
    found = {name: importlib.import_module(mod) for name, mod in BUILTIN.items()}
    for ep in entry_points(group=GROUP):
        if ep.name not in found:
            found[ep.name] = ep.load()
    return found


def get(name: str) -> ModuleType:
    """The plug-in called `name` (SceneError listing the known ones otherwise)."""
    found = plugins()
    if name not in found:
        raise SceneError("scene.plugin", name, "one of the installed plug-ins: " + ", ".join(found))
    return found[name]
