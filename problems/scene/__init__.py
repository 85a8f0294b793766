"""The scene language: files, format migration and overrides, the typed scene model,
expressions, materials, geometry, exact solutions.

Nothing here imports plug-ins or commands: a scene is read and validated before anything is
built (each plug-in's own scene model subclasses `SceneModel`).
"""

from .expressions import MAX_MAGNITUDE
from .model import FORMAT, SceneModel, Section, validate
from .reader import SCENES_DIR, Scene, find_scene, load_scene, parse_override

__all__ = [
    "FORMAT",
    "MAX_MAGNITUDE",
    "SCENES_DIR",
    "Scene",
    "SceneModel",
    "Section",
    "find_scene",
    "load_scene",
    "parse_override",
    "validate",
]
