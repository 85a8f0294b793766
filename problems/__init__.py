"""mixvi's problems: scenes, plug-ins, the solve pipeline, the command line.

The Python API (imported on first use, so `import problems.scene` stays light):
`problems.load_scene(path)` → the validated scene model, `problems.solve_scene(path_or_model,
level=..., solver=..., **overrides)` → fields, contact state and info (`problems.api`).
"""

from __future__ import annotations

from typing import Any

__all__ = ["load_scene", "solve_scene"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'problems' has no attribute {name!r}")
