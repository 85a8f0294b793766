"""Transitional re-export for branches in flight, issue 30; removed when the issue closes.

The 3D traces moved to `fem.facets` (one trace type for 2D and 3D)."""

from .facets import Trace as Surface
from .facets import facet_integrals as face_integrals
from .facets import facet_rule as face_rule
from .facets import frames, reference_direction, triangle_rule
from .facets import trace as surface

__all__ = [
    "Surface",
    "face_integrals",
    "face_rule",
    "frames",
    "reference_direction",
    "surface",
    "triangle_rule",
]
