"""Transitional re-export for branches in flight, issue 30; removed when the issue closes."""

from .geometry import Box, Extruded, Geometry3, MeshFile3

__all__ = ["Box", "Extruded", "Geometry3", "MeshFile3"]
