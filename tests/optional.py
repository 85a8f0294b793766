"""Optional packages in the tests: used where they work, the test skipped where they do not."""

from __future__ import annotations

from types import ModuleType

import pytest


def gmsh() -> ModuleType:
    """The gmsh module, or skip: not installed (ImportError), or installed but its library
    cannot load the system's OpenGL/X11 libraries (OSError from ctypes)."""
    try:
        import gmsh as module
    except (ImportError, OSError) as err:
        pytest.skip(f"gmsh unusable here: {type(err).__name__}: {err}")
    return module


def has_gmsh() -> bool:
    """Whether gmsh imports (see `gmsh`)."""
    try:
        import gmsh  # noqa: F401
    except (ImportError, OSError):
        return False
    return True
