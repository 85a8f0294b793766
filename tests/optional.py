"""Optional packages in the tests: used where they work, the test skipped where they do not."""

from __future__ import annotations

from types import ModuleType

import pytest


def _load_gmsh() -> ModuleType | Exception:
    """The gmsh module, or why it cannot be used: not installed (ImportError), or installed but
    its library cannot load the system's OpenGL/X11 libraries (OSError from ctypes)."""
    try:
        import gmsh as module
    except (ImportError, OSError) as err:
        return err
    return module


def gmsh() -> ModuleType:
    """The gmsh module, or skip the test (`_load_gmsh`)."""
    loaded = _load_gmsh()
    if isinstance(loaded, Exception):
        pytest.skip(f"gmsh unusable here: {type(loaded).__name__}: {loaded}")
    return loaded


def has_gmsh() -> bool:
    """Whether gmsh can be used (`_load_gmsh`)."""
    return not isinstance(_load_gmsh(), Exception)
