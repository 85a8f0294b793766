"""The dimension of a contact scene, told from its raw data before it is validated: the
deprecated plug-in name says it (`piezo_contact` 2, `contact3d` 3), else the bodies'
geometries do (a 2D kind or a .geo file: 2; a 3D kind: 3; a mesh file: its highest cell
dimension). A scene whose bodies disagree is refused, naming the first body of the other
dimension."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from problems.errors import SceneError
from problems.scene.geometry import KINDS
from problems.scene.imported import file_dimension, resolve

ALIASES = {"piezo_contact": 2, "contact3d": 3}  # the former plug-ins and their dimension
DEFAULT = 2  # nothing tells (no body, an unreadable geometry): the 2D model names the error


def _geometry_dimension(geometry: Any, scene_file: str | None) -> int | None:
    """2 or 3 for one raw [bodies.NAME.geometry] table; None if it does not tell."""
    if not isinstance(geometry, dict):
        return None
    kind = geometry.get("kind")
    for d, kinds in KINDS.items():
        if kind in kinds:
            return d
    if "geo" in geometry:
        return 2
    name = geometry.get("mesh")
    if isinstance(name, str):
        folder = None if not scene_file or scene_file.startswith("<") else Path(scene_file).parent
        return file_dimension(resolve(folder, name))
    return None


def scene_dimension(data: Any, scene_file: str | None = None) -> int:
    """The dimension (2 or 3) of the raw scene `data` (module docstring)."""
    if not isinstance(data, dict):
        return DEFAULT
    head = data.get("scene")
    plugin = head.get("plugin") if isinstance(head, dict) else None
    if plugin in ALIASES:
        return ALIASES[plugin]
    bodies = data.get("bodies")
    seen: dict[int, str] = {}
    for name, table in bodies.items() if isinstance(bodies, dict) else ():
        geometry = table.get("geometry") if isinstance(table, dict) else None
        dim = _geometry_dimension(geometry, scene_file)
        if dim is not None:
            seen.setdefault(dim, name)
    if len(seen) > 1:
        raise SceneError(
            f"bodies.{seen[3]}.geometry",
            "a 3D geometry",
            f"bodies of one dimension (body {seen[2]!r} is 2D): a contact scene is 2D or 3D",
        )
    return next(iter(seen), DEFAULT)
