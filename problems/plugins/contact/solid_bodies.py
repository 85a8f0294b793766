"""Kept only for `solid_checks`, which imports SURFACE_ORDER from here (a module another
change rewrites): the 3D body section is `bodies.BodySection`, one for 2D and 3D, and
SURFACE_ORDER lives in `interface`. Delete this module once `solid_checks` imports it there."""

from .interface import SURFACE_ORDER

__all__ = ["SURFACE_ORDER"]
