"""Plug-in registry: built-in plug-ins plus third-party ones from the entry point group
`mixvi.plugins` (each entry point names a module with CONTRACT = 2, NAME, DESCRIPTION, build,
postprocess and the optional declarations of the commands; see `problems.plugins.contract` for
the contract and docs/plugins.md for a worked example). A plug-in written against another
contract version is refused when it is loaded, with what changed.

A third-party package declares, in its pyproject.toml,

    [project.entry-points."mixvi.plugins"]
    myplug = "myplug"            # entry point name = the module's NAME

Only the plug-in a scene asks for is imported, so a broken third-party plug-in cannot stop the
built-in ones from working.
"""

from __future__ import annotations

import importlib
import sys
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from problems.errors import SceneError

from .contract import CONTRACT, conforms

BUILTIN = {
    "contact": "problems.plugins.contact",
    "obstacle": "problems.plugins.obstacle",
    "antiplane": "problems.plugins.antiplane",
    "signorini": "problems.plugins.signorini",
}
# former names still accepted in scenes (one release): each is the plug-in it names, with a
# one-line notice on stderr; `contact` reads the dimension they fixed from them
ALIASES = {"piezo_contact": "contact", "contact3d": "contact"}
GROUP = "mixvi.plugins"
DEFAULT = "contact"  # the plug-in of a scene without [scene] plugin


def _third_party() -> dict[str, EntryPoint]:
    """Entry points of the group by name (built-in names cannot be replaced)."""
    return {ep.name: ep for ep in entry_points(group=GROUP) if ep.name not in BUILTIN}


def names() -> list[str]:
    """Names of all plug-ins, built-in first, without importing any."""
    return [*BUILTIN, *sorted(_third_party())]


def _checked(name: str, obj: Any, origin: str) -> Any:
    missing = conforms(obj)
    if missing:
        raise SceneError(
            "scene.plugin",
            name,
            f"a plug-in of contract v{CONTRACT} providing CONTRACT, NAME, DESCRIPTION, build() "
            f"and postprocess(); {origin} lacks {'; '.join(missing)}",
        )
    if obj.NAME != name:
        raise SceneError(
            "scene.plugin",
            name,
            f"a plug-in whose NAME equals its registered name; {origin} has NAME = {obj.NAME!r}",
        )
    return obj


def _load(name: str, eps: dict[str, EntryPoint]) -> Any:
    if name in BUILTIN:
        return _checked(name, importlib.import_module(BUILTIN[name]), f"module {BUILTIN[name]}")
    ep = eps[name]
    origin = f"entry point {name} = {ep.value!r} (group {GROUP})"
    try:
        obj = ep.load()
    except Exception as err:  # a third-party import can fail in any way; name it, don't crash
        raise SceneError(
            "scene.plugin", name, f"an importable plug-in; {origin} failed to load: {err!r}"
        ) from None
    return _checked(name, obj, origin)


def plugins() -> dict[str, Any]:
    """All plug-ins by name, imported (built-in first; entry points may add, not replace)."""
    eps = _third_party()
    return {name: _load(name, eps) for name in [*BUILTIN, *sorted(eps)]}


def fronts(plugin: Any) -> list[Any]:
    """The modules that serve a plug-in's scenes: its `FRONTS` (contact: 2D and 3D), or the
    plug-in itself."""
    return list(getattr(plugin, "FRONTS", {None: plugin}).values())


def get(name: str) -> Any:
    """The plug-in called `name`, imported and checked (SceneError listing the known ones); a
    former name (`ALIASES`) gives the plug-in it became, with a notice on stderr."""
    if name in ALIASES:
        print(
            f"notice: plug-in {name!r} is now {ALIASES[name]!r}: write [scene] plugin = "
            f"{ALIASES[name]!r} (the old name is accepted for one release)",
            file=sys.stderr,
        )
        name = ALIASES[name]
    eps = _third_party()
    if name not in BUILTIN and name not in eps:
        raise SceneError(
            "scene.plugin",
            name,
            "one of the installed plug-ins: "
            + ", ".join(names())
            + f" (third-party plug-ins register under the entry point group {GROUP!r})",
        )
    return _load(name, eps)


def for_scene(scene: Any) -> Any:
    """The plug-in a scene asks for (`[scene] plugin`, default "contact"); a plug-in with
    several fronts (`front(scene)`: contact's 2D and 3D ones) gives the scene's. Any
    SceneError names the scene file."""
    head = scene.data.get("scene", {})
    name = head.get("plugin", DEFAULT) if isinstance(head, dict) else DEFAULT
    try:
        if not isinstance(name, str):
            raise SceneError("scene.plugin", name, "the name of an installed plug-in (a string)")
        plugin = get(name)
        front = getattr(plugin, "front", None)
        return plugin if front is None else _checked(plugin.NAME, front(scene), "its front")
    except SceneError as err:
        raise err.in_file(scene.path) from None
