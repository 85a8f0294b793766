"""The scene language: files and overrides, expressions, materials, geometry, exact solutions.

Nothing here imports plug-ins or commands: a scene is read and checked before anything is built.
"""

from .reader import MAX_MAGNITUDE, SCENES_DIR, Scene, Table, find_scene, load_scene, parse_override

__all__ = [
    "MAX_MAGNITUDE",
    "SCENES_DIR",
    "Scene",
    "Table",
    "find_scene",
    "load_scene",
    "parse_override",
]
